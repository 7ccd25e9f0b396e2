//! Bad input everywhere: each case is a clear error or a documented clamp, never a panic, and a refused
//! input leaves no trace in the next frame.
//!
//! Documented behaviour tested here:
//! - `Clipmap::update` refuses a non-finite eye and an eye beyond the lattice (|coordinate| >= 2^48 level-0
//!   samples) with `Error::Camera`, before touching any state.
//! - Any finite eye inside the lattice is accepted, however far from the data: the terrain extends flat
//!   beyond its border (edge samples repeat), so rings fill with edge heights. An eye at or below the ground
//!   counts as height 0 (every level enabled); a very high eye keeps only the coarsest level.
//! - `clipsat render --camera/--look-at` refuses NaN, infinite and coincident points with exit 2.
//!
//! Profile fields are covered by tests/cpu/profiles.rs, scene fields by tests/cpu/scene.rs, loaders by
//! tests/cpu/sources.rs; here the same file problems go through the binary.

use std::path::PathBuf;
use std::process::Output;

use super::clipsat;

use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path as FlightPath};
use clipsat::profile::Profile;
use clipsat::source::procedural::{generate, ProceduralParams};
use clipsat::source::Heightmap;
use clipsat::Error;
use glam::DVec3;

fn terrain() -> Heightmap {
    generate(&ProceduralParams {
        seed: 3,
        size: 257,
        spacing: 30.0,
    })
    .expect("procedural")
}

fn clipmap(hm: &Heightmap, synth: u32) -> Clipmap {
    let p = Profile::load("gles3-low").expect("profile");
    Clipmap::new(
        hm,
        &p,
        ClipmapOptions {
            synth_levels: synth,
        },
    )
    .expect("clipmap")
}

/// Every texel of every active region equals the CPU twin `Clipmap::sample`: the rings hold no stale or
/// corrupted data where they are drawn.
fn assert_rings_true(cm: &Clipmap, tag: &str) {
    let frame = cm.frame();
    for (l, lf) in frame.levels.iter().enumerate() {
        let a = lf.active;
        if a.is_empty() {
            continue;
        }
        let l32 = u32::try_from(l).expect("level");
        let ring = cm.ring(l32);
        for j in a.y0..a.y0 + i64::from(a.h) {
            for i in a.x0..a.x0 + i64::from(a.w) {
                let (got, want) = (ring.get(i, j), cm.sample(l32, i, j));
                assert!(
                    got[0].to_bits() == want[0].to_bits() && got[1].to_bits() == want[1].to_bits(),
                    "{tag}: level {l} sample ({i}, {j}) is {got:?}, expected {want:?}"
                );
            }
        }
    }
}

#[test]
fn refused_eyes_leave_no_trace() {
    let hm = terrain();
    let flight = Flight::new(FlightPath::Figure8, 90.0, &hm).expect("flight");
    let bad = [
        DVec3::new(f64::NAN, 100.0, 300.0),
        DVec3::new(100.0, f64::INFINITY, 300.0),
        DVec3::new(100.0, 100.0, f64::NEG_INFINITY),
        DVec3::new(1e300, 100.0, 300.0),
        DVec3::new(100.0, -1e17, 300.0),
    ];
    for synth in [0, 1] {
        let mut clean = clipmap(&hm, synth);
        let mut dirty = clipmap(&hm, synth);
        for f in 0..80u64 {
            let eye = flight.camera(f).eye;
            if f % 10 == 3 {
                let before = dirty.frame().hash;
                for b in bad {
                    match dirty.update(b) {
                        Err(Error::Camera { reason: msg, .. }) => assert!(!msg.is_empty()),
                        other => panic!("eye {b}: expected a camera error, got {other:?}"),
                    }
                    assert_eq!(
                        dirty.frame().hash,
                        before,
                        "a refused eye changed the frame"
                    );
                }
            }
            let want = clean.update(eye).expect("update").hash;
            let got = dirty.update(eye).expect("update").hash;
            assert_eq!(
                got, want,
                "synth {synth} frame {f}: differs after refused eyes"
            );
        }
        assert_rings_true(&dirty, "after refused eyes");
    }
}

