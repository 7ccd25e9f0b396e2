//! Stage 1b, the package: a measurement aid for the exact queries' cost (`TerrainRenderer::height_at`
//! and `raycast`, through `package::query` and `package::ray`, which they call).
//! `cargo run --release --example query_time [-- TERRAIN [SPACING_M]]`: the terrain (default: the
//! procedural terrain, 1025^2 at 30 m) baked into a package in a temp folder, then 10^4 heights and 10^4
//! rays in a 256 x 256-sample window around its centre, timed one by one after a pass that made the
//! window's tiles resident: through the query cache of gles3-mid's query share (streamed), and over the
//! grid held whole (resident); then heights in tiles not resident (each decodes its tile). The rays start 200 m above the highest sample over the window's centre and
//! aim at random ground points of the window, as picking under a cursor does. Prints p50, p99 and the
//! largest, microseconds. Without a release build of the dependencies at hand,
//! `CARGO_PROFILE_TEST_OPT_LEVEL=3 cargo run --profile test --example query_time` builds only clipsat
//! again (at opt-level 3, beside the tests' dependencies at 2).

use std::time::Instant;

use clipsat::package::query::{self, GridRanges, Level0, QueryTiles, ResidentGrid};
use clipsat::package::ray::{self, GridRay};
use clipsat::package::{self, BakeOptions, Package};
use clipsat::source::procedural::{self, ProceduralParams};
use clipsat::source::{self, LoadOptions};

const N: usize = 10_000;
const WINDOW: f64 = 256.0;

/// SplitMix64 uniforms in [0, 1).
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

/// p50, p99 and the largest of `t` (microseconds), sorted in place.
fn percentiles(t: &mut [f64]) -> (f64, f64, f64) {
    t.sort_by(f64::total_cmp);
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        clippy::cast_precision_loss,
        reason = "an index into a sorted list of 10^4"
    )]
    let at = |p: f64| t[((t.len() - 1) as f64 * p).round() as usize];
    (at(0.5), at(0.99), t[t.len() - 1])
}

/// Times heights and rays over `grid` in the window centred on grid point `c`; prints one line each.
fn measure(label: &str, grid: &mut impl Level0, c: (f64, f64), spacing: f64) {
    let mut rng = Rng(5);
    let pts: Vec<(f64, f64)> = (0..N)
        .map(|_| {
            (
                c.0 + (rng.next() - 0.5) * WINDOW,
                c.1 + (rng.next() - 0.5) * WINDOW,
            )
        })
        .collect();
    let (_, zhi) = grid.range();
    let ground: Vec<f64> = pts
        .iter()
        .map(|&(u, v)| query::height(grid, u, v).expect("height").expect("inside"))
        .collect();
    let mut times = Vec::with_capacity(N);
    let mut sink = 0.0;
    for &(u, v) in &pts {
        let t = Instant::now();
        grid.begin();
        sink += query::height(grid, u, v).expect("height").unwrap_or(0.0);
        times.push(t.elapsed().as_secs_f64() * 1e6);
    }
    let (p50, p99, max) = percentiles(&mut times);
    println!("{label:<10} height_at  p50 {p50:6.2} us  p99 {p99:6.2} us  max {max:8.2} us");
    let o = [c.0, c.1, zhi + 200.0];
    let rays: Vec<GridRay> = pts
        .iter()
        .zip(&ground)
        .map(|(&(u, v), &z)| {
            // World metres per unit: columns and rows are `spacing` apart.
            let d = [(u - o[0]) * spacing, (v - o[1]) * spacing, z - o[2]];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            GridRay {
                o,
                d: [d[0] / len / spacing, d[1] / len / spacing, d[2] / len],
                t: (0.0, f64::INFINITY),
            }
        })
        .collect();
    let mut hits = 0;
    for r in &rays {
        hits += usize::from(ray::raycast(grid, r).expect("ray").is_some());
    }
    times.clear();
    for r in &rays {
        let t = Instant::now();
        grid.begin();
        let h = ray::raycast(grid, r).expect("ray");
        times.push(t.elapsed().as_secs_f64() * 1e6);
        sink += h.map_or(0.0, |h| h.t);
    }
    let (p50, p99, max) = percentiles(&mut times);
    println!(
        "{label:<10} raycast    p50 {p50:6.2} us  p99 {p99:6.2} us  max {max:8.2} us  ({hits} hits of {N}) {}",
        if sink.is_nan() { "!" } else { "" }
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let hm = match args.first() {
        Some(path) => {
            let opts = LoadOptions {
                spacing: args.get(1).map(|s| s.parse().expect("a spacing in metres")),
                ..LoadOptions::default()
            };
            source::load(std::path::Path::new(path), &opts).expect("a terrain")
        }
        None => procedural::generate(&ProceduralParams {
            seed: 1,
            size: 1025,
            spacing: 30.0,
        })
        .expect("procedural"),
    };
    let dir = std::env::temp_dir().join(format!("clipsat-query-time-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("t.clipsat");
    let opts = BakeOptions {
        lod_tables: false,
        ..BakeOptions::default()
    };
    package::bake(&hm, &path, &opts, clipsat::Progress::default()).expect("bake");
    let profile = clipsat::profile::Profile::load("gles3-mid").expect("profile");
    let share = profile.cpu_split().queries;
    let mut tiles = QueryTiles::new(Package::open(&path).expect("package"), share, "gles3-mid")
        .expect("query cache");
    let c = (
        f64::from(hm.width() - 1) * 0.5,
        f64::from(hm.height() - 1) * 0.5,
    );
    let spacing = f64::from(hm.spacing());
    println!(
        "{} x {} samples, {spacing} m; query cache {} KiB of gles3-mid's {} KiB share",
        hm.width(),
        hm.height(),
        tiles.bytes() >> 10,
        share >> 10
    );
    measure("streamed", &mut tiles, c, spacing);
    println!("           {:?}", tiles.stats());
    // Misses: a fresh cache, one height in each of up to 64 level-0 tiles, each decoding its tile (and,
    // the first in a region, the coarser tiles its prediction reads).
    let mut cold = QueryTiles::new(Package::open(&path).expect("package"), share, "gles3-mid")
        .expect("query cache");
    let mut times = Vec::new();
    'tiles: for ty in 0..hm.height().div_ceil(64) {
        for tx in 0..hm.width().div_ceil(64) {
            if times.len() == 64 {
                break 'tiles;
            }
            let (u, v) = (
                f64::from((tx * 64 + 32).min(hm.width() - 1)),
                f64::from((ty * 64 + 32).min(hm.height() - 1)),
            );
            let t = Instant::now();
            cold.begin();
            let _ = query::height(&mut cold, u, v).expect("height");
            times.push(t.elapsed().as_secs_f64() * 1e6);
        }
    }
    let (p50, p99, max) = percentiles(&mut times);
    println!(
        "streamed   height_at, each in a tile not resident: p50 {p50:6.1} us  p99 {p99:6.1} us  max {max:8.1} us ({} tiles)",
        times.len()
    );
    let ranges = GridRanges::new(&hm);
    let mut held = ResidentGrid {
        grid: &hm,
        ranges: &ranges,
    };
    measure("resident", &mut held, c, spacing);
    let _ = std::fs::remove_dir_all(&dir);
}
