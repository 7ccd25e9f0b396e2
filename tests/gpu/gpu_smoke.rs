//! The GPU stage on the strict OpenGL ES 3.0 context (Mesa llvmpipe through EGL), or the backend
//! `CLIPSAT_GPU` names: adapter, brute-force reference render, readback and image hash.

use std::collections::BTreeSet;
use std::path::Path;

use crate::render_support::{on_vulkan, strict};
use clipsat::gpu::brute::{BruteForce, Frame};
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::plan::camera::Camera;
use clipsat::shading::basic::SKY;
use clipsat::source::procedural::{self, ProceduralParams};
use clipsat::source::Heightmap;

const W: u32 = 256;
const H: u32 = 160;

/// A 129 x 129 terrain with relief that does not depend on the procedural generator: a tilted plane with
/// a ridge and a valley, partly below sea level.
fn sloped() -> Heightmap {
    let n = 129u32;
    let heights = (0..n * n)
        .map(|i| {
            // Exact: i % n and i / n are below 2^24.
            let (u, v) = ((i % n) as f32, (i / n) as f32);
            let ridge = 400.0 * (-((u - 80.0).powi(2) + (v - 50.0).powi(2)) / 600.0).exp();
            let waves = 60.0 * (u * 0.15).sin() * (v * 0.11).cos();
            u * 4.0 + (128.0 - v) * 3.0 - 120.0 + ridge + waves
        })
        .collect();
    Heightmap::new(Path::new("<sloped>"), n, n, 30.0, heights).expect("valid synthetic terrain")
}

fn render(gpu: &Gpu, hm: &Heightmap) -> Frame {
    let camera = Camera::default_for(hm).expect("default camera");
    let mut brute = BruteForce::new(gpu, hm).expect("brute-force set-up");
    brute.render(&camera, W, H).expect("brute-force frame")
}

/// The top-left pixel of the default view is sky: check it is the clear colour and return it.
fn sky(img: &clipsat::gpu::readback::Image) -> [u8; 4] {
    let p = img.pixel(0, 0);
    for (got, want) in p.iter().zip(SKY) {
        assert!(
            (f64::from(*got) / 255.0 - want).abs() <= 1.0 / 255.0,
            "top-left pixel {p:?} is not the sky colour {:?}",
            SKY
        );
    }
    p
}

/// The device offers what clipsat uses, whatever its version string says (NVIDIA's EGL hands out
/// OpenGL ES 3.2 for a 3.0 request, with no way to pin it): every limit of the GLES 3.0 floor and every
/// texture format with the usages clipsat gives it (`gpu::floor`), and the device is created on that
/// floor whatever the adapter could do (no compute, no storage buffers: their limits are 0). A GL context
/// is OpenGL ES 3.0 or later; Mesa's, pinned by `MESA_GLES_VERSION_OVERRIDE=3.0`, exactly 3.0.
#[test]
fn adapter_offers_what_clipsat_uses() {
    let gpu = strict();
    let r = gpu.report();
    let checks = clipsat::gpu::floor::check(gpu.adapter());
    let short = clipsat::gpu::floor::shortfalls(&checks);
    assert!(short.is_empty(), "{r:?}: {short:?}");
    assert!(checks.len() > 5, "{checks:?}");
    let l = gpu.device().limits();
    let floor = wgpu::Limits::downlevel_webgl2_defaults();
    assert_eq!(l.max_storage_buffers_per_shader_stage, 0, "{r:?}");
    assert_eq!(l.max_compute_workgroups_per_dimension, 0, "{r:?}");
    assert_eq!(
        (l.max_texture_dimension_2d, l.max_texture_array_layers),
        (
            floor.max_texture_dimension_2d,
            floor.max_texture_array_layers
        ),
        "the device is created on the floor"
    );
    if on_vulkan() {
        assert_eq!((r.backend.as_str(), r.mode.as_str()), ("Vulkan", "vulkan"));
        return;
    }
    assert_eq!((r.backend.as_str(), r.mode.as_str()), ("Gl", "strict"));
    // GL_VERSION of an ES context is "OpenGL ES N.M <vendor text>" (GLES 3.0 spec, section 6.1.5).
    let version = r
        .gl_version
        .strip_prefix("OpenGL ES ")
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.split_once('.'))
        .and_then(|(a, b)| Some((a.parse::<u32>().ok()?, b.parse::<u32>().ok()?)));
    let Some(version) = version else {
        panic!("not an OpenGL ES context: {r:?}");
    };
    assert!(version >= (3, 0), "{r:?}");
    let pinned = std::env::var("MESA_GLES_VERSION_OVERRIDE").ok();
    if r.driver.starts_with("Mesa") && pinned.as_deref() == Some("3.0") {
        assert_eq!(version, (3, 0), "Mesa pinned to ES 3.0: {r:?}");
    }
}