#[test]
fn far_low_and_high_eyes_are_clamped_not_panics() {
    let hm = terrain();
    let (ex, ey) = hm.extent_m();
    let centre = DVec3::new(ex / 2.0, ey / 2.0, 400.0);
    let accepted = [
        ("1e7 m east", DVec3::new(1e7, ey / 2.0, 400.0)),
        ("1e7 m south-west", DVec3::new(-1e7, -1e7, 400.0)),
        ("near the lattice edge", DVec3::new(1e15, -1e15, 400.0)),
        ("at sea level", DVec3::new(ex / 2.0, ey / 2.0, 0.0)),
        ("far below ground", DVec3::new(ex / 3.0, ey / 3.0, -5000.0)),
        ("1e6 m up", DVec3::new(ex / 2.0, ey / 2.0, 1e6)),
        ("1e12 m up", DVec3::new(ex / 2.0, ey / 2.0, 1e12)),
    ];
    for synth in [0, 1] {
        let mut cm = clipmap(&hm, synth);
        let prof = Profile::load("gles3-low").expect("profile");
        let budget = prof.budget.update_samples_per_frame;
        for (what, eye) in accepted {
            for _ in 0..3 {
                let f = cm
                    .update(eye)
                    .unwrap_or_else(|e| panic!("{what}: refused: {e}"));
                assert!(f.samples_updated <= budget, "{what}: over budget");
                if let Err(v) = cm.check_constraints() {
                    panic!("synth {synth}, {what}: {v}");
                }
            }
            if eye.z >= 1e6 {
                // Only the coarsest level is kept far above the terrain.
                let frame = cm.frame();
                assert_eq!(
                    frame.disabled_levels,
                    cm.levels() - 1,
                    "{what}: disabled levels"
                );
            }
            // Back home: the rings converge to the true heights.
            while cm.pending_samples(centre) > 0 {
                cm.update(centre).expect("update");
            }
            assert_rings_true(&cm, what);
        }
    }
}

// ---- through the binary ---------------------------------------------------------------------------

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Exit 2 with one `error:` line mentioning `needle`, no panic.
fn assert_refused(out: &Output, needle: &str, what: &str) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(2), "{what}: {err}");
    assert!(!err.contains("panicked"), "{what}: {err}");
    assert!(
        err.starts_with("error: ") && err.lines().count() == 1,
        "{what}: not a one-line error: {err}"
    );
    assert!(
        err.contains(needle),
        "{what}: error does not name `{needle}`: {err}"
    );
}

fn scratch(name: &str) -> PathBuf {
    super::scratch_in("bad_input", name)
}

#[test]
fn render_refuses_bad_cameras_and_survives_odd_ones() {
    let dir = scratch("render");
    let out = dir.join("x.png");
    let o = out.to_string_lossy();
    let base = [
        "render",
        "--profile",
        "gles3-low",
        "--terrain",
        "procedural:size=129",
        "--size",
        "64x36",
        "--out",
        &o,
        "--json",
    ];
    let refused = [
        ("nan,0,500", "1000,1000,0", "not finite"),
        ("0,inf,500", "1000,1000,0", "not finite"),
        ("0,0,500", "-inf,1000,0", "not finite"),
        ("100,200,300", "100,200,300", "zero length"),
        ("1,2", "100,200,300", "--camera"),
        ("1,2,x", "100,200,300", "--camera"),
    ];
    for (eye, at, needle) in refused {
        let mut a = base.to_vec();
        a.extend(["--camera", eye, "--look-at", at]);
        assert_refused(&clipsat(&a), needle, &format!("{eye} -> {at}"));
    }
    // Accepted: far away, at and below the ground, very high. The frame renders (clear sky or terrain).
    let accepted = [
        ("1e7,1e7,500", "1900,1900,0"),
        ("-1e7,500,500", "1900,1900,0"),
        ("1900,1900,0", "3000,3000,0"),
        ("1900,1900,-3000", "3000,3000,-2900"),
        ("1900,1900,1e6", "1901,1950,0"),
        // Straight down: north up.
        ("100,200,300", "100,200,-50"),
    ];
    for (eye, at) in accepted {
        let mut a = base.to_vec();
        a.extend(["--camera", eye, "--look-at", at]);
        let r = clipsat(&a);
        let err = stderr(&r);
        assert!(r.status.success(), "{eye} -> {at}: {err}");
        assert!(!err.contains("panicked"), "{eye} -> {at}: {err}");
        let j: serde_json::Value = serde_json::from_slice(&r.stdout).expect("JSON");
        assert!(j["image_hash"].is_string(), "{j}");
    }
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 == 1 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A PNG that declares `w` x `h` 16-bit grey (valid CRCs) and holds no pixels.
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut data = w.to_be_bytes().to_vec();
    data.extend(h.to_be_bytes());
    data.extend([16, 0, 0, 0, 0]);
    out.extend(u32::try_from(data.len()).expect("len").to_be_bytes());
    let start = out.len();
    out.extend(b"IHDR");
    out.extend(&data);
    let crc = crc32(&out[start..]);
    out.extend(crc.to_be_bytes());
    out
}

