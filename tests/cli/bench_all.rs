//! `clipsat bench all --quick` end to end: the built binary writes report.md with every section and its PNG
//! plots (procedural terrain only, a few seconds on llvmpipe).

use std::path::Path;
use std::process::Command;

#[test]
fn quick_report_has_every_section_and_its_plots() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_bench_all");
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_clipsat"))
        .args(["bench", "all", "--quick", "--profile", "gles3-low", "--out"])
        .arg(&dir)
        .env("CLIPSAT_CACHE", super::cache_dir())
        .output()
        .expect("run the clipsat binary");
    assert!(
        out.status.success(),
        "clipsat bench all failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("skip"),
        "no skip line for the shared terrains: {stdout}"
    );
    let report = std::fs::read_to_string(dir.join("report.md")).expect("report.md is written");
    for section in [
        "## Headline",
        "## LOD: triangles, time and error against epsilon",
        "## Shading: error against patch count",
        "## Budget: samples updated and stale levels against speed",
        "## Memory: peak per profile",
        "## Memory: terrain package and resident set",
        "decode / memcpy",
        "Decode plus fill, one thread",
        "render --lod sat",
        "Measured on ",
        "render time / distance",
        "update time / 1x",
        "| gles3-low |",
        "| desktop |",
    ] {
        assert!(
            report.contains(section),
            "report.md lacks `{section}`:\n{report}"
        );
    }
    for png in ["lod.png", "budget.png"] {
        assert!(
            report.contains(&format!("]({png})")),
            "report.md does not show {png}"
        );
        let img = image::open(dir.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
        assert!(
            img.width() >= 320 && img.height() >= 240,
            "{png} is too small"
        );
    }
}

/// `clipsat bench imagery` on a small view: the four configurations drawn through `TerrainRenderer`,
/// their ms and the two ratios in the JSON; without `--imagery` a one-line refusal.
#[test]
fn bench_imagery_reports_both_ratios() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_bench_imagery");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let png = dir.join("imagery.png");
    let byte = |v: u32| u8::try_from(v % 256).expect("a byte");
    image::RgbImage::from_fn(64, 64, |x, y| {
        image::Rgb([byte(x * 4), byte(y * 4), byte(x + y)])
    })
    .save(&png)
    .expect("save PNG");
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_clipsat"))
            .args(["bench", "imagery", "--terrain", "procedural:size=129"])
            .args([
                "--profile",
                "gles3-mid",
                "--size",
                "160x90",
                "--frames",
                "1",
            ])
            .args(extra)
            .env("CLIPSAT_CACHE", super::cache_dir())
            .output()
            .expect("run the clipsat binary")
    };
    let p = png.display().to_string();
    let out = run(&["--imagery", &p, "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(v["p50_ms"].as_array().map(Vec::len), Some(4), "{v}");
    for ratio in ["basic_imagery_ratio", "sg_imagery_ratio"] {
        assert!(v[ratio].as_f64().is_some_and(|r| r > 0.0), "{ratio}: {v}");
    }
    let refused = run(&[]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--imagery"));
}
