//! The CLI test binary: runs the built `clipsat` binary end to end (`CARGO_BIN_EXE_clipsat`): its outputs,
//! refusals, determinism across runs, and the window under Xvfb (ignored; `bash .ci/view-xvfb`). Run one
//! module with `cargo test --test cli fly::`.

mod bad_input;
mod bake_cluster;
mod bake_killed;
mod bench_all;
mod cross_driver;
mod determinism;
mod fly;
mod hard_terrains;
mod hash;
mod imagery;
mod mosaic_info;
mod real_tiles;
mod render_json;
mod set_input;
mod stream_rss;
mod view_xvfb;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

/// Runs the built `clipsat` binary with `args`.
fn clipsat(args: &[&str]) -> Output {
    clipsat_env(args, &[])
}

/// The bake cache every run of this test binary shares (`CLIPSAT_CACHE`): `render`, `fly` and `view`
/// stream a plain source from a package baked there on first use. Emptied once per test run, so that a
/// run starts from a clean cache (no package left by an older build) and leaves nothing in the source
/// tree's target/clipsat-cache.
fn cache_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("clipsat-cache");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create the bake cache folder");
        dir
    })
}

/// Runs the built `clipsat` binary with `args` and the extra environment `env` (which may set its own
/// `CLIPSAT_CACHE`). The first run naming each `--terrain` runs alone among those naming it, so that the
/// tests running in parallel bake each default-cached package once (a concurrent first use is safe, every
/// bake renames its own temporary file into place, but would spend the machine's cores on the same bake).
fn clipsat_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    static FIRST: OnceLock<Mutex<HashMap<String, Arc<Mutex<bool>>>>> = OnceLock::new();
    let terrain = args
        .iter()
        .position(|a| *a == "--terrain")
        .and_then(|i| args.get(i + 1))
        .copied()
        .unwrap_or("procedural")
        .to_owned();
    let gate = FIRST
        .get_or_init(Mutex::default)
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .entry(terrain)
        .or_default()
        .clone();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_clipsat"));
    cmd.args(args).env("CLIPSAT_CACHE", cache_dir());
    for (k, v) in env {
        cmd.env(k, v);
    }
    let mut warm = gate.lock().unwrap_or_else(PoisonError::into_inner);
    if *warm {
        drop(warm);
        return cmd.output().expect("run the clipsat binary");
    }
    let out = cmd.output().expect("run the clipsat binary");
    *warm = out.status.success();
    out
}

/// A geographic (EPSG 4326) f32 GeoTIFF tile of `n` x `n` samples, pixel-is-point, its north-west sample
/// at (`lon`, `lat`), `step` degrees apart, heights from `z`.
fn geotiff_tile(
    path: &Path,
    n: u32,
    (lon, lat): (f64, f64),
    step: f64,
    z: impl Fn(u32, u32) -> f32,
) {
    use tiff::encoder::colortype::Gray32Float;
    use tiff::tags::Tag;
    let data: Vec<f32> = (0..n * n).map(|i| z(i % n, i / n)).collect();
    let mut file = std::fs::File::create(path).expect("create");
    let mut enc = tiff::encoder::TiffEncoder::new(&mut file).expect("encoder");
    let mut img = enc.new_image::<Gray32Float>(n, n).expect("image");
    img.encoder()
        .write_tag(Tag::ModelPixelScaleTag, &[step, step, 0.0][..])
        .expect("scale");
    img.encoder()
        .write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, lon, lat, 0.0][..])
        .expect("tiepoint");
    // Geographic model, pixel-is-point, WGS 84.
    let keys: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326];
    img.encoder()
        .write_tag(Tag::GeoKeyDirectoryTag, &keys[..])
        .expect("geokeys");
    img.write_data(&data).expect("data");
}

/// A fresh, empty folder `group/name` under the target's test scratch space, for one test's outputs.
fn scratch_in(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch folder");
    dir
}
