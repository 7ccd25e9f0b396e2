//! The GPU half of SG shading: the WGSL `sg_shade` against its CPU twin `shading::shade` (probe pipeline),
//! the SAT texture lookup against brute-force box means, and the per-scene variants (what is baked, bound
//! and compiled).

use crate::render_support;

use clipsat::bake::horizon;
use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen};
use clipsat::gpu::sg_probe::{shade_gpu, ProbeCase};
use clipsat::gpu::shaders::{self, SgVariant};
use clipsat::package::shading_sats::{ShadingBake, MAX_BOX_SIDE};
use clipsat::shading::scene::{Needs, Scene};
use clipsat::shading::{self, Inputs, Patches};
use glam::Vec3;

/// gles3-low's rings and budget, allowed SG (so its `cpu_memory_bytes` carves the shading share,
/// `CpuSplit::shading`): the small profile these tests draw SG on.
fn sg_low_profile(width: u32, height: u32, budget: Option<u32>) -> clipsat::profile::Profile {
    let mut p = render_support::profile("gles3-low", width, height, budget);
    p.shading.features.push(clipsat::profile::Feature::Sg);
    p
}

/// Deterministic inputs covering the hard cases: flat (r = z), tilted, |r| -> 0 and -> 1, a vertical
/// cliff (r horizontal), grazing and overhead views, low and high horizons.
fn cases(d: usize) -> Vec<ProbeCase> {
    let mut out = Vec::new();
    let dirs = [
        Vec3::Z,
        Vec3::new(0.3, -0.2, 0.9),
        Vec3::new(-0.7, 0.1, 0.7),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, -0.6, 0.8),
        Vec3::new(0.5, 0.5, 0.2),
    ];
    let lens = [1.0, 0.9999, 0.98, 0.8, 0.4, 1e-4];
    let views = [
        Vec3::Z,
        Vec3::new(0.6, 0.0, 0.8),
        Vec3::new(-0.2, 0.97, 0.05),
    ];
    let mut seed = 1u32;
    for dir in dirs {
        for len in lens {
            for view in views {
                let mut hz = heapless::Vec::new();
                for _ in 0..d {
                    seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    let t = (seed >> 8) as f32 / (1u32 << 24) as f32;
                    let _ = hz.push(-0.4 + 1.1 * t);
                }
                out.push(ProbeCase {
                    r: dir.normalize() * len,
                    view: view.normalize(),
                    horizon: hz,
                });
            }
        }
    }
    out
}

/// GPU vs CPU twin, every shipped scene x patch count, visibility with D = 8 where the scene has it.
/// Tolerance: 5e-4 of the largest channel of the scene's results (llvmpipe's exp/log/atan2/sin differ
/// from Rust's by a few ulps, and band edges amplify that near |r| -> 1 where kappa is 1e4). Measured
/// on llvmpipe: at most 1.7e-7 (noon), 1.1e-4 (evening), 1.7e-6 (overcast).
#[test]
fn gpu_shading_matches_cpu_twin() {
    let gpu = render_support::strict();
    let mut report = Vec::new();
    for (name, _) in clipsat::shading::scene::SHIPPED {
        let scene = Scene::load(name).expect("shipped scene");
        let d = if scene.effects.visibility { 8 } else { 0 };
        let cases = cases(d);
        for patches in Patches::ALL {
            let gpu_out = shade_gpu(&gpu, &scene, patches, &cases).expect("probe");
            let sky = shading::SkyTable::new(&scene, patches);
            let cpu: Vec<Vec3> = cases
                .iter()
                .map(|c| {
                    shading::shade(
                        &Inputs {
                            r: c.r,
                            horizon: &c.horizon,
                            view: c.view,
                        },
                        &scene,
                        &sky,
                    )
                })
                .collect();
            let scale = cpu.iter().map(|c| c.max_element()).fold(0.0f32, f32::max);
            let mut worst = 0.0f32;
            for (i, (g, c)) in gpu_out.iter().zip(&cpu).enumerate() {
                assert!(g.is_finite() && g.min_element() >= 0.0, "{name} {i}: {g}");
                let err = (*g - *c).abs().max_element();
                worst = worst.max(err / scale);
                assert!(
                    err <= 5e-4 * scale,
                    "{name} {} case {i} ({:?}): gpu {g} cpu {c}",
                    patches.label(),
                    cases[i]
                );
            }
            report.push(format!("{name} {}: {worst:.2e}", patches.label()));
        }
    }
    println!("max |gpu - cpu| / scene max: {}", report.join(", "));
}

