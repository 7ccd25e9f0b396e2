// Stage 3, the GPU: the visibility fetch for scenes with `effects.visibility`: the D horizon angles
// (radians) of the pixel's level, 4 azimuths per RGBA16F layer, ceil(D / 4) layers per ring, blended
// bilinearly as the normals are (sg_clipmap.wgsl). No ring holding the pixel: no horizon (the lowered
// tangent plane only).

@group(2) @binding(2) var level_horizon: texture_2d_array<f32>;

fn sg_fetch_horizon(t: SgTaps) {
    let d = u32(sg_scene.material.z);
    if (t.level < 0) {
        sg_hz_count = 0u;
        return;
    }
    let per = i32(sg_scene.grid.y);
    for (var l = 0u; l < (d + 3u) / 4u; l++) {
        let layer = t.level * per + i32(l);
        let a = sg_bilinear(
            textureLoad(level_horizon, t.t00, layer, 0),
            textureLoad(level_horizon, t.t10, layer, 0),
            textureLoad(level_horizon, t.t01, layer, 0),
            textureLoad(level_horizon, t.t11, layer, 0),
            t.f,
        );
        for (var c = 0u; c < 4u; c++) {
            if (4u * l + c < d) {
                sg_hz[4u * l + c] = a[c];
            }
        }
    }
    sg_hz_count = d;
}
