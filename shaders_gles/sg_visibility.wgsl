// Stage 3, the GPU: the visibility fetch for scenes with `effects.visibility`: the sines of the D horizon
// angles of the pixel's level, 4 azimuths per RGBA16F layer, ceil(D / 4) layers per ring, blended
// bilinearly as the normals are (sg_clipmap.wgsl). No ring holding the pixel: no horizon (the lowered
// tangent plane only). The layers are read under uniform branches, into constant indices of sg_hz.

@group(2) @binding(2) var level_horizon: texture_2d_array<f32>;

fn sg_horizon_layer(t: SgTaps, l: i32) -> vec4<f32> {
    let layer = t.level * i32(sg_scene.grid.y) + l;
    return sg_bilinear(
        textureLoad(level_horizon, t.t00, layer, 0),
        textureLoad(level_horizon, t.t10, layer, 0),
        textureLoad(level_horizon, t.t01, layer, 0),
        textureLoad(level_horizon, t.t11, layer, 0),
        t.f,
    );
}

fn sg_fetch_horizon(t: SgTaps) {
    let d = u32(sg_scene.material.z);
    if (t.level < 0) {
        sg_hz_count = 0u;
        return;
    }
    sg_hz[0] = sg_horizon_layer(t, 0);
    if (d > 4u) {
        sg_hz[1] = sg_horizon_layer(t, 1);
    }
    if (d > 8u) {
        sg_hz[2] = sg_horizon_layer(t, 2);
    }
    if (d > 12u) {
        sg_hz[3] = sg_horizon_layer(t, 3);
    }
    sg_hz_count = d;
}
