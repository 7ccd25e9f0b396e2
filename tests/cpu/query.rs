//! Stage 1b, the package: the exact queries (`package::query`, `package::ray`) against independent
//! references: the bilinear height bit for bit over the decoded level 0 and within the bake's stated
//! error of the source; ray hits against a slow marcher on the same bilinear surface.
//!
//! The default run takes the procedural terrain (257^2, streamed through a package in a temp folder and
//! held whole) and Puget Sound 1k where the shared data has it. `cargo test --test cpu query:: --
//! --ignored` adds the other seven shared terrains.

use std::path::PathBuf;

use clipsat::package::query::{self, GridRanges, Level0, QueryTiles, ResidentGrid};
use clipsat::package::ray::{self, GridRay};
use clipsat::package::{self, BakeOptions, Package};
use clipsat::source::procedural::{self, ProceduralParams};
use clipsat::source::Heightmap;

use super::shared;

/// Points and rays per terrain.
const N: usize = 10_000;

/// The query cache's budget in these tests: 8 MiB, room for every tile of a 1k terrain, since random
/// points over the whole terrain would otherwise decode a tile a query (a profile's share holds the
/// neighbourhood an engine queries).
const QUERY_BUDGET: u64 = 8 << 20;

/// A deterministic generator (SplitMix64) of uniform f64 in [0, 1).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        #[expect(clippy::cast_precision_loss, reason = "53 bits of a u64")]
        let f = (z >> 11) as f64 / (1u64 << 53) as f64;
        f
    }
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("clipsat-query-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// The straightforward reference: level 0 as a plain row-major grid, bilinear by the formula
/// `query::bilinear` documents, written out here.
struct Plain {
    w: usize,
    h: usize,
    z: Vec<f32>,
}

impl Plain {
    fn at(&self, i: usize, j: usize) -> f64 {
        f64::from(self.z[j.min(self.h - 1) * self.w + i.min(self.w - 1)])
    }

    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        clippy::cast_precision_loss,
        reason = "grid coordinates of small test grids"
    )]
    fn height(&self, u: f64, v: f64) -> Option<f64> {
        let (wm, hm) = ((self.w - 1) as f64, (self.h - 1) as f64);
        if !(0.0..=wm).contains(&u) || !(0.0..=hm).contains(&v) {
            return None;
        }
        let i = (u.floor() as usize).min(self.w - 2);
        let j = (v.floor() as usize).min(self.h - 2);
        let (fx, fy) = (u - i as f64, v - j as f64);
        let top = self.at(i, j) + fx * (self.at(i + 1, j) - self.at(i, j));
        let bottom = self.at(i, j + 1) + fx * (self.at(i + 1, j + 1) - self.at(i, j + 1));
        Some(top + fy * (bottom - top))
    }

    /// The first crossing of the ray with the surface: marched in steps of `step` (grid parameter
    /// units), a sign change bisected; slow and simple.
    fn march(&self, r: &GridRay, step: f64) -> Option<f64> {
        let at = |t: f64| {
            [
                r.o[0] + t * r.d[0],
                r.o[1] + t * r.d[1],
                r.o[2] + t * r.d[2],
            ]
        };
        let f = |t: f64| {
            let p = at(t);
            self.height(p[0], p[1]).map(|h| p[2] - h)
        };
        // Where the ray leaves the grid's columns and rows (no surface past them).
        #[expect(clippy::cast_precision_loss, reason = "small grids")]
        let size = [(self.w - 1) as f64, (self.h - 1) as f64];
        let mut end = r.t.1;
        for (k, side) in size.into_iter().enumerate() {
            if r.d[k] > 0.0 {
                end = end.min((side - r.o[k]) / r.d[k]);
            } else if r.d[k] < 0.0 {
                end = end.min(-r.o[k] / r.d[k]);
            }
        }
        let mut prev: Option<(f64, f64)> = None;
        let mut t = r.t.0;
        loop {
            let t1 = t.min(end);
            match (prev, f(t1)) {
                (Some((tp, fp)), Some(fc)) if (fp >= 0.0) != (fc >= 0.0) || fc == 0.0 => {
                    let (mut lo, mut hi) = (tp, t1);
                    for _ in 0..100 {
                        let mid = 0.5 * (lo + hi);
                        match f(mid) {
                            Some(fm) if (fm >= 0.0) == (fp >= 0.0) && fm != 0.0 => lo = mid,
                            _ => hi = mid,
                        }
                    }
                    return Some(hi);
                }
                (None, Some(0.0)) => return Some(t1),
                (_, c) => prev = c.map(|c| (t1, c)),
            }
            if t1 >= end {
                return None;
            }
            t += step;
        }
    }
}

