//! Stage 1b, package sets: `scripts/bake_cluster.py` bakes a tile mosaic's package set on a Dask
//! `LocalCluster` (one `clipsat bake --parts DIR --cell N` a task, then `--finish`), and its folder holds
//! the same files, bit-equal, as `clipsat bake --parts DIR`'s; run again, it keeps every part. Ignored:
//! it needs Python with dask.distributed.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use super::{clipsat, geotiff_tile as tile, scratch_in};

/// Every file in `dir` by name, with its bytes.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .expect("read the set's folder")
        .map(|e| {
            let e = e.expect("entry");
            let name = e.file_name().to_string_lossy().into_owned();
            (name, std::fs::read(e.path()).expect("read a set's file"))
        })
        .collect()
}

#[test]
#[ignore = "needs Python with dask.distributed: pip install 'dask[distributed]', then cargo test --test cli bake_cluster -- --ignored"]
fn dask_bakes_the_same_set_as_the_cli() {
    let dir = scratch_in("bake_cluster", "four_tiles");
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).expect("folder");
    // 2 x 2 tiles of 513^2 samples, 1" apart, sharing their edge rows and columns (the same heights
    // there): integer heights from a smooth function of the mosaic's sample.
    let (n, step) = (513u32, 1.0 / 3600.0);
    let z = |x: u32, y: u32| {
        let (x, y) = (x as f32, y as f32);
        (300.0 + 120.0 * (x / 97.0).sin() * (y / 131.0).cos() + 0.05 * x - 0.03 * y).round()
    };
    for (ty, tx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
        let (x0, y0) = (tx * (n - 1), ty * (n - 1));
        let lon = 11.0 + f64::from(x0) * step;
        let lat = 58.0 - f64::from(y0) * step;
        let name = format!("t{ty}{tx}.tif");
        tile(&tiles.join(name), n, (lon, lat), step, |x, y| {
            z(x0 + x, y0 + y)
        });
    }
    let t = tiles.to_str().expect("utf-8 path");
    let (a, b) = (dir.join("cli"), dir.join("dask"));
    let out = clipsat(&[
        "bake",
        "--terrain",
        t,
        "--parts",
        a.to_str().expect("utf-8 path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/bake_cluster.py");
    let run = || {
        let out = Command::new("python3")
            .arg(&script)
            .args(["--clipsat", env!("CARGO_BIN_EXE_clipsat"), "--terrain", t])
            .arg("--parts")
            .arg(&b)
            .args(["--workers", "2"])
            .output()
            .expect("run python3");
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(out.status.success(), "bake_cluster.py: {text}");
        text
    };
    let first = run();
    assert!(first.contains("4 cells, 4 to bake, 0 kept"), "{first}");
    let (cli, dask) = (files(&a), files(&b));
    // Four parts, the top and the index.
    assert_eq!(cli.len(), 6, "{:?}", cli.keys());
    assert_eq!(
        cli.keys().collect::<Vec<_>>(),
        dask.keys().collect::<Vec<_>>()
    );
    for (name, bytes) in &cli {
        assert!(dask[name] == *bytes, "{name} differs");
    }
    // Run again: every part stands, so none is baked, and the set is unchanged.
    let again = run();
    assert!(again.contains("4 cells, 0 to bake, 4 kept"), "{again}");
    assert!(files(&b) == dask, "the set changed when run again");
}
