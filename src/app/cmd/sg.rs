//! `render` / `fly` / `bench shading`: the SG shading options (`--shading`, `--scene`, `--patches`,
//! `--no-shadows`, `--reference`) and the CPU reference image they are measured against.
//!
//! The reference is computed on a fixed grid of pixels (not the whole image: each pixel costs a dense
//! hemisphere quadrature): a ray through the pixel centre is marched against the bilinear heightmap for
//! the hit point, the exact (f64) mean of texel normals over the pixel's footprint box gives r, the
//! horizon is ray-marched at 64 azimuths, and `shading::reference` integrates it; fog and display encoding
//! follow as in the shader. Pixels whose ray leaves the data, or that show sky on the GPU, are skipped.

use super::args::{arg_error, PatchesArg, ShadingArg};
use clap::Args;
use clipsat::bake::horizon;
use clipsat::engine::setup;
use clipsat::gpu::readback::Image;
use clipsat::gpu::renderer::{SgShading, Shading};
use clipsat::package::shading_sats::ShadingBake;
use clipsat::plan::camera::Camera;
use clipsat::profile::Profile;
use clipsat::shading::scene::{self, Scene};
use clipsat::shading::{self, HorizonTable, Patches, RefCosine, RefGrid, RefInputs};
use clipsat::source::Heightmap;
use clipsat::Result;
use glam::{DVec3, Vec4};

/// The shading options shared by `render` and `fly`.
#[derive(Args, Debug, Clone)]
pub(crate) struct ShadingArgs {
    /// Shading.
    #[arg(long, value_enum, default_value_t = ShadingArg::Basic)]
    pub(crate) shading: ShadingArg,
    /// SG scene: a shipped name (noon, evening, overcast) or a TOML file. Default with --shading sg: noon.
    #[arg(long, value_name = "FILE|NAME")]
    pub(crate) scene: Option<String>,
    /// SG patches per lobe, MxN.
    #[arg(long, value_enum, value_name = "MxN", default_value_t = PatchesArg::P4x8)]
    pub(crate) patches: PatchesArg,
    /// SG: drop visibility (no horizon bake, no visibility texture) even if the scene asks for it.
    #[arg(long)]
    pub(crate) no_shadows: bool,
    /// SG: also compute a CPU reference of the same view on a pixel grid and report the error.
    #[arg(long)]
    pub(crate) reference: bool,
}

/// What `--shading sg` resolved to.
#[derive(Clone, Debug)]
pub(crate) struct SgChoice {
    pub(crate) scene: Scene,
    pub(crate) patches: Patches,
    pub(crate) shadows: bool,
}

impl SgChoice {
    /// Bakes (or reads from the disk cache) the tables this choice's scene needs within `profile`'s
    /// shading share of `cpu_memory_bytes`: from `package` out of core when the terrain streams, else
    /// from `hm`. The scene returned is the one drawn. [`shading`] turns the pair into the renderer's
    /// shading.
    pub(crate) fn bake(
        &self,
        profile: &Profile,
        hm: &Heightmap,
        package: Option<&clipsat::package::Package>,
    ) -> Result<(Scene, ShadingBake)> {
        crate::app::progress::bars!(true, bars, report, progress);
        setup::sg_tables(
            profile,
            hm,
            package,
            &self.scene,
            self.shadows,
            Some(&clipsat::bake::default_cache_dir()),
            progress,
        )
    }

    /// The scene as rendered: visibility off under `--no-shadows`.
    pub(crate) fn effective_scene(&self) -> Scene {
        let mut s = self.scene.clone();
        s.effects.visibility &= self.shadows;
        s
    }
}

/// The renderer's shading: SG over `baked` (from [`SgChoice::bake`]) when `--shading sg` chose it, else
/// basic.
pub(crate) fn shading<'a>(
    sg: Option<&SgChoice>,
    baked: Option<&'a (Scene, ShadingBake)>,
) -> Shading<'a> {
    match (sg, baked) {
        (Some(sg), Some((scene, bake))) => Shading::Sg(SgShading {
            scene,
            patches: sg.patches,
            bake,
            omit: clipsat::gpu::shaders::SgOmit::None,
        }),
        _ => Shading::Basic,
    }
}

