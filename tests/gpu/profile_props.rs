//! Budget profiles under random and extreme values: no profile text panics. Each is either refused with
//! an [`Error::Config`] naming a field, or it validates and then every later stage built from it works:
//! the meshes, the footprint within the budget, a clipmap, one planned frame and its draw list, and (for
//! the first few small ones) a GPU renderer. About 300 cases, a few seconds.

use crate::render_support;

use std::cell::Cell;
use std::path::Path;
use std::sync::OnceLock;

use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::cull::{build_draws, DrawList, DrawParams};
use clipsat::plan::mesh;
use clipsat::profile::{Profile, MAX_N};
use clipsat::source::Heightmap;
use clipsat::Error;
use glam::DVec3;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed, TestRunner};

/// Values that break arithmetic: zero, one, powers of two and their neighbours, the top of u32.
fn extreme_u32() -> impl Strategy<Value = u32> {
    prop_oneof![
        Just(0u32),
        Just(1),
        Just(u32::MAX),
        Just(u32::MAX - 1),
        Just(1 << 31),
        Just((1 << 31) - 1),
        (0u32..32).prop_map(|k| 1u32 << k),
        (1u32..32).prop_map(|k| (1u32 << k) - 1),
        (1u32..32).prop_map(|k| (1u32 << k) + 1),
        any::<u32>(),
    ]
}

/// Mostly plausible values (`typical`), sometimes extreme ones: with 14 fields, about a third of the
/// profiles have every field in range and exercise the later stages.
fn field(typical: impl Strategy<Value = u32> + 'static) -> BoxedStrategy<u32> {
    prop_oneof![12 => typical, 1 => extreme_u32()].boxed()
}

fn float(typical: std::ops::Range<f32>) -> BoxedStrategy<String> {
    prop_oneof![
        12 => typical.prop_map(|v| format!("{v:?}")),
        1 => prop::sample::select(vec![
            "0.0", "-1.0", "nan", "inf", "-inf", "1e-45", "3.4028235e38", "1e300", "179.0", "1.0",
        ])
        .prop_map(str::to_owned),
    ]
    .boxed()
}

/// A byte budget: mostly 16 MiB .. 512 GiB, sometimes 0, the top of u64 or anything.
fn memory() -> impl Strategy<Value = u64> {
    prop_oneof![
        1 => Just(0u64),
        1 => Just(u64::MAX),
        8 => (24u32..40).prop_map(|k| 1u64 << k),
        1 => any::<u64>()
    ]
}

/// A whole profile text: every field drawn, features a random non-empty or empty subset.
fn profile_text() -> impl Strategy<Value = String> {
    let clipmap = (
        field(prop::sample::select(vec![
            15u32, 31, 63, 127, 255, 511, 15, 31, 63, 1023, 2047,
        ])),
        field(1u32..18),
        field(prop_oneof![0u32..40, 0u32..1100]),
    );
    let budget = (
        field(1u32..300_000),
        field(prop_oneof![1u32..2049, 0u32..5000]),
        field(1u32..2_000_000),
        memory(),
        memory(),
    );
    let view = (
        float(0.1..20.0),
        field(1u32..2100),
        field(1u32..2100),
        float(2.0..178.0),
    );
    let shading = (
        prop::sample::subsequence(
            vec!["basic", "sg", "visibility", "specular", "fog", "synthesis"],
            0..=6,
        ),
        field(0u32..10),
    );
    (clipmap, budget, view, shading).prop_map(|((n, l, m), (u, d, t, g, c), (e, w, h, f), (fs, s))| {
        let fs: Vec<String> = fs.iter().map(|f| format!("\"{f}\"")).collect();
        format!(
            "name = \"prop\"\n[clipmap]\nn = {n}\nlevels = {l}\nclip_margin = {m}\n\
             [budget]\nupdate_samples_per_frame = {u}\nmax_draws = {d}\nmax_triangles = {t}\n\
             gpu_memory_bytes = {g}\ncpu_memory_bytes = {c}\n[view]\nepsilon_px = {e}\nwidth = {w}\nheight = {h}\n\
             fov_y_deg = {f}\n[shading]\nfeatures = [{}]\nmax_sg_lights = {s}\n",
            fs.join(", ")
        )
    })
}

/// A profile text with one line's value replaced by something out of range or of the wrong type.
fn damaged_text() -> impl Strategy<Value = String> {
    (
        profile_text(),
        any::<prop::sample::Index>(),
        prop::sample::select(vec![
            "-1",
            "4294967296",
            "18446744073709551616",
            "1e400",
            "\"x\"",
            "[]",
            "{}",
            "true",
            "",
        ]),
    )
        .prop_map(|(text, at, value)| {
            let lines: Vec<&str> = text.lines().collect();
            let i = at.index(lines.len());
            lines
                .iter()
                .enumerate()
                .map(|(j, l)| match l.split_once('=') {
                    Some((k, _)) if j == i => format!("{k}= {value}"),
                    _ => (*l).to_owned(),
                })
                .collect::<Vec<_>>()
                .join("\n")
        })
}