#[test]
fn hash_is_stable_across_renders_and_devices() {
    for hm in [
        sloped(),
        procedural::generate(&ProceduralParams {
            size: 129,
            ..Default::default()
        })
        .expect("procedural terrain"),
    ] {
        let (a, b) = {
            let gpu = strict();
            let camera = Camera::default_for(&hm).expect("default camera");
            let mut brute = BruteForce::new(&gpu, &hm).expect("set-up");
            let a = brute.render(&camera, W, H).expect("frame 1");
            let b = brute.render(&camera, W, H).expect("frame 2");
            (a, b)
        };
        assert_eq!(a.image_hash, b.image_hash, "two renders on one device");
        assert_eq!(a.triangles, 2 * 128 * 128);
        assert_eq!(a.image.rgba.len(), (W * H * 4) as usize);
        let other = strict();
        let c = render(&other, &hm);
        assert_eq!(a.image_hash, c.image_hash, "a second Gpu instance");
    }
}

#[test]
fn two_live_gpus_on_one_thread() {
    let hm = sloped();
    let g1 = strict();
    let g2 = strict();
    let a = render(&g1, &hm);
    let b = render(&g2, &hm);
    let c = render(&g1, &hm);
    assert_eq!(a.image_hash, b.image_hash);
    assert_eq!(a.image_hash, c.image_hash);
}

#[test]
fn image_is_not_blank() {
    let gpu = strict();
    let frame = render(&gpu, &sloped());
    let img = &frame.image;
    let sky = sky(img);
    let colours: BTreeSet<[u8; 4]> = img
        .rgba
        .chunks_exact(4)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect();
    assert!(
        colours.len() > 50,
        "only {} distinct colours",
        colours.len()
    );
    // The default view looks down on the terrain: the bottom-centre pixel is terrain, not sky.
    let bottom = img.pixel(W / 2, H - 5);
    assert_ne!(bottom, sky, "terrain expected at the bottom of the view");
    let terrain = img.rgba.chunks_exact(4).filter(|p| *p != sky).count();
    assert!(
        terrain > (W * H / 3) as usize,
        "terrain covers only {terrain} of {} pixels",
        W * H
    );
    assert!(img.rgba.chunks_exact(4).all(|p| p[3] == 255), "opaque");
}

#[test]
fn gpus_on_several_threads() {
    let hashes: Vec<u64> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..3)
            .map(|_| s.spawn(|| render(&strict(), &sloped()).image_hash))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("render thread"))
            .collect()
    });
    assert!(hashes.windows(2).all(|w| w[0] == w[1]), "{hashes:x?}");
}

#[test]
fn refuses_oversized_images() {
    let gpu = strict();
    let hm = sloped();
    let camera = Camera::default_for(&hm).expect("default camera");
    let mut brute = BruteForce::new(&gpu, &hm).expect("set-up");
    assert!(brute.render(&camera, 4096, 100).is_err());
    assert!(brute.render(&camera, 0, 100).is_err());
}

#[test]
fn refuses_terrain_beyond_the_floor() {
    // 3000 x 4000 samples: the u32 index buffer needs 288 MB, over the 256 MiB buffer limit.
    let hm = Heightmap::new(Path::new("<big>"), 3000, 4000, 10.0, vec![0.0; 3000 * 4000])
        .expect("valid terrain");
    let gpu = strict();
    let err = BruteForce::new(&gpu, &hm).expect_err("over the GLES 3.0 floor");
    assert!(matches!(err, clipsat::Error::Gpu { .. }), "{err}");
    assert!(err.to_string().contains("too large"), "{err}");
}

#[test]
fn strict_survives_a_gl_mode_gpu() {
    // Both modes share EGL's one surfaceless display; a wgpu GL device coming and going must not take
    // the strict context down with it. (GL only: the Vulkan pass has no EGL display.)
    if on_vulkan() {
        return;
    }
    let hm = sloped();
    let strict_gpu = strict();
    let before = render(&strict_gpu, &hm).image_hash;
    {
        let gl = Gpu::new(GpuMode::Gl).expect("wgpu GL backend on llvmpipe");
        assert_eq!(gl.report().mode, "gl");
        let frame = render(&gl, &hm);
        assert_eq!(frame.image.rgba.len(), (W * H * 4) as usize);
    }
    assert_eq!(render(&strict_gpu, &hm).image_hash, before);
    assert_eq!(
        Gpu::new(GpuMode::Auto).expect("auto").report().mode,
        "strict"
    );
}
