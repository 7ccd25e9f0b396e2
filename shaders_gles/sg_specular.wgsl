// Stage 3, the GPU: the SG specular term (clipsat::shading::warped_ndf and the specular loop of
// clipsat::shading::shade), appended after sg_shading.wgsl only for scenes with `effects.specular`.

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

// k_s times the sum over lights of the product lobe's integral, D / 4 with the cosine at the lobe's axis,
// times the fraction of its one-sigma cap above the cut elevation.
fn sg_specular(vmf: SgVmf, view: vec3<f32>, cut: SgCut, s: SgScene) -> vec3<f32> {
    let ks = s.material.x;
    if (ks <= 0.0) {
        return vec3<f32>(0.0);
    }
    let n = vmf.axis;
    let lobe = sg_warped_ndf(vmf, s.material.y, view);
    var spec = vec3<f32>(0.0);
    let count = min(u32(s.kd_count.w), SG_MAX_LIGHTS);
    for (var i = 0u; i < count; i++) {
        let l = s.lights[i];
        let q = sg_product(Sg(l.axis_lambda.xyz, l.axis_lambda.w, l.mu.xyz), lobe);
        let c = max(dot(n, q.axis), 0.0);
        let sigma = min(sqrt(2.0 / max(q.lambda, 1.0e-6)), SG_HALF_PI);
        spec += q.mu * sg_unit_integral(q.lambda) * (0.25 * c * sg_soft_visible(cut, q.axis, sigma));
    }
    return spec * ks;
}
