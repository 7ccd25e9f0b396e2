// Stage 3, the GPU: the specular stub for scenes without `effects.specular`: no specular code is compiled.

fn sg_specular(vmf: SgVmf, view: vec3<f32>, cut: SgCut, suns: u32, count: u32, s: SgScene) -> vec3<f32> {
    return vec3<f32>(0.0);
}
