//! Stage 1b: the exact queries allocate nothing once their cache is built, misses and evictions
//! included (a query cache far smaller than the terrain, queried all over it).

use clipsat::package::query::{self, Level0, QueryTiles};
use clipsat::package::ray::{self, GridRay};
use clipsat::package::{self, BakeOptions, Package};
use clipsat::source::procedural::{self, ProceduralParams};

use crate::counting_alloc::count;

#[test]
fn queries_allocate_nothing_once_built() {
    let hm = procedural::generate(&ProceduralParams {
        seed: 9,
        size: 513,
        spacing: 30.0,
    })
    .expect("procedural");
    let dir = std::env::temp_dir().join(format!("clipsat-alloc-query-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("q.clipsat");
    let opts = BakeOptions {
        lod_tables: false,
        ..BakeOptions::default()
    };
    package::bake(&hm, &path, &opts, clipsat::Progress::default()).expect("bake");
    let pkg = Package::open(&path).expect("open");
    // The fewest slots that decode any tile (9 a level) and a few more: less than the terrain's
    // 81 + 25 + ... tiles, so queries all over it miss and evict.
    let header = pkg.header().clone();
    let slots = 9 * header.levels.len() as u64 + 4;
    let budget = clipsat::package::CacheSplit::budget_for_slots(&header, slots) + 8 * 81;
    let mut tiles = QueryTiles::new(pkg, budget, "alloc test").expect("query cache");
    let (_, zhi) = tiles.range();
    let run = |tiles: &mut QueryTiles, n: u32| {
        for k in 0..n {
            let (u, v) = (
                f64::from((k * 7919) % 512) + 0.25,
                f64::from((k * 104_729) % 512) + 0.5,
            );
            tiles.begin();
            let _ = query::height(tiles, u, v).expect("height");
            tiles.begin();
            let r = GridRay {
                o: [u, v, zhi + 100.0],
                d: [0.02, -0.01, -0.5],
                t: (0.0, f64::INFINITY),
            };
            let _ = ray::raycast(tiles, &r).expect("ray");
        }
    };
    run(&mut tiles, 200);
    let before = tiles.stats();
    let n = count(|| run(&mut tiles, 2000));
    let after = tiles.stats();
    assert_eq!(n, 0, "allocations while querying");
    assert!(
        after.decoded > before.decoded && after.evictions > before.evictions,
        "the counted queries must miss and evict: {before:?} -> {after:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