/// A random point of the grid's box, a little past its edges too (10 % of points are outside).
fn point(rng: &mut Rng, w: usize, h: usize) -> (f64, f64) {
    #[expect(clippy::cast_precision_loss, reason = "small grids")]
    let (wm, hm) = ((w - 1) as f64, (h - 1) as f64);
    (
        rng.next() * wm * 1.1 - 0.05 * wm,
        rng.next() * hm * 1.1 - 0.05 * hm,
    )
}

/// Heights bit for bit against [`Plain`], within `bound` (+ an f32 rounding) of `source`'s bilinear
/// heights, None outside; returns the largest error against the source.
fn check_heights(
    name: &str,
    grid: &mut impl Level0,
    plain: &Plain,
    source: &Plain,
    bound: f64,
) -> f64 {
    let mut rng = Rng(7);
    let mut worst = 0.0f64;
    for _ in 0..N {
        let (u, v) = point(&mut rng, plain.w, plain.h);
        grid.begin();
        let got = query::height(grid, u, v).expect("query");
        let want = plain.height(u, v);
        assert_eq!(
            got.map(f64::to_bits),
            want.map(f64::to_bits),
            "{name}: ({u}, {v}): {got:?} != {want:?}"
        );
        if let (Some(g), Some(s)) = (got, source.height(u, v)) {
            let e = (g - s).abs();
            let slack = 2.0 * f64::from(f32::EPSILON) * s.abs().max(1.0);
            assert!(e <= bound + slack, "{name}: ({u}, {v}): {g} vs source {s}");
            worst = worst.max(e);
        }
    }
    // The corners and edges exactly.
    #[expect(clippy::cast_precision_loss, reason = "small grids")]
    let (wm, hm) = ((plain.w - 1) as f64, (plain.h - 1) as f64);
    for (u, v) in [(0.0, 0.0), (wm, hm), (wm, 0.0), (0.0, hm), (wm, hm * 0.5)] {
        let got = query::height(grid, u, v).expect("query");
        assert_eq!(
            got.map(f64::to_bits),
            plain.height(u, v).map(f64::to_bits),
            "{name}: edge ({u}, {v})"
        );
    }
    for (u, v) in [
        (-1e-9, 0.0),
        (wm + 1e-9, 1.0),
        (f64::NAN, 1.0),
        (1.0, f64::INFINITY),
    ] {
        assert_eq!(
            query::height(grid, u, v).expect("query"),
            None,
            "{name}: outside ({u}, {v})"
        );
    }
    worst
}

/// Random rays: 80 % from above the terrain looking down at 3..80 degrees, 10 % from under the surface
/// looking up, 10 % any direction; each hit distance against [`Plain::march`] within 1 cm or 1e-5
/// relative. Returns the largest difference, metres.
fn check_rays(name: &str, grid: &mut impl Level0, plain: &Plain, spacing: f64) -> f64 {
    let mut rng = Rng(11);
    let (zlo, zhi) = grid.range();
    let mut worst = 0.0f64;
    let mut hits = 0;
    for k in 0..N {
        #[expect(clippy::cast_precision_loss, reason = "small grids")]
        let (u, v) = (
            rng.next() * (plain.w - 1) as f64,
            rng.next() * (plain.h - 1) as f64,
        );
        let ground = plain.height(u, v).expect("inside");
        let az = rng.next() * std::f64::consts::TAU;
        let (z, pitch) = match k % 10 {
            0 => (
                ground - 0.1 - 20.0 * rng.next(),
                (5.0 + 60.0 * rng.next()).to_radians(),
            ),
            1 => (
                zlo + (zhi - zlo) * 1.2 * rng.next(),
                (rng.next() * 180.0 - 90.0).to_radians(),
            ),
            _ => (
                zhi + 1.0 + (zhi - zlo) * rng.next(),
                -(3.0 + 77.0 * rng.next()).to_radians(),
            ),
        };
        // World direction (x east, y north) to grid units: columns east, rows south.
        let (c, s) = (pitch.cos(), pitch.sin());
        let d = [c * az.cos() / spacing, -c * az.sin() / spacing, s];
        let r = GridRay {
            o: [u, v, z],
            d,
            t: (0.0, 1.0e7),
        };
        grid.begin();
        let got = ray::raycast(grid, &r).expect("raycast").map(|h| h.t);
        // The reference walks a quarter of a cell at a time; where it disagrees, again 250 times finer
        // (a ray grazing a ridge can cross it twice within one step).
        let mut want = plain.march(&r, spacing / 4.0);
        if got.map(|g| g.to_bits()) != want.map(|w| w.to_bits()) {
            let close =
                matches!((got, want), (Some(g), Some(w)) if (g - w).abs() <= 0.01f64.max(1e-5 * w));
            if !close {
                let end = got.or(want).map_or(r.t.1, |t| t + spacing);
                want = plain.march(&GridRay { t: (0.0, end), ..r }, spacing / 1000.0);
            }
        }
        match (got, want) {
            (Some(g), Some(w)) => {
                let e = (g - w).abs();
                assert!(
                    e <= 0.01f64.max(1e-5 * w),
                    "{name}: ray {k} {r:?}: hit at {g}, reference {w}"
                );
                worst = worst.max(e);
                hits += 1;
            }
            (None, None) => {}
            _ => panic!("{name}: ray {k} {r:?}: {got:?} vs reference {want:?}"),
        }
    }
    assert!(hits > N / 2, "{name}: only {hits} hits");
    worst
}

