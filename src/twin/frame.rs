//! CPU twin of a drawn frame's colours: `basic_shade` (`shaders_gles/basic_shading.wgsl`) and `sg_colour`
//! (`shaders_gles/sg_clipmap.wgsl`), recomputed per pixel from what the GPU shaded the pixel with (the
//! shading probe, [`crate::gpu::renderer::ShadingProbe`]); for SG also what it read, from the tables'
//! CPU twin ([`super::shading::sg_taps`], [`super::shading::sg_inputs`], [`super::shading::sg_light`]).
//!
//! The tolerance is what GLES 3.0 allows a conformant driver (docs/real-drivers.md): a colour's conversion
//! to 8 bits may take either of the two nearest values (GLES 3.0 section 2.1.6.1), one level; highp
//! arithmetic (GLSL ES 3.00 section 4.5.1: correctly rounded +, -, *; 2.5 ulp division; exp, log within a
//! few ulp) moves a shaded colour by well under 1e-4, far below a level, so one more level is allowed for
//! it and for the functions whose precision GLSL ES leaves open (sin, cos, asin), which at the sun's
//! shadow edge (a cut about 0.03 rad wide) can move a pixel by a level or two. A conformant frame has at
//! most [`OUTLIERS`] of its pixels past [`LEVELS`] levels, and a mean difference of at most
//! [`MEAN_LEVELS`].

use glam::{Vec3, Vec4};

use crate::gpu::readback::Image;
use crate::gpu::renderer::ProbedFrame;
use crate::package::shading_sats::ShadingBake;
use crate::plan::clipmap::Clipmap;
use crate::plan::uniforms::Globals;
use crate::shading::basic::BasicShading;
use crate::shading::scene::Scene;
use crate::shading::{SkyTable, TexelLight, TexelLighting};

/// Levels (of 255) a pixel may differ from its twin: the 8-bit conversion's rounding, and highp
/// arithmetic.
pub const LEVELS: f32 = 2.0;
/// The share of pixels allowed past [`LEVELS`]: edges where a function GLSL ES gives no precision for
/// (the sun's cut) or a rounding of the footprint's level (`round(log2 w)` at a half) flips the result.
pub const OUTLIERS: f64 = 0.01;
/// The largest mean difference, levels (of each pixel's largest channel difference): a conversion that
/// truncates, which GLES 3.0 allows, averages 0.75 there, one that rounds to nearest 0.375.
pub const MEAN_LEVELS: f64 = 1.0;
/// How far the SG shader's r may lie from its twin's: a bilinear blend of the same f32 texels with
/// weights from a 2.5-ulp division, in either mix form.
pub const R_TOLERANCE: f32 = 1.0e-5;

/// The linear RGB of the ramp's stops, as `basic_shading.wgsl` decodes them (^2.2).
fn stop(c: [f32; 3]) -> Vec3 {
    Vec3::new(c[0].powf(2.2), c[1].powf(2.2), c[2].powf(2.2))
}

fn mix3(a: Vec3, b: Vec3, t: f32) -> Vec3 {
    a * (1.0 - t) + b * t
}

/// The CPU twin of `basic_shade`: the display-encoded colour of a terrain point of height `h`, geometric
/// normal `n` (not unit) at distance `dist` (m).
pub fn basic_colour(h: f32, n: Vec3, dist: f32, s: &BasicShading) -> Vec3 {
    basic_lit(basic_albedo(h, s), n, dist, s)
}

/// The CPU twin of `basic_albedo`: the ramp's linear-light albedo at height `h`.
pub fn basic_albedo(h: f32, s: &BasicShading) -> Vec3 {
    let lo = s.ramp_fog[0];
    let span = (s.ramp_fog[1] - lo).max(1.0e-3);
    let t = ((h - lo) / span).clamp(0.0, 1.0);
    let mut land = mix3(
        stop([0.30, 0.50, 0.22]),
        stop([0.45, 0.56, 0.28]),
        (t / 0.25).clamp(0.0, 1.0),
    );
    land = mix3(
        land,
        stop([0.56, 0.49, 0.31]),
        ((t - 0.25) / 0.20).clamp(0.0, 1.0),
    );
    land = mix3(
        land,
        stop([0.46, 0.37, 0.27]),
        ((t - 0.45) / 0.20).clamp(0.0, 1.0),
    );
    land = mix3(
        land,
        stop([0.55, 0.54, 0.52]),
        ((t - 0.65) / 0.15).clamp(0.0, 1.0),
    );
    land = mix3(
        land,
        stop([0.95, 0.96, 0.98]),
        ((t - 0.80) / 0.08).clamp(0.0, 1.0),
    );
    let depth = (-h / (0.25 * span).max(1.0)).clamp(0.0, 1.0);
    if h <= 0.0 {
        mix3(stop([0.18, 0.40, 0.64]), stop([0.05, 0.16, 0.36]), depth)
    } else {
        land
    }
}

