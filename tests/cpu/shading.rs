//! The CPU shading twin against the f64 reference: the numerical hard cases of docs/design.md "Numerics" and
//! the patch-count error/cost table (2x4, 4x8, 8x16).

use std::path::Path;
use std::time::Instant;

use clipsat::bake::horizon::{self, Horizons};
use clipsat::shading::scene::{direction, Effects, Material, Scene};
use clipsat::shading::sg::Sg;
use clipsat::shading::{self, HorizonTable, Inputs, Patches, RefCosine, RefGrid, RefInputs};
use clipsat::source::Heightmap;
use glam::{DVec3, Vec3};

/// Sun SG of unit irradiance at (compass azimuth, elevation) in degrees.
fn sun(az: f32, el: f32, lambda: f32) -> Sg {
    Sg::with_integral(direction(az, el), lambda, Vec3::ONE)
}

fn scene(lights: Vec<Sg>, visibility: bool, specular: bool) -> Scene {
    Scene {
        name: "test".into(),
        lights,
        material: Material {
            kd: Vec3::ONE,
            ks: if specular { 0.5 } else { 0.0 },
            roughness: 0.5,
        },
        effects: Effects {
            visibility,
            specular,
            fog: false,
            synthesis: false,
        },
        fog: None,
    }
}

/// Shade vs reference at one point; returns (shade, reference) of the red channel.
fn compare(
    r: Vec3,
    baked: &[f32],
    exact: Option<&HorizonTable>,
    sc: &Scene,
    p: Patches,
) -> (f64, f64) {
    let view = Vec3::new(0.3, -0.5, 0.8).normalize();
    let s = shading::shade(
        &Inputs {
            r,
            horizon: baked,
            view,
        },
        sc,
        &shading::SkyTable::new(sc, p),
    );
    assert!(
        s.is_finite() && s.min_element() >= 0.0,
        "shade {s} for r {r}"
    );
    let refv = shading::reference(
        &RefInputs {
            r: r.as_dvec3(),
            view: view.as_dvec3(),
            horizon: exact,
        },
        sc,
        RefGrid::default(),
    );
    assert!(refv.is_finite() && refv.min_element() >= 0.0);
    (f64::from(s.x), refv.x)
}

/// A terrain with rolling hills, a ridge and a 100 m vertical cliff along column 40 (west side high).
fn terrain() -> Heightmap {
    let (w, h) = (64u32, 64u32);
    let mut z = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (
                f32::from(u16::try_from(x).unwrap_or(0)),
                f32::from(u16::try_from(y).unwrap_or(0)),
            );
            let hills =
                60.0 * (fx * 0.21).sin() * (fy * 0.17).cos() + 40.0 * ((fx + fy) * 0.09).sin();
            let ridge = 120.0 * (-((fy - 20.0) / 4.0).powi(2)).exp();
            let cliff = if x < 40 { 100.0 } else { 0.0 };
            z.push(hills + ridge + cliff);
        }
    }
    Heightmap::new(Path::new("<test>"), w, h, 10.0, z).unwrap_or_else(|e| panic!("{e}"))
}

const FLAT: [f32; 8] = [0.0; 8];

/// |shade - reference| <= REL * reference + ABS * (irradiance / pi). Both come from the clamped-cosine SG
/// fit (lambda 2.133, mu 1.17), not from the integration: ABS from its tail, 1.17 e^-2.133 = 0.138 at
/// grazing incidence where the true cosine is 0; REL from its peak, 17 % high at normal incidence, which
/// exceeds ABS there by 0.03 of the reference. Measured over every case of this file (80 pairs, `cargo
/// test --test cpu shading:: -- --nocapture`): the largest |shade - reference| is 0.170 x irradiance / pi (the
/// peak, lambda 1e4 at 90 degrees: 0.37227 against 0.31828), the worst case uses 89 % of this tolerance;
/// with ABS = 0.14 the cases need REL >= 0.030. (It was REL 0.25, which let a shade 25 % too bright pass:
/// `tolerance_rejects_a_wrong_shade`.)
const REL: f64 = 0.05;
const ABS: f64 = 0.14;

