//! Frames worth looking at: the default camera frames any terrain, shading comes from the finest
//! resident ring data (GC section 6) whatever level a block is drawn at (CPU twin `twin::shading` and the
//! renderer: SAT LOD's image error against the brute-force render stays near distance LOD's), and scene fog
//! is fitted to the terrain. Headless strict GLES 3.0 on llvmpipe for the GPU test.

use std::path::Path;

use crate::render_support::{clipmap, lod, profile, relief, renderer_in, strict};
use bytemuck::Zeroable;
use clipsat::gpu::brute::BruteForce;
use clipsat::gpu::headless::{render_frame, FrameOptions};
use clipsat::measure::image_rmse;
use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::Clipmap;
use clipsat::plan::lod::LodMode;
use clipsat::plan::uniforms::{shading_levels, Globals};
use clipsat::profile::Profile;
use clipsat::shading::debug_view::DebugView;
use clipsat::source::Heightmap;
use clipsat::twin::border;
use clipsat::twin::shading::data_surface;
use glam::{DVec3, DVec4};

fn filled(hm: &Heightmap, p: &Profile, eye: DVec3) -> Clipmap {
    let mut cm = clipmap(hm, p);
    cm.fill_at(eye, 10_000).expect("fill");
    cm
}

/// The relief terrain, an eye above it, the clipmap filled there (gles3-mid) and the shading globals
/// the renderer would write for that frame: what the twin tests read.
fn twin_frame() -> (Heightmap, DVec3, Clipmap, Globals) {
    let hm = relief();
    let p = profile("gles3-mid", 320, 180, None);
    let eye = DVec3::new(7000.0, 6000.0, 1500.0);
    let cm = filled(&hm, &p, eye);
    let cam = Camera::new(eye, DVec3::new(9000.0, 9000.0, 0.0), 60.0).expect("camera");
    let mut globals = Globals::zeroed();
    (globals.levels, globals.level_info) = shading_levels(&cm, &cam, cm.ring(0).size());
    (hm, eye, cm, globals)
}

fn grid(name: &str, w: u32, h: u32, spacing: f32, f: impl Fn(f32, f32) -> f32) -> Heightmap {
    let heights = (0..w * h)
        .map(|i| f((i % w) as f32, (i / w) as f32))
        .collect();
    Heightmap::new(Path::new(name), w, h, spacing, heights).expect("valid test terrain")
}

/// Flat, tiny, huge and non-square terrains, and terrains with outliers (an untagged void 30 km down, a
/// spike): the default camera looks down at the terrain's middle from above every sample, sees its centre,
/// far part and the middle 40 % of its width at its typical height, and stands within a terrain's extent
/// of it (not a plate on the horizon).
#[test]
fn default_camera_frames_any_terrain() {
    let terrains = [
        grid("<flat>", 65, 65, 30.0, |_, _| 0.0),
        grid("<tiny>", 3, 3, 1.0, |u, v| u + v),
        grid("<huge>", 257, 257, 4000.0, |u, v| {
            3000.0 * (u * 0.05).sin() * (v * 0.04).cos()
        }),
        grid("<wide>", 513, 33, 30.0, |u, _| 200.0 * (u * 0.02).sin()),
        grid("<tall>", 17, 400, 10.0, |_, v| v),
        grid("<pit>", 513, 129, 30.0, |u, v| {
            if u < 5.0 && v < 5.0 {
                -32768.0
            } else {
                150.0 * (u * 0.03).sin() * (v * 0.05).cos()
            }
        }),
        grid("<spike>", 257, 257, 30.0, |u, v| {
            if u == 128.0 && v == 128.0 {
                8000.0
            } else {
                0.0
            }
        }),
    ];
    let names = ["flat", "tiny", "huge", "wide", "tall", "pit", "spike"];
    for (hm, name) in terrains.iter().zip(names) {
        let cam = Camera::default_for(hm).expect("default camera");
        let (lo, hi) = hm.range();
        let (ex, ey) = hm.extent_m();
        let (ox, oy) = hm.origin();
        assert!(cam.eye.z > f64::from(hi), "{name}: eye below the top");
        assert!(cam.forward().z < -0.3, "{name}: not an oblique view down");
        let size = ex.max(ey);
        let dist = cam.eye.distance(cam.target);
        let reach = 0.8 * size + f64::from(hi - lo);
        assert!(
            dist < reach,
            "{name}: {dist} m away from a {size} m terrain"
        );
        let vp = cam.view_proj_relative(16.0 / 9.0).as_dmat4();
        let (tlo, thi) = hm.typical_range();
        let mid = f64::from(tlo) + 0.5 * f64::from(thi - tlo);
        for (fx, fy) in [(0.5, 0.5), (0.5, 0.9), (0.3, 0.6), (0.7, 0.6)] {
            let p = DVec3::new(ox + fx * ex, oy + fy * ey, mid) - cam.eye;
            let c = vp * DVec4::new(p.x, p.y, p.z, 1.0);
            let ndc = c.truncate() / c.w;
            assert!(
                c.w > 0.0 && ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0,
                "{name}: ({fx}, {fy}) of the terrain is out of view (ndc {ndc})"
            );
        }
    }
}

