// Stage 3, the GPU: the SG specular term (clipsat::shading::warped_ndf and the specular terms of
// clipsat::shading::shade_pixel), appended after sg_shading.wgsl only for scenes with `effects.specular`.

// The NDF as an SG (lambda = 2 / alpha^2, mu = 1 / (pi alpha^2), alpha = roughness^2), widened by the vMF,
// warped to light-direction space about the mirror direction, lambda_w = lambda / (4 |n.o|)
// (Wang et al. 2009, section 4.2).
fn sg_warped_ndf(vmf: SgVmf, roughness: f32, view: vec3<f32>) -> Sg {
    let alpha = max(roughness * roughness, 1.0e-3);
    let ndf = sg_convolve_vmf(
        Sg(vmf.axis, 2.0 / (alpha * alpha), vec3<f32>(1.0 / (SG_PI * alpha * alpha))),
        vmf.kappa,
    );
    let n_o = max(dot(vmf.axis, view), 1.0e-4);
    let m = vmf.axis * (2.0 * n_o) - view;
    let ml = length(m);
    var mirror = vmf.axis;
    if (ml > 0.0) {
        mirror = m / ml;
    }
    return Sg(mirror, ndf.lambda / (4.0 * n_o), ndf.mu);
}

// k_s times product lobe q's integral, D / 4 with the cosine at the lobe's axis, times the fraction of
// its one-sigma cap above the cut, `hs` the horizon's sine there.
fn sg_lobe_specular(q: Sg, n: vec3<f32>, cut: SgCut, hs: f32, s: SgScene) -> vec3<f32> {
    let c = max(dot(n, q.axis), 0.0);
    let sigma = min(sqrt(2.0 / max(q.lambda, 1.0e-6)), SG_HALF_PI);
    return q.mu * (sg_unit_integral(q.lambda) * 0.25 * c * sg_soft_visible(cut, q.axis, sigma, hs) * s.material.x);
}

// Every light's specular term: the product of the light and the pixel's warped NDF, cut at the higher
// of the lowered plane and the horizon: the first sun's at its own azimuth (`sg_sun_sin`: its product
// lobe's axis is within a few degrees of the sun, lambda 2000 against the lobe's tens), every other
// lobe's at the horizon's mean (`sg_texel.a`; -2, no horizon, without visibility).
fn sg_specular(vmf: SgVmf, view: vec3<f32>, cut: SgCut, suns: u32, count: u32, s: SgScene) -> vec3<f32> {
    var spec = vec3<f32>(0.0);
    // Uniform: the scene's k_s.
    if (s.material.x <= 0.0) {
        return spec;
    }
    let lobe = sg_warped_ndf(vmf, s.material.y, view);
    for (var i = 0u; i < count; i++) {
        let l = s.lights[i];
        let q = sg_product(Sg(l.axis_lambda.xyz, l.axis_lambda.w, l.mu.xyz), lobe);
        let hs = select(sg_texel.a, sg_sun_sin, i == 0u && suns > 0u);
        spec += sg_lobe_specular(q, vmf.axis, cut, hs, s);
    }
    return spec;
}