fn within((s, r): (f64, f64), scale: f64) -> bool {
    (s - r).abs() <= REL * r + ABS * scale
}

fn check(label: &str, (s, r): (f64, f64), scale: f64) {
    println!("{label:<48} shade {s:>10.5} reference {r:>10.5}");
    assert!(
        within((s, r), scale),
        "{label}: shade {s} vs reference {r} (tolerance {REL} x ref + {ABS} x {scale})"
    );
}

/// The tolerance catches a wrong shade: 25 % too bright or too dark at normal incidence under unit
/// irradiance (reference 1 / pi) fails it, while the SG fit's own peak error there (17 %) passes.
#[test]
fn tolerance_rejects_a_wrong_shade() {
    let scale = 1.0 / std::f64::consts::PI;
    let r = scale;
    assert!(within((1.17 * r, r), scale), "the fit's peak error passes");
    for wrong in [1.25 * r, 0.75 * r] {
        assert!(!within((wrong, r), scale), "{wrong} against {r} must fail");
    }
}

#[test]
fn flat_terrain_sharpness_sweep_and_grazing_light() {
    let flat = HorizonTable::constant(0.0, 64);
    let scale = 1.0 / std::f64::consts::PI;
    for lambda in [1e-6f32, 1e-3, 0.5, 3.0, 30.0, 300.0, 3e3, 1e4] {
        for el in [90.0f32, 45.0, 10.0, 2.0, 0.0, -1.0, -20.0] {
            let sc = scene(vec![sun(200.0, el, lambda)], true, false);
            let pair = compare(Vec3::Z, &FLAT, Some(&flat), &sc, Patches::P4x8);
            check(
                &format!("flat, lambda {lambda:e}, elevation {el}"),
                pair,
                scale,
            );
            if el <= -20.0 && lambda >= 300.0 {
                assert!(
                    pair.0 < 1e-3 * scale,
                    "a sharp sun below the horizon is dark"
                );
            }
        }
    }
}

#[test]
fn mean_normal_length_extremes() {
    // |r| -> 1 (one normal), intermediate, and |r| -> 0 (normals everywhere): no visibility, so the
    // reference averages the clamped cosine over the vMF over the whole sphere.
    let scale = 1.0 / std::f64::consts::PI;
    for len in [1.0f32, 0.999, 0.9, 0.6, 0.3, 0.05, 1e-3, 0.0] {
        for el in [80.0f32, 30.0] {
            let sc = scene(
                vec![
                    sun(90.0, el, 100.0),
                    Sg::new(Vec3::Z, 1.0, Vec3::splat(0.2)),
                ],
                false,
                false,
            );
            let r = Vec3::new(0.2, 0.1, 1.0).normalize() * len;
            let pair = compare(r, &[], None, &sc, Patches::P4x8);
            check(&format!("|r| = {len}, sun elevation {el}"), pair, scale);
        }
    }
}

#[test]
fn vertical_cliff() {
    let hm = terrain();
    // Foot of the cliff on its east side (column 40): the wall rises 100 m one sample west.
    let (x, y) = (40u32, 50u32);
    let hz = horizon::bake(&hm, 8, horizon::DEFAULT_MAX_SAMPLES).unwrap_or_else(|e| panic!("{e}"));
    let exact = HorizonTable::march(
        &hm,
        f64::from(x),
        f64::from(y),
        1024,
        horizon::DEFAULT_MAX_SAMPLES,
    );
    let west = horizon::interpolate(hz.at(x, y), std::f32::consts::PI);
    assert!(
        west > 1.2,
        "the wall's horizon to the west is steep: {west}"
    );
    let scale = 1.0 / std::f64::consts::PI;
    // The cliff face itself: a normal pointing east, nearly horizontal.
    let face = Vec3::new(1.0, 0.0, 1e-3).normalize();
    for (az, el) in [
        (90.0f32, 30.0f32),
        (270.0, 30.0),
        (270.0, 80.0),
        (180.0, 10.0),
    ] {
        let sc = scene(vec![sun(az, el, 500.0)], true, false);
        let on_face = compare(
            face,
            &FLAT,
            None,
            &scene(vec![sun(az, el, 500.0)], false, false),
            Patches::P4x8,
        );
        check(&format!("cliff face, sun az {az} el {el}"), on_face, scale);
        let foot = compare(
            horizon::texel_normal(&hm, x, y).as_vec3(),
            hz.at(x, y),
            Some(&exact),
            &sc,
            Patches::P4x8,
        );
        check(&format!("cliff foot, sun az {az} el {el}"), foot, scale);
        if az == 270.0 && el == 30.0 {
            assert!(
                foot.0 < 0.01 * scale,
                "the wall shadows a western sun at 30 degrees"
            );
        }
    }
}

