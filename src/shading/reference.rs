//! Shading: the f64 reference [`reference()`] that [`super::shade`] is measured against: dense quadrature
//! of the same light transport with the true clamped cosine (averaged over the vMF normal distribution)
//! and ray-marched visibility.

use std::f32::consts::PI;

use glam::{DVec3, Vec3};

use super::plane_drop;
use crate::bake::horizon;
use crate::shading::scene::Scene;
use crate::shading::sg::{self, Sg, Vmf};

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
    pub fn march(hm: &crate::source::Heightmap, u: f64, v: f64, azimuths: u32, max_samples: f64) -> Self {
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
    /// [`shade`](super::shade)'s own model, the vMF-widened cosine SG cut at the lowered tangent plane: isolates the
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

/// Dense f64 quadrature of the same light transport [`shade`](super::shade) approximates: for each light, midpoints
/// uniform in its energy fraction and in phi of its own frame (exact importance sampling of the lobe, so
/// lambda from 1e-6 to 1e4 needs no special grid), times
/// - diffuse: k_d / pi times the clamped cosine averaged over the vMF of r (the plain clamped cosine when
///   |r| >= [`sg::R_MAX`]),
/// - specular (when the scene enables it): k_s D(h) (n.i)+ / 4, D the same vMF-widened NDF SG [`shade`](super::shade)
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
