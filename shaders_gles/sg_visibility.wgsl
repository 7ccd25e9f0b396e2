// Stage 3, the GPU: the light-table fetch for scenes with `effects.visibility`: the view-independent part
// of the shading per texel of the pixel's ring (`clipsat::shading::texel_light`, written on the CPU with
// the ring's texels: every light's diffuse term but the first sun's with the horizon applied, and the horizon's mean sine;
// RGBA16F, one layer per ring), blended bilinearly as the normals are (sg_clipmap.wgsl).

@group(2) @binding(2) var level_light: texture_2d_array<f32>;

// Fills sg_texel from the taps' 4 texels; `sun_sin` (the normal table's blended w) is the horizon's sine
// toward the first sun.
fn sg_fetch_light(t: SgTaps, sun_sin: f32) {
    // No ring (a clipmap without one of 4 x 4 samples): no layer -1 is read (out of the texture, undefined
    // in GLSL ES 3.00); as without visibility.
    sg_texel = vec4<f32>(0.0, 0.0, 0.0, -2.0);
    sg_sun_sin = -2.0;
    if (t.level >= 0) {
        sg_texel = sg_blend(level_light, t);
        sg_sun_sin = sun_sin;
    }
}
