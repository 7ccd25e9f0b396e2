//! Shading: the CPU twin of the fragment shader's reduced SG integration (SAT paper section 5, algorithms
//! 2 and 3; `shaders_gles/sg_shading.wgsl`). See [`crate::shading`] for the approximations it makes.

use std::f32::consts::{FRAC_PI_2, PI, TAU};

use glam::Vec3;

use crate::bake::horizon;
use crate::shading::sg::{self, Sg, Vmf};

/// How finely [`shade`](fn@crate::shading::shade) splits each product lobe: M theta bands x N phi sectors of its local frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Patches {
    /// 2 x 4: the cheapest.
    #[serde(rename = "2x4")]
    P2x4,
    /// 4 x 8: the SAT paper's choice and the default.
    #[default]
    #[serde(rename = "4x8")]
    P4x8,
    /// 8 x 16: the accurate one.
    #[serde(rename = "8x16")]
    P8x16,
}

/// Most theta bands of any [`Patches`].
pub const MAX_BANDS: usize = 8;
/// Most phi sectors of any [`Patches`].
pub const MAX_SECTORS: usize = 16;

impl Patches {
    /// All of them, cheapest first.
    pub const ALL: [Self; 3] = [Self::P2x4, Self::P4x8, Self::P8x16];

    /// Theta bands M.
    pub fn bands(self) -> usize {
        match self {
            Self::P2x4 => 2,
            Self::P4x8 => 4,
            Self::P8x16 => 8,
        }
    }

    /// Phi sectors N.
    pub fn sectors(self) -> usize {
        2 * self.bands()
    }

    /// "MxN".
    pub fn label(self) -> &'static str {
        match self {
            Self::P2x4 => "2x4",
            Self::P4x8 => "4x8",
            Self::P8x16 => "8x16",
        }
    }
}

/// What the fragment shader knows at one pixel, after SAT filtering over its footprint.
#[derive(Clone, Copy, Debug)]
pub struct Inputs<'a> {
    /// Box-averaged unnormalised mean normal r (world, z up).
    pub r: Vec3,
    /// Box-averaged horizon angles, D of them at azimuths 2 pi k / D ([`crate::bake::horizon`]); empty when
    /// visibility is off.
    pub horizon: &'a [f32],
    /// Unit direction from the surface to the eye.
    pub view: Vec3,
}

/// How far the clamped cosine's cut-off plane is lowered for a spread of normals: sqrt(2 / kappa) is the
/// vMF's RMS angle from its mean (E[theta^2] = 2 / kappa for large kappa), capped at pi/2 where the
/// distribution is near-uniform and no direction is cut. Exact (0) for a single normal.
pub fn plane_drop(kappa: f32) -> f32 {
    (2.0 / kappa.max(1e-12)).sqrt().min(FRAC_PI_2)
}

/// Lights at least this sharp are one direction, not a product lobe over patches: at lambda = 64 the
/// light's one-sigma radius sqrt(2 / lambda) is 10 degrees, so the cosine and the horizon barely change
/// over it and the integral is the light's times the vMF-averaged clamped cosine at its axis
/// ([`vmf_cosine`]) times the fraction of it above the horizon. A sun (lambda 2000) is such a light; a sky
/// lobe (lambda near 1) is not. This also avoids the cosine SG's fit error (17 % high at the peak) for
/// the light that carries most of the energy.
pub const SHARP_LAMBDA: f32 = 64.0;

