//! Camera paths: determinism, speed, clearance, and refusal of bad input.

use std::path::Path as FsPath;

use clipsat::plan::flight::{Flight, Path, CRUISE_HEIGHT_M, DEFAULT_TELEPORT_EVERY, PATH_NAMES};
use clipsat::source::Heightmap;
use clipsat::Error;

const FRAMES: u64 = 1500;

/// A terrain of `size` x `size` samples whose height is `f(column, row)`.
fn terrain(size: u32, spacing: f32, f: impl Fn(u32, u32) -> f32) -> Heightmap {
    let heights = (0..size)
        .flat_map(|v| (0..size).map(move |u| (u, v)))
        .map(|(u, v)| f(u, v))
        .collect();
    Heightmap::new(FsPath::new("<test>"), size, size, spacing, heights).expect("valid test terrain")
}

/// Rolling hills with a sharp 3 km spike near the middle and a high ridge along one side.
fn rugged() -> Heightmap {
    terrain(257, 30.0, |u, v| {
        let (x, y) = (u as f32, v as f32);
        let hills = 300.0 * (x / 17.0).sin() * (y / 23.0).cos() + 400.0;
        let spike = if (u, v) == (130, 126) { 3000.0 } else { 0.0 };
        let ridge = if u > 200 {
            1500.0 * (x - 200.0) / 56.0
        } else {
            0.0
        };
        hills + spike + ridge
    })
}

fn flat(h: f32) -> Heightmap {
    terrain(129, 50.0, |_, _| h)
}

fn all_paths() -> Vec<Path> {
    PATH_NAMES
        .iter()
        .map(|n| n.parse().expect("shipped path name parses"))
        .chain([Path::Teleport { every: 17 }])
        .collect()
}

#[test]
fn every_path_name_parses() {
    for name in PATH_NAMES {
        let p: Path = name.parse().expect("path name parses");
        let shown = p.to_string();
        assert!(shown.starts_with(name), "{name} displays as {shown}");
        assert_eq!(shown.parse::<Path>().ok(), Some(p), "{shown} round-trips");
    }
    assert_eq!(
        "teleport".parse::<Path>().ok(),
        Some(Path::Teleport {
            every: DEFAULT_TELEPORT_EVERY
        })
    );
    assert_eq!(
        "teleport:7".parse::<Path>().ok(),
        Some(Path::Teleport { every: 7 })
    );
    for bad in [
        "",
        "nope",
        "Circle",
        "teleport:0",
        "teleport:x",
        "teleport:",
        "circle:3",
    ] {
        match bad.parse::<Path>() {
            Err(Error::Invalid { what: arg, reason }) => {
                assert_eq!(arg, "flight path");
                assert!(!reason.is_empty());
            }
            other => panic!("`{bad}` should be refused, got {other:?}"),
        }
    }
}

#[test]
fn refuses_bad_speed() {
    let hm = flat(0.0);
    for speed in [0.0, -1.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        match Flight::new(Path::Circle, speed, &hm) {
            Err(Error::Invalid { what: arg, .. }) => assert_eq!(arg, "flight speed"),
            other => panic!("speed {speed} should be refused, got {other:?}"),
        }
    }
    assert!(Flight::new(Path::Teleport { every: 0 }, 10.0, &hm).is_err());
    assert!(Flight::new(Path::Circle, 1e-3, &hm).is_ok());
}

#[test]
fn cameras_are_a_pure_function_of_the_frame() {
    let hm = rugged();
    for path in all_paths() {
        let a = Flight::new(path, 37.5, &hm).expect("flight");
        let b = Flight::new(path, 37.5, &hm).expect("flight");
        let forward: Vec<_> = (0..FRAMES).map(|f| a.camera(f)).collect();
        for (f, cam) in forward.iter().enumerate().rev() {
            assert_eq!(b.camera(f as u64), *cam, "{path} frame {f}");
        }
    }
}

#[test]
fn eyes_move_at_the_given_speed() {
    let hm = rugged();
    let speed = 25.0;
    for path in all_paths() {
        if path == Path::Dive {
            continue;
        }
        let fl = Flight::new(path, speed, &hm).expect("flight");
        let mut slow = 0;
        for f in 1..FRAMES {
            let (a, b) = (fl.camera(f - 1).eye, fl.camera(f).eye);
            let d = a.truncate().distance(b.truncate());
            if fl.jumps_at(f) {
                continue;
            }
            assert!(d <= speed * 1.001, "{path} frame {f}: moved {d} m");
            // Turning back at the end of a track cuts one frame's chord short; nothing else may.
            if d < speed * 0.99 {
                slow += 1;
            }
        }
        assert!(
            slow <= FRAMES / 50,
            "{path}: {slow} frames slower than the speed"
        );
    }
}

