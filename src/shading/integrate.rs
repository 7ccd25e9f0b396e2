//! Shading: the CPU twin of the fragment shader's reduced SG integration (SAT paper section 5,
//! algorithms 2 and 3; design.md "Shading: reduced SG integration") and the f64 reference it is measured
//! against.
//!
//! [`shade`] is f32, allocation-free and written as the WGSL will be: fixed loops over lights, theta
//! bands and phi sectors, no library calls WGSL lacks. [`reference()`] integrates the same light transport
//! densely in f64 with the true clamped cosine (averaged over the vMF normal distribution) and ray-marched
//! visibility, so every approximation of [`shade`] shows up in its error.
//!
//! The approximations of [`shade`], each measured by `tests/shading.rs`:
//! - the clamped cosine is one SG (lambda 2.133, mu 1.17; [`crate::sg::COSINE_LAMBDA`]), widened by the vMF
//!   with [`Sg::convolve_vmf`], and cut at the mean normal's tangent plane lowered by the vMF's angular
//!   spread ([`plane_drop`]);
//! - each patch's visibility is the fraction of its elevation span (over its corners and centre) above the
//!   horizon at the azimuth of its centre, the horizon interpolated between the D baked azimuths;
//! - specular: Fresnel = 1 (folded into k_s), the implicit geometry term G = (n.i)(n.o), so the BRDF is
//!   D(h) / 4; the cosine is taken at the product lobe's axis and visibility as the fraction of the lobe's
//!   one-sigma cap above the horizon.

use std::f32::consts::{FRAC_PI_2, PI, TAU};

use glam::{DVec3, Vec3};

use crate::horizon;
use crate::scene::Scene;
use crate::sg::{self, Sg, Vmf};

/// How finely [`shade`] splits each product lobe: M theta bands x N phi sectors of its local frame.
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
    /// Box-averaged horizon angles, D of them at azimuths 2 pi k / D ([`crate::horizon`]); empty when
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

/// The elevation below which direction at world azimuth `a` is cut: the higher of the baked horizon (when
/// given) and the mean normal's tangent plane lowered by `drop` (TransferVis + PatchVis, SAT paper
/// algorithm 3).
fn cut_elevation(n: Vec3, horizon: &[f32], drop: f32, a: f32) -> f32 {
    let (s, c) = a.sin_cos();
    let plane = (-(n.x * c + n.y * s)).atan2(n.z) - drop;
    if horizon.is_empty() {
        plane
    } else {
        plane.max(horizon::interpolate(horizon, a))
    }
}

