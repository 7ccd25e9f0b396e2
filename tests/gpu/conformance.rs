//! What GLES 3.0 leaves undefined and Mesa happens to define (docs/real-drivers.md): checks that fail on
//! Mesa too where a shader or the renderer relied on it. The SG shader's ring and texel choice on a
//! frame whose finest rings hold no data (NVIDIA read the flat middle of the coarsest ring, and hung),
//! and the read-back's wait, which wgpu's GL backend cut at 2.15 s.

use crate::render_support;

use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen};
use clipsat::gpu::readback::wait_for_gpu;
use clipsat::gpu::renderer::{ProbedFrame, ShadingProbe};
use clipsat::plan::camera::Camera;
use clipsat::plan::lod::LodMode;
use clipsat::shading::scene::Scene;
use clipsat::shading::{Patches, TexelLighting};
use clipsat::twin::border;
use clipsat::twin::frame::{compare_basic, compare_sg, SgDrawn};
use std::time::Duration;

/// gles3-low with SG allowed, the golden SG frame's profile.
fn sg_profile(width: u32, height: u32) -> clipsat::profile::Profile {
    let mut p = render_support::profile("gles3-low", width, height, None);
    p.shading.features.push(clipsat::profile::Feature::Sg);
    p.budget.update_samples_per_frame = u32::MAX;
    p
}

/// The golden SG frame's terrain: procedural 257^2.
fn procedural() -> clipsat::source::Heightmap {
    clipsat::source::procedural::generate(&clipsat::source::procedural::ProceduralParams {
        size: 257,
        ..Default::default()
    })
    .expect("procedural terrain")
}

/// Every texel the SG shader reads (the CPU twin `sg_taps`, whose float-to-int conversions panic where
/// GLSL ES 3.00 leaves them undefined) lies in a ring that holds data, at a layer in use, inside the
/// ring's clip region (which the tables write, `sg_tables_follow_the_rings`) and inside the texture, and
/// holds the bake's value there; on the golden SG frame, whose levels 0 to 6 hold no data (the eye is
/// high: spacing 0 in their uniforms), for points near and far, and footprints from below one sample to
/// NaN and infinity. Before the fix the twin overflowed here (the data level came from level 0's zero
/// spacing: log2 of an infinity, converted to int).
#[test]
fn sg_reads_only_written_texels_of_held_rings() {
    let gpu = render_support::strict();
    let hm = procedural();
    let p = sg_profile(160, 90);
    let mut cm = render_support::clipmap(&hm, &p);
    let cam = Camera::default_for(&hm).expect("camera");
    cm.update(cam.eye).expect("update");
    let scene = Scene::load("evening").expect("evening");
    let share = p.cpu_split().shading;
    let (_, bake) = clipsat::gpu::headless::sg_bake(share, &hm, &scene, true).expect("bake");
    let mut r =
        Offscreen::with_sg(&gpu, &p, &cm, &hm, &scene, Patches::P4x8, true).expect("sg renderer");
    render_frame(&mut r, &cm, &cam, &FrameOptions::default()).expect("frame");
    let g = *r.globals();
    let used = g.level_info[0];
    let empty = (0..used)
        .filter(|&l| g.levels[l as usize].tex[2] == 0)
        .count();
    assert!(empty > 0, "the frame should have levels without data");
    let tables = r.read_sg_normals().expect("normal table");
    let s = i64::from(p.clip_size());
    let synth = i32::try_from(cm.synth_levels()).expect("levels");
    let (ex, ey) = hm.extent_m();
    let (ox, oy) = cm.origin();
    let mut read = 0;
    for fy in -4..=12 {
        for fx in -4..=12 {
            // Over the data and well past it, relative to the eye.
            let x = ox + ex * f64::from(fx) / 8.0 - cam.eye.x;
            let y = oy + ey * f64::from(fy) / 8.0 - cam.eye.y;
            #[expect(
                clippy::cast_possible_truncation,
                reason = "eye-relative metres, as f32"
            )]
            let rel = [x as f32, y as f32];
            for w in [
                0.0,
                0.5,
                1.0,
                1.49,
                2.0,
                7.0,
                1.0e3,
                1.0e30,
                f32::INFINITY,
                f32::NAN,
            ] {
                let t = clipsat::twin::shading::sg_taps(&g, bake.data_spacing(), rel, w)
                    .expect("the frame has a ring of 4 x 4 samples");
                let l = t.level as usize;
                assert!(
                    t.level < used.unsigned_abs(),
                    "level {l} past the levels in use"
                );
                assert!(t.level < p.sg_normal_layers(), "level {l} past the layers");
                let lv = g.levels[l];
                assert!(
                    lv.tex[2] >= 4 && lv.tex[3] >= 4,
                    "level {l} holds no data: {lv:?}"
                );
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (cx, cy) = (t.cell[0] + dx, t.cell[1] + dy);
                    assert!(
                        (0..lv.tex[2]).contains(&cx) && (0..lv.tex[3]).contains(&cy),
                        "({rel:?}, {w}): texel ({cx}, {cy}) of level {l} outside its clip region"
                    );
                    let (tx, ty) = (lv.tex[0] + cx, lv.tex[1] + cy);
                    let (tx, ty) = (i64::from(tx) % s, i64::from(ty) % s);
                    let clip = cm.frame().levels[l].clip;
                    let i = clip.x0 + i64::from(cx);
                    let j = clip.y0 + i64::from(cy);
                    assert_eq!(
                        (tx, ty),
                        (i.rem_euclid(s), j.rem_euclid(s)),
                        "toroidal texel"
                    );
                    let want = bake
                        .level_texel(i32::try_from(l).expect("level") - synth, i, j)
                        .0;
                    let got = tables[l][usize::try_from(ty * s + tx).expect("texel")];
                    assert_eq!(
                        [got[0], got[1], got[2]],
                        [want.x, want.y, want.z],
                        "level {l} texel ({tx}, {ty}) was not written with the bake's value"
                    );
                }
                read += 1;
            }
        }
    }
    assert!(read > 2000, "{read} points read");
}