/// The light and fog of `basic_shade` (and of `imagery_shade`) on `albedo`: the display-encoded colour
/// with geometric normal `n` (not unit) at distance `dist` (m).
pub fn basic_lit(albedo: Vec3, n: Vec3, dist: f32, s: &BasicShading) -> Vec3 {
    let z = s.ramp_fog[3] / n.z.max(1.0e-6);
    let nn = Vec3::new(n.x * z, n.y * z, 1.0).normalize();
    let sun_dir = Vec3::new(s.sun_dir[0], s.sun_dir[1], s.sun_dir[2]);
    let sun = nn.dot(sun_dir).max(0.0);
    let sky = 0.5 + 0.5 * nn.z;
    let light =
        Vec3::new(1.00, 0.95, 0.86) * (1.45 * sun) + Vec3::new(0.50, 0.62, 0.80) * (0.30 * sky);
    let fog = 1.0 - (-dist * s.ramp_fog[2]).exp();
    let fog_colour = Vec3::new(s.fog_colour[0], s.fog_colour[1], s.fog_colour[2]);
    let lit = mix3(albedo * light, fog_colour, fog);
    encode(lit)
}

/// Display encoding: clamped to [0, 1], ^(1 / 2.2).
fn encode(c: Vec3) -> Vec3 {
    let c = c.clamp(Vec3::ZERO, Vec3::ONE);
    Vec3::new(
        c.x.powf(1.0 / 2.2),
        c.y.powf(1.0 / 2.2),
        c.z.powf(1.0 / 2.2),
    )
}

/// What the SG fragment program shades with besides r: the scene as drawn, its sky table, its texel
/// lighting (the light table's inputs) and the bake the tables are written from.
#[derive(Clone, Copy, Debug)]
pub struct SgDrawn<'a> {
    /// The scene as drawn ([`crate::gpu::renderer::Renderer::sg_drawn`]).
    pub scene: &'a Scene,
    /// Its sky table.
    pub sky: &'a SkyTable,
    /// Its texel lighting ([`TexelLighting::new`] of the scene).
    pub lighting: &'a TexelLighting,
    /// The baked tables.
    pub bake: &'a ShadingBake,
    /// The data's spacing (m), the footprint's unit.
    pub data_spacing: f32,
}

/// The CPU twin of `sg_colour` given r (xyz, w the horizon's sine toward the first sun) and, with
/// visibility, the light table's blend (rgb diffuse, a the horizon's mean sine), at eye-relative `rel`.
pub fn sg_colour(r: Vec4, light: Option<[f32; 4]>, rel: Vec3, d: &SgDrawn<'_>) -> Vec3 {
    sg_colour_scaled(r, light, rel, d, Vec3::ONE)
}

/// [`sg_colour`] with the diffuse term scaled by `albedo_scale` (draped imagery's albedo over k_d).
pub fn sg_colour_scaled(
    r: Vec4,
    light: Option<[f32; 4]>,
    rel: Vec3,
    d: &SgDrawn<'_>,
    albedo_scale: Vec3,
) -> Vec3 {
    let texel = light.map(|l| TexelLight {
        diffuse: Vec3::new(l[0], l[1], l[2]),
        mean_sin: l[3],
        sun_sin: r.w,
    });
    let view = (-rel).normalize();
    let mut c = crate::shading::shade_pixel_scaled(
        r.truncate(),
        view,
        texel.as_ref(),
        d.scene,
        d.sky,
        albedo_scale,
    );
    if let (true, Some(f)) = (d.scene.effects.fog, d.scene.fog.as_ref()) {
        let keep = (-(f.density_per_km * 1.0e-3) * rel.length()).exp();
        c = c * keep + f.rgb * (1.0 - keep);
    }
    encode(c)
}

