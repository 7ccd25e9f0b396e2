// Stage 3, the GPU: the visibility stub for scenes without `effects.visibility`: no horizon texture is
// declared or bound, and PatchVis cuts at the lowered tangent plane only.

fn sg_fetch_horizon(t: SgTaps) {
    sg_hz_count = 0u;
}
