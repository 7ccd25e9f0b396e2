//! Stage 1, bake: horizon elevation angles for D azimuths per texel (SAT paper section 5, the prebaked
//! visibility), and the footprint box averages the shader filters them with.
//!
//! Azimuths are mathematical: a = 0 points east (+x), a = pi/2 north (+y); azimuth k of D is 2 pi k / D.
//! A horizon angle is the elevation (radians above the horizontal plane, in [-pi/2, pi/2]) of the highest
//! terrain seen from the texel along that azimuth, marched out to a bounded distance. Light from direction
//! (azimuth a, elevation e) reaches the texel iff e > horizon(a).

use std::f64::consts::{FRAC_PI_2, TAU};

use glam::{DVec3, Vec3};

use crate::bake::sat::Sat;
use crate::{Error, Result};
use crate::source::Heightmap;

/// Default number of baked azimuths D: 16, the shader's most. The horizon between baked azimuths is
/// linear, and a low sun's shadows follow the horizon at its exact azimuth: on Aletsch at 640 x 360
/// (`clipsat render --profile desktop --terrain aletsch_200m.tif --size 640x360
/// --shading sg --scene evening --reference --json`) the RMSE against the CPU reference is 0.0208 with
/// D = 8 and 0.0124 with D = 16 (0.0120 without visibility): D = 8 was most of the evening error.
pub const DEFAULT_AZIMUTHS: u32 = 16;
/// Most azimuths a bake may hold (the shader's fixed-size array).
pub const MAX_AZIMUTHS: u32 = 16;
/// Default march distance, in samples: far enough for the soft shadows of ridges a few hundred samples
/// long, bounded so a bake costs O(texels x D x log(distance)).
pub const DEFAULT_MAX_SAMPLES: f64 = 256.0;
/// The march's sample distances in samples: every sample out to 16, then growing by 1/16 per step (about
/// 6 %, so a 2-sample-wide ridge at distance d is never stepped over by more than d/16), up to `max`.
pub fn march_distances(max: f64) -> impl Iterator<Item = f64> {
    std::iter::successors(Some(1.0f64), |&d| Some(d + (d / 16.0).max(1.0)))
        .take_while(move |&d| d <= max)
}

/// Height at fractional grid coordinates (column u, row v), bilinear, clamped flat beyond the border.
#[expect(
    clippy::cast_possible_truncation,
    reason = "floors of finite grid coordinates; at_clamped clamps them"
)]
pub fn height_bilinear(hm: &Heightmap, u: f64, v: f64) -> f64 {
    let (u0, v0) = (u.floor(), v.floor());
    let (fu, fv) = (u - u0, v - v0);
    let (iu, iv) = (u0 as i64, v0 as i64);
    let h = |x: i64, y: i64| f64::from(hm.at_clamped(x, y));
    let a = h(iu, iv) * (1.0 - fu) + h(iu + 1, iv) * fu;
    let b = h(iu, iv + 1) * (1.0 - fu) + h(iu + 1, iv + 1) * fu;
    a * (1.0 - fv) + b * fv
}

/// The horizon elevation seen from grid point (u, v) along world azimuth `azimuth`, marching
/// [`march_distances`] out to `max_samples`. Row v grows southward, so a step north is -v.
pub fn horizon_elevation(hm: &Heightmap, u: f64, v: f64, azimuth: f64, max_samples: f64) -> f64 {
    let h0 = height_bilinear(hm, u, v);
    let (du, dv) = (azimuth.cos(), -azimuth.sin());
    let s = f64::from(hm.spacing());
    let mut best = -FRAC_PI_2;
    for d in march_distances(max_samples) {
        let h = height_bilinear(hm, u + du * d, v + dv * d);
        best = best.max((h - h0).atan2(d * s));
    }
    best
}

/// Baked horizons: D angles (f32 radians) per texel, texel-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Horizons {
    width: u32,
    height: u32,
    azimuths: u32,
    angles: Vec<f32>,
}

impl Horizons {
    /// Texels per row.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// D, the azimuths per texel.
    pub fn azimuths(&self) -> u32 {
        self.azimuths
    }

    /// All angles, texel-major (D per texel).
    pub fn angles(&self) -> &[f32] {
        &self.angles
    }

    /// The D angles of texel (x, y). Panics outside the grid (a caller bug).
    pub fn at(&self, x: u32, y: u32) -> &[f32] {
        assert!(
            x < self.width && y < self.height,
            "texel ({x}, {y}) outside horizons"
        );
        let d = self.azimuths as usize;
        let i = (y as usize * self.width as usize + x as usize) * d;
        &self.angles[i..i + d]
    }
}

