// Stage 3, the GPU: the visibility stub for scenes without `effects.visibility`: no light table is
// declared or bound; sg_shade integrates the diffuse term itself and cuts the specular lobes at the
// lowered tangent plane only.

fn sg_fetch_light(t: SgTaps, sun_sin: f32) {
    sg_texel = vec4<f32>(0.0, 0.0, 0.0, -2.0);
    sg_sun_sin = -2.0;
}
