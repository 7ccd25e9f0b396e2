//! The default frames on every driver present: `clipsat selftest --json --images` on Mesa's llvmpipe (GL,
//! strict ES 3.0), softpipe (GL), lavapipe (Vulkan) and Google's SwiftShader (Vulkan, no code shared with
//! Mesa). Each driver's basic, SG, detail-pool and imagery frames must match their CPU twins within the tolerance
//! of `twin::frame` (the selftest's own checks), and the largest difference between any two drivers'
//! frames is reported as a table: docs/real-drivers.md's, built by
//! `cargo test --test cli cross_driver -- --ignored --nocapture` (also written to
//! `target/tmp/cross-driver/table.md`). CI runs the self-test on llvmpipe alone: the four at once cost
//! about a minute and a half on CI's 2 cores, and CI's Vulkan passes run the same twin checks on lavapipe
//! and SwiftShader.
//!
//! Under `CI=true` lavapipe and SwiftShader must be present (`.ci/setup` installs them); elsewhere a
//! missing one is skipped with a printed reason. With `CLIPSAT_VALIDATION_LOG` set (`.ci/run`) the
//! Vulkan selftests run under the Khronos validation layer.

use std::path::{Path, PathBuf};

use clipsat::gpu::readback::Image;

use std::process::{Command, Output};

use crate::{cache_dir, scratch_in};

/// The frames `selftest --images` writes, each checked against its twin.
const FRAMES: [(&str, &str); 4] = [
    ("basic", "basic frame"),
    ("sg", "SG frame"),
    ("pool", "detail-pool frame"),
    ("imagery", "imagery frame"),
];

/// A driver: its name in the table, `--gpu`, the environment that picks it, and whether CI needs it.
struct Driver {
    name: &'static str,
    gpu: &'static str,
    env: Vec<(&'static str, String)>,
    required_on_ci: bool,
}

/// The Vulkan ICD manifest of a driver, if installed.
fn icd(candidates: &[&str]) -> Option<String> {
    candidates
        .iter()
        .find(|p| Path::new(p).exists())
        .map(|p| (*p).to_string())
}

fn drivers() -> Vec<(Driver, Option<String>)> {
    let lvp = icd(&[
        "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json",
        "/usr/share/vulkan/icd.d/lvp_icd.aarch64.json",
    ]);
    let swiftshader = icd(&["/usr/lib/chromium/vk_swiftshader_icd.json"]);
    let vulkan = |name, icd: Option<String>| {
        let missing = icd
            .is_none()
            .then(|| format!("{name}'s ICD is not installed"));
        let env = icd
            .map(|f| vec![("VK_ICD_FILENAMES", f)])
            .unwrap_or_default();
        (
            Driver {
                name,
                gpu: "vulkan",
                env,
                required_on_ci: true,
            },
            missing,
        )
    };
    vec![
        (
            Driver {
                name: "llvmpipe (GL)",
                gpu: "strict",
                env: vec![("GALLIUM_DRIVER", "llvmpipe".into())],
                required_on_ci: true,
            },
            None,
        ),
        (
            Driver {
                name: "softpipe (GL)",
                gpu: "strict",
                env: vec![("GALLIUM_DRIVER", "softpipe".into())],
                required_on_ci: false,
            },
            None,
        ),
        vulkan("lavapipe (Vulkan)", lvp),
        vulkan("SwiftShader (Vulkan)", swiftshader),
    ]
}

/// Pixel differences of two frames where both drew terrain (neither is the clear colour): mean and largest
/// absolute difference of the largest channel, in levels of 255, and the pixels past 2 levels.
fn difference(a: &Image, b: &Image, clear: [u8; 4]) -> (f64, u8, u64, u64) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let (mut sum, mut max, mut past, mut n) = (0u64, 0u8, 0u64, 0u64);
    for (p, q) in a.rgba.chunks_exact(4).zip(b.rgba.chunks_exact(4)) {
        if p == clear || q == clear {
            continue;
        }
        let d = (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0);
        sum += u64::from(d);
        max = max.max(d);
        past += u64::from(d > 2);
        n += 1;
    }
    #[expect(clippy::cast_precision_loss, reason = "pixel sums far below 2^52")]
    let mean = sum as f64 / n.max(1) as f64;
    (mean, max, past, n)
}

