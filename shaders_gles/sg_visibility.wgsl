// Stage 3, the GPU: the visibility fetch for scenes with `effects.visibility`: the box means of the D
// baked horizon angles from their SATs (4 azimuths per RGBA32UI layer, same wrapping fixed point as the
// normal table; see sg_clipmap.wgsl), mapped back from (a + pi/2) / pi.

@group(2) @binding(2) var sat_horizon: texture_2d_array<u32>;

fn sg_fetch_horizon(lo: vec2<i32>, hi: vec2<i32>, q: f32) {
    let d = u32(sg_scene.material.z);
    for (var l = 0u; l < (d + 3u) / 4u; l++) {
        let li = i32(l);
        let s = textureLoad(sat_horizon, hi + 1, li, 0)
            - textureLoad(sat_horizon, vec2<i32>(lo.x, hi.y + 1), li, 0)
            - textureLoad(sat_horizon, vec2<i32>(hi.x + 1, lo.y), li, 0)
            + textureLoad(sat_horizon, lo, li, 0);
        let a = vec4<f32>(s) * q * SG_PI - vec4<f32>(SG_HALF_PI);
        for (var c = 0u; c < 4u; c++) {
            if (4u * l + c < d) {
                sg_hz[4u * l + c] = a[c];
            }
        }
    }
    sg_hz_count = d;
}
