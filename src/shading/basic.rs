//! Shading: the basic shading's parameters (height ramp, Lambert sun, sky, fog), the CPU side of
//! `shaders_gles/basic_shading.wgsl`.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

/// Uniform parameters of the basic shading; mirrors `BasicShading` in `shaders_gles/basic_shading.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BasicShading {
    /// x: height (m) where the land ramp starts, y: where it ends, z: fog density (1/m), w: unused.
    pub ramp_fog: [f32; 4],
    /// xyz: unit vector toward the sun (x east, y north, z up), w: unused.
    pub sun_dir: [f32; 4],
    /// rgb: fog colour (display-encoded), a: unused.
    pub fog_colour: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<BasicShading>() == 48);

/// The sky behind the terrain (display-encoded RGBA), the clear colour of every render.
pub const SKY: [f64; 4] = [0.63, 0.76, 0.90, 1.0];

/// The fog colour, a little paler than the sky at the zenith.
const FOG: [f32; 4] = [0.74, 0.81, 0.89, 1.0];

impl BasicShading {
    /// Shading for a terrain whose heights span `range` (m) over a horizontal `diagonal` (m).
    ///
    /// The land ramp runs from max(lowest, 0) to the highest sample, so every terrain uses the whole
    /// ramp; water is anything at or below 0 m. Fog halves the colour at 1.5 diagonals. The sun sits
    /// in the north-west, 40 degrees up, as in cartographic hill shading.
    #[expect(
        clippy::cast_possible_truncation,
        reason = "fog density is a small positive number, f32 is its GPU precision"
    )]
    pub fn for_terrain(range: (f32, f32), diagonal: f64) -> Self {
        let lo = range.0.max(0.0);
        let hi = range.1.max(lo + 1.0);
        let fog_density = std::f64::consts::LN_2 / (1.5 * diagonal.max(1.0));
        let (az, el) = (315f32.to_radians(), 40f32.to_radians());
        // Azimuth clockwise from north: east = sin, north = cos.
        let sun = Vec3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin()).normalize();
        Self {
            ramp_fog: [lo, hi, fog_density as f32, 0.0],
            sun_dir: [sun.x, sun.y, sun.z, 0.0],
            fog_colour: FOG,
        }
    }
}
