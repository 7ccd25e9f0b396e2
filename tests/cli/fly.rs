//! `clipsat fly` end to end: the built binary, its JSON, CSV and plot outputs, determinism, and clean refusals.

use std::path::PathBuf;
use std::process::Output;

use super::clipsat;

/// A fresh folder for one test's outputs.
fn scratch(name: &str) -> PathBuf {
    super::scratch_in("cli_fly", name)
}

fn json_of(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "clipsat fly failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is JSON")
}

const SHORT: [&str; 8] = [
    "fly",
    "--profile",
    "gles3-low",
    "--path",
    "teleport:10",
    "--frames",
    "40",
    "--json",
];

#[test]
fn short_fly_writes_json_csv_and_plot() {
    let dir = scratch("outputs");
    // Nested folders that do not exist yet: fly creates them.
    let csv = dir.join("deep/er/fly.csv");
    let png = dir.join("plots/fly.png");
    let mut args = SHORT.to_vec();
    let (csv_s, png_s) = (csv.to_string_lossy(), png.to_string_lossy());
    args.extend(["--csv", &csv_s, "--plot", &png_s]);
    let j = json_of(&clipsat(&args));

    assert_eq!(j["frames"], 40);
    assert_eq!(j["profile"], "gles3-low");
    assert_eq!(j["path"], "teleport:10");
    assert_eq!(j["speed"], 50.0);
    assert!(j["terrain"].as_str().is_some_and(|t| !t.is_empty()));
    let hash = j["final_hash"].as_str().expect("final_hash is a string");
    assert!(
        hash.len() == 16 && hash.chars().all(|c| c.is_ascii_hexdigit()),
        "final_hash {hash} is not 16 hex digits"
    );
    assert_eq!(j["frames_over_budget"], 0);
    assert_eq!(j["constraint_violations"], 0);
    let budget = j["budget"].as_u64().expect("budget");
    let p50 = j["samples_updated_p50"].as_u64().expect("p50");
    let p99 = j["samples_updated_p99"].as_u64().expect("p99");
    let max = j["samples_updated_max"].as_u64().expect("max");
    assert!(
        p50 <= p99 && p99 <= max && max <= budget,
        "{p50} {p99} {max} {budget}"
    );
    assert!(max > 0, "the first frame fills rings");
    assert!(j["max_stale_levels"].as_u64().is_some());
    let t50 = j["triangles_p50"].as_u64().expect("triangles_p50");
    assert!(t50 <= j["triangles_max"].as_u64().expect("triangles_max"));

    let text = std::fs::read_to_string(&csv).expect("CSV written");
    let mut lines = text.lines();
    let header = lines.next().expect("CSV header");
    assert!(
        header.starts_with("frame,samples_updated,budget_used,"),
        "{header}"
    );
    assert!(header.contains(",hash,active_l0"), "{header}");
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 40);
    let cols = header.split(',').count();
    for (i, row) in rows.iter().enumerate() {
        let fields: Vec<&str> = row.split(',').collect();
        assert_eq!(fields.len(), cols, "row {i}: {row}");
        assert_eq!(fields[0], i.to_string());
    }
    assert!(
        rows[39].contains(hash),
        "last CSV row carries the final hash"
    );

    let plot = image::open(&png).expect("the plot is a readable PNG");
    assert!(
        plot.width() >= 320 && plot.height() >= 200,
        "plot is {}x{}",
        plot.width(),
        plot.height()
    );
}

#[test]
fn same_fly_gives_the_same_hashes() {
    // Everything but the plan's wall and CPU times, which are measured in the run.
    let timeless = |mut j: serde_json::Value| {
        if let Some(o) = j.as_object_mut() {
            o.retain(|k, _| !k.starts_with("plan_ms") && !k.starts_with("plan_cpu_ms"));
        }
        j
    };
    let a = timeless(json_of(&clipsat(&SHORT)));
    let b = timeless(json_of(&clipsat(&SHORT)));
    assert_eq!(a["final_hash"], b["final_hash"]);
    assert_eq!(a["run_hash"], b["run_hash"]);
    assert_eq!(a["plan_run_hash"], b["plan_run_hash"]);
    assert_eq!(a, b);
}

