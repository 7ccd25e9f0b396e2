//! Shading: a texel's and a pixel's shading from the SG integrals of `integrate.rs` and the sky table
//! (SAT paper section 5, algorithm 3): the CPU twin of what `shaders_gles/sg_shading.wgsl` computes per
//! texel of the light table and per pixel.

use std::f32::consts::{FRAC_PI_2, PI};

use glam::Vec3;

use super::integrate::{
    above_cut, elevation, occluded, plane_drop, vmf_cosine, warped_ndf, Cut, Inputs,
    SHARP_LAMBDA,
};
use crate::shading::scene::Scene;
use crate::shading::sg::{self, Sg, Vmf};
use crate::shading::sky_table::SkyTable;

/// What the per-level light table holds for one texel (`gpu/renderer/sg_tables.rs`), computed on the CPU
/// when the texel is written: everything of the shading that does not depend on the view. The fragment
/// shader of a scene with visibility blends 4 of them instead of integrating the horizon per pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelLight {
    /// k_d / pi times the diffuse integral of every light but the first sun with the horizon applied
    /// (linear RGB): the other suns each one direction, the broad lights from the sky table less what the
    /// horizon hides. The first sun's term is the pixel's own ([`shade_pixel`]): its shadow edge is as
    /// sharp as the blended horizon sine toward it, where a blend of shaded texels would soften it over
    /// a texel (several pixels near the eye).
    pub diffuse: Vec3,
    /// The mean of the horizon's sines over the baked azimuths: the horizon the specular terms of the broad
    /// lights and of every sun but the first are cut at (their lobes' azimuths depend on the view).
    pub mean_sin: f32,
    /// The horizon's sine toward the scene's first sun, for its diffuse and specular terms (-2, below any
    /// cut, when the scene has no sun).
    pub sun_sin: f32,
}

/// The view-independent part of [`shade`] at one texel ([`TexelLight`]): mean normal `r` and the sines of
/// its horizon angles at the D baked azimuths (`sines`, D a multiple of 4 up to 16; empty: no horizon)
/// for the scene's lights and k_d; `sky` is the scene's [`SkyTable`]. Suns but the first (which the pixel
/// shades itself, [`shade_pixel`]): the vMF-averaged cosine at the sun ([`vmf_cosine`]) times the sun's
/// fraction above the horizon at its own azimuth; broad lights:
/// the sky table less what the horizon hides of them (`occluded`: a wedge per pair of azimuths; SAT
/// paper algorithm 3, TransferVis + PatchVis). [`TexelLighting`] holds the scene's part, for writing
/// many texels.
pub fn texel_light(r: Vec3, sines: &[f32], scene: &Scene, sky: &SkyTable) -> TexelLight {
    TexelLighting::new(scene).texel(r, sines, sky)
}

/// What [`texel_light`] needs of a scene, computed once: the lights by kind, each sun's integral,
/// one-sigma radius, elevation and azimuth, and k_d / pi.
#[derive(Clone, Debug, PartialEq)]
pub struct TexelLighting {
    /// Per sun: the light, its integral, sigma, elevation and azimuth (radians).
    suns: heapless::Vec<(Sg, Vec3, f32, f32, f32), { crate::profile::MAX_SG_LIGHTS }>,
    broad: heapless::Vec<Sg, { crate::profile::MAX_SG_LIGHTS }>,
    kd_over_pi: Vec3,
    /// The cosine SG's own unit integral (its vMF convolution divides by the widened one's).
    cosine_integral: f32,
}