/// Elevation of unit direction d, radians.
fn elevation(d: Vec3) -> f32 {
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

/// The direction at (u = 1 - cos theta, phi) in the frame (t, b, axis).
fn frame_dir(axis: Vec3, t: Vec3, b: Vec3, u: f32, phi: f32) -> Vec3 {
    let sin_theta = (u * (2.0 - u)).max(0.0).sqrt();
    let (s, c) = phi.sin_cos();
    axis * (1.0 - u) + (t * c + b * s) * sin_theta
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
fn integrate_patches(p: &Sg, n: Vec3, horizon: &[f32], drop: f32, patches: Patches) -> Vec3 {
    let (bands, sectors) = (patches.bands(), patches.sectors());
    let (t, b) = sg::basis(p.axis);
    let dphi = TAU / sectors as f32;
    // Heights z at the band edges x sector edges, computed once and shared by neighbouring patches.
    let mut edge_z = [[0.0f32; MAX_SECTORS]; MAX_BANDS + 1];
    let mut edge_u = [0.0f32; MAX_BANDS + 1];
    for (i, row) in edge_z.iter_mut().enumerate().take(bands + 1) {
        edge_u[i] = band_edge(p.lambda, i as f32 / bands as f32);
        for (k, z) in row.iter_mut().enumerate().take(sectors) {
            *z = frame_dir(p.axis, t, b, edge_u[i], k as f32 * dphi).z;
        }
    }
    let mut total = 0.0f32;
    for i in 0..bands {
        let (u1, u2) = (edge_u[i], edge_u[i + 1]);
        let du = u2 - u1;
        let whole = sg::one_minus_exp_over(p.lambda * du);
        let band = (-p.lambda * u1).exp() * du * whole;
        let u_mid = band_edge(p.lambda, (i as f32 + 0.5) / bands as f32);
        for k in 0..sectors {
            let centre = frame_dir(p.axis, t, b, u_mid, (k as f32 + 0.5) * dphi);
            let k2 = (k + 1) % sectors;
            let (inner, outer) = (
                edge_z[i][k] + edge_z[i][k2],
                edge_z[i + 1][k] + edge_z[i + 1][k2],
            );
            let corners = [
                edge_z[i][k],
                edge_z[i][k2],
                edge_z[i + 1][k],
                edge_z[i + 1][k2],
            ];
            let (mut lo, mut hi) = (centre.z, centre.z);
            for c in corners {
                lo = lo.min(c);
                hi = hi.max(c);
            }
            let cut = cut_elevation(n, horizon, drop, centre.y.atan2(centre.x))
                .max(-FRAC_PI_2)
                .sin();
            let s = if hi - lo > 1e-7 {
                ((hi - cut) / (hi - lo)).clamp(0.0, 1.0)
            } else if centre.z > cut {
                1.0
            } else {
                0.0
            };
            // Energy of the visible sub-range over the band's, in expm1-safe form.
            let part = s * sg::one_minus_exp_over(p.lambda * s * du) / whole;
            let visible = if inner >= outer {
                part
            } else {
                (-p.lambda * (1.0 - s) * du).exp() * part
            };
            total += band * visible;
        }
    }
    p.mu * (total * dphi)
}

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

/// The CPU twin of the fragment shader: outgoing radiance (RGB, linear) toward `inputs.view` for the
/// scene's lights and material, integrating each light x cosine product over `patches`. Visibility is used
/// when the scene enables it and `inputs.horizon` is not empty; specular only when the scene enables it.
pub fn shade(inputs: &Inputs<'_>, scene: &Scene, patches: Patches) -> Vec3 {
    let vmf = Vmf::from_mean_normal(inputs.r);
    let n = vmf.axis;
    let horizon: &[f32] = if scene.effects.visibility {
        inputs.horizon
    } else {
        &[]
    };
    let drop = plane_drop(vmf.kappa);
    let cosine = Sg {
        axis: n,
        lambda: sg::COSINE_LAMBDA,
        mu: Vec3::splat(sg::COSINE_MU),
    }
    .convolve_vmf(vmf.kappa);
    let mut diffuse = Vec3::ZERO;
    for light in &scene.lights {
        diffuse += integrate_patches(&light.product(&cosine), n, horizon, drop, patches);
    }
    let m = &scene.material;
    let mut out = m.kd * diffuse / PI;
    if scene.effects.specular && m.ks > 0.0 {
        let lobe = warped_ndf(&vmf, m.roughness, inputs.view);
        let mut spec = Vec3::ZERO;
        for light in &scene.lights {
            let q = light.product(&lobe);
            let cos = n.dot(q.axis).max(0.0);
            let sigma = (2.0 / q.lambda.max(1e-6)).sqrt().min(FRAC_PI_2);
            let cut = cut_elevation(n, horizon, drop, q.axis.y.atan2(q.axis.x));
            let visible = ((elevation(q.axis) + sigma - cut) / (2.0 * sigma)).clamp(0.0, 1.0);
            spec += q.integral() * (0.25 * cos * visible);
        }
        out += spec * m.ks;
    }
    out
}

/// The f64 reference's knowledge of one surface point.
#[derive(Clone, Copy, Debug)]
pub struct RefInputs<'a> {
    /// Unnormalised mean normal r.
    pub r: DVec3,
    /// Unit direction to the eye.
    pub view: DVec3,
    /// The exact horizon, when visibility is on.
    pub horizon: Option<&'a HorizonTable>,
}

/// A finely sampled horizon at one point: ray-marched at many azimuths, for the reference.
#[derive(Clone, Debug, PartialEq)]
pub struct HorizonTable {
    angles: Vec<f64>,
}

impl HorizonTable {
    /// Marches `azimuths` directions from grid point (u, v) of `hm` out to `max_samples` samples.
    pub fn march(hm: &crate::Heightmap, u: f64, v: f64, azimuths: u32, max_samples: f64) -> Self {
        let angles = (0..azimuths)
            .map(|k| {
                let a = std::f64::consts::TAU * f64::from(k) / f64::from(azimuths);
                horizon::horizon_elevation(hm, u, v, a, max_samples)
            })
            .collect();
        Self { angles }
    }

    /// A constant horizon at `elevation` (flat ground: 0).
    pub fn constant(elevation: f64, azimuths: u32) -> Self {
        Self {
            angles: vec![elevation; azimuths as usize],
        }
    }

    /// Horizon at azimuth `a`, linear between the marched azimuths.
    #[expect(
        clippy::cast_possible_truncation,
        reason = "the floor of a value in [0, len) indexes the table"
    )]
    #[expect(clippy::cast_precision_loss, reason = "table lengths are small")]
    pub fn at(&self, a: f64) -> f64 {
        let d = self.angles.len();
        let t = (a / std::f64::consts::TAU).rem_euclid(1.0) * d as f64;
        let k0 = (t.floor() as usize).min(d - 1);
        let f = t - k0 as f64;
        self.angles[k0] * (1.0 - f) + self.angles[(k0 + 1) % d] * f
    }
}

