//! `clipsat view` under a virtual X display: starts `Xvfb`, opens the window, flies it with real X input
//! events from `xdotool` (W held, a mouse-look drag, V for the level-colour view, 1 for SG shading),
//! screenshots the display with `xwd` and checks the pictures are not blank and that the keys changed
//! what is drawn. The screenshots are saved as examples/pictures/view-xvfb.png (normal view) and
//! view-xvfb-sg.png (SG shading).
//!
//! `view_frames_json_under_xvfb` runs the non-interactive measurement (`--frames 8 --json`) and checks the
//! window got an OpenGL ES 3.0 context and that both paths were timed, then again streamed from a package.
//!
//! Ignored by default (needs Xvfb, xdotool and xwd, and takes about a minute on llvmpipe):
//! `bash .ci/view-xvfb`, or `cargo test --test cli view_xvfb -- --ignored --nocapture`.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::thread::sleep;
use std::time::{Duration, Instant};

const W: u32 = 640;
const H: u32 = 360;
/// Seconds allowed for the SG switch: the normal-SAT bake of the 1025^2 terrain, then frames.
const SG_WAIT_S: u64 = 15;

/// Kills and reaps a child process when dropped (the test's own Xvfb and viewer only).
struct Reaped(Child);

impl Drop for Reaped {
    fn drop(&mut self) {
        // SIGTERM first, so Xvfb removes its lock file and socket; SIGKILL if it lingers.
        let pid = self.0.id().to_string();
        let _ = Command::new("kill").args(["-TERM", &pid]).status();
        for _ in 0..50 {
            if matches!(self.0.try_wait(), Ok(Some(_))) {
                return;
            }
            sleep(Duration::from_millis(100));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn have(tool: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

fn run(display: &str, cmd: &str, args: &[&str]) -> Output {
    Command::new(cmd)
        .args(args)
        .env("DISPLAY", display)
        .output()
        .unwrap_or_else(|e| panic!("{cmd}: {e}"))
}

fn xdotool(display: &str, args: &[&str]) {
    let out = run(display, "xdotool", args);
    assert!(
        out.status.success(),
        "xdotool {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A tight RGB8 picture of the whole X screen, from `xwd -root` (XWD format, version 7, ZPixmap).
fn screenshot(display: &str) -> (u32, u32, Vec<u8>) {
    let out = run(display, "xwd", &["-root", "-silent"]);
    assert!(
        out.status.success(),
        "xwd: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    parse_xwd(&out.stdout)
}

fn parse_xwd(data: &[u8]) -> (u32, u32, Vec<u8>) {
    let field = |i: usize| {
        let b = &data[i * 4..i * 4 + 4];
        u32::from_be_bytes([b[0], b[1], b[2], b[3]])
    };
    assert!(data.len() >= 100, "xwd: {} bytes", data.len());
    let (header, version, format) = (field(0) as usize, field(1), field(2));
    assert_eq!((version, format), (7, 2), "xwd: version 7 ZPixmap expected");
    let (w, h) = (field(4), field(5));
    let (byte_order, bpp, stride) = (field(7), field(11), field(12) as usize);
    let masks = [field(14), field(15), field(16)];
    let ncolors = field(19) as usize;
    assert_eq!(bpp, 32, "xwd: 32 bits per pixel expected");
    let start = header + 12 * ncolors;
    let mut rgb = Vec::with_capacity(w as usize * h as usize * 3);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let at = start + y * stride + x * 4;
            let b = [data[at], data[at + 1], data[at + 2], data[at + 3]];
            let v = if byte_order == 0 {
                u32::from_le_bytes(b)
            } else {
                u32::from_be_bytes(b)
            };
            for m in masks {
                let c = (v & m) >> m.trailing_zeros();
                rgb.push(u8::try_from(c).unwrap_or(u8::MAX));
            }
        }
    }
    (w, h, rgb)
}

fn distinct_colours(rgb: &[u8]) -> usize {
    let mut seen: Vec<[u8; 3]> = rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    seen.sort_unstable();
    seen.dedup();
    seen.len()
}

/// Whether the tools the tests need are installed (if not: skipped with the reason, a failure under CI=true).
fn tools_present() -> bool {
    let missing: Vec<&str> = ["Xvfb", "xdotool", "xwd"]
        .into_iter()
        .filter(|t| !have(t))
        .collect();
    if missing.is_empty() {
        return true;
    }
    let why = format!("missing {missing:?} (bash .ci/view-xvfb installs them)");
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!("{why}");
    }
    eprintln!("skipped: {why}");
    false
}

/// Starts a private Xvfb of `w` x `h`; returns it (killed on drop) and its display name. Xvfb picks a free
/// display number itself (`-displayfd`: it takes the first whose lock file it can create, atomically,
/// and writes the number to the descriptor once it accepts connections), so two tests, or two processes
/// (another checkout's CI run), never race for one: picking a number that looked free and starting
/// Xvfb on it lost that race ("Xvfb :91 did not start").
fn start_xvfb(w: u32, h: u32) -> (Reaped, String) {
    use std::io::BufRead as _;
    let mut child = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            &format!("{w}x{h}x24"),
            "-nolisten",
            "tcp",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("Xvfb");
    let stdout = child.stdout.take().expect("Xvfb's stdout");
    let xvfb = Reaped(child);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = std::io::BufReader::new(stdout).read_line(&mut line);
        let _ = tx.send(line);
    });
    let line = rx
        .recv_timeout(Duration::from_secs(20))
        .unwrap_or_else(|_| panic!("Xvfb did not report a display within 20 s"));
    let n: u32 = line
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("Xvfb reported no display number: {line:?}"));
    let socket = PathBuf::from(format!("/tmp/.X11-unix/X{n}"));
    assert!(
        socket.exists(),
        "Xvfb :{n} reported ready without its socket"
    );
    (xvfb, format!(":{n}"))
}

/// `--frames N --json`: the window draws in an OpenGL ES 3.0 context, times its frames, then times the
/// headless `render` path at the same size in the same run.
#[test]
#[ignore = "needs Xvfb; run: bash .ci/view-xvfb"]
fn view_frames_json_under_xvfb() {
    if !tools_present() {
        return;
    }
    let (_xvfb, display) = start_xvfb(W, H);
    let out = Command::new(env!("CARGO_BIN_EXE_clipsat"))
        .args([
            "view",
            "--size",
            &format!("{W}x{H}"),
            "--frames",
            "8",
            "--json",
            // The terrain loaded whole: streamed (the default, checked below over a package), the
            // built-in 1025^2 terrain's fill (decode included) outlasts 8 frames, leaving none to time.
            "--resident",
        ])
        .env("DISPLAY", &display)
        .env("CLIPSAT_CACHE", super::cache_dir())
        .output()
        .expect("clipsat view");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "clipsat view --frames: {stderr}");
    let j: serde_json::Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("stdout is not one JSON document: {e}\n{stderr}"));
    eprintln!("{j:#}");
    assert_eq!(
        (j["width"].as_u64(), j["height"].as_u64()),
        (Some(W.into()), Some(H.into()))
    );
    assert_eq!(j["frames"], 8);
    assert_eq!(j["streamed"], false, "{j}");
    let context = j["window"]["context"].as_str().unwrap_or_default();
    assert!(
        j["window"]["gles30"] == true && context.starts_with("OpenGL ES 3.0"),
        "the window's context is not OpenGL ES 3.0: {context}"
    );
    for path in ["window", "headless_render"] {
        let mean = j[path]["times"]["mean_ms"].as_f64();
        assert!(
            mean.is_some_and(|m| m > 0.0),
            "{path}: no mean ms/frame in {j}"
        );
    }
    assert!(j["headless_over_window_mean"]
        .as_f64()
        .is_some_and(|r| r > 0.0));

    // A package streams through the tile cache, the window and the headless path
    // alike, with the SAT LOD tables mapped.
    let pkg =
        std::env::temp_dir().join(format!("clipsat-view-xvfb-{}.clipsat", std::process::id()));
    let p = pkg.to_string_lossy().into_owned();
    let baked = Command::new(env!("CARGO_BIN_EXE_clipsat"))
        .args(["bake", "procedural:size=257", "--out", &p, "--json"])
        .output()
        .expect("clipsat bake");
    assert!(baked.status.success(), "clipsat bake: {baked:?}");
    let out = Command::new(env!("CARGO_BIN_EXE_clipsat"))
        .args([
            "view",
            "--terrain",
            &p,
            "--lod",
            "sat",
            "--size",
            &format!("{W}x{H}"),
            "--frames",
            "4",
            "--json",
        ])
        .env("DISPLAY", &display)
        .env("CLIPSAT_CACHE", super::cache_dir())
        .output()
        .expect("clipsat view P.clipsat");
    let _ = std::fs::remove_file(&pkg);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "clipsat view P.clipsat: {stderr}");
    let j: serde_json::Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("stdout is not one JSON document: {e}\n{stderr}"));
    assert_eq!(j["streamed"], true, "{j}");
    assert_eq!(j["frames"], 4, "{j}");
    assert!(
        j["headless_render"]["times"]["mean_ms"]
            .as_f64()
            .is_some_and(|m| m > 0.0),
        "{j}"
    );
}

