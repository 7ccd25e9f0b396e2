//! `--imagery` through the binary (issue 43): bad imagery is a one-line error naming the file or flag,
//! exit 2, nothing written (before the GPU is touched); `bake --imagery` writes the imagery package
//! beside the terrain's and `info` describes it; `fly --imagery` stays in the texel budget and repeats
//! its hashes run to run.

use std::path::{Path, PathBuf};
use std::process::Output;

use super::clipsat;

const TERRAIN: &str = "procedural:size=129";

fn scratch(name: &str) -> PathBuf {
    super::scratch_in("imagery", name)
}

/// A small RGB PNG of `w` x `h` texels.
fn png(dir: &Path, name: &str, w: u32, h: u32) -> PathBuf {
    let path = dir.join(name);
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        let byte = |v: u32| u8::try_from(v % 256).expect("a byte");
        image::Rgb([byte(x * 7), byte(y * 5), byte(x + y)])
    });
    img.save(&path).expect("save PNG");
    path
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Exit 2, a one-line `error:` naming `needle`, no panic.
fn assert_refused(out: &Output, needle: &str, what: &str) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(2), "{what}: {err}");
    assert!(!err.contains("panicked"), "{what}: {err}");
    assert!(
        err.starts_with("error: ") && err.lines().count() == 1,
        "{what}: not a one-line error: {err}"
    );
    assert!(err.contains(needle), "{what}: `{needle}` not named: {err}");
}

#[test]
fn bad_imagery_is_refused_and_nothing_is_written() {
    let dir = scratch("refused");
    let good = png(&dir, "good.png", 40, 30);
    let bytes = std::fs::read(&good).expect("read");
    let truncated = dir.join("truncated.png");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).expect("write");
    let garbage = dir.join("garbage.jpg");
    std::fs::write(&garbage, b"\xFF\xD8\xFF\xE0 not really a JPEG").expect("write");
    let one = png(&dir, "one.png", 1, 1);
    let row = png(&dir, "row.png", 9, 1);
    let missing = dir.join("missing.png");
    let s = |p: &Path| p.display().to_string();
    let cases: Vec<(Vec<String>, String)> = vec![
        (vec![s(&truncated)], s(&truncated)),
        (vec![s(&garbage)], s(&garbage)),
        (vec![s(&one)], "at least 2 x 2".into()),
        (vec![s(&row)], "at least 2 x 2".into()),
        (vec![s(&missing)], s(&missing)),
        (
            vec![
                s(&good),
                "--imagery-extent".into(),
                "1e6,1e6,2e6,2e6".into(),
            ],
            "--imagery-extent".into(),
        ),
        (
            vec![s(&good), "--max-imagery-texels".into(), "100".into()],
            "--max-imagery-texels".into(),
        ),
    ];
    for (imagery, needle) in cases {
        let out_png = dir.join("frame.png");
        let out_pkg = dir.join("t.clipsat");
        let mut args = vec!["render", "--terrain", TERRAIN, "--imagery"];
        args.extend(imagery.iter().map(String::as_str));
        let frame = s(&out_png);
        args.extend(["--out", frame.as_str()]);
        assert_refused(&clipsat(&args), &needle, &format!("render {imagery:?}"));
        assert!(
            !out_png.exists(),
            "render {imagery:?} wrote {}",
            out_png.display()
        );
        let pkg = s(&out_pkg);
        let mut args = vec!["bake", TERRAIN, "--out", pkg.as_str(), "--imagery"];
        args.extend(imagery.iter().map(String::as_str));
        assert_refused(&clipsat(&args), &needle, &format!("bake {imagery:?}"));
        assert!(
            !out_pkg.exists(),
            "bake {imagery:?} wrote {}",
            out_pkg.display()
        );
    }
}

#[test]
fn bake_writes_the_imagery_package_and_info_describes_it() {
    let dir = scratch("bake");
    let img = png(&dir, "image.png", 300, 200);
    let out = dir.join("t.clipsat");
    let r = clipsat(&[
        "bake",
        TERRAIN,
        "--out",
        &out.display().to_string(),
        "--imagery",
        &img.display().to_string(),
        "--json",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).expect("JSON");
    let companion = dir.join("t.clipsat-imagery");
    assert_eq!(v["imagery"]["out"], companion.display().to_string());
    assert_eq!(v["imagery"]["levels"], 2);
    assert!(
        v["imagery"]["psnr_db"].as_f64().expect("psnr") > 30.0,
        "{v}"
    );
    let r = clipsat(&["info", &companion.display().to_string(), "--json"]);
    assert!(r.status.success(), "{}", stderr(&r));
    let i: serde_json::Value = serde_json::from_slice(&r.stdout).expect("JSON");
    assert_eq!(
        (i["width"].as_u64(), i["height"].as_u64()),
        (Some(300), Some(200))
    );
    // Procedural 129^2 at 30 m: 3840 m each way, 12.8 m a texel east-west, 19.2 m north-south.
    assert_eq!(i["extent_m"], serde_json::json!([0.0, 0.0, 3840.0, 3840.0]));
    assert_eq!(
        i["levels"][1]["texel_spacing_m"],
        serde_json::json!([25.6, 38.4])
    );
    // Level 0 is stored as residuals of level 1, which is stored whole; the plain text says so too.
    assert_eq!(i["levels"][0]["stored"], "residual of the level above");
    assert_eq!(i["levels"][1]["stored"], "whole");
    let r = clipsat(&["info", &companion.display().to_string()]);
    assert!(r.status.success(), "{}", stderr(&r));
    let text = String::from_utf8_lossy(&r.stdout);
    assert!(text.contains("levels 0 stored as residuals"), "{text}");
}

#[test]
fn fly_with_imagery_stays_in_budget_and_repeats() {
    let dir = scratch("fly");
    let img = png(&dir, "image.png", 500, 500);
    let fly = || {
        let r = clipsat(&[
            "fly",
            "--terrain",
            TERRAIN,
            "--imagery",
            &img.display().to_string(),
            "--profile",
            "gles3-low",
            "--frames",
            "40",
            "--json",
        ]);
        assert!(r.status.success(), "{}", stderr(&r));
        serde_json::from_slice::<serde_json::Value>(&r.stdout).expect("JSON")
    };
    let (a, b) = (fly(), fly());
    assert_eq!(a["run_hash"], b["run_hash"]);
    let i = &a["imagery"];
    assert!(
        i["texels_per_frame_max"].as_u64().expect("texels") <= 16384,
        "{i}"
    );
    assert!(
        i["tiles_per_frame_max"].as_u64().expect("tiles") <= 1,
        "{i}"
    );
    assert_eq!(i["rings"], 2, "{i}");
}