#[test]
fn bad_terrain_files_exit_2_naming_the_file() {
    let dir = scratch("terrain");
    let f32s = |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
    let mut nan = vec![1.0f32; 12];
    nan[6] = f32::NAN;
    let cases: Vec<(&str, Vec<u8>, Vec<&str>)> = vec![
        ("empty.png", Vec::new(), vec![]),
        ("empty.tif", Vec::new(), vec![]),
        ("magic.png", b"GIF89a, not a png".to_vec(), vec![]),
        ("magic.tif", b"\x89PNG\r\n\x1a\n....".to_vec(), vec![]),
        ("truncated.png", png_header(64, 64), vec![]),
        (
            "truncated.tif",
            b"II*\x00\x08\x00\x00\x00\x0a".to_vec(),
            vec![],
        ),
        ("N00E000.hgt", vec![0u8; 1000], vec![]),
        ("huge.png", png_header(200_000, 200_000), vec![]),
        (
            "huge.raw",
            vec![0u8; 64],
            vec!["--raw-size", "200000x200000"],
        ),
        ("short.raw", vec![0u8; 64], vec!["--raw-size", "100x100"]),
        (
            "nan.f32",
            f32s(&nan),
            vec!["--raw-size", "4x3", "--raw-format", "f32"],
        ),
        (
            "inf.f32",
            f32s(&[1.0, f32::INFINITY, 0.0, 0.0]),
            vec!["--raw-size", "2x2", "--raw-format", "f32"],
        ),
        ("text.dem", b"whatever".to_vec(), vec![]),
    ];
    for (name, bytes, extra) in &cases {
        let p = dir.join(name);
        std::fs::write(&p, bytes).expect("write fixture");
        let t = p.to_string_lossy();
        let named = p.display().to_string();
        for cmd in [
            vec!["info", "--terrain", &t],
            vec!["fly", "--terrain", &t, "--frames", "2"],
        ] {
            let mut a = cmd.clone();
            a.extend(extra.iter().copied());
            assert_refused(&clipsat(&a), &named, &format!("{} {name}", cmd[0]));
        }
    }
    let missing = dir.join("missing.tif");
    let m = missing.to_string_lossy();
    assert_refused(
        &clipsat(&["info", "--terrain", &m]),
        &missing.display().to_string(),
        "missing file",
    );
}