impl TexelLighting {
    /// The scene's part; lights past [`crate::profile::MAX_SG_LIGHTS`] (which no renderer accepts) are
    /// left out.
    pub fn new(scene: &Scene) -> Self {
        let mut suns = heapless::Vec::new();
        let mut broad = heapless::Vec::new();
        for l in &scene.lights {
            if l.lambda >= SHARP_LAMBDA {
                let sigma = (2.0 / l.lambda).sqrt();
                let azimuth = l.axis.y.atan2(l.axis.x);
                let _ = suns.push((*l, l.integral(), sigma, elevation(l.axis), azimuth));
            } else {
                let _ = broad.push(*l);
            }
        }
        Self {
            suns,
            broad,
            kd_over_pi: scene.material.kd / PI,
            cosine_integral: sg::unit_integral(sg::COSINE_LAMBDA),
        }
    }

    /// [`texel_light`] of `r` and `sines` with this scene's sky table `sky`.
    pub fn texel(&self, r: Vec3, sines: &[f32], sky: &SkyTable) -> TexelLight {
        let vmf = Vmf::from_mean_normal(r);
        let n = vmf.axis;
        let cut = Cut::new(n, sines, plane_drop(vmf.kappa));
        let mut diffuse = Vec3::ZERO;
        let mut sun_sin = -2.0;
        for (i, (light, integral, sigma, el, azimuth)) in self.suns.iter().enumerate() {
            let hs = if cut.horizon.is_empty() {
                -2.0
            } else {
                cut.horizon_sin_at(*azimuth)
            };
            if i == 0 {
                // The pixel adds the first sun (shade_pixel), with its horizon sine blended.
                sun_sin = hs;
                continue;
            }
            let visible = if cut.horizon.is_empty() {
                1.0
            } else {
                above_cut(*el, *sigma, hs)
            };
            if visible > 0.0 {
                diffuse += *integral * (vmf_cosine(n.dot(light.axis), &vmf) * visible);
            }
        }
        if !self.broad.is_empty() {
            // The cosine lobe widened by the vMF (sg::Sg::convolve_vmf, its constant part hoisted).
            let c = sg::COSINE_LAMBDA;
            let lambda = c * vmf.kappa / (c + vmf.kappa).max(1e-30);
            let cosine = Sg {
                axis: n,
                lambda,
                mu: Vec3::splat(sg::COSINE_MU * (self.cosine_integral / sg::unit_integral(lambda))),
            };
            let mut hidden = Vec3::ZERO;
            if !cut.horizon.is_empty() {
                for light in &self.broad {
                    hidden += occluded(&light.product(&cosine), &cut);
                }
            }
            diffuse += (sky.lookup(n, vmf.r_len) - hidden).max(Vec3::ZERO);
        }
        #[expect(clippy::cast_precision_loss, reason = "D <= 16")]
        let mean_sin = if cut.horizon.is_empty() {
            -2.0
        } else {
            cut.horizon.iter().sum::<f32>() / cut.horizon.len() as f32
        };
        TexelLight {
            diffuse: self.kd_over_pi * diffuse,
            mean_sin,
            sun_sin,
        }
    }
}

/// The CPU twin of the fragment shader: outgoing radiance (RGB, linear) toward `inputs.view` for the
/// scene's lights and material. With visibility (the scene enables it and `inputs.horizon` is not empty)
/// the view-independent part is [`texel_light`] of the inputs (the horizon angles' sines) and the rest
/// [`shade_pixel`]; without, [`shade_pixel`] alone.
pub fn shade(inputs: &Inputs<'_>, scene: &Scene, sky: &SkyTable) -> Vec3 {
    let sines: heapless::Vec<f32, 16> = if scene.effects.visibility {
        inputs.horizon.iter().take(16).map(|a| a.sin()).collect()
    } else {
        heapless::Vec::new()
    };
    let texel = (!sines.is_empty()).then(|| texel_light(inputs.r, &sines, scene, sky));
    shade_pixel(inputs.r, inputs.view, texel.as_ref(), scene, sky)
}

