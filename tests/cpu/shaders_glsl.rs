//! Every shader in `shaders_gles/`, assembled exactly as the renderer assembles it, must parse, validate
//! and translate with naga into GLSL ES 3.00 (`#version 300 es`) for every entry point.

use std::collections::BTreeSet;
use std::sync::OnceLock;

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

/// Every program parses and validates with no capability beyond the core (GLES 3.0 offers nothing more),
/// and each entry point translates to `#version 300 es` (a failure panics naming the program).
#[test]
fn every_entry_point_translates_to_glsl_es_300() {
    let texts = glsl_texts(300);
    for (i, ep, text) in texts {
        assert!(
            text.starts_with("#version 300 es"),
            "{}:{ep}: output does not start with #version 300 es",
            programs()[*i].0
        );
    }
    assert!(
        texts.len() >= 2,
        "expected at least the brute-force vertex and fragment entry points"
    );
}

/// A program as the renderer assembles it: its name, naga's module and its validation info.
pub(crate) type Program = (String, naga::Module, naga::valid::ModuleInfo);

/// Every program as the renderer assembles it: the plain files, every SG variant and the benchmark's
/// omissions, parsed and validated once for the whole test binary (unoptimised naga takes seconds over
/// them; five tests read them).
pub(crate) fn programs() -> &'static [Program] {
    static PROGRAMS: OnceLock<Vec<Program>> = OnceLock::new();
    PROGRAMS.get_or_init(|| {
        shaders::sources()
            .into_iter()
            .map(|(n, t)| (n.to_string(), t))
            .chain(shaders::sg_variants())
            .map(|(name, text)| {
                let module = naga::front::wgsl::parse_str(&text)
                    .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&text)));
                let info = Validator::new(ValidationFlags::all(), Capabilities::empty())
                    .validate(&module)
                    .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&text)));
                (name, module, info)
            })
            .collect()
    })
}

/// The GLSL ES texts of every program's entry points for `#version {version} es` (300 or 320), in
/// [`programs`]' order, written once for the test binary: (program index, entry point, text).
pub(crate) fn glsl_texts(version: u16) -> &'static [(usize, String, String)] {
    static ES300: OnceLock<Vec<(usize, String, String)>> = OnceLock::new();
    static ES320: OnceLock<Vec<(usize, String, String)>> = OnceLock::new();
    let cell = match version {
        300 => &ES300,
        320 => &ES320,
        _ => panic!("#version {version} es is not one a device gets"),
    };
    cell.get_or_init(|| {
        programs()
            .iter()
            .enumerate()
            .flat_map(|(i, (_, module, info))| {
                glsl_es(module, info, version)
                    .into_iter()
                    .map(move |(ep, text)| (i, ep, text))
            })
            .collect()
    })
}

/// The GLSL ES text of every entry point of `module` for `#version {version} es`, with the writer flags
/// wgpu's GL backend sets and its bounds-check policy on GLES (none: image loads are `Unchecked` there).
pub(crate) fn glsl_es(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    version: u16,
) -> Vec<(String, String)> {
    let options = glsl::Options {
        version: glsl::Version::Embedded {
            version,
            is_webgl: false,
        },
        writer_flags: glsl::WriterFlags::ADJUST_COORDINATE_SPACE
            | glsl::WriterFlags::FORCE_POINT_SIZE,
        ..Default::default()
    };
    module
        .entry_points
        .iter()
        .map(|ep| {
            let pipeline = glsl::PipelineOptions {
                shader_stage: ep.stage,
                entry_point: ep.name.clone(),
                multiview: None,
            };
            let mut out = String::new();
            glsl::Writer::new(
                &mut out,
                module,
                info,
                &options,
                &pipeline,
                naga::proc::BoundsCheckPolicies::default(),
            )
            .and_then(|mut w| w.write())
            .unwrap_or_else(|e| panic!("{}: {e}", ep.name));
            (ep.name.clone(), out)
        })
        .collect()
}