/// Heights near `f32::MAX` (finite, so the loader accepts them) in the SAT LOD modes: their range and
/// the error maps overflow to infinity, which is a one-line error naming the cause, never a panic or a
/// silent render. Two terrains: a +-3e38 checkerboard (the range overflows) and a -f32::MAX | +f32::MAX
/// step (the range and the errors beside the step overflow).
#[test]
fn extreme_heights_in_sat_lod_are_a_clear_error() {
    let dir = scratch("extreme_heights");
    let n = 65usize;
    let checker = |i: usize| {
        if (i % n + i / n).is_multiple_of(2) {
            3.0e38f32
        } else {
            -3.0e38
        }
    };
    let step = |i: usize| if i % n < n / 2 { -f32::MAX } else { f32::MAX };
    let out = dir.join("x.png");
    let o = out.to_string_lossy();
    let mut files = Vec::new();
    for (name, f) in [
        ("checker", &checker as &dyn Fn(usize) -> f32),
        ("step", &step),
    ] {
        let bytes: Vec<u8> = (0..n * n).flat_map(|i| f(i).to_le_bytes()).collect();
        let p = dir.join(format!("{name}.f32"));
        std::fs::write(&p, bytes).expect("write fixture");
        files.push(p);
    }
    for (p, mode) in files
        .iter()
        .flat_map(|p| ["sat", "sat-conservative", "exact"].map(|m| (p, m)))
    {
        let t = p.to_string_lossy();
        let args = [
            "render",
            "--profile",
            "gles3-low",
            "--terrain",
            &t,
            "--raw-size",
            "65x65",
            "--raw-format",
            "f32",
            "--size",
            "64x36",
            "--out",
            &o,
            "--lod",
            mode,
            "--camera",
            "-100,-100,1000",
            "--look-at",
            "900,900,0",
        ];
        // Streamed (the default), the package's quantum cannot hold the range: a clear error first.
        assert_refused(&clipsat(&args), "--resident", &format!("{t} {mode}"));
        // Resident, the SAT LOD bake refuses the range.
        let mut resident = args.to_vec();
        resident.push("--resident");
        assert_refused(
            &clipsat(&resident),
            "too large for f32",
            &format!("{t} {mode} --resident"),
        );
    }
    let p = &files[1];
    // The library says the same, before any GPU work.
    let hm = clipsat::source::load(
        p,
        &clipsat::source::LoadOptions {
            raw: Some(clipsat::source::RawLayout {
                width: 65,
                height: 65,
                format: clipsat::source::RawFormat::F32,
            }),
            ..Default::default()
        },
    )
    .expect("finite heights load");
    let pyramid = clipsat::bake::pyramid::Pyramid::build(&hm);
    let params = clipsat::bake::BakeParams {
        p: clipsat::bake::lod_tables::P,
        levels: 8,
        synth_levels: 0,
        g0: 30.0,
    };
    match clipsat::bake::bake_uncached(&pyramid, &params, clipsat::Progress::default()).map(|_| ())
    {
        Err(Error::Terrain { reason, .. }) => {
            assert!(reason.contains("too large for f32"), "{reason}")
        }
        other => panic!("expected Error::Terrain, got {other:?}"),
    }
    // An error map that overflowed (or a NaN) is refused per level too, naming the sample; before, E_L
    // folded past the NaN and the SAT quantiser met inf x 0.
    for bad in [f32::INFINITY, f32::NAN, -1.0] {
        let errors = vec![0.0, 1.0, bad, 2.0];
        match clipsat::bake::lod_tables::LevelTables::build(
            2,
            2,
            errors,
            clipsat::bake::lod_tables::P,
        )
        .map(|_| ())
        {
            Err(Error::Terrain { reason, .. }) => {
                assert!(reason.contains("column 0, row 1"), "{reason}")
            }
            other => panic!("{bad}: expected Error::Terrain, got {other:?}"),
        }
    }
}

/// The library names its options (`LoadOptions::raw`, `BakeOptions::max_error`); the binary prints the
/// flags that set them, so a CLI user never sees a library field.
#[test]
fn errors_name_flags_not_library_fields() {
    let dir = scratch("flag_words");
    let raw = dir.join("x.raw");
    std::fs::write(&raw, [0u8; 64]).expect("write fixture");
    let huge = dir.join("huge.png");
    std::fs::write(&huge, png_header(200_000, 200_000)).expect("write fixture");
    let pkg = dir.join("x.pkg");
    let (raw, huge, pkg) = (
        raw.to_string_lossy(),
        huge.to_string_lossy(),
        pkg.to_string_lossy(),
    );
    let cases: [(Vec<&str>, &str); 4] = [
        (
            vec!["info", "--terrain", &raw],
            "`--raw-size WxH` (and `--raw-format u16|f32`)",
        ),
        (vec!["info", "--terrain", &huge], "raise `--max-samples`"),
        (
            vec![
                "bake",
                "procedural:size=65",
                "--max-error",
                "0",
                "--out",
                &pkg,
            ],
            "argument `--max-error`",
        ),
        (
            vec!["bake", "procedural:size=65", "--tile", "5", "--out", &pkg],
            "argument `--tile`",
        ),
    ];
    for (args, needle) in &cases {
        let out = clipsat(args);
        assert_refused(&out, needle, &args.join(" "));
        let err = stderr(&out);
        assert!(
            !err.contains("Options::"),
            "{args:?}: names a library field: {err}"
        );
    }
}