/// The CPU twin of `data_surface` reads the finest ring holding a point: at the data's samples near the
/// eye (away from level 0's blend band) it returns the sample's height exactly and the full-resolution
/// central-difference normal; farther out it reads coarser rings, whose heights stay close to the data.
#[test]
#[expect(
    clippy::cast_possible_truncation,
    reason = "eye-relative metres as the shader's f32"
)]
fn data_surface_twin_reads_the_finest_ring() {
    let (hm, eye, cm, globals) = twin_frame();
    let s = hm.spacing();
    let mut levels_seen = std::collections::BTreeSet::new();
    for v in (2..hm.height() - 2).step_by(7) {
        for u in (2..hm.width() - 2).step_by(7) {
            let (x, y) = hm.grid_to_world(f64::from(u), f64::from(v));
            let rel = [(x - eye.x) as f32, (y - eye.y) as f32];
            let d = data_surface(&globals, &cm, rel).expect("a ring holds every data sample");
            levels_seen.insert(d.level);
            let (ui, vi) = (i64::from(u), i64::from(v));
            let z = hm.at_clamped(ui, vi);
            if d.level == 0 && d.weight == 1.0 {
                assert!(
                    (d.height - z).abs() <= 1e-3 * z.abs().max(1.0),
                    "level 0 at ({u}, {v}): {} against {z}",
                    d.height
                );
                let dzdx = (hm.at_clamped(ui + 1, vi) - hm.at_clamped(ui - 1, vi)) / (2.0 * s);
                let dzdy = (hm.at_clamped(ui, vi - 1) - hm.at_clamped(ui, vi + 1)) / (2.0 * s);
                let n = d.normal;
                assert!(
                    (n[0] + dzdx).abs() < 1e-3 && (n[1] + dzdy).abs() < 1e-3,
                    "level 0 normal at ({u}, {v}): {n:?} against ({}, {})",
                    -dzdx,
                    -dzdy
                );
            } else {
                // A coarser ring is the filtered data: within the terrain's relief of it.
                assert!(
                    (d.height - z).abs() < 400.0,
                    "level {} at ({u}, {v})",
                    d.level
                );
            }
        }
    }
    assert!(
        levels_seen.contains(&0) && levels_seen.len() > 1,
        "levels read: {levels_seen:?}"
    );
}

/// Shading survives LOD (goal): at epsilon 2 px SAT LOD draws far fewer triangles, but its
/// image RMSE against the brute-force render stays within 1.2x of distance LOD's, because both shade from
/// the same ring data rather than from the drawn mesh.
#[test]
fn sat_lod_keeps_the_shading() {
    let hm = relief();
    let gpu = strict();
    let p = profile("gles3-mid", 320, 180, Some(u32::MAX));
    let cam = Camera::default_for(&hm).expect("camera");
    let cm = filled(&hm, &p, cam.eye);
    let mut brute = BruteForce::new(&gpu, &hm).expect("brute force");
    let truth = brute.render(&cam, 320, 180).expect("brute frame").image;
    let tables = lod(&hm, &p, &cm);
    let mut rmse = Vec::new();
    for mode in [LodMode::Distance, LodMode::Sat] {
        let mut r = renderer_in(&gpu, &p, &cm, mode, Some(&tables), DebugView::Normal);
        let opts = FrameOptions {
            epsilon_px: Some(2.0),
            ..FrameOptions::default()
        };
        let out = render_frame(&mut r, &cm, &cam, &opts).expect("frame");
        rmse.push((
            out.stats.triangles,
            image_rmse(&out.image, &truth).expect("same size"),
        ));
    }
    let (dist, sat) = (rmse[0], rmse[1]);
    eprintln!("distance {dist:?}, sat {sat:?}");
    assert!(sat.0 < dist.0, "SAT LOD draws fewer triangles: {rmse:?}");
    assert!(
        sat.1 <= 1.2 * dist.1,
        "SAT LOD's RMSE {} against distance LOD's {} (triangles {} / {})",
        sat.1,
        dist.1,
        sat.0,
        dist.0
    );
}

