//! Every shader in `shaders_gles/`, assembled exactly as the renderer assembles it, must parse, validate
//! and translate with naga into GLSL ES 3.00 (`#version 300 es`) for every entry point.

use std::collections::BTreeSet;

use clipsat::gpu::shaders;
use naga::back::glsl;
use naga::valid::{Capabilities, ValidationFlags, Validator};

#[test]
fn every_shader_file_is_assembled() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders_gles");
    let on_disk: BTreeSet<String> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|entry| {
            let name = entry.ok()?.file_name().to_string_lossy().into_owned();
            name.ends_with(".wgsl").then_some(name)
        })
        .collect();
    let assembled: BTreeSet<String> = shaders::sources()
        .into_iter()
        .map(|(name, _)| name.to_string())
        .collect();
    assert_eq!(
        on_disk, assembled,
        "gpu::shaders::sources() must list every shaders_gles/*.wgsl file"
    );
}

#[test]
fn every_entry_point_translates_to_glsl_es_300() {
    let mut failures = Vec::new();
    let mut translated = 0;
    let all = shaders::sources()
        .into_iter()
        .map(|(n, t)| (n.to_string(), t))
        .chain(shaders::sg_variants());
    for (name, text) in all {
        let module = match naga::front::wgsl::parse_str(&text) {
            Ok(m) => m,
            Err(e) => {
                failures.push(format!("{name}: parse: {}", e.emit_to_string(&text)));
                continue;
            }
        };
        // No capabilities beyond the core: GLES 3.0 offers nothing more.
        let info =
            match Validator::new(ValidationFlags::all(), Capabilities::empty()).validate(&module) {
                Ok(i) => i,
                Err(e) => {
                    failures.push(format!("{name}: validate: {}", e.emit_to_string(&text)));
                    continue;
                }
            };
        let options = glsl::Options {
            version: glsl::Version::Embedded {
                version: 300,
                is_webgl: false,
            },
            ..Default::default()
        };
        for ep in &module.entry_points {
            let pipeline = glsl::PipelineOptions {
                shader_stage: ep.stage,
                entry_point: ep.name.clone(),
                multiview: None,
            };
            let mut out = String::new();
            let result = glsl::Writer::new(
                &mut out,
                &module,
                &info,
                &options,
                &pipeline,
                naga::proc::BoundsCheckPolicies::default(),
            )
            .and_then(|mut w| w.write());
            match result {
                Ok(_) if out.starts_with("#version 300 es") => translated += 1,
                Ok(_) => failures.push(format!(
                    "{name}:{}: output does not start with #version 300 es",
                    ep.name
                )),
                Err(e) => failures.push(format!("{name}:{}: GLSL ES 3.00: {e}", ep.name)),
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(
        translated >= 2,
        "expected at least the brute-force vertex and fragment entry points"
    );
}