/// E[max(n' . i, 0)] over the vMF of normals n' about `vmf.axis`, for a direction i at cosine `t` from the
/// mean normal: n' . i taken as Gaussian with the vMF's first two moments, mean m = A t (A = |r|, the
/// mean resultant length the vMF was fitted to) and second moment
/// t^2 (1 - 2 A / kappa) + (1 - t^2) A / kappa (E[cos^2] = 1 - 2 A / kappa for the 3D vMF; Mardia & Jupp
/// 2000, section 9.3), so E[max(X, 0)] = m Phi(m / s) + s phi(m / s). Phi uses Abramowitz & Stegun
/// 7.1.26 (error 1.5e-7), sharing phi's exponential. Exact for a single normal (s = 0: max(t, 0)) and
/// for the uniform distribution's mean; `tests/cpu/shading.rs` `vmf_cosine_matches_dense_integration`
/// measures it against dense integration over the vMF (at most 0.025 absolute, at |r| = 0.5).
pub fn vmf_cosine(t: f32, vmf: &Vmf) -> f32 {
    let a = vmf.r_len;
    let ak = a / vmf.kappa;
    let m = a * t;
    let t2 = t * t;
    // t^2 (1 - 2 A / kappa - A^2) + (1 - t^2) A / kappa, with 1 - A^2 factored against cancellation.
    let var = (t2 * ((1.0 - a) * (1.0 + a) - 2.0 * ak) + (1.0 - t2) * ak).max(0.0);
    if var < 1e-14 {
        return m.max(0.0);
    }
    let s = var.sqrt();
    let x = m / s;
    // Floored where e^-80 is already 0 to f32 sums: exp's slow underflow path costs the light table's
    // writer (texel_light) more than the rest of the function.
    let e = (-0.5 * x * x).max(-80.0).exp();
    let z = x.abs() * std::f32::consts::FRAC_1_SQRT_2;
    let tau = 1.0 / (1.0 + 0.327_591_1 * z);
    let poly = tau
        * (0.254_829_6
            + tau
                * (-0.284_496_74 + tau * (1.421_413_7 + tau * (-1.453_152_1 + tau * 1.061_405_4))));
    // Phi(|x|) = 1 - erfc(z) / 2, erfc(z) = poly e^(-z^2), e^(-z^2) = e.
    let tail = 0.5 * poly * e;
    let phi_cdf = if x >= 0.0 { 1.0 - tail } else { tail };
    (m * phi_cdf + s * e * 0.398_942_3).max(0.0)
}

/// The cut of one pixel (TransferVis + PatchVis, SAT paper algorithm 3): the higher of the baked horizon
/// (when given) and the mean normal's tangent plane lowered by `drop`, as the sine of an elevation.
/// cos and sin of `drop` are taken once, so a direction's plane cut needs no trigonometry: with
/// p = -(n_xy . d), q = n_z the plane's elevation is e = atan2(p, q) and
/// sin(e - drop) = (p cos drop - q sin drop) / |(p, q)|, clamped to -1 where e - drop < -pi/2
/// (cos(e - drop) < 0; n_z >= 0 keeps e in [-pi/2, pi/2]).
#[derive(Clone, Debug)]
pub(super) struct Cut {
    n: Vec3,
    /// The sines of the horizon angles (empty: no visibility): the shader's table holds sines, so
    /// nothing per azimuth needs trigonometry, and interpolates them linearly between azimuths.
    pub(super) horizon: heapless::Vec<f32, 16>,
    cos_drop: f32,
    sin_drop: f32,
}

impl Cut {
    /// The cut of mean normal `n`, the plane lowered by `drop`, with the horizon's sines `sines` (at
    /// most 16 are kept, bake::horizon::MAX_AZIMUTHS; empty: the plane only).
    pub(super) fn new(n: Vec3, sines: &[f32], drop: f32) -> Self {
        let (sin_drop, cos_drop) = drop.sin_cos();
        let horizon = sines.iter().take(16).copied().collect();
        Self {
            n,
            horizon,
            cos_drop,
            sin_drop,
        }
    }

    /// The sine of the horizon toward world azimuth `a`, linear between the baked azimuths' sines.
    pub(super) fn horizon_sin_at(&self, a: f32) -> f32 {
        horizon::interpolate(&self.horizon, a)
    }

