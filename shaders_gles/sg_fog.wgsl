// Stage 3, the GPU: scene fog for the SG fragment shader, compiled only into the variants of scenes that
// declare fog (src/gpu/shaders.rs; `sg_no_fog.wgsl` otherwise). The density is fitted to the terrain on
// the CPU (`Scene::fit_fog`).

// Linear colour seen at distance `dist` (m) through the scene's fog.
fn sg_fog(colour: vec3<f32>, dist: f32) -> vec3<f32> {
    let keep = exp(-sg_scene.material.w * dist);
    return colour * keep + sg_scene.fog.rgb * (1.0 - keep);
}