impl ShadingArgs {
    /// None for basic shading; the scene (checked against the profile), patches and shadows for sg.
    pub(crate) fn choice(&self, profile: &Profile) -> Result<Option<SgChoice>> {
        let patches = Patches::from(self.patches);
        match self.shading {
            ShadingArg::Basic => {
                let sg_only = [
                    (self.scene.is_some(), "--scene"),
                    (self.no_shadows, "--no-shadows"),
                    (self.reference, "--reference"),
                    (patches != Patches::default(), "--patches"),
                ];
                match sg_only.iter().find(|(on, _)| *on) {
                    Some((_, arg)) => {
                        Err(arg_error(arg, "applies to SG shading: add --shading sg"))
                    }
                    None => Ok(None),
                }
            }
            ShadingArg::Sg => {
                let name = self.scene.as_deref().unwrap_or("noon");
                let scene = Scene::load(name).map_err(super::args::flag("--scene"))?;
                scene.check_profile(name, profile)?;
                Ok(Some(SgChoice {
                    scene,
                    patches,
                    shadows: !self.no_shadows,
                }))
            }
        }
    }
}

/// The reference colours (display-encoded, [0, 1]) at a fixed grid of pixels, and beside each the CPU twin
/// of the shader (`shading::shade`, 4 x 8) given the reference's own inputs: r over the pixel's footprint
/// in the full-resolution data and the marched horizon at the baked azimuths.
#[derive(Clone, Debug, Default)]
pub(crate) struct Reference {
    pixels: Vec<((u32, u32), [f64; 3])>,
    model: Vec<[f64; 3]>,
}

/// Error of an image against a [`Reference`], display-encoded units in [0, 1].
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct RefError {
    pub(crate) rmse: f64,
    pub(crate) max: f64,
    pub(crate) pixels: usize,
    /// The shading model's part of the error: the RMSE of the CPU twin against the reference on the
    /// same pixels and the same inputs. The rest of `rmse` is the inputs: the renderer reads the
    /// normals and horizons of the finest ring holding the pixel, which far away is coarser than the
    /// pixel's footprint in the data (the clipmap's resolution, fixed by the profile's ring size).
    pub(crate) model_rmse: f64,
}

/// Reference pixels per image side, at most (a `REF_GRID` x `REF_GRID` grid).
pub(crate) const REF_GRID: u32 = 24;

/// The ray through pixel (px, py)'s centre, from the eye (unit direction).
fn pixel_ray(camera: &Camera, size: (u32, u32), px: u32, py: u32) -> DVec3 {
    let aspect = f64::from(size.0) / f64::from(size.1);
    let inv = camera.view_proj_relative(aspect).inverse();
    #[expect(clippy::cast_possible_truncation, reason = "NDC in [-1, 1]")]
    let ndc = (
        ((f64::from(px) + 0.5) / f64::from(size.0) * 2.0 - 1.0) as f32,
        (1.0 - (f64::from(py) + 0.5) / f64::from(size.1) * 2.0) as f32,
    );
    let p = inv * Vec4::new(ndc.0, ndc.1, 0.5, 1.0);
    (p.truncate() / p.w).as_dvec3().normalize()
}

