//! The per-frame plan over every named camera path: GC section 5 constraints and the budget hold on every
//! frame, on the procedural terrain and on Puget Sound, and the frame-hash sequence is pinned so that a debug
//! and a release build can be checked against the same number.
//!
//! Release check of the same goldens: `cargo test --release --test cpu fly_paths::`.

use clipsat::hash::{hex, Hash64};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::plan::frame::LevelState;
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use clipsat::source::{self, procedural, LoadOptions};

const PATHS: [Path; 5] = [
    Path::Straight,
    Path::Circle,
    Path::Figure8,
    Path::Dive,
    Path::Teleport { every: 150 },
];

/// Flies `frames` frames and checks every one; returns the hash of the frame-hash sequence.
fn fly(hm: &Heightmap, profile: &str, path: Path, speed: f64, frames: u64, synth: u32) -> u64 {
    let prof = Profile::load(profile).expect("shipped profile");
    let mut cm = Clipmap::new(
        hm,
        &prof,
        ClipmapOptions {
            synth_levels: synth,
        },
    )
    .expect("clipmap");
    let flight = Flight::new(path, speed, hm).expect("flight");
    let budget = prof.budget.update_samples_per_frame;
    let mut run = Hash64::new();
    let mut stale_frames = 0u32;
    for f in 0..frames {
        let frame = cm.update(flight.camera(f).eye).expect("update");
        let tag = format!("{profile} {path} frame {f}");
        assert!(
            frame.samples_updated <= budget,
            "{tag}: {} samples over budget {budget}",
            frame.samples_updated
        );
        // Coarse to fine: once a level is left stale, no finer level may have been written this frame.
        let mut seen_stale = false;
        for l in (0..frame.levels.len()).rev() {
            match frame.levels[l].state {
                LevelState::Stale => seen_stale = true,
                LevelState::Updated => {
                    assert!(!seen_stale, "{tag}: level {l} updated below a stale level")
                }
                _ => {}
            }
        }
        stale_frames += u32::from(frame.stale_levels > 0);
        run.write_u64(frame.hash);
        if let Err(v) = cm.check_constraints() {
            panic!("{tag}: {v}");
        }
    }
    eprintln!("{profile} {path}: {frames} frames, {stale_frames} with stale levels");
    run.finish()
}

fn procedural_terrain() -> Heightmap {
    procedural::generate(&procedural::ProceduralParams {
        seed: 1,
        size: 513,
        spacing: 30.0,
    })
    .expect("procedural")
}

fn puget() -> Option<Heightmap> {
    let path = crate::shared_file("ps_height_1k.png")?;
    Some(
        source::load(
            &path,
            &LoadOptions {
                spacing: Some(160.0),
                ..Default::default()
            },
        )
        .expect("ps_height_1k.png"),
    )
}

#[test]
fn every_path_on_the_procedural_terrain() {
    let hm = procedural_terrain();
    for path in PATHS {
        fly(&hm, "gles3-low", path, 120.0, 2000, 1);
    }
}

#[test]
fn every_path_on_puget_sound() {
    let Some(hm) = puget() else { return };
    for path in PATHS {
        fly(&hm, "gles3-mid", path, 400.0, 2000, 0);
    }
}

/// Frame hashes are exact: the same fly-through gives the same sequence in every build. If this changes,
/// every user's stored hashes break: only update the constant for an intended change of the frame record.
#[test]
fn frame_hash_sequence_is_pinned() {
    let hm = procedural_terrain();
    let a = fly(&hm, "gles3-low", Path::Figure8, 200.0, 300, 1);
    let b = fly(&hm, "gles3-low", Path::Figure8, 200.0, 300, 1);
    assert_eq!(a, b, "two runs differ");
    assert_eq!(
        hex(a),
        GOLDEN_FIGURE8,
        "frame-hash sequence changed (debug and release must agree)"
    );
}

const GOLDEN_FIGURE8: &str = "0f79f50531807d11";

/// On every shipped profile: a fast flight leaves fine levels stale; once the viewer stops, every level is
/// current again within ceil(pending / B') frames, B' = the budget rounded down to whole rows of the clip
/// texture (the planner's unit of work). For gles3-low and gles3-mid B' = B exactly.
#[test]
fn shipped_profiles_recover_after_a_fast_flight() {
    let hm = procedural_terrain();
    for name in ["gles3-low", "gles3-mid", "desktop"] {
        let prof = Profile::load(name).expect("shipped profile");
        let s = u64::from(prof.clip_size());
        let budget = u64::from(prof.budget.update_samples_per_frame);
        let rows_budget = budget / s * s;
        if name != "desktop" {
            assert_eq!(rows_budget, budget, "{name}: budget is not whole rows");
        }
        let mut cm = Clipmap::new(&hm, &prof, ClipmapOptions::default()).expect("clipmap");
        let flight = Flight::new(Path::Straight, 2000.0, &hm).expect("flight");
        let mut stale_seen = false;
        for f in 0..40 {
            stale_seen |= cm
                .update(flight.camera(f).eye)
                .expect("update")
                .stale_levels
                > 0;
        }
        assert!(stale_seen, "{name}: 2 km/frame never left a level stale");
        let eye = flight.camera(40).eye;
        let pending = cm.pending_samples(eye);
        let bound = pending.div_ceil(rows_budget);
        let mut frames = 0;
        while cm.pending_samples(eye) > 0 {
            let frame = cm.update(eye).expect("update");
            assert!(u64::from(frame.samples_updated) <= budget);
            frames += 1;
            assert!(
                frames <= bound,
                "{name}: not recovered within ceil({pending} / {rows_budget}) = {bound} frames"
            );
        }
        let frame = cm.frame();
        assert_eq!(frame.stale_levels, 0, "{name}");
        eprintln!("{name}: {pending} samples pending after the flight, recovered in {frames} frames (bound {bound})");
    }
}