    /// The sine of the lowered plane's elevation toward unit horizontal direction (ux, uy). n_z is
    /// floored at 1e-4: for a horizontal mean normal (a cliff) the plane is vertical and its elevation
    /// along the face would flip between +-90 degrees with the sign of a rounding error in p.
    fn plane_sin(&self, ux: f32, uy: f32) -> f32 {
        let p = -(self.n.x * ux + self.n.y * uy);
        let q = self.n.z.max(1e-4);
        let inv = 1.0 / (p * p + q * q).max(1e-30).sqrt();
        if (q * self.cos_drop + p * self.sin_drop) * inv < 0.0 {
            -1.0
        } else {
            (p * self.cos_drop - q * self.sin_drop) * inv
        }
    }

    /// The sine of the cut elevation toward horizontal direction (dx, dy) (unnormalised, not zero).
    fn sin_at(&self, dx: f32, dy: f32) -> f32 {
        let inv_d = 1.0 / (dx * dx + dy * dy).max(1e-30).sqrt();
        let (ux, uy) = (dx * inv_d, dy * inv_d);
        let plane = self.plane_sin(ux, uy);
        if self.horizon.is_empty() {
            plane
        } else {
            plane.max(self.horizon_sin_at(uy.atan2(ux)))
        }
    }

    /// The fraction of a lobe about unit `axis`, of angular radius `sigma`, above the cut (the higher of
    /// the lowered plane and `hs`, the horizon's sine toward it): linear in the axis's elevation over
    /// +/- sigma.
    pub(super) fn soft_visible(&self, axis: Vec3, sigma: f32, hs: f32) -> f32 {
        let inv_d = 1.0 / (axis.x * axis.x + axis.y * axis.y).max(1e-30).sqrt();
        let plane = self.plane_sin(axis.x * inv_d, axis.y * inv_d);
        above_cut(elevation(axis), sigma, plane.max(hs))
    }
}

/// Elevation of unit direction d, radians.
pub(super) fn elevation(d: Vec3) -> f32 {
    d.z.clamp(-1.0, 1.0).asin()
}

/// The theta band edge holding fraction `f` of an SG's energy, as u = 1 - cos(theta): the inverse of
/// F(u) = (1 - e^(-lambda u)) / (1 - e^(-2 lambda)). Equal-energy bands resolve a sharp lobe near its axis
/// and a broad one over the whole sphere; the last edge is the antipode (u = 2).
fn band_edge(lambda: f32, f: f32) -> f32 {
    if f >= 1.0 {
        2.0
    } else if lambda < 1e-6 {
        2.0 * f
    } else {
        -sg::ln_1p(f * sg::expm1(-2.0 * lambda)) / lambda
    }
}

/// sin(theta) at u = 1 - cos(theta).
fn sin_theta(u: f32) -> f32 {
    (u * (2.0 - u)).max(0.0).sqrt()
}