fn plain_of(hm: &Heightmap) -> Plain {
    Plain {
        w: hm.width() as usize,
        h: hm.height() as usize,
        z: hm.heights().to_vec(),
    }
}

/// Bakes `hm` into a temp package and checks heights and rays through the query cache and, held whole,
/// through the resident grid.
fn check_terrain(name: &str, hm: &Heightmap) {
    let dir = temp_dir(name);
    let path = dir.join("t.clipsat");
    let opts = BakeOptions {
        lod_tables: false,
        ..BakeOptions::default()
    };
    package::bake(hm, &path, &opts, clipsat::Progress::default()).expect("bake");
    let pkg = Package::open(&path).expect("open");
    let bound = pkg.header().max_error;
    let decoded = plain_of(&pkg.to_heightmap().expect("decode"));
    let source = plain_of(hm);
    let spacing = f64::from(hm.spacing());
    let start = std::time::Instant::now();
    let mut tiles = QueryTiles::new(pkg, QUERY_BUDGET, "test").expect("query cache");
    let e = check_heights(name, &mut tiles, &decoded, &source, bound);
    eprintln!(
        "{name}: streamed heights within {e:.4} m of the source (bound {bound} m), {:.1} s",
        start.elapsed().as_secs_f64()
    );
    let d = check_rays(name, &mut tiles, &decoded, spacing);
    eprintln!(
        "{name}: streamed ray hits within {d:.2e} m of the reference; {:?}",
        tiles.stats()
    );
    let ranges = GridRanges::new(hm);
    let mut held = ResidentGrid {
        grid: hm,
        ranges: &ranges,
    };
    check_heights(name, &mut held, &source, &source, 0.0);
    let d = check_rays(name, &mut held, &source, spacing);
    eprintln!(
        "{name}: resident ray hits within {d:.2e} m of the reference ({:.1} s in all)",
        start.elapsed().as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn query_procedural_heights_and_rays_are_exact() {
    let p = ProceduralParams {
        seed: 3,
        size: 257,
        spacing: 30.0,
    };
    check_terrain(
        "procedural 257",
        &procedural::generate(&p).expect("procedural"),
    );
}

#[test]
fn query_puget_sound_heights_and_rays_are_exact() {
    if let Some(hm) = shared("ps_height_1k.png", Some(160.0)) {
        check_terrain("ps_height_1k", &hm);
    }
}

/// `cargo test --test cpu query:: -- --ignored` (about 30 s).
#[test]
#[ignore = "bakes seven more shared terrains"]
fn query_shared_heights_and_rays_are_exact() {
    for (name, spacing) in [
        ("srtm_bigtujunga30m_utm11.tif", None),
        ("n07_w006_3arc_v2.tif", None),
        ("lidar_pkg_dem_1m_400x400.tif", None),
        ("aletsch_200m.tif", None),
        ("srtm_bigtujunga30m_utm11_u16dm.png", Some(30.0)),
        ("n07_w006_3arc_v2_u16dm.png", Some(92.0)),
        ("N57E011.hgt", None),
    ] {
        if let Some(hm) = shared(name, spacing) {
            check_terrain(name, &hm);
        }
    }
}