/// Which cosine [`reference()`] integrates against.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RefCosine {
    /// The true clamped cosine, averaged over the vMF: the physical answer.
    #[default]
    Exact,
    /// [`shade`]'s own model, the vMF-widened cosine SG cut at the lowered tangent plane: isolates the
    /// error of the patch integration and of PatchVis from the error of the SG fit.
    SgModel,
}

/// Quadrature density of [`reference()`]: midpoints in (energy fraction, phi) of each light's own frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RefGrid {
    /// Theta samples (uniform in the light's energy fraction, i.e. importance-sampled).
    pub theta: u32,
    /// Phi samples.
    pub phi: u32,
    /// The cosine integrated against.
    pub cosine: RefCosine,
}

impl Default for RefGrid {
    fn default() -> Self {
        Self {
            theta: 256,
            phi: 512,
            cosine: RefCosine::Exact,
        }
    }
}

/// The vMF-averaged clamped cosine g(t) = E_n[max(n . i, 0)] for mean direction at cosine t from i,
/// tabulated; the phi integral is closed-form, theta is importance-sampled in the vMF's energy fraction.
struct VmfCosine {
    table: Option<Vec<f64>>,
}

const VMF_TABLE: usize = 2048;

impl VmfCosine {
    fn new(kappa: f64, single_normal: bool) -> Self {
        if single_normal {
            return Self { table: None };
        }
        let steps = 1024;
        let table = (0..=VMF_TABLE)
            .map(|k| {
                let t = -1.0 + 2.0 * f64::from(u32::try_from(k).unwrap_or(0)) / VMF_TABLE as f64;
                let st = (1.0 - t * t).max(0.0).sqrt();
                let mut acc = 0.0;
                for j in 0..steps {
                    let u = band_edge_f64(kappa, (f64::from(j) + 0.5) / f64::from(steps));
                    let (ct, sn) = (1.0 - u, (u * (2.0 - u)).max(0.0).sqrt());
                    let (a, b) = (ct * t, sn * st);
                    acc += if a >= b {
                        a
                    } else if a <= -b {
                        0.0
                    } else {
                        let phi0 = (-a / b).acos();
                        (a * phi0 + b * phi0.sin()) / std::f64::consts::PI
                    };
                }
                acc / f64::from(steps)
            })
            .collect();
        Self { table: Some(table) }
    }

    #[expect(
        clippy::cast_possible_truncation,
        reason = "the floor of a value in [0, VMF_TABLE] indexes the table"
    )]
    fn at(&self, t: f64) -> f64 {
        match &self.table {
            None => t.max(0.0),
            Some(tab) => {
                let x = ((t + 1.0) * 0.5 * VMF_TABLE as f64).clamp(0.0, VMF_TABLE as f64);
                let k = (x.floor() as usize).min(VMF_TABLE - 1);
                let f = x - k as f64;
                tab[k] * (1.0 - f) + tab[k + 1] * f
            }
        }
    }
}

fn band_edge_f64(lambda: f64, f: f64) -> f64 {
    if f >= 1.0 {
        2.0
    } else if lambda < 1e-12 {
        2.0 * f
    } else {
        -(f * (-2.0 * lambda).exp_m1()).ln_1p() / lambda
    }
}

fn unit_integral_f64(lambda: f64) -> f64 {
    let x = 2.0 * lambda;
    let frac = if x < 1e-12 { 1.0 } else { -(-x).exp_m1() / x };
    4.0 * std::f64::consts::PI * frac
}

fn basis_f64(n: DVec3) -> (DVec3, DVec3) {
    let t = if n.z.abs() < 0.9 { DVec3::Z } else { DVec3::X };
    let t = t.cross(n).normalize();
    (t, n.cross(t))
}