/// `info --plot-projection` on a terrain that is not in degrees (the procedural one, a grid in metres) is
/// refused, naming the flag, and writes nothing; on a grid in degrees (an ASCII grid with a geographic
/// `.prj`, 2 x 2 samples) `info` prints its frame's distortion and the plot is written.
#[test]
fn plot_projection_needs_a_terrain_in_degrees() {
    let dir = scratch("projection");
    let png = dir.join("p.png");
    let out = png.to_string_lossy();
    let metres = dir.join("m.asc");
    std::fs::write(&metres, b"ncols 2\nnrows 2\ncellsize 5\n1 2\n3 4\n").expect("write fixture");
    let m = metres.to_string_lossy();
    for terrain in ["procedural:size=65", &*m] {
        let r = clipsat(&["info", "--terrain", terrain, "--plot-projection", &out]);
        assert_refused(&r, "argument `--plot-projection`", terrain);
        assert!(!png.exists(), "{terrain}: wrote {out}");
    }
    // 1 degree cells from 57 to 59 N: the frame is taken at 58 N.
    let deg = dir.join("g.asc");
    std::fs::write(
        &deg,
        b"ncols 2\nnrows 3\nxllcenter 11\nyllcenter 57\ncellsize 1\n1 2\n3 4\n5 6\n",
    )
    .expect("write fixture");
    std::fs::write(dir.join("g.prj"), br#"GEOGCS["WGS 84",DATUM["WGS_1984"]]"#).expect("write prj");
    let d = deg.to_string_lossy();
    let r = clipsat(&["info", "--terrain", &d, "--plot-projection", &out]);
    assert_eq!(r.status.code(), Some(0), "{}", stderr(&r));
    let text = String::from_utf8_lossy(&r.stdout);
    assert!(
        text.contains(
            "projection equirectangular about 58.000 N (the middle row): E-W lengths -2.70 % at the \
             south edge (57.000 N), +2.88 % at the north edge (59.000 N); N-S within 0.016 %"
        ),
        "{text}"
    );
    let bytes = std::fs::read(&png).expect("the plot is written");
    assert!(bytes.starts_with(b"\x89PNG"));
}

/// A FIFO given as a terrain (whatever its extension) or as imagery is refused as not a regular file:
/// the format sniffers opened it, which waits for a writer, and the command hung.
#[cfg(unix)]
#[test]
fn a_fifo_is_refused_not_waited_on() {
    let dir = scratch("fifo");
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).expect("create");
    let hm = generate(&ProceduralParams {
        size: 65,
        ..ProceduralParams::default()
    })
    .expect("terrain");
    let heights = dir.join("heights.f32");
    let bytes: Vec<u8> = hm.heights().iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(&heights, bytes).expect("write heights");
    let h = heights.to_string_lossy().to_string();
    for name in ["fifo.hgt", "fifo.tif", "fifo.clipsat", "fifo.png"] {
        let fifo = dir.join(name);
        let _ = std::fs::remove_file(&fifo);
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            return;
        }
        let f = fifo.to_string_lossy().to_string();
        let runs: [Vec<String>; 2] = [
            vec!["info".into(), "--terrain".into(), f.clone()],
            [
                "bake",
                "--terrain",
                &h,
                "--raw-size",
                "65x65",
                "--raw-format",
                "f32",
                "--imagery",
                &f,
                "--out",
            ]
            .iter()
            .map(ToString::to_string)
            .chain([dir.join("out.clipsat").to_string_lossy().to_string()])
            .collect(),
        ];
        for args in runs {
            // On a thread, so that a wait is a failure rather than a hang.
            let (tx, rx) = std::sync::mpsc::channel();
            let a = args.clone();
            std::thread::spawn(move || {
                let a: Vec<&str> = a.iter().map(String::as_str).collect();
                let _ = tx.send(clipsat(&a));
            });
            let out = rx
                .recv_timeout(std::time::Duration::from_secs(60))
                .unwrap_or_else(|_| panic!("{args:?}: still running after 60 s"));
            assert_refused(&out, "not a regular file", &format!("{args:?}"));
        }
    }
}