/// The shader's 4-corner wrapping-u32 lookup (its CPU twin `ShadingBake::box_mean`) against brute-force
/// box means of texel normals and horizons.
#[test]
fn sat_texture_box_means_match_brute_force() {
    let hm = render_support::terraces();
    let needs = Needs {
        bake_horizons: true,
        bind_visibility: true,
        ..Needs::default()
    };
    let bake =
        ShadingBake::bake(&hm, &needs, 8, u64::MAX, clipsat::Progress::default()).expect("bake");
    assert_eq!(bake.step(), 1);
    assert_eq!(bake.baked(), ["normal_sat", "horizons", "horizon_sat"]);
    let hz = horizon::bake(&hm, 8, horizon::DEFAULT_MAX_SAMPLES).expect("horizons");
    let mut worst = (0.0f32, 0.0f32);
    for (x0, y0, side) in [
        (0, 0, 1),
        (10, 20, 5),
        (100, 7, 63),
        (200, 200, 56),
        (250, 0, 7),
    ] {
        let hi = (x0 + side - 1, y0 + side - 1);
        let (r, a) = bake.box_mean((x0, y0), hi);
        let b = horizon::box_average(&hm, &hz, x0, y0, hi.0, hi.1);
        worst.0 = worst.0.max((r - b.r).abs().max_element());
        for (p, q) in a.iter().zip(&b.horizon) {
            worst.1 = worst.1.max((p - q).abs());
        }
    }
    // f32 conversion of a sum up to 2^32 (2^-24 relative) and the 2^-20 quantum.
    assert!(worst.0 < 2e-6 && worst.1 < 6e-6, "{worst:?}");
    println!(
        "box mean max error: normal {:.1e}, horizon {:.1e} rad",
        worst.0, worst.1
    );
    // Larger boxes are capped, not wrapped: a 100-sample request averages 63.
    let (r, _) = bake.box_mean((0, 0), (99, 99));
    let b = horizon::box_average(&hm, &hz, 0, 0, MAX_BOX_SIDE - 1, MAX_BOX_SIDE - 1);
    assert!((r - b.r).abs().max_element() < 2e-6);
}

#[test]
fn terrain_larger_than_the_shading_share_uses_a_pyramid_level() {
    let hm = render_support::terraces();
    let bytes = clipsat::package::shading_sats::grid_bytes(199, 199, 0);
    let bake = ShadingBake::bake(
        &hm,
        &Needs::default(),
        8,
        bytes,
        clipsat::Progress::default(),
    )
    .expect("bake");
    assert_eq!((bake.step(), bake.width()), (2, 129));
    assert_eq!(bake.baked(), ["normal_sat"]);
}

#[test]
fn variants_compile_only_what_the_scene_declares() {
    for v in SgVariant::all() {
        let text = shaders::sg_clipmap(v);
        assert_eq!(
            text.contains("fn sg_warped_ndf"),
            v.specular,
            "{}",
            v.label()
        );
        assert_eq!(text.contains("level_light"), v.visibility, "{}", v.label());
        // Fog: no fog code in a variant whose scene has none.
        assert_eq!(text.contains("sg_scene.fog"), v.fog, "{}", v.label());
        assert_eq!(text.contains("material.w"), v.fog, "{}", v.label());
        assert!(text.contains(&format!("const SG_BANDS: u32 = {}u;", v.patches.bands())));
        // Every rendering variant computes every term; only `bench shading`'s breakdown omits one.
        assert!(text.contains("const SG_OMIT: u32 = 0u;"), "{}", v.label());
    }
}

