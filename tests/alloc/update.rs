//! Proves `Clipmap::update` allocates nothing: a counting global allocator around steady motion, a teleport
//! refill and synthesised rings. Only the test's own thread is counted, so other tests may run meanwhile.

#![expect(
    clippy::cast_possible_truncation,
    reason = "the test terrain is an f64 formula stored as f32 heights"
)]

use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::profile::ClipmapBudget;
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use glam::DVec3;

use crate::counting_alloc::count;

fn terrain(size: u32) -> Heightmap {
    let h = (0..size * size)
        .map(|k| {
            let (x, y) = (f64::from(k % size), f64::from(k / size));
            (150.0 * (x / 31.0).sin() * (y / 17.0).cos()) as f32
        })
        .collect();
    Heightmap::new(std::path::Path::new("<alloc>"), size, size, 30.0, h).expect("terrain")
}

#[test]
fn update_allocates_nothing() {
    // Sanity: the counter sees allocations.
    assert!(count(|| drop(std::hint::black_box(vec![1u8; 16]))) > 0);

    let hm = terrain(257);
    let mut p = Profile::load("gles3-low").expect("profile");
    p.clipmap = ClipmapBudget {
        n: 31,
        levels: 6,
        clip_margin: 4,
    };
    p.budget.update_samples_per_frame = 400;
    for synth in [0, 1] {
        let mut cm = Clipmap::new(
            &hm,
            &p,
            ClipmapOptions {
                synth_levels: synth,
            },
        )
        .expect("clipmap");
        let c = 128.0 * 30.0;
        let eye = |t: u32| {
            let t = f64::from(t);
            DVec3::new(c + 40.0 * t, c + 900.0 * (t * 0.02).sin(), 300.0)
        };
        // Warm-up: the first frames fill every ring.
        for t in 0..50 {
            cm.update(eye(t)).expect("update");
        }
        let steady = count(|| {
            for t in 50..250 {
                cm.update(eye(t)).expect("update");
            }
        });
        assert_eq!(steady, 0, "synth {synth}: allocations in 200 steady frames");
        let teleport = count(|| {
            for t in 0..100 {
                let e = DVec3::new(500.0 + 3.0 * f64::from(t), 7000.0, 250.0);
                let f = cm.update(e).expect("update");
                std::hint::black_box(f.hash);
            }
        });
        assert_eq!(
            teleport, 0,
            "synth {synth}: allocations during a teleport refill"
        );
        assert_eq!(cm.frame().stale_levels, 0, "the teleport refill completed");
    }
}