/// Texels sampled every `step` samples of the test terrain, with the normals, baked and exact horizons.
struct Sample {
    r: Vec3,
    baked: Vec<f32>,
    exact: HorizonTable,
}

fn samples(hm: &Heightmap, hz: &Horizons, step: u32) -> Vec<Sample> {
    let mut out = Vec::new();
    for y in (4..hm.height() - 4).step_by(step as usize) {
        for x in (4..hm.width() - 4).step_by(step as usize) {
            out.push(Sample {
                r: horizon::texel_normal(hm, x, y).as_vec3(),
                baked: hz.at(x, y).to_vec(),
                exact: HorizonTable::march(
                    hm,
                    f64::from(x),
                    f64::from(y),
                    1024,
                    horizon::DEFAULT_MAX_SAMPLES,
                ),
            });
        }
    }
    out
}

/// (patches, rmse, max vs exact, rmse, max vs model, ns per light).
type Row = (Patches, f64, f64, f64, f64, f64);

/// RMSE and max absolute error per patch count over terrain points x light setups, relative to the
/// reference's mean; ns per shade call.
fn patch_table(step: u32) -> Vec<Row> {
    let hm = terrain();
    let hz = horizon::bake(&hm, 8, horizon::DEFAULT_MAX_SAMPLES).unwrap_or_else(|e| panic!("{e}"));
    let pts = samples(&hm, &hz, step);
    let setups: Vec<Scene> = [
        (250.0f32, 7.0f32),
        (135.0, 25.0),
        (0.0, 50.0),
        (300.0, 80.0),
    ]
    .iter()
    .map(|&(az, el)| {
        scene(
            vec![
                sun(az, el, 2000.0),
                Sg::new(direction(60.0, 60.0), 1.0, Vec3::splat(0.15)),
            ],
            true,
            false,
        )
    })
    .collect();
    let (mut refs, mut models) = (Vec::new(), Vec::new());
    for sc in &setups {
        for p in &pts {
            let inputs = RefInputs {
                r: p.r.as_dvec3(),
                view: DVec3::Z,
                horizon: Some(&p.exact),
            };
            refs.push(shading::reference(&inputs, sc, RefGrid::default()).x);
            let model = RefGrid {
                cosine: RefCosine::SgModel,
                ..RefGrid::default()
            };
            models.push(shading::reference(&inputs, sc, model).x);
        }
    }
    let mean = refs.iter().sum::<f64>() / refs.len() as f64;
    let stats = |shaded: &[f64], against: &[f64]| {
        let (mut se, mut max) = (0.0f64, 0.0f64);
        for (s, r) in shaded.iter().zip(against) {
            se += (s - r).powi(2);
            max = max.max((s - r).abs());
        }
        ((se / against.len() as f64).sqrt() / mean, max / mean)
    };
    let mut rows = Vec::new();
    for patches in Patches::ALL {
        let skies: Vec<shading::SkyTable> = setups
            .iter()
            .map(|sc| shading::SkyTable::new(sc, patches))
            .collect();
        let mut shaded = Vec::new();
        for (sc, sky) in setups.iter().zip(&skies) {
            for p in &pts {
                let inputs = Inputs {
                    r: p.r,
                    horizon: &p.baked,
                    view: Vec3::Z,
                };
                shaded.push(f64::from(shading::shade(&inputs, sc, sky).x));
            }
        }
        let (rmse, max) = stats(&shaded, &refs);
        let (model_rmse, model_max) = stats(&shaded, &models);
        // Timing: repeat the whole batch; black_box keeps the optimiser honest.
        let reps = 20;
        let start = Instant::now();
        for _ in 0..reps {
            for (sc, sky) in setups.iter().zip(&skies) {
                for p in &pts {
                    let inputs = Inputs {
                        r: std::hint::black_box(p.r),
                        horizon: &p.baked,
                        view: Vec3::Z,
                    };
                    std::hint::black_box(shading::shade(&inputs, sc, sky));
                }
            }
        }
        let calls = (reps * setups.len() * pts.len()) as f64;
        let ns = start.elapsed().as_secs_f64() * 1e9 / calls / 2.0; // per light (2 lights per call)
        rows.push((patches, rmse, max, model_rmse, model_max, ns));
    }
    println!(
        "{} points x {} light setups (sun lambda 2000 + sky lobe), reference 256 x 512, D = 8",
        pts.len(),
        setups.len()
    );
    println!("errors / mean reference; vs exact = physical answer, vs model = the SG model integrated densely");
    println!("patches  rmse(exact) max(exact)  rmse(model) max(model)  ns per light per call (this build's profile)");
    for (p, rmse, max, mrmse, mmax, ns) in &rows {
        println!(
            "{:<8} {rmse:>11.4} {max:>10.4} {mrmse:>12.4} {mmax:>10.4} {ns:>10.0}",
            p.label()
        );
    }
    rows
}