/// A scene without shadows bakes no horizons and binds no visibility texture; one with them does; the SG
/// frame differs from the basic one and is lit (not all sky).
#[test]
fn renderer_bakes_and_binds_only_what_the_scene_needs() {
    let gpu = render_support::strict();
    let hm = render_support::terraces();
    let profile = sg_low_profile(96, 64, None);
    let mut clipmap = render_support::clipmap(&hm, &profile);
    let camera = clipsat::plan::camera::Camera::default_for(&hm).expect("camera");
    let mut renderer =
        Offscreen::new(&gpu, &profile, &clipmap, Default::default()).expect("renderer");
    assert_eq!(renderer.bound_textures(), ["heights"]);
    assert!(renderer.baked().is_empty());
    clipmap.update(camera.eye).expect("update");
    let opts = FrameOptions::default();
    let basic = render_frame(&mut renderer, &clipmap, &camera, &opts).expect("basic frame");

    let noon = Scene::load("noon").expect("noon");
    let mut renderer =
        Offscreen::with_sg(&gpu, &profile, &clipmap, &hm, &noon, Patches::P4x8, true)
            .expect("sg noon");
    assert_eq!(
        renderer.bound_textures(),
        ["heights", "level_normal", "sky_table"]
    );
    assert_eq!(renderer.baked(), ["normal_sat"]);
    assert_eq!(renderer.renderer().sg_layout_entries(), Some(3));
    let sg = render_frame(&mut renderer, &clipmap, &camera, &opts).expect("sg frame");
    assert_ne!(sg.image.hash(), basic.image.hash());
    // Switching SG off and on again draws basic and SG frames and creates nothing (the tables
    // are never re-created on a toggle).
    let objects = renderer.renderer().ledger().count();
    renderer.renderer_mut().set_sg_enabled(false);
    assert!(!renderer.renderer().sg_enabled());
    let off = render_frame(&mut renderer, &clipmap, &camera, &opts).expect("sg off frame");
    assert_eq!(off.image.hash(), basic.image.hash());
    renderer.renderer_mut().set_sg_enabled(true);
    let on = render_frame(&mut renderer, &clipmap, &camera, &opts).expect("sg on frame");
    assert_eq!(on.image.hash(), sg.image.hash());
    assert_eq!(renderer.renderer().ledger().count(), objects);
    #[expect(
        clippy::cast_possible_truncation,
        reason = "colours in [0, 1] as bytes"
    )]
    let sky = clipsat::shading::basic::SKY.map(|c| (c * 255.0).round() as u8);
    let lit = sg
        .image
        .rgba
        .chunks_exact(4)
        .filter(|p| p[..3] != sky[..3])
        .count();
    assert!(lit > 96 * 64 / 4, "{lit} terrain pixels");

    let evening = Scene::load("evening").expect("evening");
    let renderer = Offscreen::with_sg(
        &gpu,
        &profile,
        &clipmap,
        &hm,
        &evening,
        Patches::P2x4,
        false,
    )
    .expect("sg evening, no shadows");
    assert_eq!(
        renderer.bound_textures(),
        ["heights", "level_normal", "sky_table"]
    );
    assert_eq!(renderer.baked(), ["normal_sat"]);
    assert!(renderer
        .renderer()
        .sg_variant()
        .is_some_and(|v| v.specular && !v.visibility));
    let mut renderer =
        Offscreen::with_sg(&gpu, &profile, &clipmap, &hm, &evening, Patches::P2x4, true)
            .expect("sg evening");
    assert_eq!(
        renderer.bound_textures(),
        ["heights", "level_normal", "sky_table", "level_light"]
    );
    assert_eq!(renderer.baked(), ["normal_sat", "horizons", "horizon_sat"]);
    assert_eq!(renderer.renderer().sg_layout_entries(), Some(4));
    let full = render_frame(&mut renderer, &clipmap, &camera, &opts).expect("sg evening frame");

    // The effect keys: visibility and specular off and on again switch the renderer's
    // programs; the tables, bindings and bytes stay. Off draws what a renderer built without them draws.
    let (bytes, objects) = (
        renderer.renderer().ledger().bytes(),
        renderer.renderer().ledger().count(),
    );
    let mut plain = evening.clone();
    (plain.effects.visibility, plain.effects.specular) = (false, false);
    let dev = gpu.device();
    renderer
        .renderer_mut()
        .set_sg_effects(dev, plain.effects)
        .expect("effects off");
    let off = render_frame(&mut renderer, &clipmap, &camera, &opts).expect("effects off frame");
    let fresh = Offscreen::with_sg(&gpu, &profile, &clipmap, &hm, &plain, Patches::P2x4, true)
        .expect("sg evening without visibility and specular");
    let mut fresh = fresh;
    let want = render_frame(&mut fresh, &clipmap, &camera, &opts).expect("fresh frame");
    assert_eq!(off.image.hash(), want.image.hash());
    assert_ne!(off.image.hash(), full.image.hash());
    // The first switch to a set of effects compiles its module and two programs, at zero bytes.
    assert_eq!(renderer.renderer().ledger().count(), objects + 3);
    renderer
        .renderer_mut()
        .set_sg_effects(dev, evening.effects)
        .expect("effects on");
    let on = render_frame(&mut renderer, &clipmap, &camera, &opts).expect("effects on frame");
    assert_eq!(on.image.hash(), full.image.hash());
    renderer
        .renderer_mut()
        .set_sg_effects(dev, plain.effects)
        .expect("effects off again");
    assert_eq!(renderer.renderer().ledger().count(), objects + 3);
    assert_eq!(renderer.renderer().ledger().bytes(), bytes);
    // What the scene left out has no table to switch on: refused, and what is drawn stays.
    let err = fresh
        .renderer_mut()
        .set_sg_effects(dev, evening.effects)
        .expect_err("visibility was not built");
    assert!(err.to_string().contains("visibility"), "{err}");
    let again = render_frame(&mut fresh, &clipmap, &camera, &opts).expect("fresh frame again");
    assert_eq!(again.image.hash(), want.image.hash());
}