/// The read-back waits for a frame that takes longer than one poll's slice (wgpu's GL backend waits at
/// most 2.15 s per poll, even when asked to wait indefinitely, and then reports a timeout): here with
/// 100-microsecond slices on a frame llvmpipe takes far longer to draw, which a single wait would have
/// reported as a timeout; and a frame still running when the limit passes is reported as hung.
#[test]
fn readback_waits_past_one_poll_and_names_a_hang() {
    let gpu = render_support::strict();
    let hm = procedural();
    let p = sg_profile(480, 270);
    let mut cm = render_support::clipmap(&hm, &p);
    let cam = Camera::default_for(&hm).expect("camera");
    cm.update(cam.eye).expect("update");
    let scene = Scene::load("evening").expect("evening");
    let mut r =
        Offscreen::with_sg(&gpu, &p, &cm, &hm, &scene, Patches::P4x8, true).expect("sg renderer");
    // The first frame also compiles the programs: warm up, then time one.
    render_frame(&mut r, &cm, &cam, &FrameOptions::default()).expect("frame");
    r.frame(&cm, &cam, &FrameOptions::default()).expect("frame");
    let slice = Duration::from_micros(100);
    let wait = wait_for_gpu(gpu.device(), Duration::from_secs(60), slice).expect("waited");
    assert!(
        wait.polls > 1,
        "the frame finished within one {slice:?} poll ({wait:?}): too light to test the loop"
    );
    r.frame(&cm, &cam, &FrameOptions::default()).expect("frame");
    let err = wait_for_gpu(gpu.device(), Duration::from_micros(200), slice)
        .expect_err("a frame longer than the limit");
    assert!(err.to_string().contains("hung"), "{err}");
    // The device is still usable: the next read-back waits for both frames.
    render_frame(&mut r, &cm, &cam, &FrameOptions::default()).expect("frame after the hang report");
}

/// What `r` drew for its last frame, and what its programs shaded each pixel with.
fn probed(
    r: &mut Offscreen<'_>,
    cm: &clipsat::plan::clipmap::Clipmap,
    cam: &Camera,
    opts: &FrameOptions,
) -> (clipsat::gpu::readback::Image, ProbedFrame) {
    let probe = ShadingProbe::new(r).expect("shading probe");
    let image = render_frame(r, cm, cam, opts).expect("frame").image;
    (image, probe.capture(r).expect("probe"))
}

