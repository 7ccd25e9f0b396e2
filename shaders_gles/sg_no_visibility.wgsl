// Stage 3, the GPU: the visibility stub for scenes without `effects.visibility`: no horizon texture is
// declared or bound, and PatchVis cuts at the lowered tangent plane only.

fn sg_fetch_horizon(lo: vec2<i32>, hi: vec2<i32>, q: f32) {
    sg_hz_count = 0u;
}
