//! Golden images of the clipmap renderer: 3 views x 3 terrains (procedural, Puget Sound, synthetic terraces)
//! at 160 x 90 on gles3-low.
//!
//! `tests/goldens/hashes.txt` holds exact image hashes per driver, lines `adapter|driver<TAB>view<TAB>hash`;
//! a driver with a stored hash must match it exactly. Every view also has a small PNG, compared with a
//! tolerance (per-channel mean and max absolute difference) on every driver. `CLIPSAT_BLESS=1` rewrites the
//! PNGs and this driver's hashes. A failure writes `<view>-actual.png` and `<view>-diff.png` beside the
//! golden (gitignored).
//!
//! Puget Sound comes from the shared data: without it the `puget-*` views are skipped (a failure under
//! `CI=true`).

mod render_support;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen};
use clipsat::gpu::readback::Image;
use clipsat::source::procedural::{self, ProceduralParams};
use clipsat::{hash, Camera, Heightmap};
use glam::DVec3;
use render_support::*;

const W: u32 = 160;
const H: u32 = 90;
/// Tolerance against the PNG on drivers without a stored hash: mean and max absolute difference per
/// channel, in 8-bit levels (rasterisation rules and float rounding move silhouettes by a pixel or so).
const MEAN_TOL: f64 = 3.0;
const MAX_TOL: u8 = 160;

fn goldens_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/goldens")
}

/// The three views of a terrain: a high overview, a low oblique flight, a steep look down.
fn views(hm: &Heightmap) -> [(&'static str, Camera); 3] {
    let s = f64::from(hm.spacing());
    let (ex, ey) = (
        f64::from(hm.width() - 1) * s,
        f64::from(hm.height() - 1) * s,
    );
    let (lo, hi) = hm.range();
    let (lo, hi) = (f64::from(lo), f64::from(hi));
    let mid = DVec3::new(0.5 * ex, 0.5 * ey, lo);
    let over = DVec3::new(0.1 * ex, 0.05 * ey, hi + 0.3 * ex.max(ey));
    let low_eye = DVec3::new(0.2 * ex, 0.3 * ey, ground(hm, 0.2 * ex, 0.3 * ey) + 120.0);
    let down_eye = DVec3::new(0.55 * ex, 0.45 * ey, hi + 0.15 * ex.max(ey));
    [
        ("overview", camera(over, mid - over)),
        ("low", camera(low_eye, DVec3::new(1.0, 0.6, -0.12))),
        ("down", camera(down_eye, DVec3::new(0.2, 0.3, -1.0))),
    ]
}

fn render(gpu: &clipsat::gpu::Gpu, hm: &Heightmap, cam: &Camera) -> Image {
    let p = profile("gles3-low", W, H, None);
    let mut cm = clipmap(hm, &p);
    for _ in 0..500 {
        let f = cm.update(cam.eye).expect("update");
        if f.stale_levels == 0 && cm.pending_samples(cam.eye) == 0 {
            break;
        }
    }
    let mut r = Offscreen::new(gpu, &p, &cm, Default::default()).expect("renderer");
    render_frame(&mut r, &cm, cam, &FrameOptions::default())
        .expect("frame")
        .image
}

fn read_hashes(path: &Path) -> BTreeMap<(String, String), String> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .filter_map(|l| {
            let mut f = l.split('\t');
            Some((
                (f.next()?.to_string(), f.next()?.to_string()),
                f.next()?.to_string(),
            ))
        })
        .collect()
}

fn write_hashes(path: &Path, hashes: &BTreeMap<(String, String), String>) {
    let mut text = String::from(
        "# Exact clipmap image hashes per driver: adapter|driver<TAB>view<TAB>hash (tests/render_goldens.rs).\n",
    );
    for ((k, v), h) in hashes {
        text.push_str(&format!("{k}\t{v}\t{h}\n"));
    }
    std::fs::write(path, text).expect("write hashes");
}

fn load_png(path: &Path) -> Option<Image> {
    let img = image::open(path).ok()?.to_rgba8();
    Some(Image {
        width: img.width(),
        height: img.height(),
        rgba: img.into_raw(),
    })
}

/// (mean, max) absolute difference per channel, and the difference image (x4, opaque).
fn compare(a: &Image, b: &Image) -> (f64, u8, Image) {
    let mut rgba = Vec::with_capacity(a.rgba.len());
    let (mut sum, mut max) = (0u64, 0u8);
    for (p, q) in a.rgba.chunks_exact(4).zip(b.rgba.chunks_exact(4)) {
        for c in 0..4 {
            let d = p[c].abs_diff(q[c]);
            sum += u64::from(d);
            max = max.max(d);
            rgba.push(if c == 3 { 255 } else { d.saturating_mul(4) });
        }
    }
    let diff = Image {
        width: a.width,
        height: a.height,
        rgba,
    };
    (sum as f64 / a.rgba.len() as f64, max, diff)
}

#[test]
fn golden_views() {
    let gpu = strict();
    let report = gpu.report();
    let key = format!("{}|{}", report.name, report.driver);
    let bless = std::env::var_os("CLIPSAT_BLESS").is_some_and(|v| v == "1");
    let dir = goldens_dir();
    let hashes_path = dir.join("hashes.txt");
    let mut hashes = read_hashes(&hashes_path);
    let proc = procedural::generate(&ProceduralParams {
        size: 257,
        ..Default::default()
    })
    .expect("procedural terrain");
    let mut failures = Vec::new();
    let mut terrains = vec![("procedural", proc), ("terraces", terraces())];
    terrains.extend(puget().map(|hm| ("puget", hm)));
    for (tname, hm) in terrains {
        for (vname, cam) in views(&hm) {
            let name = format!("{tname}-{vname}");
            let img = render(&gpu, &hm, &cam);
            let h = hash::hex(img.hash());
            let png = dir.join(format!("{name}.png"));
            if bless {
                std::fs::create_dir_all(&dir).expect("goldens dir");
                img.save_png(&png).expect("write golden");
                hashes.insert((key.clone(), name.clone()), h);
                continue;
            }
            let Some(golden) = load_png(&png) else {
                failures.push(format!(
                    "{name}: no golden {}; run CLIPSAT_BLESS=1",
                    png.display()
                ));
                continue;
            };
            let exact = hashes.get(&(key.clone(), name.clone()));
            let (mean, max, diff) = compare(&img, &golden);
            let bad_hash = exact.is_some_and(|e| *e != h);
            let bad_png = golden.width != img.width
                || golden.height != img.height
                || mean > MEAN_TOL
                || max > MAX_TOL;
            if bad_hash || bad_png {
                let _ = img.save_png(&dir.join(format!("{name}-actual.png")));
                let _ = diff.save_png(&dir.join(format!("{name}-diff.png")));
                failures.push(format!(
                    "{name}: hash {h} (stored {exact:?} for {key}), mean diff {mean:.3}, max {max}"
                ));
            }
        }
    }
    if bless {
        write_hashes(&hashes_path, &hashes);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