fn terrain() -> &'static Heightmap {
    static T: OnceLock<Heightmap> = OnceLock::new();
    T.get_or_init(|| {
        let n = 65u32;
        let heights = (0..n * n)
            .map(|i| {
                let (u, v) = ((i % n) as f32, (i / n) as f32);
                40.0 * (u * 0.2).sin() * (v * 0.15).cos() + u
            })
            .collect();
        Heightmap::new(Path::new("<props>"), n, n, 30.0, heights).expect("terrain")
    })
}

/// Ring heights small enough to allocate a clipmap per case.
const CLIPMAP_BYTES: u64 = 48 << 20;
/// Renderers built (each compiles its pipelines): the first few valid small profiles.
const RENDERERS: u32 = 4;

/// How far a profile got: refused, validated, clipmap and plan built, renderer built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Reached {
    Refused,
    Validated,
    Planned,
    Rendered,
}

/// What one profile text must satisfy; returns how far it got.
fn check(text: &str, gpu: Option<&clipsat::gpu::Gpu>) -> Reached {
    let p = match Profile::parse("prop.toml", text) {
        Ok(p) => p,
        Err(Error::Config { field, reason, .. }) => {
            assert!(
                !field.is_empty() && !reason.is_empty(),
                "an empty error for:\n{text}"
            );
            return Reached::Refused;
        }
        Err(other) => panic!("expected Error::Config, got {other} for:\n{text}"),
    };
    // Whatever validates keeps every later stage inside its types.
    assert!(p.clipmap.n <= MAX_N && (p.clipmap.n + 1).is_power_of_two());
    assert!(p.footprint().total() <= p.budget.gpu_memory_bytes);
    let block = mesh::block(p.block_m());
    assert_eq!(block.triangles(), 2 * p.block_m() * p.block_m());
    let _ = mesh::skirt(p.clipmap.n + 1);
    let _ = mesh::skirt_loops(p.block_m());
    if p.footprint().heights > CLIPMAP_BYTES {
        return Reached::Validated;
    }
    let mut cm = match Clipmap::new(terrain(), &p, ClipmapOptions::default()) {
        Ok(cm) => cm,
        // A budget below one ring row is refused here, by name.
        Err(Error::Config { field, .. }) => {
            assert_eq!(field, "budget.update_samples_per_frame", "{text}");
            return Reached::Validated;
        }
        Err(other) => panic!("clipmap: {other} for:\n{text}"),
    };
    let eye = DVec3::new(900.0, 900.0, 400.0);
    cm.update(eye).expect("update");
    let camera = Camera::new(
        eye,
        DVec3::new(1200.0, 1300.0, 0.0),
        f64::from(p.view.fov_y_deg),
    )
    .expect("camera");
    let params = DrawParams {
        block_quads: p.block_m(),
        max_draws: p.budget.max_draws,
        cull: true,
        skirts: true,
        aspect: f64::from(p.view.width) / f64::from(p.view.height),
        extent: [-1e9, -1e9, 1e9, 1e9],
    };
    let mut list = DrawList::new();
    match build_draws(&cm, &camera, &params, &mut list) {
        Ok(_) => assert!(list.len() <= p.budget.max_draws as usize),
        // Too few draws for the frame: a typed error, never a silent drop.
        Err(Error::Capacity { .. }) => {}
        Err(other) => panic!("draws: {other} for:\n{text}"),
    }
    if let Some(gpu) = gpu {
        clipsat::gpu::headless::Offscreen::new(gpu, &p, &cm, Default::default())
            .unwrap_or_else(|e| panic!("renderer: {e} for:\n{text}"));
        return Reached::Rendered;
    }
    Reached::Planned
}

/// The generator's seed (see the test).
const SEED: u64 = 0x00c1_1b5a_7000_0015;

#[test]
fn random_and_extreme_profiles_error_or_work() {
    let gpu = render_support::strict();
    let counts = Cell::new([0u32; 4]);
    // A fixed seed: the same 300 profiles on every run, so the stage counts below are a property of the
    // generator, not of the day (with a random seed, one CI run drew only 18 valid profiles of 300).
    // `PROPTEST_RNG_SEED` is ignored here; change `SEED` to explore others.
    let mut runner = TestRunner::new(Config {
        cases: 300,
        failure_persistence: None,
        rng_seed: RngSeed::Fixed(SEED),
        ..Config::default()
    });
    let strategy = prop_oneof![3 => profile_text(), 1 => damaged_text()];
    runner
        .run(&strategy, |text| {
            let mut c = counts.get();
            let g = (c[Reached::Rendered as usize] < RENDERERS).then_some(&gpu);
            c[check(&text, g) as usize] += 1;
            counts.set(c);
            Ok(())
        })
        .unwrap_or_else(|e| panic!("{e}"));
    let [refused, validated, planned, rendered] = counts.get();
    eprintln!(
        "{refused} profiles refused; {validated} validated (too big to plan here), {planned} planned, \
         {rendered} planned and rendered"
    );
    let valid = validated + planned + rendered;
    assert!(
        valid >= 20 && planned > 0 && rendered > 0,
        "the generator must reach every stage"
    );
}