fn load(path: &Path) -> Image {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgba8();
    Image {
        width: img.width(),
        height: img.height(),
        rgba: img.into_raw(),
    }
}

/// `selftest` on llvmpipe alone, CI's GL driver: every check passes and reports its figures. The
/// Vulkan drivers' frames are checked against their twins by CI's Vulkan passes (the same tests as the
/// selftest's checks, on lavapipe and SwiftShader).
#[test]
fn default_frames_agree_with_their_twins_on_llvmpipe() {
    let drivers = drivers()
        .into_iter()
        .filter_map(|(d, missing)| {
            (missing.is_none() && d.name.starts_with("llvmpipe")).then_some(d)
        })
        .collect();
    let _ = self_tests(drivers, "llvmpipe");
}

/// The self-tests on every driver present, and the table of their differences. Ignored by default: the
/// four self-tests at once cost about a minute and a half of CI's 5 minutes on 2 cores. Run it with
/// `cargo test --test cli cross_driver -- --ignored --nocapture`.
#[test]
#[ignore = "four drivers' self-tests, ~100 s on 2 cores: cargo test --test cli cross_driver -- --ignored --nocapture"]
fn default_frames_agree_with_their_twins_on_every_driver() {
    let on_ci = std::env::var("CI").as_deref() == Ok("true");
    let mut present = Vec::new();
    for (driver, missing) in drivers() {
        if let Some(why) = missing {
            assert!(!(on_ci && driver.required_on_ci), "{why} (bash .ci/setup)");
            eprintln!("skipped {}: {why}", driver.name);
            continue;
        }
        present.push(driver);
    }
    let (ran, lines, root) = self_tests(present, "all");
    table(&ran, lines, &root);
}