/// `render --shading sg --json` reports what was bound and baked; `--no-shadows` drops the horizons;
/// basic shading refuses SG-only flags.
#[test]
fn cli_render_reports_bound_textures_and_baked() {
    let out = std::env::temp_dir().join(format!("clipsat_sg_cli_{}.png", std::process::id()));
    let run = |extra: &[&str]| {
        let mut args = vec![
            "render",
            "--terrain",
            "procedural:size=129",
            "--profile",
            "desktop",
            "--size",
            "64x48",
            "--out",
        ];
        let out = out.to_string_lossy().into_owned();
        args.push(&out);
        args.extend_from_slice(extra);
        // render streams the terrain from a package baked into this cache on first use.
        let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("sg_gpu-cache");
        std::process::Command::new(env!("CARGO_BIN_EXE_clipsat"))
            .args(&args)
            .env("CLIPSAT_CACHE", cache)
            .output()
            .expect("run clipsat")
    };
    let json = |o: &std::process::Output| -> serde_json::Value {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).expect("json")
    };
    let v = json(&run(&["--shading", "sg", "--scene", "evening", "--json"]));
    assert_eq!(
        v["bound_textures"],
        serde_json::json!(["heights", "level_normal", "sky_table", "level_light"])
    );
    assert_eq!(
        v["baked"],
        serde_json::json!(["normal_sat", "horizons", "horizon_sat"])
    );
    assert!(v["shading_rmse_vs_reference"].is_null(), "{v}");
    let v = json(&run(&[
        "--shading",
        "sg",
        "--scene",
        "evening",
        "--no-shadows",
        "--json",
    ]));
    assert_eq!(
        v["bound_textures"],
        serde_json::json!(["heights", "level_normal", "sky_table"])
    );
    assert_eq!(v["baked"], serde_json::json!(["normal_sat"]));
    let refused = run(&["--no-shadows"]);
    assert_eq!(refused.status.code(), Some(2));
    let _ = std::fs::remove_file(&out);
}