/// Dense f64 quadrature of the same light transport [`shade`] approximates: for each light, midpoints
/// uniform in its energy fraction and in phi of its own frame (exact importance sampling of the lobe, so
/// lambda from 1e-6 to 1e4 needs no special grid), times
/// - diffuse: k_d / pi times the clamped cosine averaged over the vMF of r (the plain clamped cosine when
///   |r| >= [`sg::R_MAX`]),
/// - specular (when the scene enables it): k_s D(h) (n.i)+ / 4, D the same vMF-widened NDF SG [`shade`]
///   uses (this checks the warp, not the NDF fit),
/// - visibility (when the scene enables it and a table is given): the direction's elevation above the
///   ray-marched horizon at its exact azimuth.
pub fn reference(inputs: &RefInputs<'_>, scene: &Scene, grid: RefGrid) -> DVec3 {
    let len = inputs.r.length();
    let n = if len > 1e-30 {
        inputs.r / len
    } else {
        DVec3::Z
    };
    let vmf = Vmf::from_mean_normal(inputs.r.as_vec3());
    let single = len >= f64::from(sg::R_MAX);
    let kappa = f64::from(vmf.kappa);
    let model = grid.cosine == RefCosine::SgModel;
    let g = VmfCosine::new(kappa, single || model);
    let cos_sg = Sg {
        axis: vmf.axis,
        lambda: sg::COSINE_LAMBDA,
        mu: Vec3::splat(sg::COSINE_MU),
    }
    .convolve_vmf(vmf.kappa);
    let (cos_lambda, cos_mu) = (f64::from(cos_sg.lambda), f64::from(cos_sg.mu.x));
    let drop = f64::from(plane_drop(vmf.kappa));
    let n_model = vmf.axis.as_dvec3();
    let horizon = inputs.horizon.filter(|_| scene.effects.visibility);
    let m = &scene.material;
    let spec_on = scene.effects.specular && m.ks > 0.0;
    let ndf = {
        let alpha = (m.roughness * m.roughness).max(1e-3);
        Sg {
            axis: vmf.axis,
            lambda: 2.0 / (alpha * alpha),
            mu: Vec3::ONE / (PI * alpha * alpha),
        }
        .convolve_vmf(if single { f32::INFINITY } else { vmf.kappa })
    };
    let (ndf_lambda, ndf_mu) = (f64::from(ndf.lambda), f64::from(ndf.mu.x));
    let mut out = DVec3::ZERO;
    for light in &scene.lights {
        let axis = light.axis.as_dvec3().normalize();
        let lambda = f64::from(light.lambda);
        let (t, b) = basis_f64(axis);
        let (mut diff, mut spec) = (0.0f64, 0.0f64);
        for i in 0..grid.theta {
            let u = band_edge_f64(lambda, (f64::from(i) + 0.5) / f64::from(grid.theta));
            let (ct, st) = (1.0 - u, (u * (2.0 - u)).max(0.0).sqrt());
            for j in 0..grid.phi {
                let phi = std::f64::consts::TAU * (f64::from(j) + 0.5) / f64::from(grid.phi);
                let d = axis * ct + (t * phi.cos() + b * phi.sin()) * st;
                if let Some(h) = horizon {
                    let el = d.z.clamp(-1.0, 1.0).asin();
                    if el <= h.at(d.y.atan2(d.x)) {
                        continue;
                    }
                }
                diff += if model {
                    let a = d.y.atan2(d.x);
                    let plane =
                        (-(n_model.x * a.cos() + n_model.y * a.sin())).atan2(n_model.z) - drop;
                    if d.z.clamp(-1.0, 1.0).asin() > plane {
                        cos_mu * (cos_lambda * (d.dot(n_model) - 1.0)).exp()
                    } else {
                        0.0
                    }
                } else {
                    g.at(d.dot(n))
                };
                if spec_on {
                    let h = (d + inputs.view).normalize_or(n);
                    spec +=
                        ndf_mu * (ndf_lambda * (h.dot(n) - 1.0)).exp() * d.dot(n).max(0.0) * 0.25;
                }
            }
        }
        let per_sample = unit_integral_f64(lambda) / (f64::from(grid.theta) * f64::from(grid.phi));
        let mu = light.mu.as_dvec3();
        out += mu * per_sample * (m.kd.as_dvec3() * diff / std::f64::consts::PI);
        if spec_on {
            out += mu * per_sample * (f64::from(m.ks) * spec);
        }
    }
    out
}
