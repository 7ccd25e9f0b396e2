//! `clipsat bench imagery`: what draped imagery costs a frame. Basic shading and SG, each without and
//! with the terrain's imagery, drawn the way an engine draws (a `TerrainRenderer` each, on one strict
//! context, into one set of offscreen targets), warmed up at the terrain's default camera; then rounds of
//! one frame of each configuration in turn (prepare, draw, read-back: the GPU's work waited for), so that
//! a drift of the machine's speed falls on all four alike. Reports p50 ms per configuration and the
//! ratios with and without imagery, measured in the same run. A measurement tool: it reads the wall clock.

use std::time::Instant;

use clap::Args;
use clipsat::gpu::headless::Targets;
use clipsat::gpu::Gpu;
use clipsat::profile::Feature;
use clipsat::{Camera, RenderOptions, Result, TerrainRenderer};
use serde_json::json;

use crate::app::cmd::args::{arg_error, pixel_size, GpuArgs, Size, StreamArgs};
use crate::app::cmd::{print_json, ProfileArgs, TerrainArgs};

#[derive(Args, Debug)]
pub(crate) struct BenchImageryArgs {
    /// The terrain and its imagery (`--imagery` is required).
    #[command(flatten)]
    terrain: TerrainArgs,
    #[command(flatten)]
    profile: ProfileArgs,
    #[command(flatten)]
    stream: StreamArgs,
    /// Image size, WxH pixels.
    #[arg(long, value_name = "WxH", value_parser = pixel_size, default_value = "1920x1080")]
    size: Size,
    /// Timed rounds (one frame of each configuration a round), after the warm-up.
    #[arg(long, value_name = "N", default_value_t = 20)]
    frames: u32,
    /// SG's scene (with --profile allowing SG). Default: noon.
    #[arg(long, value_name = "FILE|NAME")]
    scene: Option<String>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    gpu: GpuArgs,
}

/// One configuration: its label, SG or basic, with or without the imagery.
struct Config {
    label: &'static str,
    sg: bool,
    imagery: bool,
}

const CONFIGS: [Config; 4] = [
    Config {
        label: "basic",
        sg: false,
        imagery: false,
    },
    Config {
        label: "basic + imagery",
        sg: false,
        imagery: true,
    },
    Config {
        label: "sg",
        sg: true,
        imagery: false,
    },
    Config {
        label: "sg + imagery",
        sg: true,
        imagery: true,
    },
];

pub(crate) fn run(args: &BenchImageryArgs) -> Result<()> {
    if args.terrain.imagery.is_none() {
        return Err(arg_error(
            "--imagery",
            "bench imagery needs the imagery to drape",
        ));
    }
    if args.frames == 0 {
        return Err(arg_error("--frames", "time at least 1 frame"));
    }
    let mut profile = args.profile.load()?;
    (profile.view.width, profile.view.height) = args.size.pair();
    let with_sg = profile.allows(Feature::Sg);
    let scene = args.scene.clone().unwrap_or_else(|| "noon".into());
    let stream = args.stream.streams(None)?;
    let gpu = Gpu::new(args.gpu.mode())?;
    let viewport = args.size.pair();
    let targets = Targets::new(&gpu, viewport.0, viewport.1)?;
    let public = clipsat::Profile::from_stages(profile.clone());
    let mut camera: Option<Camera> = None;
    let mut renderers = Vec::new();
    for c in CONFIGS.iter().filter(|c| with_sg || !c.sg) {
        let mut terrain = args.terrain.open(stream, !args.json)?;
        if !c.imagery {
            drop(terrain.take_imagery());
        }
        let cam = match camera {
            Some(cam) => cam,
            None => *camera.insert(terrain.default_camera()?),
        };
        let mut options = RenderOptions::default()
            .color_format(targets.color_format())
            .depth_format(targets.depth_format())
            .imagery_rgba8(args.terrain.imagery_rgba8);
        if c.sg {
            options = options.sg_scene(&scene);
        }
        let mut r = TerrainRenderer::new(gpu.device(), gpu.queue(), terrain, &public, &options)?;
        r.warm_up(gpu.queue(), &cam, viewport)?;
        renderers.push((c, r, cam, Vec::with_capacity(args.frames as usize)));
    }
    for _ in 0..args.frames {
        for (_, r, cam, times) in &mut renderers {
            let t = Instant::now();
            r.prepare(gpu.queue(), cam, viewport)?;
            targets.draw("bench imagery", clipsat::shading::basic::SKY, |pass| {
                r.render(pass);
            })?;
            targets.read_image()?;
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let p50 = |times: &[f64]| {
        let mut v = times.to_vec();
        v.sort_by(f64::total_cmp);
        v[(v.len() - 1) / 2]
    };
    let rows: Vec<(&str, f64)> = renderers
        .iter()
        .map(|(c, _, _, times)| (c.label, p50(times)))
        .collect();
    let ms = |label: &str| rows.iter().find(|r| r.0 == label).map(|r| r.1);
    let ratio = |with: &str, without: &str| ms(with).zip(ms(without)).map(|(a, b)| a / b);
    let basic_ratio = ratio("basic + imagery", "basic");
    let sg_ratio = ratio("sg + imagery", "sg");
    let report = gpu.report();
    if args.json {
        print_json(&json!({
            "terrain": renderers.first().map(|(_, r, _, _)| r.terrain_name().to_owned()),
            "profile": profile.name,
            "size": [viewport.0, viewport.1],
            "frames": args.frames,
            "scene": with_sg.then_some(&scene),
            "adapter": report.name,
            "gl_version": report.gl_version,
            "p50_ms": rows.iter().map(|(l, m)| json!({"config": l, "ms": m})).collect::<Vec<_>>(),
            "basic_imagery_ratio": basic_ratio,
            "sg_imagery_ratio": sg_ratio,
        }));
        return Ok(());
    }
    outln!(
        "{} at {} x {}, {} ({}), p50 of {} frames each (prepare + draw + read-back):",
        profile.name,
        viewport.0,
        viewport.1,
        report.name,
        report.gl_version,
        args.frames
    );
    for (label, m) in &rows {
        outln!("  {label:<16} {m:8.2} ms");
    }
    if let Some(r) = basic_ratio {
        outln!("basic with imagery / without: {r:.2}");
    }
    match sg_ratio {
        Some(r) => outln!("sg with imagery / without: {r:.2}"),
        None => outln!("sg: profile {} does not allow SG shading", profile.name),
    }
    Ok(())
}