#[test]
fn patch_counts_error_and_cost_small() {
    let rows = patch_table(16);
    for (p, rmse, _, model, _, _) in &rows {
        assert!(rmse.is_finite() && *rmse < 0.2, "{} rmse {rmse}", p.label());
        assert!(
            model.is_finite() && *model < 0.1,
            "{} rmse against the model {model}",
            p.label()
        );
    }
}

/// The full table: `cargo test --release --test cpu shading::patch_counts_error_and_cost_full -- --ignored --nocapture`.
#[test]
#[ignore = "dense: about a minute in a debug build"]
fn patch_counts_error_and_cost_full() {
    patch_table(4);
}

#[test]
fn sat_footprint_averages_match_brute_force() {
    let hm = terrain();
    let hz = horizon::bake(&hm, 8, 64.0).unwrap_or_else(|e| panic!("{e}"));
    let sats = horizon::FootprintSats::build(&hm, &hz).unwrap_or_else(|e| panic!("{e}"));
    let mut worst = 0.0f32;
    for (x0, y0, x1, y1) in [
        (0, 0, 0, 0),
        (3, 5, 4, 6),
        (10, 10, 25, 17),
        (0, 0, 63, 63),
        (38, 40, 42, 60),
        (60, 1, 63, 2),
    ] {
        let a = horizon::box_average(&hm, &hz, x0, y0, x1, y1);
        let b = sats.box_average(x0, y0, x1, y1);
        worst = worst.max((a.r - b.r).abs().max_element());
        for (p, q) in a.horizon.iter().zip(&b.horizon) {
            worst = worst.max((p - q).abs());
        }
    }
    println!("SAT vs brute-force box means: worst difference {worst:.2e}");
    assert!(worst < 1e-6, "{worst}");
}