/// What each driver's self-test wrote: its name, its images' folder and its JSON report.
type Ran = Vec<(&'static str, PathBuf, serde_json::Value)>;

/// `selftest --json --images` on each of `present` at once, each checked; returns what ran, the table's
/// lines of each frame against its twin, and the scratch folder.
fn self_tests(present: Vec<Driver>, run: &str) -> (Ran, Vec<String>, PathBuf) {
    let root = scratch_in("cross-driver", run);
    let mut ran: Ran = Vec::new();
    let mut lines = Vec::new();
    // The self-tests at once: each is mostly one thread's work (the plan, the twin, the bakes).
    let outputs: Vec<(Driver, PathBuf, Output)> = std::thread::scope(|s| {
        let runs: Vec<_> = present
            .into_iter()
            .map(|driver| {
                let dir = root.join(driver.name.split(' ').next().unwrap_or("driver"));
                s.spawn(move || {
                    let out = Command::new(env!("CARGO_BIN_EXE_clipsat"))
                        .args(["selftest", "--json", "--frames", "3", "--gpu", driver.gpu])
                        .arg("--images")
                        .arg(&dir)
                        .env("CLIPSAT_CACHE", cache_dir())
                        .envs(driver.env.iter().map(|(k, v)| (k, v)))
                        .output()
                        .expect("run clipsat selftest");
                    (driver, dir, out)
                })
            })
            .collect();
        runs.into_iter()
            .map(|h| h.join().expect("selftest thread"))
            .collect()
    });
    for (driver, dir, out) in outputs {
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
            panic!(
                "{}: {e}: {}",
                driver.name,
                String::from_utf8_lossy(&out.stderr)
            )
        });
        let adapter = v["adapter"]["name"].as_str().unwrap_or("?").to_string();
        // softpipe is a build option of Mesa's Gallium: where it is not built, Mesa falls back to
        // llvmpipe, which is not a driver of its own.
        if driver.name.starts_with("softpipe") && !adapter.contains("softpipe") {
            eprintln!("skipped softpipe: this Mesa gave {adapter}");
            continue;
        }
        assert_eq!(
            out.status.code(),
            Some(0),
            "{} ({adapter}) fails the selftest:\n{v:#}",
            driver.name
        );
        // What a device farm groups failures by, and every check's figures.
        for field in ["name", "driver", "driver_info", "backend", "device_type"] {
            assert!(
                v["adapter"][field].is_string(),
                "{}: {field}: {v:#}",
                driver.name
            );
        }
        assert!(v["adapter"]["vendor"].is_u64(), "{v:#}");
        let names: Vec<&str> = v["checks"]
            .as_array()
            .map(|cs| cs.iter().filter_map(|c| c["name"].as_str()).collect())
            .unwrap_or_default();
        assert_eq!(
            names,
            [
                "adapter",
                "vertices",
                "basic frame",
                "SG frame",
                "detail-pool frame",
                "imagery frame",
                "border",
                "read-back and frame times"
            ],
            "{}",
            driver.name
        );
        for c in v["checks"].as_array().into_iter().flatten().skip(1) {
            assert!(
                c["figures"].is_object() || c["twin"].is_object(),
                "{}: {c:#}",
                driver.name
            );
        }
        for (_, check) in FRAMES {
            let c = v["checks"]
                .as_array()
                .and_then(|cs| cs.iter().find(|c| c["name"] == check))
                .unwrap_or_else(|| panic!("{}: no {check} check: {v:#}", driver.name));
            let t = &c["twin"];
            lines.push(format!(
                "| {} | {check} | {} | {:.3} | {:.2} | {} |",
                driver.name,
                t["pixels"],
                t["mean_levels"].as_f64().unwrap_or(f64::NAN),
                t["max_levels"].as_f64().unwrap_or(f64::NAN),
                t["outliers"]
            ));
        }
        ran.push((driver.name, dir, v));
    }
    assert!(!ran.is_empty(), "no driver ran");
    (ran, lines, root)
}

/// The table of each driver against its twin and of the largest difference between two drivers,
/// printed and written beside `root`.
fn table(ran: &Ran, lines: Vec<String>, root: &Path) {
    let clear =
        clipsat::twin::border::clear_rgba8(clipsat::gpu::headless::FrameOptions::default().clear);
    let mut table = vec![
        "Each driver against the CPU twin (levels of 255, the largest channel; tolerance: mean <= 1, at \
         most 1 % of pixels past 2):"
            .to_string(),
        String::new(),
        "| driver | frame | pixels | mean | max | past 2 |".into(),
        "|---|---|---|---|---|---|".into(),
    ];
    table.extend(lines);
    table.push(String::new());
    table.push("The largest difference between two drivers, per frame (pixels both drew):".into());
    table.push(String::new());
    table.push("| frame | drivers | mean | max | past 2 levels | pixels |".into());
    table.push("|---|---|---|---|---|---|".into());
    for (stem, check) in FRAMES {
        let mut worst: Option<(f64, u8, u64, u64, String)> = None;
        for (i, (a, da, _)) in ran.iter().enumerate() {
            for (b, db, _) in &ran[i + 1..] {
                let (mean, max, past, n) = difference(
                    &load(&da.join(format!("{stem}.png"))),
                    &load(&db.join(format!("{stem}.png"))),
                    clear,
                );
                let pair = format!("{a} / {b}");
                if worst.as_ref().is_none_or(|w| (max, mean) > (w.1, w.0)) {
                    worst = Some((mean, max, past, n, pair));
                }
            }
        }
        if let Some((mean, max, past, n, pair)) = worst {
            table.push(format!(
                "| {check} | {pair} | {mean:.3} | {max} | {past} | {n} |"
            ));
        }
    }
    let table = table.join("\n");
    println!("{table}");
    std::fs::write(root.join("..").join("table.md"), format!("{table}\n"))
        .expect("write the table");
}
