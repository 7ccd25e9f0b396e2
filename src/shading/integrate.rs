//! Shading: the CPU twin of the fragment shader's reduced SG integration (SAT paper section 5, algorithms
//! 2 and 3; `shaders_gles/sg_shading.wgsl`). See [`crate::shading`] for the approximations it makes.

use std::f32::consts::{FRAC_PI_2, PI, TAU};

use glam::Vec3;

use crate::bake::horizon;
use crate::shading::scene::Scene;
use crate::shading::sg::{self, Sg, Vmf};

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
