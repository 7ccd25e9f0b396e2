// Stage 3, the GPU: the specular stub for scenes without `effects.specular`: no specular code is compiled.

fn sg_specular_lobe(vmf: SgVmf, view: vec3<f32>, s: SgScene) -> Sg {
    return Sg(vmf.axis, 1.0, vec3<f32>(0.0));
}

fn sg_sun_specular(lobe: Sg, n: vec3<f32>, cut: SgCut, light: Sg, hs: f32, s: SgScene) -> vec3<f32> {
    return vec3<f32>(0.0);
}

fn sg_broad_specular(lobe: Sg, n: vec3<f32>, cut: SgCut, first: u32, count: u32, s: SgScene) -> vec3<f32> {
    return vec3<f32>(0.0);
}