/// `--reference` against the CPU reference on a small view: the RMSE stays small. Slow in a debug build
/// (dense f64 quadrature per reference pixel): `cargo test --test gpu sg_gpu:: -- --ignored`.
#[test]
#[ignore]
fn cli_render_reference_error_is_small() {
    let out = std::env::temp_dir().join(format!("clipsat_sg_ref_{}.png", std::process::id()));
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_clipsat"))
        .args([
            "render",
            "--terrain",
            "procedural:size=129",
            "--profile",
            "desktop",
        ])
        .args([
            "--size",
            "64x48",
            "--shading",
            "sg",
            "--scene",
            "evening",
            "--reference",
        ])
        .arg("--json")
        .arg("--out")
        .arg(&out)
        .output()
        .expect("run clipsat");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    let e = v["shading_rmse_vs_reference"].as_f64().expect("rmse");
    assert!(e < 0.05 && v["reference_pixels"].as_u64() > Some(50), "{v}");
    // The shading model's own part (the CPU twin on the reference's inputs): the 0.02.
    let model = v["shading_model_rmse_vs_reference"]
        .as_f64()
        .expect("model rmse");
    assert!(model <= 0.02, "{v}");
    let _ = std::fs::remove_file(&out);
}

/// Golden SG frame: procedural 257^2 terrain, evening scene (visibility, specular, fog), 4x8, 160 x 90 on
/// gles3-low's clipmap. `tests/goldens/sg_hashes.txt` holds the exact hash per driver
/// (`adapter|driver<TAB>view<TAB>hash`); `tests/goldens/sg-procedural-evening.png` is compared with the
/// same tolerance as tests/gpu/render_goldens.rs (mean 3, max 160 levels per channel) on other drivers.
/// `CLIPSAT_BLESS=1` rewrites both.
#[test]
fn golden_sg_frame() {
    let gpu = render_support::strict();
    let report = gpu.report();
    let key = format!("{}|{}", report.name, report.driver);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/goldens");
    let (png, hashes) = (
        dir.join("sg-procedural-evening.png"),
        dir.join("sg_hashes.txt"),
    );
    let hm =
        clipsat::source::procedural::generate(&clipsat::source::procedural::ProceduralParams {
            size: 257,
            ..Default::default()
        })
        .expect("procedural terrain");
    let mut profile = sg_low_profile(160, 90, None);
    profile.budget.update_samples_per_frame = u32::MAX;
    let mut cm = render_support::clipmap(&hm, &profile);
    let cam = clipsat::plan::camera::Camera::default_for(&hm).expect("camera");
    cm.update(cam.eye).expect("update");
    let scene = Scene::load("evening").expect("evening");
    let mut r =
        Offscreen::with_sg(&gpu, &profile, &cm, &hm, &scene, Patches::P4x8, true).expect("sg");
    let img = render_frame(&mut r, &cm, &cam, &FrameOptions::default())
        .expect("frame")
        .image;
    let h = clipsat::hash::hex(img.hash());
    let line = format!("{key}\tsg-procedural-evening\t{h}");
    if std::env::var_os("CLIPSAT_BLESS").is_some_and(|v| v == "1") {
        img.save_png(&png).expect("write golden");
        let mut lines: Vec<String> = std::fs::read_to_string(&hashes)
            .unwrap_or_default()
            .lines()
            .filter(|l| !l.starts_with(&format!("{key}\t")) && !l.starts_with('#'))
            .map(str::to_string)
            .collect();
        lines.push(line);
        lines.sort();
        let text = format!(
            "# Exact SG golden hashes per driver (tests/gpu/sg_gpu.rs golden_sg_frame).\n{}\n",
            lines.join("\n")
        );
        std::fs::write(&hashes, text).expect("write hashes");
        return;
    }
    let stored = std::fs::read_to_string(&hashes).unwrap_or_default();
    if let Some(l) = stored.lines().find(|l| l.starts_with(&format!("{key}\t"))) {
        assert_eq!(l, line, "exact hash for this driver");
    }
    let golden = image::open(&png)
        .unwrap_or_else(|e| panic!("{}: {e}; run CLIPSAT_BLESS=1", png.display()))
        .to_rgba8();
    assert_eq!((golden.width(), golden.height()), (img.width, img.height));
    let (mut sum, mut max) = (0u64, 0u8);
    for (a, b) in golden.as_raw().iter().zip(&img.rgba) {
        sum += u64::from(a.abs_diff(*b));
        max = max.max(a.abs_diff(*b));
    }
    let mean = sum as f64 / img.rgba.len() as f64;
    assert!(mean <= 3.0 && max <= 160, "mean {mean:.3}, max {max}");
}