/// Bakes D horizon angles for every texel of `hm`, marching out to `max_samples` samples. Deterministic
/// (single-threaded, fixed order). The renderer's tables march the same horizons through
/// `ShadingBake`, which reports progress; this whole-terrain bake serves the CPU references.
pub fn bake(hm: &Heightmap, azimuths: u32, max_samples: f64) -> Result<Horizons> {
    // Multiples of 4: the light table's writer (shading::texel_light) integrates the sky's wedges over
    // pairs, and the shader's probe reads them four to a texel.
    if azimuths == 0 || azimuths > MAX_AZIMUTHS || !azimuths.is_multiple_of(4) {
        return Err(Error::Invalid {
            what: "azimuths".into(),
            reason: format!("{azimuths} is not a multiple of 4 in 4..={MAX_AZIMUTHS}"),
        });
    }
    if !(max_samples.is_finite() && max_samples >= 1.0) {
        return Err(Error::Invalid {
            what: "max_samples".into(),
            reason: format!("{max_samples} must be at least 1 sample"),
        });
    }
    let (w, h) = (hm.width(), hm.height());
    let texels = u64::from(w) * u64::from(h);
    let d = azimuths as usize;
    let mut angles = vec![0.0f32; usize::try_from(texels * u64::from(azimuths)).unwrap_or(0)];
    for y in 0..h {
        for x in 0..w {
            let at = (y as usize * w as usize + x as usize) * d;
            texel_horizons(hm, x, y, max_samples, &mut angles[at..at + d]);
        }
    }
    Ok(Horizons {
        width: w,
        height: h,
        azimuths,
        angles,
    })
}

/// The `out.len()` = D horizon angles of texel (x, y), azimuth k at 2 pi k / D, marching out to
/// `max_samples` samples: one texel of [`bake`], for bakes that stream their output (the shading
/// tables, `package/shading_sats.rs`).
pub fn texel_horizons(hm: &Heightmap, x: u32, y: u32, max_samples: f64, out: &mut [f32]) {
    #[expect(clippy::cast_precision_loss, reason = "D <= MAX_AZIMUTHS")]
    let d = out.len() as f64;
    for (k, o) in out.iter_mut().enumerate() {
        #[expect(clippy::cast_precision_loss, reason = "k < D <= MAX_AZIMUTHS")]
        let a = TAU * k as f64 / d;
        let e = horizon_elevation(hm, f64::from(x), f64::from(y), a, max_samples);
        #[expect(clippy::cast_possible_truncation, reason = "an angle in [-pi/2, pi/2]")]
        let e = e as f32;
        *o = e;
    }
}

/// The horizon at world azimuth `a` (radians, any range) from D angles at azimuths 2 pi k / D, linearly
/// interpolated between the two nearest (the shader's PatchVis lookup).
#[expect(
    clippy::cast_possible_truncation,
    reason = "the floor of a value in [0, D) indexes the D angles"
)]
pub fn interpolate(angles: &[f32], a: f32) -> f32 {
    let d = angles.len();
    if d == 0 {
        return -std::f32::consts::FRAC_PI_2;
    }
    let t = (a / std::f32::consts::TAU).rem_euclid(1.0) * d as f32;
    let k0 = (t.floor() as usize).min(d - 1);
    let f = t - k0 as f32;
    angles[k0] * (1.0 - f) + angles[(k0 + 1) % d] * f
}

/// The unit normal of texel (x, y) from central differences (one-sided at the border), z up.
pub fn texel_normal(hm: &Heightmap, x: u32, y: u32) -> DVec3 {
    let (xi, yi) = (i64::from(x), i64::from(y));
    let s = f64::from(hm.spacing());
    let h = |x: i64, y: i64| f64::from(hm.at_clamped(x, y));
    let (xl, xr) = ((xi - 1).max(0), (xi + 1).min(i64::from(hm.width()) - 1));
    let (yn, ys) = ((yi - 1).max(0), (yi + 1).min(i64::from(hm.height()) - 1));
    #[expect(clippy::cast_precision_loss, reason = "spans of at most 2 samples")]
    let dzdx = (h(xr, yi) - h(xl, yi)) / ((xr - xl) as f64 * s);
    // Row y grows southward: north is y - 1.
    #[expect(clippy::cast_precision_loss, reason = "spans of at most 2 samples")]
    let dzdy = (h(xi, yn) - h(xi, ys)) / ((ys - yn) as f64 * s);
    DVec3::new(-dzdx, -dzdy, 1.0).normalize()
}

/// Footprint averages over a texel box: the unnormalised mean normal r and the mean of each of the D
/// horizon angles. This is what SAT-filtering (SAT paper algorithm 2: four corner fetches per table)
/// returns for the pixel's footprint box; this brute-force version is its reference.
#[derive(Clone, Debug, PartialEq)]
pub struct BoxAverage {
    /// Mean of the unit texel normals; |r| < 1 where they disagree.
    pub r: Vec3,
    /// Mean horizon angle per azimuth.
    pub horizon: Vec<f32>,
}

