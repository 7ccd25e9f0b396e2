//! SAT LOD: error maps against the clipmap's own surface, estimate <= exact <= conservative on the
//! numerical hard cases (flat terrain, a one-sample needle, errors from 1e-6 m to 1e4 m, p = 2 and 64),
//! per-frame selection, and the bake cache refusing corrupted files.
#![expect(
    clippy::cast_possible_truncation,
    reason = "test arithmetic on values known to be in range"
)]

use std::path::Path;

use clipsat::bake::lod_tables::{error_map, sample_error, LevelTables, LodTables, P};
use clipsat::bake::pyramid::Pyramid;
use clipsat::bake::sat::pow_unit;
use clipsat::bake::{bake_lod, cache_key, cache_path, BakeParams, CacheOutcome};
use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::lod::{Lod, LodFrame, LodMode};
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use glam::{DVec2, DVec3};

fn terrain(w: u32, h: u32, spacing: f32, f: impl Fn(u32, u32) -> f32) -> Heightmap {
    let heights = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| f(x, y))
        .collect();
    Heightmap::new(Path::new("<test>"), w, h, spacing, heights).expect("test terrain")
}

fn hash01(x: u32, y: u32) -> f64 {
    let mut z = (u64::from(x) << 32 | u64::from(y)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// estimate <= exact <= conservative <= E, and exact equals a brute-force max of the error map.
fn check_block(t: &LevelTables, p: u32, errs: &[f32], w: u32, b: (u32, u32, u32, u32)) {
    let be = t.block(p, b.0, b.1, b.2, b.3);
    let mut m = 0.0f32;
    for y in b.1..b.3 {
        for x in b.0..b.2 {
            m = m.max(errs[(y * w + x) as usize]);
        }
    }
    assert_eq!(be.exact, f64::from(m), "exact max, box {b:?}");
    assert!(
        be.estimate <= be.exact && be.exact <= be.conservative,
        "p {p} box {b:?}: {be:?}"
    );
    assert!(be.conservative <= f64::from(t.e_max()));
    assert!(be.estimate >= 0.0 && be.estimate.is_finite());
}

/// The error map is |H_0 - PL(H_L)| with PL built from the clipmap's own samples, split along the
/// (i, j)-(i+1, j+1) diagonal.
#[test]
fn error_map_matches_clipmap_surface() {
    let hm = terrain(129, 97, 10.0, |x, y| {
        (hash01(x, y) * 100.0) as f32 + (x * y) as f32 * 0.01
    });
    let profile = Profile::load("gles3-low").expect("profile");
    let clip = Clipmap::new(&hm, &profile, ClipmapOptions::default()).expect("clipmap");
    for k in 1..4u32 {
        let errs = error_map(clip.pyramid(), k);
        let s = 1i64 << k;
        for (x, y) in [
            (0i64, 0i64),
            (1, 0),
            (0, 1),
            (3, 5),
            (5, 3),
            (7, 7),
            (100, 90),
            (128, 96),
            (127, 95),
        ] {
            let (i, j) = (x.div_euclid(s), y.div_euclid(s));
            let (fx, fy) = ((x - i * s) as f64 / s as f64, (y - j * s) as f64 / s as f64);
            let z = |a: i64, b: i64| f64::from(clip.sample(k, a, b)[0]);
            let pl = if fx >= fy {
                z(i, j) * (1.0 - fx) + z(i + 1, j) * (fx - fy) + z(i + 1, j + 1) * fy
            } else {
                z(i, j) * (1.0 - fy) + z(i, j + 1) * (fy - fx) + z(i + 1, j + 1) * fx
            };
            let h0 = f64::from(hm.at(x as u32, y as u32));
            let got = errs[(y * 129 + x) as usize];
            assert!(
                (f64::from(got) - (h0 - pl).abs()).abs() <= 1e-3,
                "level {k} ({x}, {y}): {got} vs {}",
                (h0 - pl).abs()
            );
        }
        // At odd-odd level-(k-1) vertices the level-k surface is the diagonal mean: the clipmap's z_c.
        for (i, j) in [(1i64, 1i64), (3, 5), (9, 7)] {
            let zc = clip.sample(k - 1, i, j)[1];
            let (x, y) = (i << (k - 1), j << (k - 1));
            let h0 = hm.at(x as u32, y as u32);
            let e = errs[(y * 129 + x) as usize];
            assert!(
                (e - (h0 - zc).abs()).abs() <= 1e-3,
                "z_c at level {} ({i}, {j})",
                k - 1
            );
        }
    }
}

/// Flat terrain: E = 0 at every level, no NaN, and every block takes the coarsest level.
#[test]
fn flat_terrain_takes_the_coarsest_level() {
    let hm = terrain(257, 257, 30.0, |_, _| 123.0);
    let mut profile = Profile::load("gles3-low").expect("profile");
    profile.budget.update_samples_per_frame = u32::MAX;
    let mut clip = Clipmap::new(&hm, &profile, ClipmapOptions::default()).expect("clipmap");
    let tables =
        LodTables::build(clip.pyramid(), profile.clipmap.levels, P, |_| {}).expect("tables");
    for t in &tables.levels {
        assert_eq!(t.e_max(), 0.0);
        let b = t.block(P, 0, 0, 257, 257);
        assert_eq!((b.estimate, b.exact, b.conservative), (0.0, 0.0, 0.0));
    }
    let lod = Lod::for_clipmap(tables, &profile, &clip, &hm);
    let eye = DVec3::new(3840.0, 3840.0, 200.0);
    let frame = clip.update(eye).expect("frame").clone();
    let cam = Camera::new(eye, DVec3::new(5000.0, 5000.0, 123.0), 60.0).expect("camera");
    let mut out = LodFrame::new_boxed();
    for mode in [LodMode::Sat, LodMode::SatConservative, LodMode::Exact] {
        lod.select(&frame, &cam, mode, &mut out).expect("select");
        assert!(!out.blocks.is_empty());
        let coarsest = profile.clipmap.levels - 1;
        for b in &out.blocks {
            assert_eq!(b.wanted, coarsest, "{mode}: {b:?}");
            assert_eq!(b.level, coarsest, "{mode}: {b:?}");
            assert_eq!(b.eta_m, 0.0);
        }
        assert_eq!(out.blocks_clamped, 0);
    }
}

/// A one-sample needle on a flat plain: the block holding it has exact = conservative-or-less = the
/// needle's error (about the needle's height, less what the filtered coarse level keeps of it), at p = 2
/// and at p = 64, where (e/E)^p of the other samples underflows.
#[test]
fn needle_is_never_missed() {
    let (w, h, needle) = (257u32, 257u32, (101u32, 77u32));
    let height = 1000.0f32;
    let hm = terrain(
        w,
        h,
        30.0,
        |x, y| if (x, y) == needle { height } else { 0.0 },
    );
    let pyr = Pyramid::build(&hm);
    for p in [2u32, 8, 64] {
        for k in 1..7u32 {
            let errs = error_map(&pyr, k);
            let t = LevelTables::build(w, h, errs.clone(), p).expect("tables");
            let e_needle = errs[(needle.1 * w + needle.0) as usize];
            assert!(
                e_needle >= 0.8 * height,
                "level {k}: needle error {e_needle}"
            );
            for b in [
                (96, 64, 128, 96),
                (101, 77, 102, 78),
                (0, 0, w, h),
                (64, 64, 160, 160),
                (0, 0, 50, 50),
            ] {
                check_block(&t, p, &errs, w, b);
            }
            let be = t.block(p, 96, 64, 128, 96);
            assert!(
                be.conservative >= f64::from(e_needle),
                "p {p} level {k}: {be:?}"
            );
            assert!(t.block(p, 101, 77, 102, 78).conservative >= f64::from(e_needle));
        }
    }
}

/// Errors from about 1e-6 m to 1e4 m in one terrain, p at both ends of the tuning range: every block
/// ordered, and its SAT sum within the stated bound of an f64 brute-force sum.
///
/// The roughness sits on a 0 m base: on a 5,000 m base an f32 height resolves only 2^-11 m (4.9e-4 m),
/// so the western errors could not go below about 1e-4 m and the span was about 7 decades. The test
/// checks the span it claims: westmost errors at most 2e-5 m, eastmost at least 1e3 m, and the largest
/// over the smallest nonzero error at least 1e10.
#[test]
fn errors_spanning_ten_decades() {
    let (w, h) = (257u32, 129u32);
    // Amplitude 10^(-6 + 10 x / w): roughness grows ten decades west to east.
    let hm = terrain(w, h, 10.0, |x, y| {
        let amp = 10f64.powf(-6.0 + 10.0 * f64::from(x) / f64::from(w));
        (amp * (hash01(x, y) - 0.5)) as f32
    });
    let pyr = Pyramid::build(&hm);
    for k in [1u32, 3, 5] {
        let errs = error_map(&pyr, k);
        let band = |x0: u32, x1: u32| {
            let mut v: Vec<f32> = (0..h)
                .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                .map(|(x, y)| errs[(y * w + x) as usize])
                .collect();
            v.sort_by(f32::total_cmp);
            v
        };
        let (west, east) = (band(0, 8), band(w - 8, w));
        let west_max = west.last().copied().unwrap_or(0.0);
        let east_max = east.last().copied().unwrap_or(0.0);
        let smallest = errs
            .iter()
            .copied()
            .filter(|e| *e > 0.0)
            .fold(f32::INFINITY, f32::min);
        let largest = errs.iter().copied().fold(0.0f32, f32::max);
        eprintln!(
            "level {k}: west max {west_max:e}, east max {east_max:e}, errors {smallest:e} .. {largest:e} \
             ({:.1} decades)",
            (f64::from(largest) / f64::from(smallest)).log10()
        );
        assert!(
            west_max > 0.0 && west_max <= 2e-5 && east_max >= 1e3,
            "level {k}: west max {west_max:e}, east max {east_max:e}"
        );
        assert!(
            f64::from(largest) / f64::from(smallest) >= 1e10,
            "level {k}: errors {smallest:e} .. {largest:e} span less than ten decades"
        );
    }
    for p in [2u32, 64] {
        for k in [1u32, 3, 5] {
            let errs = error_map(&pyr, k);
            let t = LevelTables::build(w, h, errs.clone(), p).expect("tables");
            let (sat, _) = t.tables().expect("nonzero errors");
            let e = f64::from(t.e_max());
            for bx in 0..16u32 {
                for by in 0..8u32 {
                    let b = (
                        bx * 16,
                        by * 16,
                        (bx * 16 + 17).min(w),
                        (by * 16 + 17).min(h),
                    );
                    check_block(&t, p, &errs, w, b);
                    let mut s = 0.0f64;
                    for y in b.1..b.3 {
                        for x in b.0..b.2 {
                            s += pow_unit(f64::from(errs[(y * w + x) as usize]) / e, p);
                        }
                    }
                    let n = f64::from((b.2 - b.0) * (b.3 - b.1));
                    let got = sat.box_sum(b.0, b.1, b.2, b.3);
                    assert!(
                        got >= s * (1.0 - 1e-13) && got <= s * (1.0 + 1e-13) + n * sat.quantum(),
                        "p {p} level {k} {b:?}: {got} vs {s}"
                    );
                }
            }
        }
    }
}

/// Selection on a rough terrain: Sat picks levels no finer than Exact, Conservative no coarser; blocks
/// stay within the profile's draw budget; Distance keeps every block on its ring.
#[test]
fn selection_orders_the_modes() {
    let hm = terrain(257, 257, 30.0, |x, y| {
        (300.0 * (f64::from(x) / 9.0).sin() * (f64::from(y) / 13.0).cos() + 80.0 * hash01(x, y))
            as f32
    });
    let mut profile = Profile::load("gles3-low").expect("profile");
    profile.budget.update_samples_per_frame = u32::MAX;
    let mut clip = Clipmap::new(&hm, &profile, ClipmapOptions::default()).expect("clipmap");
    let tables =
        LodTables::build(clip.pyramid(), profile.clipmap.levels, P, |_| {}).expect("tables");
    let lod = Lod::for_clipmap(tables, &profile, &clip, &hm);
    let mut outs: Vec<Box<LodFrame>> = (0..4).map(|_| LodFrame::new_boxed()).collect();
    for (eye, target) in [
        (
            DVec3::new(3840.0, 3840.0, 700.0),
            DVec3::new(6000.0, 6000.0, 0.0),
        ),
        (
            DVec3::new(1000.0, 6000.0, 3000.0),
            DVec3::new(4000.0, 3000.0, 0.0),
        ),
    ] {
        let frame = clip.update(eye).expect("frame").clone();
        let cam = Camera::new(eye, target, 60.0).expect("camera");
        let modes = [
            LodMode::Distance,
            LodMode::Sat,
            LodMode::Exact,
            LodMode::SatConservative,
        ];
        for (mode, out) in modes.iter().zip(outs.iter_mut()) {
            lod.select(&frame, &cam, *mode, out).expect("select");
            assert!(out.blocks.len() <= profile.budget.max_draws as usize);
        }
        for b in &outs[0].blocks {
            assert_eq!(b.level, b.ring);
        }
        let (sat, exact, cons) = (&outs[1].blocks, &outs[2].blocks, &outs[3].blocks);
        assert_eq!(sat.len(), exact.len());
        for ((s, e), c) in sat.iter().zip(exact.iter()).zip(cons.iter()) {
            assert_eq!((s.rect, s.ring), (e.rect, e.ring));
            assert!(
                s.wanted >= e.wanted && e.wanted >= c.wanted,
                "{s:?} {e:?} {c:?}"
            );
            assert!(
                e.bound_px <= profile.view.epsilon_px || e.level < e.wanted || e.wanted < e.level
            );
        }
        let levels: std::collections::BTreeSet<u32> = exact.iter().map(|b| b.level).collect();
        assert!(
            levels.len() > 1,
            "a rough terrain should need more than one level: {levels:?}"
        );
    }
}

/// The bound tests' terrain (129 x 97 at 30 m: waves and noise), its gles3-low clipmap and SAT LOD.
fn bound_fixture() -> (Heightmap, Profile, Clipmap, Lod) {
    let hm = terrain(129, 97, 30.0, |x, y| {
        (200.0 * (f64::from(x) / 7.0).sin() * (f64::from(y) / 11.0).cos() + 60.0 * hash01(x, y))
            as f32
    });
    let profile = Profile::load("gles3-low").expect("profile");
    let clip = Clipmap::new(&hm, &profile, ClipmapOptions::default()).expect("clipmap");
    let tables =
        LodTables::build(clip.pyramid(), profile.clipmap.levels, P, |_| {}).expect("tables");
    let lod = Lod::for_clipmap(tables, &profile, &clip, &hm);
    (hm, profile, clip, lod)
}

/// The selector keeps the object-space errors it has asked across frames (they depend on the tables only):
/// every bound a selector warmed by thousands of other boxes, levels, modes and cameras gives is the one a
/// fresh selector computes, bit for bit.
#[test]
fn cached_errors_give_the_fresh_bounds() {
    let (hm, profile, clip, warm) = bound_fixture();
    let synth = clip.synth_levels();
    let spacing = clip.g0() * f64::from(1u32 << synth);
    let (ox, oy) = clip.origin();
    let top = oy + 96.0 * spacing;
    let cam = |i: u32| {
        let f = f64::from(i);
        Camera::new(
            DVec3::new(
                ox + (20.0 + f) * spacing,
                top - (30.0 + f) * spacing,
                500.0 + 40.0 * f,
            ),
            DVec3::new(ox + 100.0 * spacing, top - 70.0 * spacing, 0.0),
            60.0,
        )
        .expect("camera")
    };
    let boxes = |i: u32| {
        let r = |n: u32| (hash01(i * 13 + n, 5) * 128.0) as i64;
        let (a, b) = (r(1).min(r(2)), r(1).max(r(2)).max(r(1).min(r(2)) + 1));
        let (c, d) = (r(3).min(r(4)) * 3 / 4, r(3).max(r(4)) * 3 / 4 + 1);
        (a << synth, c << synth, b << synth, d << synth)
    };
    let modes = [LodMode::Sat, LodMode::SatConservative, LodMode::Exact];
    for i in 0..3000 {
        let _ = warm.box_bound_px(&cam(i % 7), modes[i as usize % 3], synth + i % 4, boxes(i));
    }
    for i in (0..3000).step_by(37) {
        let (c, m, l, bx) = (cam(i % 7), modes[i as usize % 3], synth + i % 4, boxes(i));
        let tables =
            LodTables::build(clip.pyramid(), profile.clipmap.levels, P, |_| {}).expect("tables");
        let fresh = Lod::for_clipmap(tables, &profile, &clip, &hm);
        assert_eq!(
            warm.box_bound_px(&c, m, l, bx).to_bits(),
            fresh.box_bound_px(&c, m, l, bx).to_bits(),
            "box {i}"
        );
    }
}

/// The split bound of `Lod::box_bound_px` stays an upper bound of what is measured: for boxes of every
/// size and alignment and every level, from two cameras (one looking across the terrain, one low and
/// steep, so that boxes sit far off the screen's axis), under `exact` and `sat-conservative`, it is at
/// least the largest `VerticalScale::px` of e_L over the box's data samples in the frustum (what
/// `measure::screen_error` reports), which is the pixel distance between the sample and the sample moved
/// up or down by e_L (the longer) through the camera's own view-projection matrix; and `exact`'s bound is
/// never above `sat-conservative`'s (the matrix is f32: to 1e-6). `Lod::box_bound_at_eps`, whose threshold
/// test cuts sub-boxes over epsilon again, is a bound too, never above the split bound.
#[test]
fn split_bound_covers_every_sample() {
    let (_, profile, clip, lod) = bound_fixture();
    let synth = clip.synth_levels();
    let spacing = clip.g0() * f64::from(1u32 << synth);
    let (ox, oy) = clip.origin();
    let top = oy + 96.0 * spacing;
    let data = clip.pyramid().level(0);
    let cams = [
        Camera::new(
            DVec3::new(ox + 40.0 * spacing, top - 30.0 * spacing, 900.0),
            DVec3::new(ox + 100.0 * spacing, top - 80.0 * spacing, 0.0),
            60.0,
        ),
        Camera::new(
            DVec3::new(ox + 64.0 * spacing, top - 48.0 * spacing, 600.0),
            DVec3::new(ox + 70.0 * spacing, top - 52.0 * spacing, -400.0),
            75.0,
        ),
    ];
    let view = (profile.view.width, profile.view.height);
    let aspect = f64::from(view.0) / f64::from(view.1);
    let mut checked = 0;
    let mut visible = 0;
    let mut tightened = 0usize;
    for cam in cams {
        let cam = cam.expect("camera");
        let frustum = clipsat::plan::cull::Frustum::new(&cam, aspect);
        let scale = cam.vertical_scale(view);
        let vp = cam.view_proj_relative(aspect).as_dmat4();
        let pixel = |q: DVec3| {
            let c = vp * q.extend(1.0);
            DVec2::new(c.x / c.w * f64::from(view.0), c.y / c.w * f64::from(view.1)) * 0.5
        };
        for level in synth..synth + 4 {
            let k = level - synth;
            for i in 0..40u32 {
                // Level-0 lattice boxes, some on the level's lattice and some not.
                let r = |n: u32| (hash01(i * 7 + n, level) * 128.0) as i64;
                let (a, b) = (r(1).min(r(2)), r(1).max(r(2)).max(r(1).min(r(2)) + 1));
                let (c, d) = (r(3).min(r(4)) * 3 / 4, r(3).max(r(4)) * 3 / 4 + 1);
                let bx = (a << synth, c << synth, b << synth, d << synth);
                let mut measured = 0.0f64;
                for y in c..=d.min(96) {
                    for x in a..=b.min(128) {
                        let z = f64::from(data.at_clamped(x, y));
                        let rel = DVec3::new(
                            ox + x as f64 * spacing - cam.eye.x,
                            top - y as f64 * spacing - cam.eye.y,
                            z - cam.eye.z,
                        );
                        if !frustum.intersects(rel, rel) {
                            continue;
                        }
                        let e = f64::from(sample_error(clip.pyramid(), k, x, y));
                        let px = scale.px(rel, e);
                        let true_px = [-e, e]
                            .map(|s| (pixel(rel + DVec3::Z * s) - pixel(rel)).length())
                            .into_iter()
                            .fold(0.0, f64::max);
                        assert!(
                            (px - true_px).abs() <= 1e-6 * true_px.max(1.0),
                            "{rel}: {px} px, projected {true_px} px"
                        );
                        measured = measured.max(px);
                        visible += 1;
                    }
                }
                let exact = lod.box_bound_px(&cam, LodMode::Exact, level, bx);
                let cons = lod.box_bound_px(&cam, LodMode::SatConservative, level, bx);
                assert!(
                    exact >= measured,
                    "level {level} {bx:?}: exact {exact} < measured {measured}"
                );
                assert!(
                    cons >= exact,
                    "level {level} {bx:?}: conservative {cons} < exact {exact}"
                );
                // The deeper cut of the threshold test (what the detail pool decides with) is still a
                // bound: at thresholds around the split bound, where it cuts sub-boxes again.
                for f in [0.7, 0.8, 0.9, 1.0] {
                    for (mode, whole) in [(LodMode::Exact, exact), (LodMode::SatConservative, cons)]
                    {
                        let eps = whole * f;
                        let deep = lod.box_bound_at_eps(&cam, mode, level, bx, eps);
                        assert!(
                            deep >= measured && deep <= whole,
                            "level {level} {bx:?} {mode:?} at {eps}: deep {deep}, split {whole}, \
                             measured {measured}"
                        );
                        tightened += usize::from(deep < whole);
                    }
                }
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 320);
    assert!(visible > 10_000, "{visible} visible samples");
    assert!(tightened > 0, "the deeper cut never tightened a bound");
}

/// The oracle run with the LOD bound in place of the measured error (`measure::bound_oracle`) keeps a
/// quad only where the bound meets epsilon, and the bound is at least the measured error
/// ([`split_bound_covers_every_sample`]): so it never needs fewer triangles than the measured oracle, in
/// either SAT mode, and `exact`'s never more than `sat-conservative`'s. The same holds at the grain of
/// fans ([`clipsat::measure::FanGrain`]).
#[test]
fn bound_oracle_needs_at_least_the_oracle() {
    let (hm, profile, clip, lod) = bound_fixture();
    let cam = Camera::default_for(&hm).expect("camera");
    let view = (profile.view.width, profile.view.height);
    let eps = [0.5, 1.0, 2.0, 4.0];
    let (levels, quads) = (profile.clipmap.levels, profile.detail_quads());
    let measured = clipsat::measure::oracle(&clip, &cam, view, levels, quads, &eps);
    let by =
        |mode| clipsat::measure::bound_oracle(&clip, &cam, view, levels, quads, &eps, &lod, mode);
    let (exact, conservative) = (by(LodMode::Exact), by(LodMode::SatConservative));
    for i in 0..eps.len() {
        let (m, e, c) = (
            measured[i].triangles,
            exact[i].triangles,
            conservative[i].triangles,
        );
        assert!(m > 0 && m <= e && e <= c, "epsilon {}: {m} {e} {c}", eps[i]);
    }
    // The bound is not vacuous: at some epsilon it needs more than the measured error does.
    assert!((0..eps.len()).any(|i| exact[i].triangles > measured[i].triangles));
    // At the grain of 2 x 2-quad fans: every kept fan is four quads that meet epsilon, so the measured
    // descent's quads never need more; balancing only splits.
    for (i, m) in measured.iter().enumerate() {
        assert!(m.triangles <= m.fan.triangles, "epsilon {}: {m:?}", eps[i]);
    }
    for o in measured.iter().chain(&exact).chain(&conservative) {
        assert!(
            o.fan.triangles > 0 && o.fan.triangles <= o.fan.balanced_triangles,
            "{o:?}"
        );
        assert!(o.fan.transition_sides > 0, "{o:?}");
    }
}

/// The bake cache: miss, hit (identical tables), and every damaged file refused and rebaked.
#[test]
fn bake_cache_detects_damage() {
    let hm = terrain(65, 33, 25.0, |x, y| (hash01(x, y) * 50.0) as f32);
    let pyr = Pyramid::build(&hm);
    let params = BakeParams {
        p: 8,
        levels: 5,
        synth_levels: 0,
        g0: 25.0,
    };
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("lod-cache-test");
    let _ = std::fs::remove_dir_all(&dir);
    let (a, o) = bake_lod(&hm, &pyr, &params, &dir, clipsat::Progress::default()).expect("bake");
    assert_eq!(o, CacheOutcome::Baked);
    let (b, o) = bake_lod(&hm, &pyr, &params, &dir, clipsat::Progress::default()).expect("hit");
    assert_eq!(o, CacheOutcome::Hit);
    assert_eq!(a, b);
    let path = cache_path(&dir, cache_key(&hm, &params));
    let good = std::fs::read(&path).expect("cache file");
    let damages: [(&str, Vec<u8>); 5] = [
        ("flipped byte", {
            let mut v = good.clone();
            let i = v.len() / 2;
            v[i] ^= 0x40;
            v
        }),
        ("truncated", good[..good.len() - 100].to_vec()),
        ("empty", Vec::new()),
        ("garbage", vec![0xAB; 4096]),
        ("bad magic", {
            let mut v = good.clone();
            v[0] = b'X';
            v
        }),
    ];
    for (what, bytes) in damages {
        std::fs::write(&path, &bytes).expect("write damaged");
        let (c, o) =
            bake_lod(&hm, &pyr, &params, &dir, clipsat::Progress::default()).expect("rebake");
        assert!(matches!(o, CacheOutcome::Rebaked(_)), "{what}: {o:?}");
        assert_eq!(c, a, "{what}");
        assert_eq!(std::fs::read(&path).expect("rewritten"), good, "{what}");
    }
    // Another terrain's valid file under this key's name: refused by the key in its header.
    let other = terrain(65, 33, 25.0, |x, y| (hash01(y, x) * 50.0) as f32);
    let (_, _) = bake_lod(
        &other,
        &Pyramid::build(&other),
        &params,
        &dir,
        clipsat::Progress::default(),
    )
    .expect("other");
    let other_bytes =
        std::fs::read(cache_path(&dir, cache_key(&other, &params))).expect("other file");
    std::fs::write(&path, other_bytes).expect("swap");
    let (c, o) = bake_lod(&hm, &pyr, &params, &dir, clipsat::Progress::default()).expect("rebake");
    assert!(
        matches!(&o, CacheOutcome::Rebaked(r) if r.contains("key")),
        "{o:?}"
    );
    assert_eq!(c, a);
    // Different parameters are a different key.
    let p64 = BakeParams { p: 64, ..params };
    assert_ne!(cache_key(&hm, &p64), cache_key(&hm, &params));
    assert_eq!(
        bake_lod(&hm, &pyr, &p64, &dir, clipsat::Progress::default())
            .expect("p64")
            .1,
        CacheOutcome::Baked
    );
}

#[test]
fn lod_mode_parses() {
    for name in LodMode::NAMES {
        let m: LodMode = name.parse().expect("mode");
        assert_eq!(m.to_string(), name);
    }
    assert!("fast".parse::<LodMode>().is_err());
}

/// The 16385 x 16385 extent at full resolution (docs/design.md "SAT LOD" hard cases): an error field spanning
/// ten decades (1e-6 .. 1e4 m) with one needle, the level tables built as the bake builds them (1.1 GB of
/// errors, a 2.1 GB SAT, a 1.4 GB max pyramid), then blocks of every size up to the whole extent keep
/// estimate <= exact <= conservative and their SAT sums match a compensated f64 sum within
/// 1e-12 relative + n quanta. Heavy, so ignored by default:
/// `cargo test --release --test cpu lod::extent_16385 -- --ignored`.
#[test]
#[ignore = "5 GB and about a minute in release: cargo test --release --test cpu lod::extent_16385 -- --ignored"]
fn extent_16385_full_resolution_tables() {
    let side = 16385u32;
    let needle = (9_999u32, 4_321u32);
    let errs: Vec<f32> = (0..side)
        .flat_map(|y| (0..side).map(move |x| (x, y)))
        .map(|(x, y)| {
            if (x, y) == needle {
                1e4
            } else {
                (10f64.powf(-6.0 + 9.0 * f64::from(x) / f64::from(side)) * hash01(x, y)) as f32
            }
        })
        .collect();
    let t = LevelTables::build(side, side, errs.clone(), P).expect("tables");
    let (sat, _) = t.tables().expect("nonzero errors");
    assert_eq!(t.e_max(), 1e4);
    let e = f64::from(t.e_max());
    let mut boxes = vec![
        (0, 0, side, side),
        (needle.0, needle.1, needle.0 + 1, needle.1 + 1),
        (needle.0 - 16, needle.1 - 16, needle.0 + 17, needle.1 + 17),
        (0, 0, 33, 33),
        (side - 33, side - 33, side, side),
        (0, 0, 4097, side),
    ];
    for k in 0..64u32 {
        let s = 33 << (k % 8);
        let (x0, y0) = (k * 251 % (side - s), k * 977 % (side - s));
        boxes.push((x0, y0, x0 + s, y0 + s));
    }
    for b in boxes {
        let be = t.block(P, b.0, b.1, b.2, b.3);
        assert!(
            be.estimate <= be.exact && be.exact <= be.conservative && be.conservative <= e,
            "box {b:?}: {be:?}"
        );
        let has_needle = (b.0..b.2).contains(&needle.0) && (b.1..b.3).contains(&needle.1);
        if has_needle {
            assert_eq!(be.exact, e, "the needle is the max of {b:?}");
            assert_eq!(
                be.conservative, e,
                "the conservative bound keeps the needle in {b:?}"
            );
        }
        // Neumaier-compensated reference sum of (e/E)^p.
        let (mut s, mut comp) = (0.0f64, 0.0f64);
        for y in b.1..b.3 {
            for x in b.0..b.2 {
                let v = pow_unit(f64::from(errs[(y * side + x) as usize]) / e, P);
                let t = s + v;
                comp += if s.abs() >= v.abs() {
                    (s - t) + v
                } else {
                    (v - t) + s
                };
                s = t;
            }
        }
        let s = s + comp;
        let n = f64::from(b.2 - b.0) * f64::from(b.3 - b.1);
        let got = sat.box_sum(b.0, b.1, b.2, b.3);
        assert!(
            got >= s * (1.0 - 1e-12) && got <= s * (1.0 + 1e-12) + n * sat.quantum(),
            "{b:?}: SAT {got} vs f64 {s}"
        );
    }
}

/// The most a decoded maximum may exceed the true `m` of a level with largest error `e`: one max-code
/// step (2^(1/16)), or the codes' floor E 2^(-254/16) (`clipsat::bake::lod_record`).
fn step_up(m: f64, e: f64) -> f64 {
    (m * (1.0f64 / 16.0).exp2()).max(e * (-254.0f64 / 16.0).exp2()) * (1.0 + 1e-6)
}

/// Level-resolution tables (cells of 2^k samples, what the bake builds) against the full-resolution ones
/// on the shared terrains and a rough procedural one. The level tables are decoded from the compact
/// records (`clipsat::bake::lod_record`): over boxes on level k's lattice the exact max is the true one
/// rounded up by at most one record step and the estimate and conservative bounds still enclose the true
/// one; over random boxes, mostly off the lattice, the same holds of the covering cells' true max (never
/// below the box's own), and estimate <= true max <= conservative <= E throughout.
#[test]
fn level_resolution_tables_keep_the_full_resolution_guarantees() {
    let mut terrains = vec![(
        "procedural 193 x 161".to_string(),
        terrain(193, 161, 30.0, |x, y| {
            (300.0 * (f64::from(x) / 9.0).sin() * (f64::from(y) / 13.0).cos() + 80.0 * hash01(x, y))
                as f32
        }),
    )];
    for (name, spacing) in [
        ("srtm_bigtujunga30m_utm11.tif", None),
        ("N57E011.hgt", None),
        ("aletsch_200m.tif", None),
        ("lidar_pkg_dem_1m_400x400.tif", None),
        ("ps_height_1k.png", Some(160.0f32)),
    ] {
        let Some(hm) = crate::shared(name, spacing) else {
            continue;
        };
        terrains.push((name.to_string(), hm));
    }
    for (name, hm) in &terrains {
        let pyr = Pyramid::build(hm);
        let (w, h) = (hm.width(), hm.height());
        for k in [1u32, 2, 4, 6] {
            let errs = error_map(&pyr, k);
            let old = LevelTables::build(w, h, errs.clone(), P).expect("full tables");
            let new = LevelTables::build_level(&pyr, k, P).expect("level tables");
            assert_eq!(new.e_max(), old.e_max(), "{name} level {k}");
            assert_eq!(new.shift(), k);
            let full = u64::from(w) * u64::from(h) * 12;
            assert!(
                new.memory_bytes() * (1 << (2 * k)) <= full * 2,
                "{name} level {k}: {} bytes",
                new.memory_bytes()
            );
            let e = f64::from(new.e_max());
            let step = 1u32 << k;
            let mut checked = 0;
            // Lattice-aligned boxes: inclusive vertices [A 2^k, B 2^k], as the LOD's data boxes are.
            for (bw, i) in [(1u32, 0u32), (2, 1), (5, 2), (32, 3), (3, 7), (64, 5)] {
                let x0 = (i * 37 * step) % w;
                let y0 = (i * 23 * step) % h;
                let x0 = x0 - x0 % step;
                let y0 = y0 - y0 % step;
                let (x1, y1) = ((x0 + bw * step + 1).min(w), (y0 + bw * step + 1).min(h));
                let (o, n) = (old.block(P, x0, y0, x1, y1), new.block(P, x0, y0, x1, y1));
                let aligned = |a: u32, len: u32| (a - 1).is_multiple_of(step) || a == len;
                if aligned(x1, w) && aligned(y1, h) {
                    assert!(
                        n.exact >= o.exact && n.exact <= step_up(o.exact, e),
                        "{name} level {k} box {x0},{y0}..{x1},{y1}: {} vs {}",
                        n.exact,
                        o.exact
                    );
                    checked += 1;
                }
                assert!(n.estimate <= o.exact, "{name} {k}: {n:?} {o:?}");
                assert!(n.conservative >= o.exact, "{name} {k}: {n:?} {o:?}");
                assert!(n.estimate <= n.exact && n.conservative <= e);
            }
            assert!(checked > 0, "{name} level {k}: no aligned box checked");
            // Random boxes, mostly off the lattice: the covering cells' max (the true max of the region
            // level k draws over the box, never below the box's own), which `exact` holds within one
            // record step, `sat` never exceeds and `sat-conservative` never falls below.
            let mut seed = 0x9e37_79b9_7f4a_7c15u64 ^ u64::from(k);
            let mut rand = |n: u32| {
                seed = seed
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                u32::try_from((seed >> 33) % u64::from(n.max(1))).expect("below n")
            };
            for i in 0..160u32 {
                let x0 = rand(w - 1);
                let y0 = rand(h - 1);
                let span = if i % 4 == 0 { 200 } else { 40 };
                let (x1, y1) = ((x0 + 1 + rand(span)).min(w), (y0 + 1 + rand(span)).min(h));
                let (o, n) = (old.block(P, x0, y0, x1, y1), new.block(P, x0, y0, x1, y1));
                // The closed cells [c 2^k, (c + 1) 2^k] covering inclusive samples [a, b].
                let widen = |a: u32, b: u32, len: u32| {
                    let cells = (len - 1).div_ceil(step).max(1);
                    let ca = (a / step).min(cells - 1);
                    let cb = b.div_ceil(step).saturating_sub(1).clamp(ca, cells - 1);
                    (ca * step, ((cb + 1) * step).min(len - 1))
                };
                let ((cx0, cx1), (cy0, cy1)) = (widen(x0, x1 - 1, w), widen(y0, y1 - 1, h));
                let mut m = 0.0f32;
                for y in cy0..=cy1 {
                    for x in cx0..=cx1 {
                        m = m.max(errs[(y * w + x) as usize]);
                    }
                }
                let m = f64::from(m);
                assert!(
                    n.exact >= m && n.exact <= step_up(m, e),
                    "{name} level {k} box {x0},{y0}..{x1},{y1}: {} vs {m}",
                    n.exact
                );
                assert!(
                    n.estimate <= m && m <= n.conservative && n.conservative <= e,
                    "{name} level {k} box {x0},{y0}..{x1},{y1}: {n:?}, true max {m}"
                );
                assert!(n.exact >= o.exact && n.conservative >= o.exact);
            }
        }
    }
}