/// How a frame compares with its twin.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct TwinReport {
    /// Pixels compared (drawn ones).
    pub pixels: u64,
    /// Pixels past [`LEVELS`].
    pub outliers: u64,
    /// Mean absolute difference, levels of 255 (largest channel per pixel).
    pub mean_levels: f64,
    /// Largest difference, levels.
    pub max_levels: f32,
    /// Where the largest is (x, y).
    pub worst_at: (u32, u32),
    /// Pixels the probe found drawn that the frame left at the clear colour, or the reverse.
    pub coverage_mismatch: u64,
    /// SG: the largest difference of the shader's r from its twin's (0 for basic shading).
    pub max_r_error: f32,
    /// SG: pixels whose r differs from the twin's by more than [`R_TOLERANCE`].
    pub r_outliers: u64,
}

impl TwinReport {
    /// Whether the frame is within what a conformant driver may draw.
    pub fn passes(&self) -> bool {
        #[expect(clippy::cast_precision_loss, reason = "pixel counts far below 2^52")]
        let share = |n: u64| n as f64 / self.pixels.max(1) as f64;
        self.pixels > 0
            && share(self.outliers) <= OUTLIERS
            && self.mean_levels <= MEAN_LEVELS
            && share(self.coverage_mismatch) <= OUTLIERS
            && share(self.r_outliers) <= OUTLIERS
    }

    fn add(&mut self, got: &[u8], want: Vec3, x: u32, y: u32, sum: &mut f64) {
        let d = [want.x, want.y, want.z]
            .iter()
            .zip(got)
            .map(|(w, g)| (w * 255.0 - f32::from(*g)).abs())
            .fold(0.0f32, f32::max);
        self.pixels += 1;
        *sum += f64::from(d);
        if d > LEVELS {
            self.outliers += 1;
        }
        if d > self.max_levels {
            self.max_levels = d;
            self.worst_at = (x, y);
        }
    }
}

/// The twin's colour of a pixel from its probed position and inputs (noting input errors in the report).
type TwinColour<'a> = dyn FnMut([f32; 4], [f32; 4], &mut TwinReport) -> Vec3 + 'a;

/// Compares `image` with its twin, pixel by pixel where `probe` (the same frame's shading probe) found a
/// fragment; `colour` gives the twin's display-encoded colour from the probe's position and inputs (and
/// may also note an input error in the report). Undrawn pixels must hold `clear` (within a level).
fn compare(
    image: &Image,
    probe: &ProbedFrame,
    clear: [u8; 4],
    colour: &mut TwinColour<'_>,
) -> TwinReport {
    assert_eq!(
        (image.width, image.height),
        (probe.width, probe.height),
        "a probe of another view"
    );
    let mut report = TwinReport::default();
    let mut sum = 0.0f64;
    for (i, (p, inputs)) in (0u32..).zip(probe.position.iter().zip(&probe.inputs)) {
        let at = i as usize * 4;
        let got = &image.rgba[at..at + 4];
        let is_clear = got.iter().zip(clear).all(|(a, b)| a.abs_diff(b) <= 1);
        let Some(p) = p else {
            report.coverage_mismatch += u64::from(!is_clear);
            continue;
        };
        let want = colour(*p, *inputs, &mut report);
        let (x, y) = (i % image.width, i / image.width);
        report.add(got, want, x, y, &mut sum);
    }
    #[expect(clippy::cast_precision_loss, reason = "pixel counts far below 2^52")]
    let n = report.pixels.max(1) as f64;
    report.mean_levels = sum / n;
    report
}

/// Compares a basic-shading frame with the twin of `basic_shade` on the height and normal each pixel
/// was shaded with.
pub fn compare_basic(
    image: &Image,
    probe: &ProbedFrame,
    clear: [u8; 4],
    s: &BasicShading,
) -> TwinReport {
    compare(image, probe, clear, &mut |p, q, _| {
        let rel = Vec3::new(p[0], p[1], p[2]);
        basic_colour(q[0], Vec3::new(q[1], q[2], q[3]), rel.length(), s)
    })
}