/// The SG frame against its CPU twin (`twin::frame::compare_sg`), within what GLES 3.0 allows a
/// conformant driver (docs/real-drivers.md): what the shader read (r, against the bake's texels at the
/// twin's taps) and the colour, pixel by pixel, on the golden SG frame (evening: visibility, specular,
/// fog; levels 0 to 6 without data) and at noon with a flight's stale rings. NVIDIA's driver drew the
/// finer rings of such frames flat (r read from the wrong ring): off by tens of levels.
#[test]
fn sg_frames_match_their_twin() {
    let gpu = render_support::strict();
    let hm = procedural();
    let clear = border::clear_rgba8(FrameOptions::default().clear);
    let p = sg_profile(160, 90);
    let mut cm = render_support::clipmap(&hm, &p);
    let cam = Camera::default_for(&hm).expect("camera");
    cm.update(cam.eye).expect("update");
    for (name, patches) in [("evening", Patches::P4x8), ("noon", Patches::P2x4)] {
        let scene = Scene::load(name).expect("scene");
        let share = p.cpu_split().shading;
        let (_, bake) = clipsat::gpu::headless::sg_bake(share, &hm, &scene, true).expect("bake");
        let mut r = Offscreen::with_sg(&gpu, &p, &cm, &hm, &scene, patches, true).expect("sg");
        let (image, probe) = probed(&mut r, &cm, &cam, &FrameOptions::default());
        let (drawn, sky, spacing) = r.renderer().sg_drawn().expect("SG");
        let lighting = TexelLighting::new(&drawn);
        let d = SgDrawn {
            scene: &drawn,
            sky,
            lighting: &lighting,
            bake: &bake,
            data_spacing: spacing,
        };
        let report = compare_sg(&image, &probe, clear, r.globals(), &cm, &d);
        println!("{name}: {report:?}");
        assert!(report.pixels > 160 * 90 / 3, "{name}: {report:?}");
        assert!(
            report.passes(),
            "{name}: the frame is not its twin's: {report:?}"
        );
    }
}

/// A basic-shading frame (distance LOD, the fragment programs' ring data) and a SAT LOD frame drawing
/// detail pool cells against the twin of `basic_shade` on the inputs each pixel was shaded with.
#[test]
fn basic_and_pool_frames_match_their_twin() {
    let gpu = render_support::strict();
    let hm = render_support::relief();
    let clear = border::clear_rgba8(FrameOptions::default().clear);
    let mut p = render_support::profile("gles3-low", 256, 144, None);
    p.budget.detail_tiles = 300;
    p.validate("test").expect("valid");
    let mut cm = render_support::clipmap(&hm, &p);
    let cam = render_support::flight(&hm, 7, 37.0, 120.0, None);
    for _ in 0..40 {
        cm.update(cam.eye).expect("update");
    }
    let tables = render_support::lod(&hm, &p, &cm);
    for mode in [LodMode::Distance, LodMode::Sat] {
        // SAT LOD at a tight bound, so blocks need finer data than the rings hold: the pool's.
        let opts = FrameOptions {
            epsilon_px: (mode == LodMode::Sat).then_some(0.5),
            ..FrameOptions::default()
        };
        let mut r = render_support::renderer_in(
            &gpu,
            &p,
            &cm,
            mode,
            Some(&tables),
            clipsat::shading::debug_view::DebugView::Normal,
        );
        if mode == LodMode::Sat {
            // The pool fills from what the settled rings leave of each frame's budget.
            for _ in 0..8 {
                cm.update(cam.eye).expect("update");
                r.frame(&cm, &cam, &opts).expect("frame");
            }
        }
        let (image, probe) = probed(&mut r, &cm, &cam, &opts);
        if mode == LodMode::Sat {
            assert!(r.plan().stats().pool_cells > 0, "no pool cells drawn");
        }
        let report = compare_basic(&image, &probe, clear, &r.shading());
        println!("{mode}: {report:?}");
        assert!(report.pixels > 256 * 144 / 3, "{mode}: {report:?}");
        assert!(
            report.passes(),
            "{mode}: the frame is not its twin's: {report:?}"
        );
    }
}

/// `clipsat selftest --json` without a device it can use (`CLIPSAT_GPU` naming no backend): the adapter
/// check fails and it exits 1. Its passing runs, on every driver present, are `tests/cli/cross_driver.rs`.
#[test]
fn selftest_exits_1_without_a_device() {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("selftest-cache");
    let failed = std::process::Command::new(env!("CARGO_BIN_EXE_clipsat"))
        .args(["selftest", "--json", "--frames", "5"])
        .env("CLIPSAT_CACHE", &cache)
        .env("CLIPSAT_GPU", "no-such-backend")
        .output()
        .expect("run clipsat selftest");
    assert_eq!(
        failed.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&failed.stdout)
    );
    let v: serde_json::Value = serde_json::from_slice(&failed.stdout).expect("json");
    assert_eq!(v["passed"], false);
    assert_eq!(v["checks"][0]["name"], "adapter");
    assert_eq!(v["checks"][0]["ok"], false);
}