/// The per-level SG normal table ("Memory") equals its CPU twin `ShadingBake::level_texel` at
/// every texel of every ring's clip region, bit for bit, after a flight on a small budget (rings move
/// toroidally and go stale, some frames are planned but never prepared, one teleport): the tables follow
/// the plan's ring uploads exactly. The twin `sg_taps` picks a held ring for points inside the data.
#[test]
fn sg_tables_follow_the_rings() {
    let gpu = render_support::strict();
    let hm = render_support::relief();
    let p = sg_low_profile(64, 48, Some(1600));
    let mut cm = render_support::clipmap(&hm, &p);
    let noon = Scene::load("noon").expect("noon");
    let share = p.cpu_split().shading;
    let (_, bake) = clipsat::gpu::headless::sg_bake(share, &hm, &noon, false).expect("bake");
    let mut r = Offscreen::with_sg(&gpu, &p, &cm, &hm, &noon, Patches::P2x4, false).expect("sg");
    for i in 0..60 {
        let cam = render_support::flight(&hm, i, 120.0, 400.0, Some(40));
        cm.update(cam.eye).expect("update");
        if i % 3 != 1 {
            let f = render_frame(&mut r, &cm, &cam, &FrameOptions::default()).expect("frame");
            // The tables write exactly the ring texels uploaded (distance LOD: no detail tiles).
            assert_eq!(f.stats.sg_samples, f.stats.upload_samples, "frame {i}");
            if i > 0 && !f.stats.full_upload {
                assert!(f.stats.sg_samples <= 3 * 1600, "frame {i}: {:?}", f.stats);
            }
        }
    }
    let tables = r.read_sg_normals().expect("normal table readback");
    let s = i64::from(p.clip_size());
    let synth = i32::try_from(cm.synth_levels()).expect("levels");
    let mut checked = 0;
    for (l, layer) in tables.iter().enumerate() {
        let clip = cm.frame().levels[l].clip;
        let data_level = i32::try_from(l).expect("level") - synth;
        for j in clip.y0..clip.y1() {
            for i in clip.x0..clip.x1() {
                let t = usize::try_from(j.rem_euclid(s) * s + i.rem_euclid(s)).expect("texel");
                let (want, _) = bake.level_texel(data_level, i, j);
                let got = layer[t];
                assert_eq!(
                    [got[0].to_bits(), got[1].to_bits(), got[2].to_bits()],
                    [want.x.to_bits(), want.y.to_bits(), want.z.to_bits()],
                    "level {l} sample ({i}, {j})"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 4 * 80 * 80, "{checked} texels checked");
    // Inside the data, some ring holds every point the last camera sees near it.
    let g = r.globals();
    let eye = render_support::flight(&hm, 59, 120.0, 400.0, Some(40)).eye;
    let (ox, oy) = cm.origin();
    for (dx, dy) in [(100.0f32, 50.0f32), (-400.0, 300.0), (2000.0, 800.0)] {
        let rel = [dx, dy];
        let (x, y) = (eye.x + f64::from(dx), eye.y + f64::from(dy));
        if x > ox && y > oy {
            let taps = clipsat::twin::shading::sg_taps(g, hm.spacing(), rel, 2.0).expect("held");
            let (r, _) = clipsat::twin::shading::sg_inputs(&bake, &cm, &taps);
            assert!(r.length() > 0.5 && r.length() <= 1.0 && r.z > 0.0, "{r}");
        }
    }
}

/// With visibility, the light table ("Cost": the view-independent shading per texel) equals
/// its CPU twin at every texel of every ring's clip region after a flight on a small budget:
/// `shading::texel_light` of `ShadingBake::level_texel`'s r and horizon sines, rounded to f16, and the
/// normal table's w the horizon's sine toward the sun, bit for bit.
#[test]
fn sg_light_table_follows_the_rings() {
    let gpu = render_support::strict();
    let hm = render_support::relief();
    let p = sg_low_profile(64, 48, Some(1600));
    let mut cm = render_support::clipmap(&hm, &p);
    let evening = Scene::load("evening").expect("evening");
    let share = p.cpu_split().shading;
    let (scene, bake) = clipsat::gpu::headless::sg_bake(share, &hm, &evening, true).expect("bake");
    let mut r = Offscreen::with_sg(&gpu, &p, &cm, &hm, &evening, Patches::P2x4, true).expect("sg");
    for i in 0..40 {
        let cam = render_support::flight(&hm, i, 120.0, 400.0, Some(40));
        cm.update(cam.eye).expect("update");
        if i % 3 != 1 {
            render_frame(&mut r, &cm, &cam, &FrameOptions::default()).expect("frame");
        }
    }
    let sky = shading::SkyTable::new(&scene, Patches::P2x4);
    let normals = r.read_sg_normals().expect("normal table readback");
    let lights = r.read_sg_light().expect("light table readback");
    let s = i64::from(p.clip_size());
    let synth = i32::try_from(cm.synth_levels()).expect("levels");
    let f16 = |x: f32| half::f16::from_f32(x).to_bits();
    let mut checked = 0;
    for (l, (normal, light)) in normals.iter().zip(&lights).enumerate() {
        let clip = cm.frame().levels[l].clip;
        let data_level = i32::try_from(l).expect("level") - synth;
        // Every 3rd row and column: the twin's integration is the test's cost.
        for j in (clip.y0..clip.y1()).step_by(3) {
            for i in (clip.x0..clip.x1()).step_by(3) {
                let t = usize::try_from(j.rem_euclid(s) * s + i.rem_euclid(s)).expect("texel");
                let (rn, hz) = bake.level_texel(data_level, i, j);
                let sines: heapless::Vec<f32, 16> = hz.iter().map(|a| a.sin()).collect();
                let want = shading::texel_light(rn, &sines, &scene, &sky);
                let d = want.diffuse;
                assert_eq!(
                    light[t],
                    [f16(d.x), f16(d.y), f16(d.z), f16(want.mean_sin)],
                    "level {l} sample ({i}, {j})"
                );
                assert_eq!(
                    normal[t][3].to_bits(),
                    want.sun_sin.to_bits(),
                    "level {l} ({i}, {j})"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 4 * 25 * 25, "{checked} texels checked");
    // The twin of the shader's blend (sg_taps, then sg_light) against the blend of the read-back texels
    // at the shader's toroidal texels ((tex + cell + {0, 1}) mod S).
    let g = r.globals();
    let lighting = shading::TexelLighting::new(&scene);
    let eye = render_support::flight(&hm, 39, 120.0, 400.0, Some(40)).eye;
    let (ox, oy) = cm.origin();
    let mut blended = 0;
    for (dx, dy) in [
        (100.0f32, 50.0f32),
        (-400.0, 300.0),
        (2000.0, 800.0),
        (37.0, -450.0),
    ] {
        if eye.x + f64::from(dx) <= ox || eye.y + f64::from(dy) <= oy {
            continue;
        }
        let taps = clipsat::twin::shading::sg_taps(g, hm.spacing(), [dx, dy], 2.0).expect("held");
        let (light, sun) = clipsat::twin::shading::sg_light(&bake, &cm, &taps, &lighting, &sky);
        let lv = &g.levels[taps.level as usize];
        let s = p.clip_size() as i32;
        let texel = |ox: i32, oy: i32| {
            let tx = (lv.tex[0] + taps.cell[0] + ox) % s;
            let ty = (lv.tex[1] + taps.cell[1] + oy) % s;
            usize::try_from(ty * s + tx).expect("texel")
        };
        let level = taps.level as usize;
        let h = |t: usize, k: usize| half::f16::from_bits(lights[level][t][k]).to_f32();
        let [fx, fy] = taps.f;
        let mix = |a: f32, b: f32, t: f32| a * (1.0 - t) + b * t;
        let bil = |v: &dyn Fn(usize) -> f32| {
            let (a, b, c, d) = (
                v(texel(0, 0)),
                v(texel(1, 0)),
                v(texel(0, 1)),
                v(texel(1, 1)),
            );
            mix(mix(a, b, fx), mix(c, d, fx), fy)
        };
        for (k, want) in light.iter().enumerate() {
            assert_eq!(
                bil(&|t| h(t, k)).to_bits(),
                want.to_bits(),
                "({dx}, {dy}) channel {k}"
            );
        }
        assert_eq!(
            bil(&|t| normals[level][t][3]).to_bits(),
            sun.to_bits(),
            "({dx}, {dy}) w"
        );
        blended += 1;
    }
    assert!(blended >= 2, "{blended} points blended");
}

/// The memory goal: the SG objects' GPU bytes are fixed by the profile and the scene's visibility,
/// whatever the terrain's size: the same on a 257^2 and a 4097^2 terrain, and equal to
/// `Profile::sg_table_bytes` (the whole renderer: `Profile::footprint` plus that, plus the scene
/// uniform). The bake (CPU memory) is capped at 129^2 here to keep the test fast; it does not change
/// the GPU side.
#[test]
fn sg_gpu_bytes_do_not_depend_on_the_terrain_size() {
    let gpu = render_support::strict();
    let p = sg_low_profile(64, 48, None);
    let evening = Scene::load("evening").expect("evening");
    let sg_bytes = |size: u32| {
        // Rolling hills from one formula: only the size matters here, and the procedural generator's
        // octaves took most of this test's 5-14 s at 4097^2 in a test build.
        let heights = (0..size * size)
            .map(|k| {
                let (x, y) = ((k % size) as f32, (k / size) as f32);
                400.0 + 300.0 * (x / 37.0).sin() * (y / 53.0).cos()
            })
            .collect();
        let hm = clipsat::source::Heightmap::new(
            std::path::Path::new("<hills>"),
            size,
            size,
            30.0,
            heights,
        )
        .expect("terrain");
        let cm = render_support::clipmap(&hm, &p);
        let bake = ShadingBake::bake(
            &hm,
            &evening.needs(),
            clipsat::bake::horizon::DEFAULT_AZIMUTHS,
            clipsat::package::shading_sats::grid_bytes(129, 129, 16),
            clipsat::Progress::default(),
        )
        .expect("bake");
        let r = Offscreen::new(
            &gpu,
            &p,
            &cm,
            clipsat::gpu::headless::OffscreenOptions {
                shading: clipsat::gpu::renderer::Shading::Sg(clipsat::gpu::renderer::SgShading {
                    scene: &evening,
                    patches: Patches::P4x8,
                    bake: &bake,
                    omit: shaders::SgOmit::None,
                }),
                ..Default::default()
            },
        )
        .expect("sg renderer");
        let sg: u64 = r
            .renderer()
            .ledger()
            .entries()
            .iter()
            .filter(|e| e.label.starts_with("sg "))
            .map(|e| e.bytes)
            .sum();
        (sg, r.renderer().ledger().bytes())
    };
    let (small, small_total) = sg_bytes(257);
    let (large, large_total) = sg_bytes(4097);
    assert_eq!(small, large);
    assert_eq!(small_total, large_total);
    let tables = p.sg_table_bytes(clipsat::bake::horizon::DEFAULT_AZIMUTHS);
    let uniform = std::mem::size_of::<shaders::SgSceneUniform>() as u64;
    assert_eq!(small, tables + uniform);
    assert!(small_total <= p.budget.gpu_memory_bytes);
    println!("SG GPU bytes on gles3-low, evening: {small} ({tables} in tables)");
}
