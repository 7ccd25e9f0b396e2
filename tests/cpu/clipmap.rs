//! The clipmap core on the CPU: GC section 5 constraints on every frame of long fly-throughs, the budget,
//! coarse-to-fine fallback and recovery, determinism, bit-exact fill, and the pyramid's prediction U.

#![expect(
    clippy::cast_possible_truncation,
    reason = "test terrains are f64 formulas stored as f32 heights; levels < 16"
)]

use clipsat::bake::pyramid::{predict, Pyramid};
use clipsat::plan::clipmap::{morph_alpha, Clipmap, ClipmapOptions};
use clipsat::plan::frame::{LevelState, Rect};
use clipsat::profile::ClipmapBudget;
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use glam::DVec3;

/// A deterministic synthetic terrain: two sine octaves and a hashed bumpiness, `amp` metres high.
fn terrain(size: u32, spacing: f32, amp: f64) -> Heightmap {
    let mut h = Vec::with_capacity(size as usize * size as usize);
    for y in 0..size {
        for x in 0..size {
            let (fx, fy) = (f64::from(x), f64::from(y));
            let hash = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) % 1000;
            let v = amp
                * (0.6 * (fx / 37.0).sin() * (fy / 23.0).cos()
                    + 0.3 * (fx / 9.0 + fy / 13.0).sin())
                + amp * 0.02 * (f64::from(hash) / 1000.0 - 0.5);
            h.push(v as f32);
        }
    }
    Heightmap::new(std::path::Path::new("<test>"), size, size, spacing, h).expect("valid terrain")
}

fn profile(n: u32, levels: u32, margin: u32, budget: u32) -> Profile {
    let mut p = Profile::load("gles3-low").expect("shipped profile");
    p.clipmap = ClipmapBudget {
        n,
        levels,
        clip_margin: margin,
    };
    p.budget.update_samples_per_frame = budget;
    p.validate("test").expect("valid test profile");
    p
}

/// Per-frame invariants: constraints (1)-(4), the budget, at most 4 uploads a level, and coarse-to-fine
/// fallback (no coarse level stale while a finer one had samples written this frame).
fn check_frame(cm: &Clipmap, what: &str) {
    let f = cm.frame();
    if let Err(v) = cm.check_constraints() {
        panic!("{what}, frame {}: {v}", f.index);
    }
    assert!(
        f.samples_updated <= f.budget,
        "{what}: budget exceeded: {f:?}"
    );
    let sum: u32 = f.levels.iter().map(|l| l.samples_updated).sum();
    assert_eq!(sum, f.samples_updated, "{what}");
    for l in 0..cm.levels() {
        let ups = f.uploads.iter().filter(|u| u.level == l).count();
        assert!(
            ups <= 4,
            "{what}, frame {}: {ups} uploads at level {l}",
            f.index
        );
    }
    for (l, lf) in f.levels.iter().enumerate() {
        if lf.samples_updated > 0 {
            for c in &f.levels[l + 1..] {
                assert!(
                    !matches!(c.state, LevelState::Stale | LevelState::Disabled),
                    "{what}, frame {}: level {l} updated while a coarser level is {:?}",
                    f.index,
                    c.state
                );
            }
        }
    }
}

struct World {
    c: f64,
    ground: f64,
}

