//! `clipsat bench all`'s terrain memory measurements: package size and error per terrain, the
//! whole pyramid's decode throughput against a memcpy of the decoded bytes in the same run, decode plus
//! fill of full desktop levels streamed from a package, and the peak RSS of `render --lod sat` and `render
//! --profile desktop --shading sg` as child processes under `/usr/bin/time -v`, with the GC table 3
//! figures beside them. A measurement tool: it allocates freely and reads the wall clock.

use std::fmt::Write as _;
use std::hint::black_box;
use std::path::{Path as FsPath, PathBuf};
use std::process::Command;
use std::time::Instant;

use clipsat::package::{self, BakeOptions, Package};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use clipsat::{Error, Result};
use indicatif::ProgressBar;

use super::common::mib;

/// One terrain's package: size, error and decode throughput.
pub(super) struct PackageRow {
    name: String,
    samples: u64,
    report: package::BakeReport,
    /// Samples of every level (what a whole-pyramid decode writes).
    pyramid_samples: u64,
    /// Whole-pyramid decode, best of the repetitions, seconds.
    decode_s: f64,
    /// A memcpy of the same decoded i32s, best of the repetitions, seconds.
    memcpy_s: f64,
}

/// Peak RSS of one terrain's render commands (None: not measured).
pub(super) struct RssRow {
    name: String,
    sat: Option<u64>,
    /// `--lod sat` streamed (the default): the package streamed, the LOD tables read through a map (full
    /// runs only).
    sat_stream: Option<u64>,
    sg: Option<u64>,
}

/// Decode plus fill of full levels: a desktop clipmap streamed from a package, refilled from scratch.
pub(super) struct Refill {
    terrain: String,
    levels: u32,
    side: u32,
    /// Best time of one whole refill (every level, its tiles decoded), seconds.
    best_s: f64,
    /// Samples decoded by that refill.
    decoded: u64,
}

/// What the memory measurements found.
pub(super) struct TerrainMemory {
    packages: Vec<PackageRow>,
    rss: Vec<RssRow>,
    rss_profile: String,
    rss_size: (u32, u32),
    rss_note: Option<String>,
    refill: Option<Refill>,
}

/// A terrain for the child `render` runs: its name and the `--terrain ...` arguments that load it.
pub(super) type TerrainSpec = (String, Vec<String>);

/// Bakes each terrain into `dir` (deleted after), times the pyramid decode and a memcpy `reps` times each,
/// measures the refill on the first terrain's package, and runs the render commands on each `specs` entry
/// (twice when `reps` > 1, the second measured).
pub(super) fn measure(
    terrains: &[(String, Heightmap)],
    specs: &[TerrainSpec],
    profile: &str,
    size: (u32, u32),
    reps: u32,
    dir: &FsPath,
    bar: &ProgressBar,
) -> Result<TerrainMemory> {
    let mut packages = Vec::new();
    let mut refill = None;
    for (i, (name, hm)) in terrains.iter().enumerate() {
        bar.set_message(format!("memory: package {name}"));
        let path = dir.join(format!("bench-memory-{i}.clipsat"));
        let report = package::bake(
            hm,
            &path,
            &BakeOptions::default(),
            clipsat::Progress::default(),
        )?;
        let pkg = Package::open(&path)?;
        let pyramid_samples: u64 = pkg
            .header()
            .levels
            .iter()
            .map(|l| u64::from(l.width) * u64::from(l.height))
            .sum();
        let (mut decode_s, mut memcpy_s) = (f64::INFINITY, f64::INFINITY);
        let src = vec![7i32; usize::try_from(pyramid_samples).unwrap_or(0)];
        let mut dst = vec![0i32; src.len()];
        for _ in 0..reps.max(1) {
            let t = Instant::now();
            black_box(pkg.decode_level0()?);
            decode_s = decode_s.min(t.elapsed().as_secs_f64());
            let t = Instant::now();
            dst.copy_from_slice(black_box(&src));
            black_box(&dst);
            memcpy_s = memcpy_s.min(t.elapsed().as_secs_f64());
        }
        if i == 0 {
            bar.set_message(format!("memory: refill {name}"));
            refill = Some(measure_refill(name, hm, &path, reps)?);
        }
        let _ = std::fs::remove_file(&path);
        packages.push(PackageRow {
            name: name.clone(),
            samples: u64::from(hm.width()) * u64::from(hm.height()),
            report,
            pyramid_samples,
            decode_s,
            memcpy_s,
        });
        bar.inc(1);
    }
    let mut rss = Vec::new();
    let exe = std::env::current_exe().ok();
    let time = FsPath::new("/usr/bin/time");
    let rss_note = match &exe {
        _ if !time.is_file() => Some("/usr/bin/time is not installed".to_string()),
        None => Some("the clipsat executable's path is unknown".to_string()),
        Some(_) => None,
    };
    for (name, args) in specs {
        bar.set_message(format!("memory: render {name}"));
        let run = |extra: &[&str]| -> Option<u64> {
            let exe = exe.as_ref().filter(|_| rss_note.is_none())?;
            let png = dir.join("bench-memory.png");
            let mut cmd = Command::new(time);
            cmd.arg("-v")
                .arg(exe)
                .arg("render")
                .args(args)
                .args(extra)
                .arg("--size")
                .arg(format!("{}x{}", size.0, size.1))
                .arg("--out")
                .arg(&png)
                .arg("--json");
            // A full run measures the second run: the first bakes the LOD tables (and SG's inputs) into
            // the cache. A quick one measures the first.
            let first = child_peak_rss(&mut cmd);
            if reps > 1 {
                first.and_then(|_| child_peak_rss(&mut cmd))
            } else {
                first
            }
        };
        rss.push(RssRow {
            name: name.clone(),
            // The whole terrain resident, against the streamed default below.
            sat: run(&["--profile", profile, "--lod", "sat", "--resident"]),
            // A quick run skips it: its first run bakes a package (seconds even for small terrains).
            sat_stream: if reps > 1 {
                run(&["--profile", profile, "--lod", "sat"])
            } else {
                None
            },
            sg: run(&["--profile", "desktop", "--shading", "sg", "--resident"]),
        });
        bar.inc(1);
    }
    Ok(TerrainMemory {
        packages,
        rss,
        rss_profile: profile.to_string(),
        rss_size: size,
        rss_note,
        refill,
    })
}