/// A clean data border: seen from outside and low, the clipmap draws nothing where no view
/// ray within a pixel meets the data, so no skirt hangs below the terrain's edge as a curtain. The truth
/// is the CPU's (`twin::border`: rays marched through the bilinear heights), not a GPU reference: on
/// NVIDIA's driver the brute-force frame this test compared against came back one colour, which made
/// every pixel (57,600) count. The GPU reference is still drawn and must look like a terrain view, so a
/// failing reference is named as such. Distance LOD at epsilon 2 px, SAT LOD at 1 px; before skirts seen
/// through the data's side were discarded, the curtains covered thousands of pixels.
#[test]
fn no_curtains_below_the_data_border() {
    let hm = relief();
    let gpu = strict();
    let (w, h) = (320, 180);
    let p = profile("gles3-mid", w, h, Some(u32::MAX));
    let eye = DVec3::new(7000.0, -2500.0, 1400.0);
    let cam = Camera::new(eye, DVec3::new(7000.0, 6000.0, 200.0), 60.0)
        .and_then(|c| c.with_clip(2.0, 6.0e4))
        .expect("camera");
    let cm = filled(&hm, &p, cam.eye);
    let coverage = border::data_coverage(&hm, &cam, w, h);
    let seen = coverage.iter().filter(|c| **c).count();
    assert!(
        seen > 5000 && seen < 50_000,
        "{seen} pixels see the data: the view should hold terrain and sky"
    );
    let mut brute = BruteForce::new(&gpu, &hm).expect("brute force");
    let truth = brute.render(&cam, w, h).expect("brute frame").image;
    let colours = truth
        .rgba
        .chunks_exact(4)
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    assert!(
        colours > 50,
        "the brute-force reference frame has {colours} colours: not drawn or not read back"
    );
    let tables = lod(&hm, &p, &cm);
    let clear = border::clear_rgba8(FrameOptions::default().clear);
    for (mode, eps) in [(LodMode::Distance, 2.0), (LodMode::Sat, 1.0)] {
        let mut r = renderer_in(&gpu, &p, &cm, mode, Some(&tables), DebugView::Normal);
        let opts = FrameOptions {
            epsilon_px: Some(eps),
            ..FrameOptions::default()
        };
        let out = render_frame(&mut r, &cm, &cam, &opts).expect("frame");
        let curtains = border::curtain_pixels(&out.image, clear, &coverage);
        eprintln!("{mode}: {curtains} curtain pixels");
        // Measured on llvmpipe and lavapipe: 0 with either LOD (and 2893 and 4964 without the discard
        // against the brute-force frame; the one-pixel band at the silhouette is not counted here).
        assert!(
            curtains <= 20,
            "{mode}: {curtains} pixels drawn where no ray meets the data"
        );
    }
}

/// `fs_ring_data` reads the rings only for blocks drawn coarser than the finest ring under the pixel
/// (`twin::shading::fragment_data`), and fades that data out over the ring's GC 6.2 transition band:
/// `finest_level` picks the same ring as `data_surface`, inside the ring's active interior the data counts
/// fully, and past its drawn edge not at all.
#[test]
#[expect(
    clippy::cast_possible_truncation,
    reason = "eye-relative metres as the shader's f32"
)]
fn fragment_reads_the_rings_only_under_coarser_blocks() {
    use clipsat::twin::shading::{finest_level, fragment_data, shade_morph_alpha};
    let (hm, eye, cm, mut globals) = twin_frame();
    // Distance LOD: morphing on, so the data fades with the ring's GC 6.2 alpha.
    globals.params[0] = 1.0;
    let (mut full, mut faded) = (0, 0);
    for v in (2..hm.height() - 2).step_by(5) {
        for u in (2..hm.width() - 2).step_by(5) {
            let (x, y) = hm.grid_to_world(f64::from(u), f64::from(v));
            let rel = [(x - eye.x) as f32, (y - eye.y) as f32];
            let d = data_surface(&globals, &cm, rel).expect("a ring holds every data sample");
            let fine = finest_level(&globals, rel).expect("the same ring holds it");
            assert_eq!(
                fine, d.level,
                "finest_level and data_surface disagree at ({u}, {v})"
            );
            assert_eq!(fragment_data(&globals, &cm, rel, fine), None);
            let f = fragment_data(&globals, &cm, rel, fine + 1).expect("a coarser block reads");
            let (data, w) = (f.data, f.share);
            assert_eq!(data.level, fine);
            // One level coarser, the band blends into the block's own vertices.
            assert_eq!(f.base, None);
            assert!((0.0..=1.0).contains(&w), "share {w}");
            let alpha = shade_morph_alpha(&globals, fine, rel);
            if alpha == 0.0 && d.weight == 1.0 {
                assert_eq!(w, 1.0);
                full += 1;
            } else if alpha == 1.0 {
                assert_eq!(w, 0.0);
                faded += 1;
            }
        }
    }
    assert!(
        full > 0 && faded > 0,
        "{full} points read fully, {faded} faded out"
    );
}