/// The motions: each a pure function of the frame index.
/// A named camera motion: eye position by frame index.
type Motion = (&'static str, Box<dyn Fn(u64) -> DVec3>);

fn motions(w: &World, g: f64) -> Vec<Motion> {
    let (c, z) = (w.c, w.ground);
    vec![
        (
            "line",
            Box::new(move |t| {
                DVec3::new(
                    c - 200.0 * g + 0.7 * g * t as f64,
                    c + 0.3 * g * t as f64,
                    z + 2.0 * g,
                )
            }),
        ),
        (
            "circle",
            Box::new(move |t| {
                let a = t as f64 * 0.01;
                DVec3::new(c + 60.0 * g * a.cos(), c + 60.0 * g * a.sin(), z + 5.0 * g)
            }),
        ),
        (
            "teleport",
            Box::new(move |t| {
                // A jump every 97 frames to a pseudo-random spot, slow drift in between.
                let k = t / 97;
                let r = k
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                let (ox, oy) = (
                    ((r >> 20) % 400) as f64 - 200.0,
                    ((r >> 40) % 400) as f64 - 200.0,
                );
                let d = (t % 97) as f64 * 0.5 * g;
                DVec3::new(c + ox * g + d, c + oy * g, z + 3.0 * g)
            }),
        ),
        (
            "dive",
            Box::new(move |t| {
                // From 20 km down to 1 m above the highest ground over 1200 frames, flying forward.
                let s = (t as f64 / 1200.0).min(1.0);
                DVec3::new(
                    c + 0.5 * g * t as f64,
                    c,
                    z + 1.0 + (20_000.0 - z) * (1.0 - s) * (1.0 - s),
                )
            }),
        ),
    ]
}

fn run_motions(frames: u64, prof: &Profile, synth: u32) {
    let hm = terrain(257, 30.0, 200.0);
    let w = World {
        c: 128.0 * 30.0,
        ground: 200.0,
    };
    let mut any_stale = false;
    let mut any_disabled = false;
    for (name, eye) in motions(&w, 30.0) {
        let mut cm = Clipmap::new(
            &hm,
            prof,
            ClipmapOptions {
                synth_levels: synth,
            },
        )
        .expect("clipmap");
        for t in 0..frames {
            cm.update(eye(t)).expect("update");
            check_frame(&cm, name);
            any_stale |= cm.frame().stale_levels > 0;
            any_disabled |= cm.frame().disabled_levels > 0;
        }
    }
    assert!(
        any_stale && any_disabled,
        "the runs should exercise stale and disabled levels"
    );
}

#[test]
fn constraints_hold_on_long_runs() {
    // n = 31, S = 40: 3000 frames per motion; the budget (6 rows) is tight enough to go stale.
    run_motions(3000, &profile(31, 6, 4, 240), 0);
}

#[test]
fn constraints_hold_with_synthesis() {
    run_motions(2000, &profile(15, 6, 2, 100), 2);
}

/// The long variant: `cargo test --release --test cpu clipmap::long_runs -- --ignored`.
#[test]
#[ignore]
fn constraints_hold_on_long_runs_long() {
    run_motions(20_000, &profile(63, 8, 8, 8192), 0);
    run_motions(5_000, &profile(63, 8, 8, 1600), 1);
}

#[test]
fn fast_motion_goes_stale_then_recovers_in_bounded_frames() {
    let hm = terrain(257, 30.0, 200.0);
    let (n, s) = (31u32, 40u32);
    let budget = 6 * s; // a multiple of S: every frame writes exactly the budget until done
    let prof = profile(n, 6, 4, budget);
    let mut cm = Clipmap::new(&hm, &prof, ClipmapOptions::default()).expect("clipmap");
    let c = 128.0 * 30.0;
    let at = |x: f64| DVec3::new(x, c, 220.0);
    // Warm up at rest.
    for _ in 0..200 {
        cm.update(at(c)).expect("update");
    }
    assert!(cm
        .frame()
        .levels
        .iter()
        .all(|l| l.state == LevelState::Current && l.active.w == n));
    // 8 level-0 samples a frame needs ~ 8 S + 4 S + 2 S + ... > 6 S: fine levels must fall behind.
    let mut x = c;
    let mut shrunk = false;
    for _ in 0..60 {
        x += 8.0 * 30.0;
        cm.update(at(x)).expect("update");
        check_frame(&cm, "fast");
        let l0 = cm.frame().levels[0];
        shrunk |= l0.state == LevelState::Disabled
            || (l0.state == LevelState::Stale && l0.active.area() < u64::from(n * n));
        // The coarsest level keeps up.
        assert_ne!(cm.frame().levels[5].state, LevelState::Stale);
    }
    assert!(shrunk, "level 0 never went stale at 8 samples/frame");
    // Stop: every level recovers within ceil(pending / budget) frames.
    let pending = cm.pending_samples(at(x));
    assert!(pending > 0);
    let frames = pending.div_ceil(u64::from(budget));
    for k in 0..frames {
        cm.update(at(x)).expect("update");
        check_frame(&cm, "recovery");
        if k + 1 < frames {
            assert_eq!(cm.frame().samples_updated, budget);
        }
    }
    for (l, lf) in cm.frame().levels.iter().enumerate() {
        assert!(
            matches!(lf.state, LevelState::Current | LevelState::Updated)
                && lf.active.w == n
                && lf.active.h == n,
            "level {l} not recovered after {frames} frames: {lf:?}"
        );
    }
    assert_eq!(cm.pending_samples(at(x)), 0);
}

#[test]
fn hash_sequence_identical_across_runs() {
    let hm = terrain(129, 30.0, 200.0);
    let prof = profile(15, 5, 2, 120);
    let w = World {
        c: 64.0 * 30.0,
        ground: 200.0,
    };
    for (name, eye) in motions(&w, 30.0) {
        let run = || {
            let mut cm =
                Clipmap::new(&hm, &prof, ClipmapOptions { synth_levels: 1 }).expect("clipmap");
            (0..300)
                .map(|t| cm.update(eye(t)).expect("update").hash)
                .collect::<Vec<u64>>()
        };
        let (a, b) = (run(), run());
        assert_eq!(a, b, "{name}: hashes differ between runs");
        let distinct: std::collections::BTreeSet<_> = a.iter().collect();
        assert!(
            distinct.len() > 200,
            "{name}: the hash should change from frame to frame"
        );
    }
}

/// Every texel in every clip region equals the direct, non-toroidal evaluation, bit for bit.
fn assert_texels_exact(cm: &Clipmap, what: &str) {
    for (l, lf) in cm.frame().levels.iter().enumerate() {
        let l32 = l as u32;
        let ring = cm.ring(l32);
        let clip: Rect = lf.clip;
        for j in clip.y0..clip.y1() {
            for i in clip.x0..clip.x1() {
                let got = ring.get(i, j);
                let want = cm.sample(l32, i, j);
                assert!(
                    got[0].to_bits() == want[0].to_bits() && got[1].to_bits() == want[1].to_bits(),
                    "{what}, frame {}: level {l} sample ({i}, {j}): ring {got:?}, direct {want:?}",
                    cm.frame().index
                );
            }
        }
    }
}

#[test]
fn filled_texels_equal_direct_evaluation() {
    let hm = terrain(129, 30.0, 200.0);
    let w = World {
        c: 64.0 * 30.0,
        ground: 200.0,
    };
    for synth in [0, 2] {
        let prof = profile(15, 5, 2, 100);
        for (name, eye) in motions(&w, 30.0) {
            let mut cm = Clipmap::new(
                &hm,
                &prof,
                ClipmapOptions {
                    synth_levels: synth,
                },
            )
            .expect("clipmap");
            for t in 0..250 {
                cm.update(eye(t * 5)).expect("update");
                if t % 10 == 9 {
                    assert_texels_exact(&cm, name);
                }
            }
        }
    }
}

#[test]
fn synthesis_adds_detail_below_the_data() {
    let hm = terrain(129, 30.0, 200.0);
    let prof = profile(15, 5, 2, 100_000);
    let mut cm = Clipmap::new(&hm, &prof, ClipmapOptions { synth_levels: 2 }).expect("clipmap");
    assert_eq!(cm.g0(), 7.5);
    let ground = f64::from(hm.height_at_world(1920.0, 1920.0));
    cm.update(DVec3::new(1920.0, 1920.0, ground + 2.0))
        .expect("update");
    let f = cm.frame();
    assert!(
        f.levels.iter().all(|l| l.state == LevelState::Updated),
        "{f:?}"
    );
    // Synthesised z departs from the coarser ring's surface z_c, but not wildly.
    let ring = cm.ring(0);
    let dev = ring
        .texels()
        .iter()
        .map(|t| f64::from((t[0] - t[1]).abs()))
        .fold(0.0, f64::max);
    assert!(dev > 0.0 && dev < 50.0, "max |z - z_c| at level 0 = {dev}");
}

#[test]
fn viewer_height_disables_fine_levels() {
    let hm = terrain(129, 30.0, 10.0);
    let prof = profile(15, 6, 2, 100_000);
    let mut cm = Clipmap::new(&hm, &prof, ClipmapOptions::default()).expect("clipmap");
    // 0.4 n g_l = 180 m * 2^l: at 1000 m levels 0-2 (180, 360, 720 m) are off, 3.. are on.
    let f = cm
        .update(DVec3::new(1920.0, 1920.0, 1000.0 + 10.0))
        .expect("update");
    let states: Vec<_> = f.levels.iter().map(|l| l.state).collect();
    assert_eq!(&states[..3], &[LevelState::Disabled; 3]);
    assert!(
        states[3..].iter().all(|s| *s == LevelState::Updated),
        "{states:?}"
    );
    assert!(cm.check_constraints().is_ok());
    // Triangles: the finest enabled level draws its full active region, the others a ring.
    let f = cm.frame();
    let n = 15u32;
    assert_eq!(f.levels[3].triangles, 2 * (n - 1) * (n - 1));
    assert_eq!(f.levels[4].triangles, 2 * ((n - 1) * (n - 1) - 7 * 7));
    assert_eq!(
        f.triangles,
        f.levels.iter().map(|l| l.triangles).sum::<u32>()
    );
}

#[test]
fn prediction_reproduces_cubics() {
    // A cubic in the fine coordinates (x, y); the coarse grid holds it at (2i, 2j).
    let p = |x: f64, y: f64| {
        0.5 + 0.25 * x - 0.125 * y + 0.01 * x * x * y - 0.003 * y * y * y + 0.002 * x * x * x
    };
    let coarse = |i: i64, j: i64| p(2.0 * i as f64, 2.0 * j as f64) as f32;
    for j in -7..9 {
        for i in -9..7 {
            let want = p(i as f64, j as f64);
            let got = f64::from(predict(coarse, i, j));
            assert!(
                (got - want).abs() <= 1e-5 * want.abs().max(1.0),
                "U at ({i}, {j}): {got} vs {want}"
            );
        }
    }
}

#[test]
fn smooth_surface_has_small_residuals() {
    let size = 257u32;
    let amp = 100.0;
    let mut h = Vec::new();
    for y in 0..size {
        for x in 0..size {
            h.push((amp * (f64::from(x) / 40.0).sin() * (f64::from(y) / 55.0).cos()) as f32);
        }
    }
    let hm =
        Heightmap::new(std::path::Path::new("<smooth>"), size, size, 10.0, h).expect("terrain");
    let pyr = Pyramid::build(&hm);
    assert_eq!(pyr.level(1).width(), 129);
    assert!(pyr.level(pyr.len() - 1).width() <= 4);
    let mut worst = 0.0f32;
    for j in 6..250 {
        for i in 6..250 {
            worst = worst.max(pyr.residual(0, i, j).abs());
        }
    }
    assert!(
        worst < 0.01 * amp as f32,
        "largest interior residual {worst} m"
    );
}

#[test]
fn morph_alpha_edges() {
    let a = Rect {
        x0: 10,
        y0: 20,
        w: 31,
        h: 31,
    };
    let v = [25.0, 35.0];
    assert_eq!(morph_alpha(25.0, 35.0, v, &a, 31), 0.0);
    assert_eq!(morph_alpha(10.0, 35.0, v, &a, 31), 1.0);
    assert_eq!(morph_alpha(25.0, 50.0, v, &a, 31), 1.0);
    let mid = morph_alpha(25.0 + 15.0 - 3.1 - 1.0 + 1.55, 35.0, v, &a, 31);
    assert!((mid - 0.5).abs() < 1e-5, "{mid}");
}

#[test]
fn update_rejects_non_finite_eye() {
    let hm = terrain(65, 30.0, 10.0);
    let mut cm =
        Clipmap::new(&hm, &profile(15, 4, 2, 1000), ClipmapOptions::default()).expect("clipmap");
    assert!(cm.update(DVec3::new(f64::NAN, 0.0, 0.0)).is_err());
    assert!(Clipmap::new(
        &hm,
        &profile(15, 4, 2, 1000),
        ClipmapOptions { synth_levels: 4 }
    )
    .is_err());
}

/// Puget Sound 1k at 160 m: constraints on every frame of an orbit, and every level current at the end.
#[test]
fn puget_sound_fly_through() {
    let Some(path) = crate::shared_file("ps_height_1k.png") else {
        return;
    };
    let opts = clipsat::source::LoadOptions {
        spacing: Some(160.0),
        ..Default::default()
    };
    let hm = clipsat::source::load(&path, &opts).expect("load ps_height_1k.png");
    let prof = Profile::load("gles3-mid").expect("profile");
    let mut cm = Clipmap::new(&hm, &prof, ClipmapOptions { synth_levels: 1 }).expect("clipmap");
    let c = 512.0 * 160.0;
    for t in 0..400u64 {
        let a = t as f64 * 0.005;
        let eye = DVec3::new(c + 20_000.0 * a.cos(), c + 20_000.0 * a.sin(), 4500.0);
        cm.update(eye).expect("update");
        check_frame(&cm, "puget");
    }
    assert_eq!(cm.frame().stale_levels, 0);
}

/// Fill throughput at n = 255 (desktop profile): every frame teleports, so every level refills all
/// clip_size^2 samples. Prints samples/s; wall-clock time is only printed, never asserted.
/// `cargo test --release --test cpu clipmap::throughput -- --ignored --nocapture`.
#[test]
#[ignore]
fn throughput() {
    let hm = terrain(1025, 30.0, 200.0);
    for synth in [0, 1] {
        let mut prof = Profile::load("desktop").expect("profile");
        let s = prof.clip_size();
        prof.budget.update_samples_per_frame = s * s * prof.clipmap.levels;
        let mut cm = Clipmap::new(
            &hm,
            &prof,
            ClipmapOptions {
                synth_levels: synth,
            },
        )
        .expect("clipmap");
        let frames = 40u32;
        let cpu0 = thread_cpu_seconds();
        let start = std::time::Instant::now();
        let mut samples = 0u64;
        for t in 0..frames {
            // Jumps far enough that no level keeps anything (coarsest spacing 30 m * 2^10).
            let x = 15_000.0 + f64::from(t % 2) * 2_000_000.0;
            let f = cm.update(DVec3::new(x, 15_000.0, 100.0)).expect("update");
            samples += u64::from(f.samples_updated);
        }
        let secs = start.elapsed().as_secs_f64();
        let cpu = thread_cpu_seconds() - cpu0;
        eprintln!(
            "synth_levels {synth}: n {} clip_size {s}: {samples} samples in {frames} frames, {secs:.3} s, \
             {:.1} M samples/s wall; thread CPU {cpu:.2} s, {:.1} M samples/s, {:.2} ms per full {s}x{s} level",
            prof.clipmap.n,
            samples as f64 / secs / 1e6,
            samples as f64 / cpu / 1e6,
            cpu * 1e3 * f64::from(s * s) / samples as f64
        );
    }
}

/// This thread's user + system CPU time from /proc (Linux; 0 elsewhere), so a busy machine does not skew
/// the throughput figure.
fn thread_cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/thread-self/stat") else {
        return 0.0;
    };
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15 (1-based).
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |k: usize| f.get(k).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