/// Steps [`measure`] reports to the progress bar.
pub(super) fn steps(terrains: usize, specs: usize) -> u64 {
    (terrains + specs) as u64
}

/// The peak RSS `/usr/bin/time -v` reports for `cmd`, bytes; None when it fails or says nothing.
fn child_peak_rss(cmd: &mut Command) -> Option<u64> {
    let out = cmd.output().ok()?;
    if !out.status.success() {
        return None;
    }
    let err = String::from_utf8_lossy(&out.stderr);
    let kib: u64 = err
        .lines()
        .find_map(|l| l.trim().strip_prefix("Maximum resident set size (kbytes):"))?
        .trim()
        .parse()
        .ok()?;
    Some(kib * 1024)
}

/// Decode plus fill (GC table 1's "decompress a full level"): the desktop profile's clipmap (n = 255) with
/// an unlimited update budget, streamed from the package at `path` through a fresh cache (rings plus 8 MiB
/// of tiles), filled from nothing at the terrain's centre: every level's tiles decoded and every texel
/// written, on this thread. The best of `reps` cold fills (the cache is built outside the timing).
fn measure_refill(name: &str, hm: &Heightmap, path: &FsPath, reps: u32) -> Result<Refill> {
    let mut profile = Profile::load("desktop")?;
    profile.budget.update_samples_per_frame = u32::MAX;
    // No SG here: the 8 MiB are not split with the SG shading inputs' share (CpuSplit::shading).
    profile
        .shading
        .features
        .retain(|&f| f != clipsat::profile::Feature::Sg);
    profile.budget.cpu_memory_bytes = profile.cpu_split().rings + (8 << 20);
    let (w, h) = (f64::from(hm.width()), f64::from(hm.height()));
    let s = f64::from(hm.spacing());
    let (ox, oy) = hm.origin();
    // 50 m above the ground at the centre, where the viewer-height rule enables every level.
    let ground = hm.at_clamped(i64::from(hm.width() / 2), i64::from(hm.height() / 2));
    let eye = glam::DVec3::new(ox + 0.5 * w * s, oy + 0.5 * h * s, f64::from(ground) + 50.0);
    let (mut best_s, mut decoded) = (f64::INFINITY, 0u64);
    for _ in 0..reps.max(1) {
        let mut clipmap =
            Clipmap::streamed(Package::open(path)?, &profile, ClipmapOptions::default())?;
        let t = Instant::now();
        black_box(clipmap.update(eye)?.hash);
        let dt = t.elapsed().as_secs_f64();
        if dt < best_s {
            best_s = dt;
            decoded = u64::from(clipmap.decoded_samples());
        }
    }
    Ok(Refill {
        terrain: name.to_string(),
        levels: profile.clipmap.levels,
        side: profile.clip_size(),
        best_s,
        decoded,
    })
}

/// The GC table 3 figures (GC section 9) beside a terrain, where the paper has one.
fn gc_table3(name: &str) -> &'static str {
    if name.starts_with("ps_height") {
        "Puget Sound 16K^2: 8.5 MB of 537 MB at 1.0 m rms (0.032 B/sample); 0.10 B/sample at runtime"
    } else {
        "-"
    }
}