/// The GPU format for the normal and horizon SATs: R32UI wrapping fixed point against RGBA32F (plain, and
/// with the global mean subtracted, Hensley et al. 2005), on a 1024^2 grid of values in [0, 1] - the size
/// of a clip texture - for footprint boxes of 1 to 64^2 samples anywhere in the grid.
#[test]
#[expect(
    clippy::cast_possible_truncation,
    reason = "simulating f32 and u32 GPU tables from values in [0, 1]"
)]
fn gpu_sat_format_error() {
    let n = 1024usize;
    // Deterministic values in [0, 1]: a smooth field plus hash noise, like mapped horizons.
    let v: Vec<f64> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f64, (i / n) as f64);
            let h = ((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f64
                / f64::from(1u32 << 24);
            (0.5 + 0.3 * (x * 0.01).sin() * (y * 0.013).cos() + 0.2 * (h - 0.5)).clamp(0.0, 1.0)
        })
        .collect();
    let prefix = |val: &dyn Fn(usize) -> f64| -> Vec<f64> {
        let mut t = vec![0.0; n * n];
        for y in 0..n {
            let mut row = 0.0;
            for x in 0..n {
                row += val(y * n + x);
                t[y * n + x] = row + if y > 0 { t[(y - 1) * n + x] } else { 0.0 };
            }
        }
        t
    };
    // f32 tables: every partial sum rounded to f32, as a GPU-built or uploaded table would be.
    let f32_table = |offset: f64| -> Vec<f32> {
        let mut t = vec![0.0f32; n * n];
        for y in 0..n {
            let mut row = 0.0f32;
            for x in 0..n {
                row += (v[y * n + x] - offset) as f32;
                t[y * n + x] = row + if y > 0 { t[(y - 1) * n + x] } else { 0.0 };
            }
        }
        t
    };
    let exact = prefix(&|i| v[i]);
    let mean = exact[n * n - 1] / (n * n) as f64;
    let plain = f32_table(0.0);
    let offset = f32_table(mean);
    // R32UI: Q fractional bits so a 64^2 box of ones stays below 2^32: 4096 * 2^Q < 2^32 -> Q = 20.
    let q = 20;
    let scale = f64::from(1u32 << q);
    let quant: Vec<u32> = v.iter().map(|x| (x * scale).round() as u32).collect();
    let mut fixed = vec![0u32; n * n];
    for y in 0..n {
        let mut row = 0u32;
        for x in 0..n {
            row = row.wrapping_add(quant[y * n + x]);
            fixed[y * n + x] = row.wrapping_add(if y > 0 { fixed[(y - 1) * n + x] } else { 0 });
        }
    }
    let corner = |x: usize, y: usize, w: usize| (x + w - 1, y + w - 1);
    let (mut e_plain, mut e_offset, mut e_fixed) = (0.0f64, 0.0f64, 0.0f64);
    for w in [1usize, 2, 4, 8, 16, 32, 64] {
        for (x, y) in [(1usize, 1usize), (500, 300), (n - 70, n - 70), (900, 17)] {
            let (x1, y1) = corner(x, y, w);
            let samples = (w * w) as f64;
            let exact_mean = (exact[y1 * n + x1] - exact[(y - 1) * n + x1] - exact[y1 * n + x - 1]
                + exact[(y - 1) * n + x - 1])
                / samples;
            let f = |t: &[f32]| {
                f64::from(
                    t[y1 * n + x1] - t[(y - 1) * n + x1] - t[y1 * n + x - 1]
                        + t[(y - 1) * n + x - 1],
                ) / samples
            };
            e_plain = e_plain.max((f(&plain) - exact_mean).abs());
            e_offset = e_offset.max((f(&offset) + mean - exact_mean).abs());
            let s = fixed[y1 * n + x1]
                .wrapping_sub(fixed[(y - 1) * n + x1])
                .wrapping_sub(fixed[y1 * n + x - 1])
                .wrapping_add(fixed[(y - 1) * n + x - 1]);
            e_fixed = e_fixed.max((f64::from(s) / scale / samples - exact_mean).abs());
        }
    }
    println!(
        "1024^2 grid, boxes 1..64^2, max |error| of a box mean: RGBA32F plain {e_plain:.2e}, \
         RGBA32F mean-offset {e_offset:.2e}, R32UI wrapping fixed point (Q = {q}) {e_fixed:.2e}"
    );
    assert!(
        e_fixed <= 0.5 / scale + 1e-12,
        "fixed point error is the rounding only"
    );
    assert!(e_fixed < e_offset && e_offset < e_plain);
}