/// SAT paper eq. 11 over M x N patches of the lobe's own frame, each patch weighted by its visible
/// energy. Per patch, with u = 1 - cos theta:
/// f = mu (phi2 - phi1) / lambda (e^(-lambda u1) - e^(-lambda u2))
///   = mu (phi2 - phi1) e^(-lambda u1) (u2 - u1) (1 - e^(-lambda (u2 - u1))) / (lambda (u2 - u1)),
/// the second form exact for small lambda and thin bands (no difference of nearly equal exponentials).
///
/// PatchVis: the patch's height span z = sin(elevation) over its corners and centre is cut at the sine of
/// the cut elevation at the azimuth of its centre; the visible fraction s of the span is taken as the
/// fraction of the patch's u range on its higher side (inner or outer edge), and weighted by the lobe's
/// energy over that sub-range in closed form. For a lobe about the zenith z = 1 - u, so this is exact on
/// flat ground; a linear weight would miss that a band's energy sits at its inner edge.
///
/// Cost (the fragment shader runs this per light): the sector directions (cos, sin of k dphi and of the
/// sector centres) come from a rotation recurrence, not trigonometry; a corner's height is
/// axis_z (1 - u) + sin(theta) (t_z cos phi + b_z sin phi), so no table of corners is kept (a dynamically
/// indexed array is slow on SIMD rasterisers).
fn integrate_patches(p: &Sg, cut: &Cut, patches: Patches) -> Vec3 {
    let (bands, sectors) = (patches.bands(), patches.sectors());
    let (t, b) = sg::basis(p.axis);
    let dphi = TAU / sectors as f32;
    let (sin_step, cos_step) = dphi.sin_cos();
    let (sin_half, cos_half) = (0.5 * dphi).sin_cos();
    let mut total = 0.0f32;
    let mut u1 = 0.0f32;
    for i in 0..bands {
        let u2 = band_edge(p.lambda, (i + 1) as f32 / bands as f32);
        let du = u2 - u1;
        let whole = sg::one_minus_exp_over(p.lambda * du);
        let band = (-p.lambda * u1).exp() * du * whole;
        let u_mid = band_edge(p.lambda, (i as f32 + 0.5) / bands as f32);
        let (s1, s2, sm) = (sin_theta(u1), sin_theta(u2), sin_theta(u_mid));
        let (z1, z2) = (p.axis.z * (1.0 - u1), p.axis.z * (1.0 - u2));
        // (cos, sin) of the sector's first edge, and t_z cos + b_z sin there.
        let (mut c, mut s) = (1.0f32, 0.0f32);
        let mut w0 = t.z;
        for _ in 0..sectors {
            let (c2, s2n) = (c * cos_step - s * sin_step, s * cos_step + c * sin_step);
            let w1 = t.z * c2 + b.z * s2n;
            let (cm, sn) = (c * cos_half - s * sin_half, s * cos_half + c * sin_half);
            let centre = p.axis * (1.0 - u_mid) + (t * cm + b * sn) * sm;
            let (z00, z01, z10, z11) = (z1 + s1 * w0, z1 + s1 * w1, z2 + s2 * w0, z2 + s2 * w1);
            let lo = centre.z.min(z00.min(z01)).min(z10.min(z11));
            let hi = centre.z.max(z00.max(z01)).max(z10.max(z11));
            let cut_z = cut.sin_at(centre.x, centre.y);
            let vis = if hi - lo > 1e-7 {
                ((hi - cut_z) / (hi - lo)).clamp(0.0, 1.0)
            } else if centre.z > cut_z {
                1.0
            } else {
                0.0
            };
            // Energy of the visible sub-range over the band's, in expm1-safe form.
            let part = vis * sg::one_minus_exp_over(p.lambda * vis * du) / whole;
            let visible = if z00 + z01 >= z10 + z11 {
                part
            } else {
                (-p.lambda * (1.0 - vis) * du).exp() * part
            };
            total += band * visible;
            (c, s, w0) = (c2, s2n, w1);
        }
        u1 = u2;
    }
    p.mu * (total * dphi)
}

/// The unshadowed diffuse integral of broad `light` for the vMF `vmf` (before k_d / pi): the light times
/// the vMF-widened cosine SG over `patches`, cut at the lowered tangent plane only. What the sky table
/// ([`super::sky_table::SkyTable`]) holds, summed over the broad lights, per texel.
pub(super) fn unshadowed(light: &Sg, vmf: &Vmf, patches: Patches) -> Vec3 {
    let cut = Cut::new(vmf.axis, &[], plane_drop(vmf.kappa));
    integrate_patches(&light.product(&cosine_lobe(vmf)), &cut, patches)
}

/// The clamped cosine about the vMF's axis as one SG, widened by the vMF.
fn cosine_lobe(vmf: &Vmf) -> Sg {
    Sg {
        axis: vmf.axis,
        lambda: sg::COSINE_LAMBDA,
        mu: Vec3::splat(sg::COSINE_MU),
    }
    .convolve_vmf(vmf.kappa)
}