/// First hit of the ray from `eye` along `dir` with the bilinear height field, as grid (u, v); None if it
/// leaves the data or the far plane first.
fn hit(hm: &Heightmap, eye: DVec3, dir: DVec3, far: f64) -> Option<(f64, f64, DVec3)> {
    let step = f64::from(hm.spacing()) * 0.5;
    let (w, h) = (f64::from(hm.width() - 1), f64::from(hm.height() - 1));
    let above = |t: f64| {
        let p = eye + dir * t;
        let (u, v) = hm.world_to_grid(p.x, p.y);
        let inside = (0.0..=w).contains(&u) && (0.0..=h).contains(&v);
        (inside, p.z - horizon::height_bilinear(hm, u, v), u, v)
    };
    let mut t0 = 0.0;
    let mut t = step;
    while t < far {
        let (inside, dz, _, _) = above(t);
        if dz <= 0.0 {
            if !inside {
                return None;
            }
            // Bisect to the surface.
            let (mut a, mut b) = (t0, t);
            for _ in 0..30 {
                let m = 0.5 * (a + b);
                if above(m).1 > 0.0 {
                    a = m;
                } else {
                    b = m;
                }
            }
            let (_, _, u, v) = above(b);
            return Some((u, v, eye + dir * b));
        }
        t0 = t;
        t += step.max(t * 1e-3);
    }
    None
}

/// Display encoding of the shader: fog, clamp, gamma 1/2.2.
fn encode(linear: DVec3, distance: f64, scene: &Scene) -> [f64; 3] {
    #[expect(clippy::cast_possible_truncation, reason = "a distance in metres")]
    let c = scene::apply_fog(linear.as_vec3(), distance as f32, scene.fog.as_ref());
    let c = c.as_dvec3();
    [c.x, c.y, c.z].map(|v| v.clamp(0.0, 1.0).powf(1.0 / 2.2))
}

/// How finely the CPU reference samples: image pixels per side (at most) and hemisphere directions.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RefQuality {
    /// Reference pixels per image side, at most.
    pub(crate) pixels: u32,
    /// Hemisphere grid: polar and azimuthal steps.
    pub(crate) theta: u32,
    pub(crate) phi: u32,
}

impl RefQuality {
    /// What `render`, `fly` and `bench shading` report: [`REF_GRID`]^2 pixels, 96 x 192 directions.
    pub(crate) const FULL: Self = Self {
        pixels: REF_GRID,
        theta: 96,
        phi: 192,
    };
    /// `bench all --quick` (a test of the report, not a measurement): 4^2 pixels, 32 x 64 directions,
    /// 324x fewer direction evaluations (1.5 s -> 0.4 s a scene in CI's test build).
    pub(crate) const QUICK: Self = Self {
        pixels: 4,
        theta: 32,
        phi: 64,
    };
}

/// The CPU reference of `scene` (as rendered) seen from `camera` at image size `size`, on a grid of at
/// most [`REF_GRID`]^2 pixels.
pub(crate) fn reference(
    hm: &Heightmap,
    camera: &Camera,
    size: (u32, u32),
    scene: &Scene,
) -> Reference {
    reference_at(hm, camera, size, scene, RefQuality::FULL)
}

