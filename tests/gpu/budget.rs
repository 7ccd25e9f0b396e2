//! Budgets on every shipped profile: long fly-throughs over every shared-data terrain on every camera path
//! keep samples updated within `budget.update_samples_per_frame` and GC section 5's constraints on every
//! frame; a short rendered fly-through per profile keeps draws and triangles within `budget.max_draws` and
//! `budget.max_triangles` on every frame, with a constant GPU object ledger.
//!
//! Zero allocations in the frame-planning path (update + draw list) are in tests/alloc/plan.rs.
//! Longer variant: `cargo test --release --test gpu budget:: -- --ignored`.

use crate::render_support;

use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::plan::frame::LevelState;
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use clipsat::source::{self, LoadOptions};

const PROFILES: [&str; 3] = ["gles3-low", "gles3-mid", "desktop"];

const PATHS: [Path; 5] = [
    Path::Straight,
    Path::Circle,
    Path::Figure8,
    Path::Dive,
    Path::Teleport { every: 40 },
];

/// The shared-data terrains (name, spacing override), loaded; a missing file is a failure under `CI=true`
/// and a printed skip otherwise.
fn terrains() -> Vec<(&'static str, Heightmap)> {
    let files: [(&str, Option<f32>); 4] = [
        ("ps_height_1k.png", Some(160.0)),
        ("n07_w006_3arc_v2.tif", None),
        ("srtm_bigtujunga30m_utm11.tif", None),
        ("aletsch_200m.tif", None),
    ];
    let mut out = Vec::new();
    for (name, spacing) in files {
        let path = clipsat::data_dir().join(name);
        if !path.exists() {
            assert!(
                std::env::var("CI").as_deref() != Ok("true"),
                "{} is missing (shared data must be present on CI)",
                path.display()
            );
            eprintln!("skip {name}: {} is missing", path.display());
            continue;
        }
        let opts = LoadOptions {
            spacing,
            ..LoadOptions::default()
        };
        let hm = source::load(&path, &opts).unwrap_or_else(|e| panic!("{name}: {e}"));
        out.push((name, hm));
    }
    out
}

/// Flies `frames` frames of every path over every terrain on every profile, checking every frame; returns
/// the frames checked per profile.
fn fly_all(frames: u64) -> Vec<(&'static str, u64)> {
    let terrains = terrains();
    let mut checked = Vec::new();
    for name in PROFILES {
        let prof = Profile::load(name).expect("shipped profile");
        let budget = prof.budget.update_samples_per_frame;
        let mut count = 0u64;
        for (tname, hm) in &terrains {
            let (ex, ey) = hm.extent_m();
            // Fast enough to cross the terrain in a few hundred frames and leave fine levels stale.
            let speed = ex.max(ey) / 150.0;
            let mut cm = Clipmap::new(hm, &prof, ClipmapOptions::default()).expect("clipmap");
            for path in PATHS {
                let flight = Flight::new(path, speed, hm)
                    .expect("flight")
                    .with_fov_y_deg(f64::from(prof.view.fov_y_deg));
                for f in 0..frames {
                    let tag = format!("{name} {tname} {path} frame {f}");
                    let frame = cm.update(flight.camera(f).eye).expect("update");
                    assert!(
                        frame.samples_updated <= budget,
                        "{tag}: {} samples over the budget {budget}",
                        frame.samples_updated
                    );
                    let mut stale_above = false;
                    for l in (0..frame.levels.len()).rev() {
                        match frame.levels[l].state {
                            LevelState::Stale => stale_above = true,
                            LevelState::Updated => {
                                assert!(!stale_above, "{tag}: level {l} updated below a stale one")
                            }
                            _ => {}
                        }
                    }
                    if let Err(v) = cm.check_constraints() {
                        panic!("{tag}: {v}");
                    }
                    count += 1;
                }
            }
        }
        eprintln!(
            "{name}: {count} frames checked ({} terrains x {} paths)",
            terrains.len(),
            PATHS.len()
        );
        checked.push((name, count));
    }
    checked
}

#[test]
fn update_budget_and_constraints_on_every_profile_terrain_and_path() {
    fly_all(300);
}

/// `cargo test --release --test gpu budget:: -- --ignored`
#[test]
#[ignore = "long: 2000 frames per flight; run in release"]
fn update_budget_and_constraints_long() {
    fly_all(2000);
}

/// Draws and triangles within the profile's limits on every rendered frame, ledger constant.
#[test]
fn draw_and_triangle_budgets_on_every_rendered_frame() {
    let gpu = render_support::strict();
    let terrains = terrains();
    for name in PROFILES {
        for (tname, hm) in &terrains {
            let prof = render_support::profile(name, 160, 90, None);
            let mut cm = Clipmap::new(hm, &prof, ClipmapOptions::default()).expect("clipmap");
            let mut r = Offscreen::new(&gpu, &prof, &cm, Default::default()).expect("renderer");
            let ledger = r.ledger().clone();
            let (ex, ey) = hm.extent_m();
            let mut frames = 0;
            let (mut max_draws, mut max_tris) = (0, 0);
            for path in [Path::Figure8, Path::Teleport { every: 10 }, Path::Dive] {
                let flight = Flight::new(path, ex.max(ey) / 100.0, hm)
                    .expect("flight")
                    .with_fov_y_deg(f64::from(prof.view.fov_y_deg));
                for f in 0..8 {
                    let cam = flight.camera(f * 7);
                    cm.update(cam.eye).expect("update");
                    let out = render_frame(&mut r, &cm, &cam, &FrameOptions::default())
                        .unwrap_or_else(|e| panic!("{name} {tname} {path} frame {f}: {e}"));
                    let s = out.stats;
                    assert!(
                        s.draws <= prof.budget.max_draws,
                        "{name} {path} frame {f}: {} draws > {}",
                        s.draws,
                        prof.budget.max_draws
                    );
                    assert!(
                        s.triangles <= u64::from(prof.budget.max_triangles),
                        "{name} {path} frame {f}: {} triangles > {}",
                        s.triangles,
                        prof.budget.max_triangles
                    );
                    max_draws = max_draws.max(s.draws);
                    max_tris = max_tris.max(s.triangles);
                    frames += 1;
                }
            }
            assert_eq!(r.ledger(), &ledger, "{name}: the GPU object ledger changed");
            assert_eq!(r.ledger().bytes(), prof.footprint().total(), "{name}");
            eprintln!(
            "{name} on {tname}: {frames} rendered frames, max {max_draws} draws (limit {}), max {max_tris} \
             triangles (limit {})",
            prof.budget.max_draws, prof.budget.max_triangles
        );
        }
    }
}