/// `surface_height` is the drawn piecewise-linear surface: exact on a tilted plane once every level is
/// current (level 0 holds the eye, and linear interpolation reproduces a plane), and `None` away from data.
#[test]
fn surface_height_follows_the_drawn_surface() {
    let n = 129u32;
    let heights = (0..n * n)
        .map(|i| 3.0 * (i % n) as f32 + 0.5 * (i / n) as f32 + 10.0)
        .collect();
    let hm = Heightmap::new(std::path::Path::new("<plane>"), n, n, 10.0, heights).expect("plane");
    let mut cm =
        Clipmap::new(&hm, &profile(31, 4, 2, 100_000), ClipmapOptions::default()).expect("clipmap");
    let eye = DVec3::new(613.7, 588.2, 400.0);
    for _ in 0..4 {
        cm.update(eye).expect("update");
    }
    assert_eq!(cm.frame().stale_levels, 0);
    let (u, v) = (613.7 / 10.0, 128.0 - 588.2 / 10.0);
    let want = 3.0 * u + 0.5 * v + 10.0;
    let got = f64::from(cm.surface_height(eye).expect("level 0 holds the eye"));
    assert!((got - want).abs() < 1e-3, "surface {got} vs plane {want}");
    assert_eq!(cm.surface_height(DVec3::new(1e7, 1e7, 400.0)), None);
}
