//! `clipsat render --json` never fails for a measurement nobody asked for: on a terrain past the
//! brute-force reference's GLES 3.0 buffer limit (3400 x 3400 samples: its index buffer would need 277 MB
//! against 256 MiB) the summary is written, with `rmse_vs_ground_truth` null. `--ground-truth` asks for
//! the comparison: a number on a small terrain, a clear error naming the limit on the big one.

use std::path::PathBuf;
use std::process::Output;

use super::clipsat;

fn scratch(name: &str) -> PathBuf {
    super::scratch_in("cli_render_json", name)
}

fn json(out: &Output, what: &str) -> serde_json::Value {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{what}: {err}");
    assert!(!err.contains("panicked"), "{what}: {err}");
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{what}: not JSON: {e}"))
}

/// Side of the big terrain: (side - 1)^2 cells x 6 indices x 4 bytes = 277 MB > 256 MiB.
const SIDE: u32 = 3400;

#[test]
fn render_json_past_the_brute_force_limit() {
    let dir = scratch("big");
    // A ramp with ripples as raw u16 (23 MB); a one-level profile keeps the LOD bake behind the measured
    // screen error to the data level, so the test stays a few seconds. `--resident`: the measured screen
    // error reads the whole pyramid (and a streamed run would first bake a package of the 11 M samples).
    let raw: Vec<u8> = (0..SIDE * SIDE)
        .flat_map(|i| {
            let (x, y) = (i % SIDE, i / SIDE);
            let v = u16::try_from((x / 2 + y / 3 + (x * 7 + y * 13) % 50) % 60_000).unwrap_or(0);
            v.to_le_bytes()
        })
        .collect();
    let terrain = dir.join("big.r16");
    std::fs::write(&terrain, raw).expect("write terrain");
    let low = clipsat::profile::SHIPPED
        .iter()
        .find(|(n, _)| *n == "gles3-low")
        .map(|(_, t)| *t)
        .expect("gles3-low");
    let profile: String = low
        .lines()
        .map(|l| {
            if l.starts_with("levels") {
                "levels = 1".to_owned()
            } else {
                l.to_owned()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let profile_path = dir.join("one-level.toml");
    std::fs::write(&profile_path, profile).expect("write profile");
    let (t, p) = (terrain.to_string_lossy(), profile_path.to_string_lossy());
    let out = dir.join("x.png");
    let o = out.to_string_lossy();
    let size = format!("{SIDE}x{SIDE}");
    let base = [
        "render",
        "--terrain",
        &t,
        "--raw-size",
        &size,
        "--profile",
        &p,
        "--size",
        "64x36",
        "--out",
        &o,
        "--json",
        "--resident",
    ];
    let j = json(&clipsat(&base), "render --json on the big terrain");
    assert!(j["image_hash"].is_string(), "{j}");
    assert_eq!(j["streamed"], false, "{j}");
    assert!(j["max_screen_error_px"].is_number(), "{j}");
    assert!(j["rmse_vs_ground_truth"].is_null(), "{j}");

    // Asked for, the ground truth on this terrain is a clear one-line error naming the limit.
    let mut asked = base.to_vec();
    asked.push("--ground-truth");
    let r = clipsat(&asked);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        !err.contains("panicked") && err.contains("brute-force") && err.contains("index buffer"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_ground_truth_on_request() {
    let dir = scratch("small");
    let out = dir.join("x.png");
    let o = out.to_string_lossy();
    let base = [
        "render",
        "--terrain",
        "procedural:size=129",
        "--profile",
        "gles3-low",
        "--size",
        "64x36",
        "--out",
        &o,
        "--json",
    ];
    let j = json(&clipsat(&base), "render --json");
    assert!(j["rmse_vs_ground_truth"].is_null(), "{j}");
    // Streamed by default, with no measured screen error (it needs the whole pyramid: --resident).
    assert_eq!(j["streamed"], true, "{j}");
    assert!(j["max_screen_error_px"].is_null(), "{j}");
    let mut asked = base.to_vec();
    asked.push("--ground-truth");
    let j = json(&clipsat(&asked), "render --json --ground-truth");
    // The ground truth reads every sample: it selects the resident path itself.
    assert_eq!(j["streamed"], false, "{j}");
    let rmse = j["rmse_vs_ground_truth"].as_f64().unwrap_or(f64::NAN);
    // RMSE in 8-bit levels: the clipmap against the full-resolution grid (16.8 measured here).
    assert!((0.0..64.0).contains(&rmse), "{j}");
    // Not with --brute, which draws the ground truth itself.
    let mut brute = asked.clone();
    brute.push("--brute");
    let r = clipsat(&brute);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("--ground-truth"));
}

/// A package rendered with basic shading streams through the profile's tile cache: `streamed` in the
/// summary, every level filled, no measured error (it needs the whole pyramid); with `--lod sat` too, its
/// LOD tables read through a map of their cache file (none held in owned memory); with
/// `--lod sat-conservative` its detail pool fills from the package too.
#[test]
fn render_streams_a_package() {
    let dir = scratch("stream");
    let pkg = dir.join("t.clipsat");
    let png = dir.join("t.png");
    let (p, o) = (pkg.to_string_lossy(), png.to_string_lossy());
    json(
        &clipsat(&["bake", "procedural:size=257", "--out", &p, "--json"]),
        "bake",
    );
    let base = [
        "render",
        "--terrain",
        &p,
        "--profile",
        "gles3-low",
        "--size",
        "64x36",
        "--out",
        &o,
        "--json",
    ];
    let j = json(&clipsat(&base), "render a package");
    assert_eq!(j["streamed"], true, "{j}");
    assert!(j["plan_ms"].as_f64().is_some_and(|ms| ms >= 0.0), "{j}");
    assert_eq!(j["stale_levels"], 0, "{j}");
    assert!(j["triangles"].as_u64().unwrap_or(0) > 0, "{j}");
    assert!(j["max_screen_error_px"].is_null(), "{j}");
    let mut sat = base.to_vec();
    sat.extend(["--lod", "sat"]);
    let j = json(&clipsat(&sat), "render a package --lod sat");
    assert_eq!(j["streamed"], true, "{j}");
    assert_eq!(j["stale_levels"], 0, "{j}");
    assert_eq!(j["lod_tables_mapped"], true, "{j}");
    assert_eq!(j["lod_tables_owned_bytes"], 0, "{j}");
    assert!(j["max_screen_error_px"].is_null(), "{j}");
    assert!(j["triangles"].as_u64().unwrap_or(0) > 0, "{j}");
    // The detail pool fills from the package's tile cache too: 49 tiles here at 1 px.
    let mut pool = base.to_vec();
    pool.extend(["--lod", "sat-conservative", "--epsilon", "1"]);
    let j = json(&clipsat(&pool), "render a package --lod sat-conservative");
    assert_eq!(j["streamed"], true, "{j}");
    assert!(j["detail_tiles_resident"].as_u64().unwrap_or(0) > 0, "{j}");
    assert!(j["blocks_from_pool"].as_u64().unwrap_or(0) > 0, "{j}");
}

/// A lone spike on a flat shows the sky past the data's far border between the spike's pixels and the
/// flat's in a pixel column: column-rule candidates that are border views, not holes. The streamed render
/// (the default) traces them through the tiles its fill left in the cache and agrees with `--resident`
/// (before, a streamed render counted every candidate as a crack pixel).
#[test]
fn streamed_render_traces_its_crack_candidates() {
    let dir = scratch("spike");
    let png = dir.join("spike.png");
    let mut img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(512, 512);
    img.put_pixel(256, 256, image::Luma([40_000]));
    img.save(&png).expect("write the spike PNG");
    let out = dir.join("frame.png");
    let (t, o) = (png.to_string_lossy(), out.to_string_lossy());
    let base = [
        "render",
        "--terrain",
        &t,
        "--spacing",
        "30",
        "--height-scale",
        "0.2",
        "--profile",
        "gles3-low",
        "--size",
        "160x90",
        "--lod",
        "sat-conservative",
        "--out",
        &o,
        "--json",
    ];
    let streamed = json(&clipsat(&base), "streamed spike");
    let mut resident = base.to_vec();
    resident.push("--resident");
    let resident = json(&clipsat(&resident), "resident spike");
    assert_eq!(streamed["streamed"], true, "{streamed}");
    for j in [&streamed, &resident] {
        assert_eq!(j["crack_pixels"], 0, "{j}");
        assert!(j["border_view_pixels"].as_u64().unwrap_or(0) > 0, "{j}");
        assert_eq!(j["crack_pixels_traced"], j["border_view_pixels"], "{j}");
    }
    assert_eq!(
        streamed["border_view_pixels"],
        resident["border_view_pixels"]
    );
}

/// The cache key covers the sidecars a loader takes its spacing from: adding a geographic `.prj` beside an
/// ESRI ASCII grid (its 30-unit cells become degrees) bakes a new package, which draws what the resident
/// load with the `.prj` draws, not the stale one.
#[test]
fn a_sidecar_edit_bakes_the_terrain_again() {
    let dir = scratch("sidecar");
    let asc = dir.join("grid.asc");
    let prj = dir.join("grid.prj");
    let _ = std::fs::remove_file(&prj);
    let mut text = String::from("ncols 40\nnrows 30\nxllcorner 0\nyllcorner 0\ncellsize 0.001\n");
    for j in 0..30 {
        let row: Vec<String> = (0..40)
            .map(|i| format!("{}", (i * 7 + j * 13) % 50))
            .collect();
        text += &row.join(" ");
        text.push('\n');
    }
    std::fs::write(&asc, text).expect("write the grid");
    std::fs::write(&prj, "PROJCS[\"local metres\"]").expect("write the .prj");
    let out = dir.join("frame.png");
    let (a, o) = (asc.to_string_lossy(), out.to_string_lossy());
    let args = [
        "render",
        "--terrain",
        &a,
        "--size",
        "64x36",
        "--out",
        &o,
        "--json",
    ];
    let projected = json(&clipsat(&args), "projected");
    std::fs::write(&prj, "GEOGCS[\"WGS 84\"]").expect("write the .prj");
    let geographic = json(&clipsat(&args), "geographic");
    let mut resident = args.to_vec();
    resident.push("--resident");
    let fresh = json(&clipsat(&resident), "geographic, resident");
    assert_eq!(geographic["streamed"], true, "{geographic}");
    assert_ne!(projected["image_hash"], geographic["image_hash"]);
    assert_eq!(geographic["image_hash"], fresh["image_hash"]);
}