/// The fragment shader's own part (`sg_shade` in `shaders_gles/sg_shading.wgsl`): the diffuse term from
/// `texel` (the light table's blend, with visibility) or, without, from the suns (one direction each,
/// unshadowed) and the sky table; plus the specular term when the scene enables it, each lobe cut at
/// the higher of the mean normal's lowered plane and the horizon: the first sun's at its own azimuth,
/// every other lobe's at the horizon's mean ([`TexelLight`]); the plane only without `texel`.
pub fn shade_pixel(
    r: Vec3,
    view: Vec3,
    texel: Option<&TexelLight>,
    scene: &Scene,
    sky: &SkyTable,
) -> Vec3 {
    shade_pixel_scaled(r, view, texel, scene, sky, Vec3::ONE)
}

/// [`shade_pixel`] with the diffuse term scaled by `albedo_scale` (draped imagery: its albedo over the
/// material's k_d, `shaders_gles/imagery.wgsl`'s SG variant); the specular term unchanged.
pub fn shade_pixel_scaled(
    r: Vec3,
    view: Vec3,
    texel: Option<&TexelLight>,
    scene: &Scene,
    sky: &SkyTable,
    albedo_scale: Vec3,
) -> Vec3 {
    let vmf = Vmf::from_mean_normal(r);
    let n = vmf.axis;
    let cut = Cut::new(n, &[], plane_drop(vmf.kappa));
    let m = &scene.material;
    let diffuse = match texel {
        Some(t) => {
            // The first sun (suns come first in the shader's uniform), cut at the blended horizon sine
            // toward it; -2 (no horizon) leaves it whole.
            let sun = scene
                .lights
                .iter()
                .find(|l| l.lambda >= SHARP_LAMBDA)
                .map_or(Vec3::ZERO, |l| {
                    let sigma = (2.0 / l.lambda).sqrt();
                    l.integral()
                        * (vmf_cosine(n.dot(l.axis), &vmf)
                            * above_cut(elevation(l.axis), sigma, t.sun_sin))
                });
            t.diffuse + m.kd * sun / PI
        }
        None => {
            let mut d = Vec3::ZERO;
            for light in scene.lights.iter().filter(|l| l.lambda >= SHARP_LAMBDA) {
                d += light.integral() * vmf_cosine(n.dot(light.axis), &vmf);
            }
            if scene.lights.iter().any(|l| l.lambda < SHARP_LAMBDA) {
                d += sky.lookup(n, vmf.r_len);
            }
            m.kd * d / PI
        }
    };
    let mut spec = Vec3::ZERO;
    if scene.effects.specular && m.ks > 0.0 {
        let lobe = warped_ndf(&vmf, m.roughness, view);
        let (mean_sin, sun_sin) = texel.map_or((-2.0, -2.0), |t| (t.mean_sin, t.sun_sin));
        // Suns first, as the shader's uniform orders them; the first sun is cut at its own horizon.
        let suns = scene.lights.iter().filter(|l| l.lambda >= SHARP_LAMBDA);
        let broad = scene.lights.iter().filter(|l| l.lambda < SHARP_LAMBDA);
        for (i, light) in suns.chain(broad).enumerate() {
            let hs = if i == 0 && light.lambda >= SHARP_LAMBDA {
                sun_sin
            } else {
                mean_sin
            };
            spec += lobe_specular(&light.product(&lobe), n, &cut, hs, m.ks);
        }
    }
    diffuse * albedo_scale + spec
}

/// k_s times product lobe `q`'s integral, D / 4 with the cosine at the lobe's axis, times the fraction of
/// its one-sigma cap above the cut (`hs`: the horizon's sine toward it).
fn lobe_specular(q: &Sg, n: Vec3, cut: &Cut, hs: f32, ks: f32) -> Vec3 {
    let cos = n.dot(q.axis).max(0.0);
    let sigma = (2.0 / q.lambda.max(1e-6)).sqrt().min(FRAC_PI_2);
    q.mu * (sg::unit_integral(q.lambda) * 0.25 * cos * cut.soft_visible(q.axis, sigma, hs) * ks)
}