/// Default precision (GLSL ES 3.00 section 4.5.4): a fragment shader has no default float precision and
/// a mediump int, and samplers other than sampler2D / samplerCube have none; a texture lookup returns the
/// sampler's precision. A driver that honours mediump (Mali, Adreno, PowerVR) computes such values in
/// 16 bits. naga declares highp for float and int and on every sampler; this pins that, for the ES 3.00
/// text a GLES 3.0 device gets and the ES 3.20 text NVIDIA's and Mesa's ES 3.2 contexts get.
#[test]
fn glsl_es_declares_highp_everywhere() {
    let mut checked = 0;
    for version in [300, 320] {
        for (i, ep, text) in glsl_texts(version) {
            let name = &programs()[*i].0;
            let at = format!("{name}:{ep} (#version {version} es)");
            assert!(text.starts_with(&format!("#version {version} es")), "{at}");
            assert!(
                text.contains("precision highp float;"),
                "{at}: no highp float"
            );
            assert!(text.contains("precision highp int;"), "{at}: no highp int");
            for line in text.lines().filter(|l| l.contains("sampler")) {
                let uniform =
                    line.trim_start().starts_with("uniform ") || line.contains(") uniform ");
                if uniform {
                    assert!(line.contains(" highp "), "{at}: {line}");
                }
            }
            // No lowp or mediump anywhere.
            assert!(
                !text.contains("lowp") && !text.contains("mediump"),
                "{at}: reduced precision"
            );
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked} entry points");
}

/// The scalar kind of expression `e` of function `f` (its info `fi`).
fn kind_of(
    module: &naga::Module,
    fi: &naga::valid::FunctionInfo,
    e: naga::Handle<naga::Expression>,
) -> Option<naga::ScalarKind> {
    fi[e].ty.inner_with(&module.types).scalar_kind()
}

/// Float-to-integer conversions (GLSL ES 3.00 section 4.1.10: a float outside the integer's range, an
/// infinity or a NaN converts to an undefined value; x86 llvmpipe gives INT_MIN, NVIDIA saturates to
/// INT_MAX and takes NaN to 0): each must convert a value clamped in float first, `i32(clamp(x, lo, hi))`,
/// possibly through floor / ceil / round / trunc. Returns `function: expression` for each that is not.
fn unclamped_float_to_int(module: &naga::Module, info: &naga::valid::ModuleInfo) -> Vec<String> {
    use naga::{Expression as E, MathFunction as M, ScalarKind as K};
    let mut bad = Vec::new();
    let mut check = |name: &str, f: &naga::Function, fi: &naga::valid::FunctionInfo| {
        for (h, e) in f.expressions.iter() {
            let E::As {
                expr,
                kind: K::Sint | K::Uint,
                convert: Some(_),
            } = *e
            else {
                continue;
            };
            if kind_of(module, fi, expr) != Some(K::Float) {
                continue;
            }
            let mut x = expr;
            while let E::Math {
                fun: M::Floor | M::Ceil | M::Round | M::Trunc,
                arg,
                ..
            } = f.expressions[x]
            {
                x = arg;
            }
            let clamped = matches!(f.expressions[x], E::Math { fun: M::Clamp, .. })
                || matches!(f.expressions[x], E::Literal(_) | E::Constant(_));
            if !clamped {
                let shown = f
                    .named_expressions
                    .get(&expr)
                    .cloned()
                    .unwrap_or_else(|| format!("{:?}", f.expressions[x]));
                bad.push(format!("{name}: {:?} of `{shown}`", h));
            }
        }
    };
    for (h, f) in module.functions.iter() {
        check(f.name.as_deref().unwrap_or("?"), f, &info[h]);
    }
    for (i, ep) in module.entry_points.iter().enumerate() {
        check(&ep.name, &ep.function, info.get_entry_point(i));
    }
    bad
}

#[test]
fn float_to_int_conversions_are_clamped() {
    let mut bad = Vec::new();
    for (name, module, info) in programs() {
        for b in unclamped_float_to_int(module, info) {
            bad.push(format!("{name}: {b}"));
        }
    }
    bad.dedup();
    assert!(
        bad.is_empty(),
        "unclamped float-to-int conversions:\n{}",
        bad.join("\n")
    );
}

/// Which functions compute a derivative, and which may discard, each with the functions it calls.
fn reaches(
    module: &naga::Module,
    own: impl Fn(&naga::Function) -> bool,
) -> std::collections::HashSet<naga::Handle<naga::Function>> {
    let mut set = std::collections::HashSet::new();
    loop {
        let before = set.len();
        for (h, f) in module.functions.iter() {
            let calls = f
                .expressions
                .iter()
                .any(|(_, e)| matches!(e, naga::Expression::CallResult(c) if set.contains(c)))
                || calls_any(&f.body, &set);
            if own(f) || calls {
                set.insert(h);
            }
        }
        if set.len() == before {
            return set;
        }
    }
}

fn calls_any(
    block: &naga::Block,
    set: &std::collections::HashSet<naga::Handle<naga::Function>>,
) -> bool {
    let mut found = false;
    walk(block, &mut |s| {
        if let naga::Statement::Call { function, .. } = s {
            found |= set.contains(function);
        }
    });
    found
}

/// Visits every statement of `block` in program order, nested blocks included.
fn walk(block: &naga::Block, visit: &mut dyn FnMut(&naga::Statement)) {
    use naga::Statement as S;
    for s in block.iter() {
        visit(s);
        match s {
            S::Block(b) => walk(b, visit),
            S::If { accept, reject, .. } => {
                walk(accept, visit);
                walk(reject, visit);
            }
            S::Switch { cases, .. } => cases.iter().for_each(|c| walk(&c.body, visit)),
            S::Loop {
                body, continuing, ..
            } => {
                // Twice: a discard late in the body precedes the next iteration's start.
                for _ in 0..2 {
                    walk(body, visit);
                    walk(continuing, visit);
                }
            }
            _ => {}
        }
    }
}

/// Derivatives after a possible `discard` (GLSL ES 3.00 section 8.9: derivatives are undefined in
/// non-uniform control flow). WGSL's `discard` demotes the invocation to a helper, so WGSL allows them;
/// naga writes GLSL's `discard`, which may end the invocation and leave its quad's neighbours without a
/// partner. Returns the fragment entry points that compute one after a discard.
fn derivatives_after_discard(module: &naga::Module) -> Vec<String> {
    let has_derivative = |f: &naga::Function| {
        f.expressions
            .iter()
            .any(|(_, e)| matches!(e, naga::Expression::Derivative { .. }))
    };
    let has_kill = |f: &naga::Function| {
        let mut k = false;
        walk(&f.body, &mut |s| k |= matches!(s, naga::Statement::Kill));
        k
    };
    let derives = reaches(module, has_derivative);
    let kills = reaches(module, has_kill);
    let mut bad = Vec::new();
    for ep in module
        .entry_points
        .iter()
        .filter(|ep| ep.stage == naga::ShaderStage::Fragment)
    {
        let f = &ep.function;
        let mut killed = false;
        walk(&f.body, &mut |s| match s {
            naga::Statement::Kill => killed = true,
            naga::Statement::Emit(range) => {
                for h in range.clone() {
                    if killed && matches!(f.expressions[h], naga::Expression::Derivative { .. }) {
                        bad.push(format!("{}: a derivative after discard", ep.name));
                    }
                }
            }
            naga::Statement::Call { function, .. } => {
                if killed && derives.contains(function) {
                    let callee = module.functions[*function].name.clone().unwrap_or_default();
                    bad.push(format!(
                        "{}: calls {callee} (a derivative) after discard",
                        ep.name
                    ));
                }
                killed |= kills.contains(function);
            }
            _ => {}
        });
    }
    bad
}

#[test]
fn derivatives_come_before_any_discard() {
    let mut bad = Vec::new();
    for (name, module, _) in programs() {
        for b in derivatives_after_discard(module) {
            bad.push(format!("{name}: {b}"));
        }
    }
    bad.dedup();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}