#[test]
fn dive_moves_at_speed_down_the_slope_from_high_up() {
    let hm = flat(120.0);
    let speed = 40.0;
    let fl = Flight::new(Path::Dive, speed, &hm).expect("flight");
    let (ex, ey) = hm.extent_m();
    let start = fl.camera(0).eye;
    let expected_top = (10.0 * ex.max(ey)).min(20_000.0);
    assert!(
        start.z - 120.0 >= expected_top,
        "dive starts {} m above ground, expected at least {expected_top}",
        start.z - 120.0
    );
    let mut lowest = f64::INFINITY;
    for f in 1..4000 {
        let (a, b) = (fl.camera(f - 1).eye, fl.camera(f).eye);
        let d = a.distance(b);
        assert!(d <= speed * 1.001, "frame {f}: moved {d} m");
        lowest = lowest.min(b.z - 120.0);
        let fwd = fl.camera(f).forward();
        assert!(
            fwd.z < 0.0,
            "frame {f}: the dive camera looks down its slope"
        );
    }
    assert!(
        (lowest - fl.min_clearance()).abs() < speed,
        "dive reaches the ground: lowest {lowest} m"
    );
}

#[test]
fn eyes_stay_over_the_terrain_and_above_it() {
    let hm = rugged();
    let (ex, ey) = hm.extent_m();
    for speed in [3.0, 60.0, 900.0] {
        for path in all_paths() {
            let fl = Flight::new(path, speed, &hm).expect("flight");
            for f in 0..FRAMES {
                let c = fl.camera(f);
                assert!(c.eye.is_finite() && c.target.is_finite(), "{path} {f}");
                assert!(
                    (0.0..=ex).contains(&c.eye.x) && (0.0..=ey).contains(&c.eye.y),
                    "{path} at {speed} m/frame, frame {f}: eye {} is off the terrain",
                    c.eye
                );
                let ground = f64::from(hm.height_at_world(c.eye.x, c.eye.y));
                assert!(
                    c.eye.z >= ground + fl.min_clearance() - 1e-9,
                    "{path} frame {f}: eye {} m over ground {ground} m",
                    c.eye.z
                );
                if path != Path::Dive {
                    // Cruising paths ride on an upper envelope: never below the cruise height.
                    assert!(
                        c.eye.z >= ground + CRUISE_HEIGHT_M - 1e-6,
                        "{path} frame {f}"
                    );
                }
            }
        }
    }
}

#[test]
fn cruising_over_flat_ground_holds_the_cruise_height() {
    let hm = flat(-35.0);
    let fl = Flight::new(Path::Figure8, 80.0, &hm).expect("flight");
    for f in 0..500 {
        let z = fl.camera(f).eye.z;
        assert!(
            (z - (-35.0 + CRUISE_HEIGHT_M)).abs() < 1e-6,
            "frame {f}: {z}"
        );
    }
}

#[test]
fn cruise_height_does_not_jitter_over_rough_ground() {
    // +-100 m of sample-to-sample noise: the eye must not follow it.
    let hm = terrain(257, 30.0, |u, v| {
        let h = (u.wrapping_mul(2_654_435_761) ^ v.wrapping_mul(40_503)) % 200;
        h as f32
    });
    let speed = 30.0;
    for path in [Path::Straight, Path::Circle, Path::Figure8] {
        let fl = Flight::new(path, speed, &hm).expect("flight");
        for f in 1..FRAMES {
            let dz = (fl.camera(f).eye.z - fl.camera(f - 1).eye.z).abs();
            assert!(dz < 0.1 * speed, "{path} frame {f}: height jumps {dz} m");
        }
    }
}

#[test]
fn teleport_jumps_every_k_frames_and_cruises_between() {
    let hm = rugged();
    let speed = 20.0;
    let fl = Flight::new(Path::Teleport { every: 30 }, speed, &hm).expect("flight");
    let mut far_jumps = 0;
    for f in 1..600u64 {
        assert_eq!(fl.jumps_at(f), f % 30 == 0, "frame {f}");
        let d = fl
            .camera(f - 1)
            .eye
            .truncate()
            .distance(fl.camera(f).eye.truncate());
        if fl.jumps_at(f) && d > 10.0 * speed {
            far_jumps += 1;
        }
    }
    assert!(
        far_jumps >= 15,
        "only {far_jumps} of 19 jumps went anywhere"
    );
}
