//! Far from the origin: a terrain placed 1e6 m out (`Heightmap::with_origin`) plans and renders like the
//! same terrain at the origin, because the offset is subtracted in f64 before any lattice maths
//! (`Clipmap::eye_lattice`) and the GPU only sees eye-relative positions (`Camera::view_proj_relative`).

use crate::render_support;

use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen};
use clipsat::gpu::readback::Image;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use glam::DVec3;

/// Offsets tried, metres east and north.
const OFFSETS: [(f64, f64); 3] = [
    (1.0e6, 1.0e6),
    (-1.0e6, 2.5e6),
    (1.0e6 + 0.37, -1.0e6 + 0.61),
];

#[test]
fn the_plan_is_the_same_far_from_the_origin() {
    let base = render_support::relief();
    let prof = render_support::profile("gles3-low", 160, 90, None);
    for (ox, oy) in OFFSETS {
        let far = base.clone().with_origin(ox, oy);
        for path in [Path::Figure8, Path::Teleport { every: 30 }, Path::Dive] {
            let (fa, fb) = (
                Flight::new(path, 60.0, &base).expect("flight"),
                Flight::new(path, 60.0, &far).expect("flight"),
            );
            let mut a = Clipmap::new(&base, &prof, ClipmapOptions::default()).expect("clipmap");
            let mut b = Clipmap::new(&far, &prof, ClipmapOptions::default()).expect("clipmap");
            for f in 0..150 {
                let (ea, eb) = (fa.camera(f).eye, fb.camera(f).eye);
                let moved = eb - ea;
                assert!(
                    (moved - DVec3::new(ox, oy, 0.0)).abs().max_element() < 1e-6,
                    "{path} frame {f}: the flight moved by {moved}, not the offset"
                );
                let ha = a.update(ea).expect("update").hash;
                let hb = b.update(eb).expect("update").hash;
                assert_eq!(
                    ha, hb,
                    "offset ({ox}, {oy}) {path} frame {f}: frame differs"
                );
                let (pa, pb) = (a.eye_lattice(ea), b.eye_lattice(eb));
                assert!(
                    (pa.0 - pb.0).abs() < 1e-6 && (pa.1 - pb.1).abs() < 1e-6,
                    "{path} frame {f}: eye lattice {pa:?} vs {pb:?}"
                );
            }
        }
    }
}

/// Largest per-channel difference and the mean absolute difference (RGB, 8-bit levels).
fn diff(a: &Image, b: &Image) -> (u8, f64) {
    let (mut max, mut sum) = (0u8, 0u64);
    for (p, q) in a.rgba.chunks_exact(4).zip(b.rgba.chunks_exact(4)) {
        for c in 0..3 {
            let d = p[c].abs_diff(q[c]);
            max = max.max(d);
            sum += u64::from(d);
        }
    }
    (max, sum as f64 / (a.rgba.len() / 4 * 3) as f64)
}

#[test]
fn the_image_is_the_same_far_from_the_origin() {
    let gpu = render_support::strict();
    let base = render_support::relief();
    let prof = render_support::profile("gles3-low", 160, 90, None);
    let mut frames = 0;
    for (ox, oy) in OFFSETS {
        let far = base.clone().with_origin(ox, oy);
        let offset = DVec3::new(ox, oy, 0.0);
        let mut a = Clipmap::new(&base, &prof, ClipmapOptions::default()).expect("clipmap");
        let mut b = Clipmap::new(&far, &prof, ClipmapOptions::default()).expect("clipmap");
        let mut ra = Offscreen::new(&gpu, &prof, &a, Default::default()).expect("renderer");
        let mut rb = Offscreen::new(&gpu, &prof, &b, Default::default()).expect("renderer");
        for i in 0..8 {
            let cam = render_support::flight(&base, i * 9, 120.0, 250.0, Some(5 * 9));
            let mut cam_far = cam;
            cam_far.eye += offset;
            cam_far.target += offset;
            a.update(cam.eye).expect("update");
            b.update(cam_far.eye).expect("update");
            let ia = render_frame(&mut ra, &a, &cam, &FrameOptions::default()).expect("frame");
            let ib = render_frame(&mut rb, &b, &cam_far, &FrameOptions::default()).expect("frame");
            // Bit-identical, as the README says (24 of 24 frames on llvmpipe); the difference is printed
            // only to say how far off a failing frame is.
            let (max, mean) = diff(&ia.image, &ib.image);
            assert!(
                ia.image_hash == ib.image_hash && ia.image == ib.image,
                "offset ({ox}, {oy}) frame {i}: images are not bit-identical, max {max} levels, \
                 mean {mean:.4}"
            );
            frames += 1;
        }
    }
    eprintln!("{frames} frames bit-identical");
}

/// SAT LOD selection measures block distances from the eye in world metres, so the terrain's origin must
/// enter them: far out, every block keeps the level it gets at the origin.
#[test]
fn sat_lod_chooses_the_same_levels_far_from_the_origin() {
    use clipsat::bake::lod_tables::P;
    use clipsat::bake::{bake_lod, BakeParams};
    use clipsat::hash::Hash64;
    use clipsat::plan::lod::{Lod, LodFrame, LodMode};
    let base = render_support::relief();
    let prof = render_support::profile("gles3-low", 160, 90, None);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("lod-cache-far");
    let lod_for = |hm: &clipsat::source::Heightmap, cm: &Clipmap| {
        let params = BakeParams {
            p: P,
            levels: prof.clipmap.levels,
            synth_levels: cm.synth_levels(),
            g0: cm.g0(),
        };
        let (tables, _) = bake_lod(
            hm,
            cm.pyramid(),
            &params,
            &dir,
            clipsat::Progress::default(),
        )
        .expect("LOD tables");
        Lod::for_clipmap(tables, &prof, cm, hm)
    };
    let (mut fa, mut fb) = (LodFrame::new_boxed(), LodFrame::new_boxed());
    for (ox, oy) in OFFSETS {
        let far = base.clone().with_origin(ox, oy);
        let offset = DVec3::new(ox, oy, 0.0);
        let mut a = Clipmap::new(&base, &prof, ClipmapOptions::default()).expect("clipmap");
        let mut b = Clipmap::new(&far, &prof, ClipmapOptions::default()).expect("clipmap");
        let (la, lb) = (lod_for(&base, &a), lod_for(&far, &b));
        let mut coarser = 0;
        for i in 0..8 {
            let cam = render_support::flight(&base, i * 9, 120.0, 250.0, Some(5 * 9));
            let mut cam_far = cam;
            cam_far.eye += offset;
            cam_far.target += offset;
            a.update(cam.eye).expect("update");
            b.update(cam_far.eye).expect("update");
            la.select(a.frame(), &cam, LodMode::Sat, &mut fa)
                .expect("select");
            lb.select(b.frame(), &cam_far, LodMode::Sat, &mut fb)
                .expect("select");
            let (mut ha, mut hb) = (Hash64::new(), Hash64::new());
            fa.hash_into(&mut ha);
            fb.hash_into(&mut hb);
            assert_eq!(
                ha.finish(),
                hb.finish(),
                "offset ({ox}, {oy}) frame {i}: SAT LOD chose different levels far from the origin"
            );
            coarser += fa.blocks_coarser;
        }
        assert!(
            coarser > 0,
            "the views must exercise coarser-than-ring blocks"
        );
    }
}
