// Stage 3, the GPU: test instrument. Evaluates `sg_shade` for a row of known inputs, one per pixel of a
// W x 1 Rgba32Uint target, and writes the exact bits of the linear result, for comparison with the CPU
// twin clipsat::shading::shade (tests/sg_gpu.rs). Appended after sg_shading.wgsl and a specular file.

@group(0) @binding(0) var<uniform> sg_scene: SgScene;
// RGBA32F, column = case. Row 0: r (xyz), w the horizon's sine toward the first sun; row 1: view (xyz);
// row 2: the light texel (rgb diffuse, a the horizon's mean sine), as the light table holds it (w and a
// -2 without visibility).
@group(0) @binding(1) var probe_inputs: texture_2d<f32>;

@vertex
fn vs_probe(@builtin(vertex_index) k: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the target.
    let p = vec2<f32>(f32((k << 1u) & 2u), f32(k & 2u));
    return vec4<f32>(p * 2.0 - vec2<f32>(1.0), 0.5, 1.0);
}

@fragment
fn fs_probe(@builtin(position) p: vec4<f32>) -> @location(0) vec4<u32> {
    let x = i32(clamp(p.x, 0.0, 16384.0));
    let r = textureLoad(probe_inputs, vec2<i32>(x, 0), 0);
    let view = textureLoad(probe_inputs, vec2<i32>(x, 1), 0).xyz;
    sg_texel = textureLoad(probe_inputs, vec2<i32>(x, 2), 0);
    sg_sun_sin = r.w;
    return bitcast<vec4<u32>>(vec4<f32>(sg_shade(r.xyz, view, sg_scene), 1.0));
}