/// Compares a frame with draped imagery with its twin: `basic_shade`'s light and fog on the imagery's
/// albedo ([`super::imagery::ImageryTwin::albedo`]) at each pixel's probed position and footprint, over
/// the ramp's albedo of the height it was shaded with.
pub fn compare_imagery(
    image: &Image,
    probe: &ProbedFrame,
    clear: [u8; 4],
    s: &BasicShading,
    twin: &super::imagery::ImageryTwin,
) -> TwinReport {
    compare(image, probe, clear, &mut |p, q, _| {
        let rel = Vec3::new(p[0], p[1], p[2]);
        let albedo = twin.albedo([p[0], p[1]], p[3], basic_albedo(q[0], s));
        basic_lit(albedo, Vec3::new(q[1], q[2], q[3]), rel.length(), s)
    })
}

/// Compares an SG frame with its twin: per pixel the taps of the GPU's own position and footprint
/// ([`super::shading::sg_taps`]; where round(log2 w) sits within 1e-3 of a half, both levels are
/// tried), r and the light texel from the bake's values at them, and the colour from those. The GPU's
/// r is checked against the twin's ([`R_TOLERANCE`]): what the shader read.
pub fn compare_sg(
    image: &Image,
    probe: &ProbedFrame,
    clear: [u8; 4],
    globals: &Globals,
    clipmap: &Clipmap,
    d: &SgDrawn<'_>,
) -> TwinReport {
    compare_sg_with(image, probe, clear, globals, clipmap, d, None)
}

/// [`compare_sg`] of a frame with draped imagery: the twin's diffuse term scaled by the imagery's albedo
/// ([`super::imagery::ImageryTwin::albedo`] at the pixel's footprint in metres) over the scene's k_d.
pub fn compare_sg_imagery(
    image: &Image,
    probe: &ProbedFrame,
    clear: [u8; 4],
    globals: &Globals,
    clipmap: &Clipmap,
    d: &SgDrawn<'_>,
    imagery: &super::imagery::ImageryTwin,
) -> TwinReport {
    compare_sg_with(image, probe, clear, globals, clipmap, d, Some(imagery))
}

fn compare_sg_with(
    image: &Image,
    probe: &ProbedFrame,
    clear: [u8; 4],
    globals: &Globals,
    clipmap: &Clipmap,
    d: &SgDrawn<'_>,
    imagery: Option<&super::imagery::ImageryTwin>,
) -> TwinReport {
    compare(image, probe, clear, &mut |p, q, report| {
        let rel = Vec3::new(p[0], p[1], p[2]);
        let w = p[3];
        // The SG footprint is in data samples; the imagery's in metres.
        let scale = imagery.map_or(Vec3::ONE, |t| {
            let kd = d.scene.material.kd;
            t.albedo([p[0], p[1]], w * d.data_spacing, kd) / kd.max(Vec3::splat(1.0e-6))
        });
        let got_r = Vec4::from(q);
        let l = w.max(1.0).log2();
        let mut sides = vec![w];
        if (l - l.floor() - 0.5).abs() < 1.0e-3 {
            // Either side of the half: the shader's log2 may round it either way.
            sides = vec![(l.floor() + 0.4).exp2(), (l.floor() + 0.6).exp2()];
        }
        let mut best: Option<(f32, Vec4, Vec3)> = None;
        for side in sides {
            let Some(taps) = super::shading::sg_taps(globals, d.data_spacing, [rel.x, rel.y], side)
            else {
                continue;
            };
            let (r, _) = super::shading::sg_inputs(d.bake, clipmap, &taps);
            // With visibility the normal table's w is the sun's horizon sine (the light table's
            // inputs); without, the tables write 0 there.
            let (r, light) = if d.scene.effects.visibility {
                let (light, sun) =
                    super::shading::sg_light(d.bake, clipmap, &taps, d.lighting, d.sky);
                (r.extend(sun), Some(light))
            } else {
                (r.extend(0.0), None)
            };
            let e = (r - got_r).abs().max_element();
            if best.is_none_or(|b| e < b.0) {
                best = Some((e, r, sg_colour_scaled(r, light, rel, d, scale)));
            }
        }
        let Some((e, _, c)) = best else {
            return Vec3::ZERO;
        };
        report.max_r_error = report.max_r_error.max(e);
        report.r_outliers += u64::from(e > R_TOLERANCE);
        c
    })
}
