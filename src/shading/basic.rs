//! Shading: the basic shading's parameters (height ramp, Lambert sun, sky, fog), the CPU side of
//! `shaders_gles/basic_shading.wgsl`.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

/// Uniform parameters of the basic shading; mirrors `BasicShading` in `shaders_gles/basic_shading.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BasicShading {
    /// x: height (m) where the land ramp starts, y: where it ends, z: fog density (1/m), w: the hill
    /// shading's z-factor ([`z_factor`]).
    pub ramp_fog: [f32; 4],
    /// xyz: unit vector toward the sun (x east, y north, z up), w: the colour target's encoding, set by the
    /// renderer (0: the shaders write display-encoded colour; 1: an sRGB target, which encodes it).
    pub sun_dir: [f32; 4],
    /// rgb: fog colour (linear light: the display-encoded colour ^ 2.2, decoded once here rather than per
    /// pixel), a: unused.
    pub fog_colour: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<BasicShading>() == 48);

/// The basic sun's azimuth, degrees clockwise from north.
pub const SUN_AZIMUTH_DEG: f32 = 290.0;
/// The basic sun's elevation, degrees.
pub const SUN_ELEVATION_DEG: f32 = 30.0;

/// The sky behind the terrain (display-encoded RGBA), the clear colour of every render.
pub const SKY: [f64; 4] = [0.63, 0.76, 0.90, 1.0];

/// The fog colour, a little paler than the sky at the zenith.
const FOG: [f32; 4] = [0.74, 0.81, 0.89, 1.0];

impl BasicShading {
    /// Shading for a terrain whose heights span `range` (m) over a horizontal `diagonal` (m).
    ///
    /// The land ramp runs from max(lowest, 0) to the highest sample, so every terrain uses the whole
    /// ramp; water is anything at or below 0 m. Fog halves the colour at 3 diagonals (a third at the far corner of the default view). The sun sits
    /// low in the west-north-west ([`SUN_AZIMUTH_DEG`], [`SUN_ELEVATION_DEG`]): from the default camera
    /// (looking north) it lights slopes from the side, so hills show their shape. `mean_slope` (rise over
    /// run, [`mean_slope`]) sets the hill shading's z-factor.
    #[expect(
        clippy::cast_possible_truncation,
        reason = "fog density is a small positive number, f32 is its GPU precision"
    )]
    pub fn for_terrain(range: (f32, f32), diagonal: f64, mean_slope: f64) -> Self {
        let lo = range.0.max(0.0);
        let hi = range.1.max(lo + 1.0);
        let fog_density = std::f64::consts::LN_2 / (3.0 * diagonal.max(1.0));
        let (az, el) = (SUN_AZIMUTH_DEG.to_radians(), SUN_ELEVATION_DEG.to_radians());
        // Azimuth clockwise from north: east = sin, north = cos.
        let sun = Vec3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin()).normalize();
        Self {
            ramp_fog: [lo, hi, fog_density as f32, z_factor(mean_slope) as f32],
            sun_dir: [sun.x, sun.y, sun.z, 0.0],
            fog_colour: [FOG[0].powf(2.2), FOG[1].powf(2.2), FOG[2].powf(2.2), FOG[3]],
        }
    }
}

/// The mean slope the hill shading aims for: a gentle terrain's normals are steepened towards it.
pub const SHADED_MEAN_SLOPE_DEG: f64 = 10.0;
/// The largest z-factor (vertical exaggeration of the shading normals).
pub const MAX_Z_FACTOR: f64 = 6.0;

/// The hill shading's z-factor for a terrain of mean slope `mean_slope` (rise over run): the gradient
/// under the sun is scaled so the mean slope shades like [`SHADED_MEAN_SLOPE_DEG`], between 1 (a steep
/// terrain is shaded as it is) and [`MAX_Z_FACTOR`]. Cartographic hill shading does the same, so a 2
/// degree plain shows its relief as an alpine range does; only the shading sees it, not the geometry.
pub fn z_factor(mean_slope: f64) -> f64 {
    let target = SHADED_MEAN_SLOPE_DEG.to_radians().tan();
    if mean_slope.is_finite() && mean_slope > 0.0 {
        (target / mean_slope).clamp(1.0, MAX_Z_FACTOR)
    } else {
        MAX_Z_FACTOR
    }
}

/// Mean slope (rise over run) of a `width`-wide grid of `heights` at `spacing` metres: the mean of
/// |forward-difference gradient| over at most about a million samples (a strided subset of a larger
/// grid).
#[expect(
    clippy::cast_precision_loss,
    reason = "sample counts and strides are far below 2^52"
)]
pub fn mean_slope(heights: &[f32], width: usize, spacing: f64) -> f64 {
    if width < 2 || heights.len() < 2 * width || spacing <= 0.0 {
        return 0.0;
    }
    let rows = heights.len() / width;
    // The smallest stride s with (width / s) (rows / s) <= 1e6.
    let mut stride = 1;
    while (width / stride) * (rows / stride) > 1_000_000 {
        stride += 1;
    }
    let (mut sum, mut count) = (0.0f64, 0u64);
    for v in (0..rows - 1).step_by(stride) {
        for u in (0..width - 1).step_by(stride) {
            let z = f64::from(heights[v * width + u]);
            let dx = f64::from(heights[v * width + u + 1]) - z;
            let dy = f64::from(heights[(v + 1) * width + u]) - z;
            sum += dx.hypot(dy) / spacing;
            count += 1;
        }
    }
    sum / count.max(1) as f64
}