/// Averages texel normals and horizons over the inclusive box [x0, x1] x [y0, y1] (clamped to the grid).
#[expect(
    clippy::cast_possible_truncation,
    reason = "means of unit vectors and of angles, stored as f32"
)]
pub fn box_average(
    hm: &Heightmap,
    hz: &Horizons,
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
) -> BoxAverage {
    let (x1, y1) = (x1.min(hm.width() - 1), y1.min(hm.height() - 1));
    let (x0, y0) = (x0.min(x1), y0.min(y1));
    let d = hz.azimuths() as usize;
    let mut r = DVec3::ZERO;
    let mut sum = vec![0.0f64; d];
    let mut n = 0.0f64;
    for y in y0..=y1 {
        for x in x0..=x1 {
            r += texel_normal(hm, x, y);
            for (s, &a) in sum.iter_mut().zip(hz.at(x, y)) {
                *s += f64::from(a);
            }
            n += 1.0;
        }
    }
    BoxAverage {
        r: (r / n).as_vec3(),
        horizon: sum.iter().map(|s| (s / n) as f32).collect(),
    }
}

/// The SAT-backed footprint filter (SAT paper algorithm 2): one [`Sat`] per normal component, mapped
/// (n + 1) / 2, and one per horizon azimuth, mapped (a + pi/2) / pi, each answering a box mean with four
/// corner fetches. The CPU twin of the GPU tables; [`box_average`] is its brute-force reference.
///
/// GPU format: R32UI wrapping fixed point, Q = 20 fractional bits (a 64^2 footprint box of ones stays below
/// 2^32, so the wrapping corner difference is exact). Measured by `tests/cpu/shading.rs gpu_sat_format_error`
/// on a 1024^2 grid, boxes of 1 to 64^2 samples: max error of a box mean 4.4e-7 (the rounding, <= 2^-21),
/// against 1.7e-4 for RGBA32F with the global mean subtracted and 4.5e-3 for plain RGBA32F. Boxes over
/// 4096 samples must be split (or clamped to a 64^2 footprint) or they wrap.
#[derive(Clone, Debug)]
pub struct FootprintSats {
    normal: [Sat; 3],
    horizon: Vec<Sat>,
}

impl FootprintSats {
    /// Builds the 3 + D tables at the finest quantum the grid allows.
    pub fn build(hm: &Heightmap, hz: &Horizons) -> Result<Self> {
        let (w, h) = (hm.width(), hm.height());
        let q = Sat::max_frac_bits(u64::from(w) * u64::from(h));
        let normals: Vec<DVec3> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| texel_normal(hm, x, y))
            .collect();
        let at = |x: u32, y: u32| y as usize * w as usize + x as usize;
        let channel = |c: usize| {
            Sat::build(w, h, 1, q, |x, y| {
                ((normals[at(x, y)][c] + 1.0) * 0.5).clamp(0.0, 1.0)
            })
        };
        let normal = [channel(0)?, channel(1)?, channel(2)?];
        let horizon = (0..hz.azimuths() as usize)
            .map(|k| {
                Sat::build(w, h, 1, q, |x, y| {
                    ((f64::from(hz.at(x, y)[k]) + FRAC_PI_2) / std::f64::consts::PI).clamp(0.0, 1.0)
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self { normal, horizon })
    }

    /// Box means over the inclusive box [x0, x1] x [y0, y1] (clamped to the grid).
    #[expect(
        clippy::cast_possible_truncation,
        reason = "means of unit vectors and of angles, stored as f32"
    )]
    pub fn box_average(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> BoxAverage {
        let (x1, y1) = (
            x1.min(self.normal[0].width() - 1),
            y1.min(self.normal[0].height() - 1),
        );
        let (x0, y0) = (x0.min(x1), y0.min(y1));
        let n = f64::from(x1 - x0 + 1) * f64::from(y1 - y0 + 1);
        // Sat boxes are half-open.
        let mean = |s: &Sat| s.box_sum(x0, y0, x1 + 1, y1 + 1) / n;
        let r = DVec3::new(
            mean(&self.normal[0]),
            mean(&self.normal[1]),
            mean(&self.normal[2]),
        ) * 2.0
            - DVec3::ONE;
        BoxAverage {
            r: r.as_vec3(),
            horizon: self
                .horizon
                .iter()
                .map(|s| (mean(s) * std::f64::consts::PI - FRAC_PI_2) as f32)
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_wraps() {
        let a = [0.0, 0.4, 0.8, 0.4];
        assert!((interpolate(&a, 0.0) - 0.0).abs() < 1e-6);
        assert!((interpolate(&a, std::f32::consts::PI) - 0.8).abs() < 1e-6);
        // Between azimuth 3 (3 pi / 2) and azimuth 0 (2 pi).
        assert!((interpolate(&a, 1.75 * std::f32::consts::PI) - 0.2).abs() < 1e-5);
        assert!((interpolate(&a, -0.25 * std::f32::consts::PI) - 0.2).abs() < 1e-5);
    }

    #[test]
    fn march_is_bounded_and_dense_near() {
        let d: Vec<f64> = march_distances(256.0).collect();
        assert_eq!(&d[..16], &(1..=16).map(f64::from).collect::<Vec<_>>()[..]);
        assert!(d.len() < 70 && *d.last().unwrap_or(&0.0) <= 256.0);
    }
}