#[test]
fn default_fly_prints_a_summary() {
    let out = clipsat(&["fly", "--frames", "60"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    for want in ["figure8", "samples", "triangles", "final hash"] {
        assert!(text.contains(want), "summary lacks `{want}`:\n{text}");
    }
}

#[test]
fn bad_inputs_fail_with_a_clear_error() {
    let dir = scratch("bad");
    let blocker = dir.join("a-file");
    std::fs::write(&blocker, b"not a folder").expect("write blocker");
    let csv_under_file = blocker.join("fly.csv");
    let csv_s = csv_under_file.to_string_lossy();
    let render_s = dir.join("frames").to_string_lossy().into_owned();
    let cases: [(&[&str], &str); 8] = [
        (&["--speed", "-1"], "--speed"),
        (&["--speed", "0"], "--speed"),
        (&["--path", "nope"], "--path"),
        (&["--path", "teleport:0"], "--path"),
        (&["--frames", "0"], "--frames"),
        (&["--profile", "missing.toml"], "missing.toml"),
        (&["--frames", "2", "--csv", &csv_s], "a-file"),
        // Synthesis only when the scene declares it.
        (
            &[
                "--shading",
                "sg",
                "--scene",
                "noon",
                "--synth-levels",
                "1",
                "--render",
                &render_s,
            ],
            "effects.synthesis",
        ),
    ];
    for (extra, names) in cases {
        let mut args = vec!["fly"];
        args.extend_from_slice(extra);
        if !extra.contains(&"--frames") {
            args.extend(["--frames", "5"]);
        }
        let out = clipsat(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{extra:?} should fail");
        assert!(!err.contains("panicked"), "{extra:?} panicked: {err}");
        // One error line; an I/O error adds the operating system's cause below it.
        assert!(
            err.trim()
                .lines()
                .skip(1)
                .all(|l| l.starts_with("  caused by: ")),
            "{extra:?}: not one error line: {err}"
        );
        assert!(
            err.starts_with("error: ") && err.contains(names),
            "{extra:?}: the error should name {names}: {err}"
        );
    }
}

/// `fly --render DIR` renders every K-th frame with the clipmap renderer, writes the PNGs and their image
/// hashes, and the hashes repeat exactly on a second run (same driver).
#[test]
fn fly_render_writes_frames_and_image_hashes() {
    let run = |name: &str| {
        let dir = scratch(name);
        let d = dir.to_str().expect("utf-8 temp path");
        let args = [
            "fly",
            "--profile",
            "gles3-low",
            "--frames",
            "12",
            "--path",
            "teleport:6",
            "--speed",
            "300",
            "--render",
            d,
            "--render-every",
            "5",
            "--size",
            "96x54",
            "--json",
        ];
        let v = json_of(&clipsat(&args));
        let renders = v["renders"].as_array().expect("renders").clone();
        assert_eq!(renders.len(), 3, "frames 0, 5, 10");
        for (r, f) in renders.iter().zip([0, 5, 10]) {
            assert_eq!(r["frame"], f);
            let png = dir.join(format!("frame_{f:06}.png"));
            let img = image::open(&png).unwrap_or_else(|e| panic!("{}: {e}", png.display()));
            assert_eq!((img.width(), img.height()), (96, 54));
        }
        let listed =
            std::fs::read_to_string(dir.join("image_hashes.txt")).expect("image_hashes.txt");
        let last = renders[2]["image_hash"].as_str().expect("hash").to_string();
        assert!(
            listed.lines().any(|l| l == format!("10\t{last}")),
            "{listed}"
        );
        renders
    };
    assert_eq!(
        run("render_a"),
        run("render_b"),
        "image hashes differ between two runs"
    );
}

/// Rendering every K-th frame uploads the union of the skipped frames' rectangles, never
/// a whole-texture refill after the first frame, so a rendered frame uploads at most K x the update
/// budget (before: every level in full, about 256k samples on gles3-mid against a 32,640 budget).
#[test]
fn fly_render_every_k_uploads_at_most_k_budgets() {
    let dir = scratch("render_every");
    let d = dir.to_str().expect("utf-8 temp path");
    let k = 4u64;
    let ks = k.to_string();
    let args = [
        "fly",
        "--profile",
        "gles3-mid",
        "--frames",
        "41",
        "--speed",
        "400",
        "--render",
        d,
        "--render-every",
        &ks,
        "--size",
        "64x36",
        "--json",
    ];
    let v = json_of(&clipsat(&args));
    let budget = v["budget"].as_u64().expect("budget");
    let max = v["upload_samples_max"]
        .as_u64()
        .expect("upload_samples_max");
    assert!(max > 0, "nothing uploaded: {v}");
    assert!(
        max <= k * budget,
        "a rendered frame uploaded {max} samples, more than {k} x {budget}"
    );
    assert_eq!(v["full_uploads_after_first"], 0, "{v}");
}

/// `fly --render` streams a package through the profile's tile cache, as `render` does
/// (`streamed` in the summary, tiles decoded, no whole heightmap loaded), and its image hashes repeat
/// exactly on a second run; with SG shading and `--lod sat` too, the LOD tables read through a map.
#[test]
fn fly_render_streams_a_package() {
    let dir = scratch("stream");
    let pkg = dir.join("t.clipsat");
    let p = pkg.to_string_lossy().into_owned();
    json_of(&clipsat(&[
        "bake",
        "procedural:size=257",
        "--out",
        &p,
        "--json",
    ]));
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let d = out.to_string_lossy().into_owned();
        let mut args = vec![
            "fly",
            "--terrain",
            &p,
            "--frames",
            "12",
            "--path",
            "teleport:6",
            "--speed",
            "300",
            "--render",
            &d,
            "--render-every",
            "5",
            "--size",
            "96x54",
            "--json",
        ];
        args.extend_from_slice(extra);
        let v = json_of(&clipsat(&args));
        assert_eq!(v["streamed"], true, "{v}");
        let decoded = v["stream"]["tile_cache"]["stats"]["decoded"]
            .as_u64()
            .unwrap_or(0);
        assert!(decoded > 0, "no tile decoded: {v}");
        assert_eq!(v["constraint_violations"], 0, "{v}");
        let renders = v["renders"].as_array().expect("renders").clone();
        assert_eq!(renders.len(), 3, "frames 0, 5, 10: {v}");
        (v, renders)
    };
    let low = ["--profile", "gles3-low"];
    let (_, a) = run("basic_a", &low);
    let (_, b) = run("basic_b", &low);
    assert_eq!(a, b, "streamed image hashes differ between two runs");
    let (v, _) = run(
        "sg_sat",
        &["--profile", "gles3-mid", "--shading", "sg", "--lod", "sat"],
    );
    assert_eq!(v["shading"], "sg", "{v}");
    assert!(v["stream"]["lod_tables"].is_object(), "{v}");
}