/// [`reference`] at a chosen [`RefQuality`].
pub(crate) fn reference_at(
    hm: &Heightmap,
    camera: &Camera,
    size: (u32, u32),
    scene: &Scene,
    quality: RefQuality,
) -> Reference {
    // The fog as the renderer binds it (Renderer::set_sg_baked).
    let mut fitted = scene.clone();
    let (ex, ey) = hm.extent_m();
    fitted.fit_fog(ex.hypot(ey));
    let scene = &fitted;
    let mut pixels = Vec::new();
    let grid = RefGrid {
        theta: quality.theta,
        phi: quality.phi,
        cosine: RefCosine::Exact,
    };
    let side = quality.pixels.max(1);
    let sky = shading::SkyTable::new(scene, Patches::P4x8);
    let mut model = Vec::new();
    for gy in 0..side.min(size.1) {
        for gx in 0..side.min(size.0) {
            let px = (2 * gx + 1) * size.0 / (2 * side.min(size.0));
            let py = (2 * gy + 1) * size.1 / (2 * side.min(size.1));
            let dir = pixel_ray(camera, size, px, py);
            let Some((u, v, p)) = hit(hm, camera.eye, dir, camera.far) else {
                continue;
            };
            // The footprint: the hit points of the neighbouring pixels' rays.
            let mut half = 0.5f64;
            for (dx, dy) in [(1, 0), (0, 1)] {
                let d2 = pixel_ray(camera, size, px + dx, py + dy);
                let dist = p.distance(camera.eye);
                let q = camera.eye + d2 * dist;
                let (u2, v2) = hm.world_to_grid(q.x, q.y);
                half = half.max(0.5 * (u2 - u).abs().max((v2 - v).abs()));
            }
            let half = half.min(f64::from(crate_box_side()) * 0.5);
            #[expect(clippy::cast_possible_truncation, reason = "grid indices, clamped")]
            let (x0, y0, x1, y1) = (
                (u - half + 0.5).floor().max(0.0) as u32,
                (v - half + 0.5).floor().max(0.0) as u32,
                (u + half + 0.5).floor().max(0.0) as u32,
                (v + half + 0.5).floor().max(0.0) as u32,
            );
            let mut r = DVec3::ZERO;
            let mut n = 0.0f64;
            for y in y0..=y1.min(hm.height() - 1) {
                for x in x0..=x1.min(hm.width() - 1) {
                    r += horizon::texel_normal(hm, x, y);
                    n += 1.0;
                }
            }
            let r = r / n.max(1.0);
            let table = scene
                .effects
                .visibility
                .then(|| HorizonTable::march(hm, u, v, 64, horizon::DEFAULT_MAX_SAMPLES));
            let c = shading::reference(
                &RefInputs {
                    r,
                    view: -dir,
                    horizon: table.as_ref(),
                },
                scene,
                grid,
            );
            pixels.push(((px, py), encode(c, p.distance(camera.eye), scene)));
            // The shader's D baked azimuths (every 4th of the 64 marched ones).
            #[expect(clippy::cast_possible_truncation, reason = "angles in radians")]
            let hz: Vec<f32> = table.as_ref().map_or_else(Vec::new, |t| {
                (0..horizon::DEFAULT_AZIMUTHS)
                    .map(|k| {
                        let a = std::f64::consts::TAU * f64::from(k)
                            / f64::from(horizon::DEFAULT_AZIMUTHS);
                        t.at(a) as f32
                    })
                    .collect()
            });
            let twin = shading::shade(
                &shading::Inputs {
                    r: r.as_vec3(),
                    horizon: &hz,
                    view: (-dir).as_vec3(),
                },
                scene,
                &sky,
            );
            model.push(encode(twin.as_dvec3(), p.distance(camera.eye), scene));
        }
    }
    Reference { pixels, model }
}

fn crate_box_side() -> u32 {
    clipsat::package::shading_sats::MAX_BOX_SIDE
}

impl Reference {
    /// RMSE and max error of `image` at the reference pixels it shows terrain at (not `sky`).
    pub(crate) fn error(&self, image: &Image, sky: [u8; 4]) -> RefError {
        let (mut sum, mut max, mut n, mut model) = (0.0f64, 0.0f64, 0usize, 0.0f64);
        for (((x, y), c), m) in self.pixels.iter().zip(&self.model) {
            let p = image.pixel(*x, *y);
            if p == sky {
                continue;
            }
            for k in 0..3 {
                let e = (f64::from(p[k]) / 255.0 - c[k]).abs();
                sum += e * e;
                max = max.max(e);
                model += (m[k] - c[k]).powi(2);
            }
            n += 1;
        }
        #[expect(clippy::cast_precision_loss, reason = "pixel counts")]
        let per = |s: f64| {
            if n > 0 {
                (s / (3 * n) as f64).sqrt()
            } else {
                0.0
            }
        };
        RefError {
            rmse: per(sum),
            max,
            pixels: n,
            model_rmse: per(model),
        }
    }
}

/// The clear colour of every render as RGBA8.
pub(crate) fn sky_rgba8() -> [u8; 4] {
    #[expect(
        clippy::cast_possible_truncation,
        reason = "colours in [0, 1] scaled to bytes"
    )]
    clipsat::shading::basic::SKY.map(|c| (c * 255.0).round() as u8)
}