/// The sun's diffuse factor `vmf_cosine` (the vMF's two moments with a Gaussian) against E[max(n . i, 0)]
/// integrated densely over the vMF (f64, 1024 x 128 midpoints uniform in the vMF's energy fraction and
/// in phi). Measured: at most 0.025 absolute (|r| 0.5, t 0.9: moderate kappa, where the bounded
/// n . i is least Gaussian), exact at one normal and at the uniform distribution.
#[test]
fn vmf_cosine_matches_dense_integration() {
    use clipsat::shading::sg::{kappa_from_mean_length, Vmf};
    let mut worst = 0.0f64;
    for r_len in [0.9999f32, 0.999, 0.99, 0.95, 0.8, 0.5, 0.2, 1e-3] {
        let kappa = kappa_from_mean_length(r_len);
        let vmf = Vmf {
            axis: Vec3::Z,
            kappa,
            r_len,
        };
        let k = f64::from(kappa);
        for t32 in [-1.0f32, -0.6, -0.2, -0.05, 0.0, 0.05, 0.2, 0.5, 0.9, 1.0] {
            let t = f64::from(t32);
            let st = (1.0 - t * t).max(0.0).sqrt();
            let (n_theta, n_phi) = (1024, 128);
            let mut acc = 0.0;
            for j in 0..n_theta {
                // u = 1 - cos(theta) at energy fraction f of the vMF (its density is an SG of sharpness kappa).
                let f = (f64::from(j) + 0.5) / f64::from(n_theta);
                let u = -(f * (-2.0 * k).exp_m1()).ln_1p() / k;
                let (ct, sn) = (1.0 - u, (u * (2.0 - u)).max(0.0).sqrt());
                for p in 0..n_phi {
                    let phi = std::f64::consts::TAU * (f64::from(p) + 0.5) / f64::from(n_phi);
                    acc += (ct * t + sn * st * phi.cos()).max(0.0);
                }
            }
            let dense = acc / f64::from(n_theta * n_phi);
            let fast = f64::from(shading::vmf_cosine(t32, &vmf));
            let err = (fast - dense).abs();
            worst = worst.max(err);
            assert!(
                err < 0.03,
                "|r| {r_len}, t {t}: vmf_cosine {fast} against {dense}"
            );
        }
    }
    println!("vmf_cosine max |error| {worst:.4}");
}

/// The SG tables baked out of core from a package (`ShadingBake::bake_package`): with the grid
/// at level 0 they equal the resident bake of the decoded terrain; a share too small for level 0 takes
/// the package's own coarser level, decoded alone, and keeps the data's extent and spacing; a share too
/// small for any level is an error.
#[test]
fn shading_bake_from_a_package() {
    use clipsat::package::shading_sats::{grid_bytes, ShadingBake};
    use clipsat::package::{self, BakeOptions, Package};
    use clipsat::shading::scene::Needs;
    let hm =
        clipsat::source::procedural::generate(&clipsat::source::procedural::ProceduralParams {
            size: 129,
            ..Default::default()
        })
        .expect("terrain");
    let dir = std::env::temp_dir().join(format!("clipsat-sg-package-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let out = dir.join("p129.clipsat");
    package::bake(
        &hm,
        &out,
        &BakeOptions::default(),
        clipsat::Progress::default(),
    )
    .expect("bake");
    let p = Package::open(&out).expect("open");
    let needs = Needs {
        bake_horizons: true,
        ..Needs::default()
    };
    let streamed = ShadingBake::bake_package(&p, &needs, 8, u64::MAX, clipsat::Progress::default())
        .expect("package bake");
    let decoded = p.to_heightmap().expect("decode");
    let resident = ShadingBake::bake(&decoded, &needs, 8, u64::MAX, clipsat::Progress::default())
        .expect("resident bake");
    assert_eq!(streamed, resident);
    assert_eq!((streamed.step(), streamed.width()), (1, 129));
    // Level 1 (65^2) is the finest that fits.
    let coarse = ShadingBake::bake_package(
        &p,
        &needs,
        8,
        grid_bytes(65, 65, 8),
        clipsat::Progress::default(),
    )
    .expect("coarse");
    assert_eq!(
        (coarse.step(), coarse.width(), coarse.height()),
        (2, 65, 65)
    );
    assert_eq!(coarse.data_extent_m(), hm.extent_m());
    assert_eq!(coarse.data_spacing(), hm.spacing());
    assert!(ShadingBake::bake_package(&p, &needs, 8, 100, clipsat::Progress::default()).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}
