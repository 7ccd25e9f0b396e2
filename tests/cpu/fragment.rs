//! Stage 2's fragment-program choice (`clipsat::plan::fragment`) against the CPU twin of the fragment
//! shader (`clipsat::twin::shading::fragment_data`): a block the plan draws with `fs_plain` or
//! `fs_interior` must be one where `fs_ring_data` would keep the drawn vertices' values at every pixel, and
//! one drawn with `fs_interior` must have no pixel that `outside_data` discards.

use clipsat::bake::lod_tables::LodTables;
use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::cull::DrawKind;
use clipsat::plan::fragment::FragmentPath;
use clipsat::plan::frame_plan::{FramePlan, LodSetup, PlanParams, Planner};
use clipsat::plan::lod::{Lod, LodMode};
use clipsat::profile::Profile;
use clipsat::source::procedural::{generate, ProceduralParams};
use clipsat::twin::shading::fragment_data;
use glam::DVec3;

/// Samples per footprint side, its edges included.
const SAMPLES: u32 = 9;

/// `outside_data` of `clipmap.wgsl`, in its f32 arithmetic.
fn outside_data(e: [f32; 4], rel: [f32; 2]) -> bool {
    let inset = (1.0e-4 * (e[2] - e[0]).min(e[3] - e[1])).clamp(0.0, 0.02);
    let tol = inset + 4.0e-6 * e.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    rel[0] < e[0] + tol || rel[1] < e[1] + tol || rel[0] > e[2] - tol || rel[1] > e[3] - tol
}

/// Checks every plain and interior block of `plan` on a grid over its footprint; returns the number of
/// (interior, plain, ring-data) blocks.
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_precision_loss,
    reason = "lattice coordinates are small here; eye-relative f32 is the shader's precision"
)]
fn check_plain_blocks(plan: &FramePlan, cm: &Clipmap, cam: &Camera, quads: u32) -> [u32; 3] {
    let p = cm.eye_lattice(cam.eye);
    let g0 = cm.g0();
    let mut counts = [0; 3];
    for (d, planned) in plan.draws().iter().zip(plan.planned()) {
        if d.kind != DrawKind::Block {
            assert_eq!(planned.fragment, FragmentPath::Skirt);
            continue;
        }
        let interior = planned.fragment == FragmentPath::Interior;
        match planned.fragment {
            FragmentPath::Interior => counts[0] += 1,
            FragmentPath::Plain => counts[1] += 1,
            _ => {
                counts[2] += 1;
                continue;
            }
        }
        let r = d.covered(quads);
        let f = f64::from(1u32 << d.fine);
        for j in 0..SAMPLES {
            for i in 0..SAMPLES {
                let t =
                    |k: u32, n: u32| f64::from(k) / f64::from(SAMPLES - 1) * (f64::from(n) - 1.0);
                let x = (r.x0 as f64 + t(i, r.w)) * f;
                let y = (r.y0 as f64 + t(j, r.h)) * f;
                let rel = [((x - p.0) * g0) as f32, (-(y - p.1) * g0) as f32];
                assert!(
                    !(interior && outside_data(plan.globals().extent, rel)),
                    "an interior block at level {} reaches past the data at lattice ({x}, {y})",
                    d.level
                );
                if let Some(fd) = fragment_data(plan.globals(), cm, rel, d.level) {
                    assert!(
                        fd.share == 0.0 && fd.base.is_none(),
                        "a plain block at level {} would be shaded from level {} at lattice ({x}, \
                         {y}): share {}, base {:?}",
                        d.level,
                        fd.data.level,
                        fd.share,
                        fd.base.map(|b| b.level)
                    );
                }
            }
        }
    }
    counts
}

/// A fast flight under a small update budget (stale, cropped rings), with morphing on and off, and SAT
/// LOD: every plain or interior block is so at each sampled pixel, and every program occurs.
#[test]
fn plain_blocks_never_need_ring_data() {
    let hm = generate(&ProceduralParams {
        size: 257,
        ..ProceduralParams::default()
    })
    .expect("terrain");
    let mut profile = Profile::load("gles3-low").expect("profile");
    profile.budget.update_samples_per_frame = 6000;
    let mut cm = Clipmap::new(&hm, &profile, ClipmapOptions::default()).expect("clipmap");
    let tables = LodTables::build(cm.pyramid(), profile.clipmap.levels, 2, |_| {}).expect("tables");
    let lod = Lod::for_clipmap(tables, &profile, &cm, &hm);
    let mut distance = Planner::new(&profile, &cm, LodSetup::Distance).expect("planner");
    let mut sat = Planner::new(
        &profile,
        &cm,
        LodSetup::new(LodMode::SatConservative, Some(lod)).expect("setup"),
    )
    .expect("planner");
    let mut plan = distance.new_plan();
    let quads = profile.block_m();
    let mut counts = [0; 3];
    let extent = f64::from(hm.width() - 1) * f64::from(hm.spacing());
    for frame in 0..24u32 {
        // Across the terrain at 1/12 of its width a frame, low and looking ahead.
        let s = f64::from(frame) / 24.0;
        let eye = DVec3::new(extent * (0.1 + 0.8 * s), extent * (0.2 + 0.5 * s), 400.0);
        let cam = Camera::new(eye, eye + DVec3::new(900.0, 400.0, -150.0), 60.0).expect("camera");
        cm.update(cam.eye).expect("update");
        for case in 0..3 {
            let (planner, morph) = match case {
                0 => (&mut distance, true),
                1 => (&mut distance, false),
                _ => (&mut sat, false),
            };
            let params = PlanParams {
                morph,
                epsilon_px: Some(1.0),
                ..PlanParams::default()
            };
            planner.plan(&cm, &cam, &params, &mut plan).expect("plan");
            for (c, n) in counts
                .iter_mut()
                .zip(check_plain_blocks(&plan, &cm, &cam, quads))
            {
                *c += n;
            }
        }
    }
    assert!(
        counts.iter().all(|&c| c > 0),
        "interior, plain, ring-data blocks: {counts:?}"
    );
}
