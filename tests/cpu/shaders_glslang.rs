//! Every GLSL ES program naga writes for clipsat (each file, each SG variant, each entry point) in both
//! versions a device gets, `#version 300 es` (a GLES 3.0 device) and `320 es` (an ES 3.2 context such as
//! NVIDIA's or Mesa's), through the Khronos reference compiler, `glslangValidator` (Debian's
//! `glslang-tools`, which `.ci/setup` installs): no error and no warning. Mesa's compiler accepts some
//! programs a stricter driver's refuses; glslang follows the specification's text.
//!
//! Without `glslangValidator` the test skips with a printed reason, and fails under `CI=true`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use super::shaders_glsl::{glsl_texts, programs};

const GLSLANG: &str = "glslangValidator";

/// glslang's stage suffix for an entry point's stage.
fn stage(module: &naga::Module, entry: &str) -> &'static str {
    match module.entry_points.iter().find(|e| e.name == entry) {
        Some(e) if e.stage == naga::ShaderStage::Fragment => "frag",
        Some(e) if e.stage == naga::ShaderStage::Vertex => "vert",
        other => panic!("{entry}: no vertex or fragment entry point ({other:?})"),
    }
}

/// Programs a call: glslang compiles each file apart (no link without `-l`) and names each before its
/// messages; one process per program cost 4x the time.
const BATCH: usize = 64;

#[test]
fn every_glsl_es_program_passes_the_reference_compiler() {
    if Command::new(GLSLANG).arg("--version").output().is_err() {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "{GLSLANG} is missing (CI installs glslang-tools through .ci/setup)"
        );
        eprintln!(
            "skipped: {GLSLANG} not found (apt-get install glslang-tools, or bash .ci/setup)"
        );
        return;
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("glslang");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder");
    // Each distinct text once (SG variants share many entry points), named after its first program.
    let mut seen = HashMap::new();
    let mut files: Vec<(PathBuf, String)> = Vec::new();
    let mut programs_checked = 0;
    for version in [300u16, 320] {
        for (i, entry, text) in glsl_texts(version) {
            let (name, module, _) = &programs()[*i];
            programs_checked += 1;
            let label = format!("{name}:{entry} (#version {version} es)");
            if seen.insert(text.clone(), label.clone()).is_some() {
                continue;
            }
            let file = dir.join(format!("{}.{}", files.len(), stage(module, entry)));
            std::fs::write(&file, text).expect("write the program");
            files.push((file, label));
        }
    }
    let chunks: Vec<&[(PathBuf, String)]> = files.chunks(BATCH).collect();
    let problems: Vec<String> = std::thread::scope(|s| {
        let (even, odd): (Vec<_>, Vec<_>) =
            chunks.iter().enumerate().partition(|(i, _)| i % 2 == 0);
        let run = |part: Vec<(usize, &&[(PathBuf, String)])>| {
            part.into_iter()
                .flat_map(|(_, c)| compile(c))
                .collect::<Vec<_>>()
        };
        let a = s.spawn(move || run(even));
        let mut out = run(odd);
        out.extend(a.join().expect("glslang thread"));
        out
    });
    assert!(
        problems.is_empty(),
        "{} of {} distinct programs:\n{}",
        problems.len(),
        files.len(),
        problems.join("\n")
    );
    assert!(programs_checked > 1000, "{programs_checked} programs");
}

/// One glslangValidator call over `batch`: each program's messages (errors and warnings alike), with its
/// label and file.
fn compile(batch: &[(PathBuf, String)]) -> Vec<String> {
    let out = Command::new(GLSLANG)
        .args(batch.iter().map(|(f, _)| f))
        .output()
        .expect("run glslangValidator");
    let said =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    // A file's name on a line of its own opens its section; any other non-empty line is a finding.
    let mut findings: HashMap<&Path, Vec<&str>> = HashMap::new();
    let mut current: Option<&Path> = None;
    for line in said.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if let Some((f, _)) = batch.iter().find(|(f, _)| f.as_os_str() == line) {
            current = Some(f);
        } else {
            findings
                .entry(current.unwrap_or(Path::new("?")))
                .or_default()
                .push(line);
        }
    }
    let mut problems: Vec<String> = batch
        .iter()
        .filter_map(|(f, label)| {
            let lines = findings.remove(f.as_path())?;
            Some(format!(
                "{label} ({}):\n  {}",
                f.display(),
                lines.join("\n  ")
            ))
        })
        .collect();
    problems.extend(findings.into_values().map(|l| l.join("\n  ")));
    if !out.status.success() && problems.is_empty() {
        problems.push(format!(
            "glslangValidator exited {} with no message",
            out.status
        ));
    }
    problems
}

/// The check can fail: a program glslang refuses (no default float precision in a fragment shader, GLSL
/// ES 3.00 section 4.5.4, which Mesa's compiler does not enforce), and one it warns about, are reported.
#[test]
fn the_reference_compiler_reports_an_error_and_a_warning() {
    if Command::new(GLSLANG).arg("--version").output().is_err() {
        return;
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("glslang-bad");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let bad = dir.join("bad.frag");
    let warned = dir.join("warned.frag");
    let good = dir.join("good.frag");
    let write = |f: &Path, body: &str| std::fs::write(f, format!("#version 300 es\n{body}\n"));
    write(&bad, "out vec4 c; void main() { c = vec4(1.0); }").expect("write");
    // A `#extension` glslang does not know: a warning, and the program compiles.
    write(
        &warned,
        "#extension GL_NO_SUCH_extension : enable\nprecision highp float; out vec4 c;\nvoid main() { c = vec4(1.0); }",
    )
    .expect("write");
    write(
        &good,
        "precision highp float; out vec4 c;\nvoid main() { c = vec4(1.0); }",
    )
    .expect("write");
    let batch = [
        (bad.clone(), "bad".to_string()),
        (warned.clone(), "warned".to_string()),
        (good, "good".to_string()),
    ];
    let problems = compile(&batch);
    assert_eq!(problems.len(), 2, "{problems:#?}");
    assert!(
        problems[0].starts_with("bad") && problems[0].contains("ERROR"),
        "{problems:#?}"
    );
    assert!(
        problems[1].starts_with("warned") && problems[1].contains("WARNING"),
        "{problems:#?}"
    );
}
