// Stage 3, the GPU: the SG variant of a scene without fog: no fog code (src/gpu/shaders.rs).

fn sg_fog(colour: vec3<f32>, dist: f32) -> vec3<f32> {
    return colour;
}