#[test]
#[ignore = "needs Xvfb, xdotool and xwd; run: bash .ci/view-xvfb"]
fn view_flies_under_xvfb() {
    if !tools_present() {
        return;
    }
    let (_xvfb, display) = start_xvfb(W, H);

    let mut view = Reaped(
        Command::new(env!("CARGO_BIN_EXE_clipsat"))
            .args([
                "view",
                // gles3-mid: the smallest shipped profile that allows SG shading (key 1).
                "--profile",
                "gles3-mid",
                "--size",
                &format!("{W}x{H}"),
                "--exit-after",
                "120",
            ])
            .env("DISPLAY", &display)
            .env("CLIPSAT_CACHE", super::cache_dir())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("clipsat view"),
    );
    // Wait for the window and its first frames.
    let t0 = Instant::now();
    let window = loop {
        let out = run(&display, "xdotool", &["search", "--name", "clipsat view"]);
        let ids = String::from_utf8_lossy(&out.stdout);
        if let Some(id) = ids
            .split_whitespace()
            .next()
            .filter(|_| out.status.success())
        {
            break id.to_string();
        }
        if let Ok(Some(status)) = view.0.try_wait() {
            panic!("clipsat view exited early: {status}");
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no clipsat view window"
        );
        sleep(Duration::from_millis(200));
    };
    sleep(Duration::from_secs(4));
    let (_, _, start) = screenshot(&display);

    // There is no window manager to give the window the keyboard focus: take it, then fly.
    xdotool(&display, &["windowfocus", "--sync", &window]);
    let (cx, cy) = ((W / 2).to_string(), (H / 2).to_string());
    xdotool(&display, &["mousemove", &cx, &cy]);
    xdotool(&display, &["keydown", "w"]);
    sleep(Duration::from_millis(2500));
    xdotool(&display, &["keyup", "w"]);
    xdotool(&display, &["mousedown", "1"]);
    for _ in 0..10 {
        xdotool(&display, &["mousemove_relative", "--", "-8", "2"]);
        sleep(Duration::from_millis(50));
    }
    xdotool(&display, &["mouseup", "1"]);
    sleep(Duration::from_secs(2));
    let (w, h, flown) = screenshot(&display);
    xdotool(&display, &["key", "v"]);
    sleep(Duration::from_secs(3));
    let (_, _, levels) = screenshot(&display);
    // V twice more is back to the normal view; 1 switches to SG shading (the first switch bakes the
    // shading SATs of the scene, noon: the normal SAT only). 2 asks for visibility, which gles3-mid does
    // not allow: refused, with the reason, and the SG frame stays.
    xdotool(&display, &["key", "v"]);
    xdotool(&display, &["key", "v"]);
    xdotool(&display, &["key", "1"]);
    sleep(Duration::from_secs(SG_WAIT_S));
    xdotool(&display, &["key", "2"]);
    sleep(Duration::from_secs(2));
    let (_, _, sg) = screenshot(&display);
    // 1 twice: SG off and on again, each a switch of the renderer built above (the SG tables
    // are never re-created on a toggle), back to the same SG frame.
    xdotool(&display, &["key", "1"]);
    sleep(Duration::from_secs(2));
    xdotool(&display, &["key", "1"]);
    sleep(Duration::from_secs(3));
    let (_, _, sg_again) = screenshot(&display);
    // 4: fog, which noon gives no parameters for, so no effect: a switch too, nothing built. (The effect
    // switches within a built renderer are `tests/gpu/sg_gpu.rs`'s; gles3-mid allows no other effect.)
    xdotool(&display, &["key", "4"]);
    sleep(Duration::from_secs(2));
    xdotool(&display, &["key", "Escape"]);

    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = view.0.try_wait().expect("wait") {
            break s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "Escape did not close the window"
        );
        sleep(Duration::from_millis(100));
    };
    let mut stdout = String::new();
    let mut stderr = String::new();
    use std::io::Read as _;
    if let Some(mut s) = view.0.stdout.take() {
        let _ = s.read_to_string(&mut stdout);
    }
    if let Some(mut s) = view.0.stderr.take() {
        let _ = s.read_to_string(&mut stderr);
    }
    eprintln!("clipsat view stdout: {stdout}\nstderr: {stderr}");
    assert!(status.success(), "clipsat view: {status}\n{stderr}");

    let pictures = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/pictures");
    std::fs::create_dir_all(&pictures).expect("examples/pictures");
    let png = pictures.join("view-xvfb.png");
    image::save_buffer(&png, &flown, w, h, image::ExtendedColorType::Rgb8)
        .expect("save screenshot");
    eprintln!("screenshot: {}", png.display());
    let png_sg = pictures.join("view-xvfb-sg.png");
    image::save_buffer(&png_sg, &sg, w, h, image::ExtendedColorType::Rgb8)
        .expect("save screenshot");
    eprintln!("screenshot: {}", png_sg.display());

    // Shaded terrain has thousands of colours (hundreds in grey); the level view's flat colours under a
    // Lambert factor and the stats text a few hundred. A blank or single-colour window has a handful.
    for (name, shot, least) in [
        ("start", &start, 1000),
        ("flown", &flown, 1000),
        ("levels", &levels, 100),
        // The noon scene's material is grey: fewer colours, still far from blank.
        ("sg", &sg, 150),
    ] {
        let colours = distinct_colours(shot);
        eprintln!("{name} screenshot: {colours} colours");
        assert!(
            colours > least,
            "{name} screenshot: only {colours} colours (blank?)"
        );
    }
    assert_ne!(start, flown, "W and the mouse drag did not move the camera");
    assert_ne!(flown, levels, "V did not change the view");
    assert_ne!(flown, sg, "1 did not switch to SG shading");
    assert!(
        stderr.contains("baking the shading SATs"),
        "key 1 baked nothing: {stderr}"
    );
    assert_eq!(
        stderr.matches("baking the shading SATs").count(),
        1,
        "SG off and on again baked again: {stderr}"
    );
    for state in ["off", "on (vis off, spec off, fog off)"] {
        assert!(
            stderr.contains(&format!("SG shading {state} (switched")),
            "SG {state} was not a switch of the built renderer: {stderr}"
        );
    }
    // SG on again, and fog on (no effect here): both switches.
    assert_eq!(
        stderr
            .matches("SG shading on (vis off, spec off, fog off) (switched")
            .count(),
        2,
        "fog on was not a switch of the built renderer: {stderr}"
    );
    // The same SG frame again, but for the stats text.
    let differing = sg
        .chunks(3)
        .zip(sg_again.chunks(3))
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        differing * 50 < sg.len() / 3,
        "SG off and on again: {differing} pixels differ from the first SG frame"
    );
    assert!(
        stderr.contains("switch refused"),
        "key 2 (visibility, not in gles3-mid) was not refused: {stderr}"
    );
    assert!(
        stdout.contains("ms/frame"),
        "no frame-time summary on stdout: {stdout}"
    );
}