/// The part of product lobe `p`'s integral that the horizon hides above the lowered plane: per pair of
/// baked azimuths (2j, 2j + 1), the wedge of width 4 pi / D about the pair's middle azimuth between the
/// plane's sine z_lo there and the horizon's z_hi (the pair's mean sine, the linear horizon at the middle)
/// when higher, integrated over z = sin(elevation) (dOmega = dz dphi) by 2-point Gauss-Legendre. The
/// sky table holds the integral above the plane, so the visible part is the table's minus this. Pairs
/// rather than single azimuths: the broad lobes vary slowly in azimuth, and half the wedges halve the
/// cost of writing a light-table texel ([`texel_light`]); the suns read the horizon at their own azimuth.
/// D is a multiple of 4 ([`horizon::bake`]). The wedges' directions come from a rotation recurrence
/// (no trigonometry per wedge).
#[expect(clippy::cast_precision_loss, reason = "D <= 16")]
pub(super) fn occluded(p: &Sg, cut: &Cut) -> Vec3 {
    let d = cut.horizon.len();
    let dphi = TAU / d as f32;
    let (sin_step, cos_step) = (2.0 * dphi).sin_cos();
    let (mut sa, mut ca) = (0.5 * dphi).sin_cos();
    let mut sum = 0.0f32;
    for pair in cut.horizon.chunks_exact(2) {
        let lo = cut.plane_sin(ca, sa);
        let hi = 0.5 * (pair[0] + pair[1]);
        // A horizon below the plane hides nothing there (most wedges of gentle terrain): on the CPU the
        // branch saves the exponentials.
        if hi > lo {
            let half = 0.5 * (hi - lo);
            let mid = 0.5 * (hi + lo);
            let horizontal = p.axis.x * ca + p.axis.y * sa;
            let mut wedge = 0.0f32;
            for z in [mid - GAUSS_2 * half, mid + GAUSS_2 * half] {
                let rho = (1.0 - z * z).max(0.0).sqrt();
                wedge += (p.lambda * (horizontal * rho + p.axis.z * z - 1.0)).exp();
            }
            sum += wedge * half;
        }
        (ca, sa) = (ca * cos_step - sa * sin_step, sa * cos_step + ca * sin_step);
    }
    p.mu * (sum * 2.0 * dphi)
}

/// The 2-point Gauss-Legendre node, 1 / sqrt(3).
const GAUSS_2: f32 = 0.577_350_3;

/// The specular lobe for the mean normal: the NDF as an SG (Beckmann-like, lambda = 2 / alpha^2,
/// mu = 1 / (pi alpha^2), alpha = roughness^2; Wang et al. 2009 section 4), convolved with the vMF, then
/// spherically warped from half-vector to light-direction space about the mirror direction with
/// lambda_w = lambda / (4 |n.o|) (Wang et al. 2009 section 4.2).
pub fn warped_ndf(vmf: &Vmf, roughness: f32, view: Vec3) -> Sg {
    let alpha = (roughness * roughness).max(1e-3);
    let ndf = Sg {
        axis: vmf.axis,
        lambda: 2.0 / (alpha * alpha),
        mu: Vec3::splat(1.0 / (PI * alpha * alpha)),
    }
    .convolve_vmf(vmf.kappa);
    let n_o = vmf.axis.dot(view).max(1e-4);
    let mirror = (vmf.axis * (2.0 * n_o) - view).normalize_or(vmf.axis);
    Sg {
        axis: mirror,
        lambda: ndf.lambda / (4.0 * n_o),
        mu: ndf.mu,
    }
}

/// The fraction of a lobe of elevation `el` and one-sigma radius `sigma` (radians) above a cut of sine
/// `cut_sin` (clamped: -2 leaves it whole): linear over the lobe's +/- sigma.
pub(super) fn above_cut(el: f32, sigma: f32, cut_sin: f32) -> f32 {
    ((el + sigma - cut_sin.clamp(-1.0, 1.0).asin()) / (2.0 * sigma)).clamp(0.0, 1.0)
}