/// The report section.
pub(super) fn section(m: &TerrainMemory, machine: &str, cpu_budget: u64) -> String {
    let mut s = String::from("## Memory: terrain package and resident set\n\n");
    let _ = writeln!(
        s,
        "Each terrain baked with `clipsat bake`'s defaults (`--max-error` half the source's own step: 0.5 m \
         for integer metres, 0.05 m for decimetres, 0.005 m for floats), zstd tiles of the GC section 7 \
         residual pyramid and the SAT LOD tables' compact records. B/sample: the whole file over the level-0 \
         samples; pyramid: the height tiles' payloads alone; LOD tables: the record tiles' payloads \
         alone (the shading inputs are still built at load time, their memory shows in the RSS table). Decode: the whole pyramid decoded coarse to \
         fine on one thread, against a memcpy of the same decoded i32s in the same run. GC table 3 (GC \
         section 9): 0.02 B/sample at runtime for the 20-billion-sample U.S., prior methods 1.8-6.0 \
         B/sample.\n\n*Table: {machine}*\n"
    );
    s.push_str(
        "| terrain | samples | B/sample | pyramid B/sample | LOD tables B/sample | max error bound | \
         rms error | max error | decode Msamples/s | memcpy Msamples/s | decode / memcpy | GC table 3 |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for p in &m.packages {
        let r = &p.report;
        let rate = |t: f64| p.pyramid_samples as f64 / t / 1e6;
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.3} | {:.3} | {} m | {:.4} m | {:.4} m | {:.0} | {:.0} | {:.3} | {} |",
            p.name,
            p.samples,
            r.bytes_per_sample,
            r.pyramid_bytes_per_sample,
            r.lod_table_bytes_per_sample,
            r.max_error_bound,
            r.rms_error,
            r.max_error,
            rate(p.decode_s),
            rate(p.memcpy_s),
            p.memcpy_s / p.decode_s,
            gc_table3(&p.name),
        );
    }
    if let Some(f) = &m.refill {
        let per_level_ms = f.best_s * 1e3 / f64::from(f.levels.max(1));
        let _ = writeln!(
            s,
            "\nDecode plus fill, one thread: the desktop clipmap ({} levels of {}^2) streamed from the {} \
             package, filled from nothing through a fresh cache ({} samples decoded, every texel written): \
             {:.1} ms a fill, {per_level_ms:.2} ms a level (goal: 2 ms for a full n = 255 level; GC table \
             1: 8 ms to decompress one).",
            f.levels,
            f.side,
            f.terrain,
            f.decoded,
            f.best_s * 1e3,
        );
    }
    let _ = writeln!(
        s,
        "\nPeak RSS (`/usr/bin/time -v`; a full run reports the second run, as the first bakes the LOD \
         tables and shading inputs into the cache) of `clipsat render --terrain T --size {}x{}` with `--profile {} --lod sat \
         --resident` (the whole terrain loaded), the same streamed (the default: the terrain baked into a \
         package in the cache and streamed through the tile cache, the LOD tables read through a map of \
         their cache file; full runs only), and with `--profile desktop --shading sg --resident`; \
         terrain-dependent: minus the same command on the first terrain. \
         The budget: `budget.cpu_memory_bytes` of the SAT run's profile ({}); the desktop profile has 256 \
         MiB.{}\n",
        m.rss_size.0,
        m.rss_size.1,
        m.rss_profile,
        mib(cpu_budget),
        m.rss_note
            .as_ref()
            .map_or_else(String::new, |n| format!(" Not measured: {n}."))
    );
    s.push_str(
        "| terrain | render --lod sat --resident | terrain-dependent | within budget | --lod sat (streamed) | \
         terrain-dependent | within budget | render --shading sg --resident (desktop) | terrain-dependent |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    let base = m.rss.first();
    let cell = |v: Option<u64>| v.map_or_else(|| "-".to_string(), mib);
    let extra = |v: Option<u64>, b: Option<u64>| -> Option<u64> { Some(v?.saturating_sub(b?)) };
    for r in &m.rss {
        let sat_extra = extra(r.sat, base.and_then(|b| b.sat));
        let stream_extra = extra(r.sat_stream, base.and_then(|b| b.sat_stream));
        let within = |e: Option<u64>| e.map_or("-", |e| if e <= cpu_budget { "yes" } else { "no" });
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.name,
            cell(r.sat),
            cell(sat_extra),
            within(sat_extra),
            cell(r.sat_stream),
            cell(stream_extra),
            within(stream_extra),
            cell(r.sg),
            cell(extra(r.sg, base.and_then(|b| b.sg))),
        );
    }
    s.push('\n');
    s
}

/// The folder the memory measurements bake into.
pub(super) fn scratch(out: &FsPath) -> Result<PathBuf> {
    let dir = out.join("memory-scratch");
    std::fs::create_dir_all(&dir)
        .map_err(|e| Error::io(&dir, "cannot create the scratch folder", e))?;
    Ok(dir)
}
