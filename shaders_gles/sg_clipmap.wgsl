// Stage 3, the GPU: the clipmap renderer's SG fragment shader. Appended after basic_shading.wgsl,
// clipmap.wgsl, sg_shading.wgsl, one specular file, one visibility file and one fog file (src/gpu/shaders.rs).
//
// SAT paper algorithm 2: the pixel's footprint box on the shading grid from dpdx/dpdy of its grid
// coordinates, then a 4-corner textureLoad of each SAT (integer textures are not filterable on GLES 3.0).
// The SATs are R32UI-style wrapping fixed point with Q = 20 fractional bits (RGBA32UI, 4 channels per
// texel): a box mean comes out with max error 4.4e-7, against 1.7e-4 for RGBA32F with the mean subtracted
// and 4.5e-3 for plain RGBA32F (measured, tests/shading.rs gpu_sat_format_error). Each table is padded
// with a zero row and column, entry (x, y) = sum over [0, x) x [0, y), so a box needs no branch at the
// border; the corner difference wraps mod 2^32 and is exact while the box sum stays below 2^32, which
// the box side cap (grid.w = 63 samples: 63^2 2^20 < 2^32) guarantees.

@group(2) @binding(0) var<uniform> sg_scene: SgScene;
@group(2) @binding(1) var sat_normal: texture_2d<u32>;

// Sum over the inclusive sample box [lo, hi] of the normal table, wrapping.
fn sg_normal_sum(lo: vec2<i32>, hi: vec2<i32>) -> vec4<u32> {
    return textureLoad(sat_normal, hi + 1, 0) - textureLoad(sat_normal, vec2<i32>(lo.x, hi.y + 1), 0)
        - textureLoad(sat_normal, vec2<i32>(hi.x + 1, lo.y), 0) + textureLoad(sat_normal, lo, 0);
}

@fragment
fn fs_sg(v: VsOut) -> @location(0) vec4<f32> {
    // Shading-grid coordinates (column east, row south) from the data's extent around the eye; the
    // derivatives come first, in uniform control flow.
    let ext = globals.extent;
    let g = sg_scene.grid;
    let c = vec2<f32>(
        (v.rel.x - ext.x) / (ext.z - ext.x) * g.x,
        (ext.w - v.rel.y) / (ext.w - ext.y) * g.y,
    ) / g.z;
    let half = 0.5 * max(abs(dpdx(c)), abs(dpdy(c)));
    if (outside_data(v.rel.xy) || (v.skirt > 0.0 && through_side(v.rel))) {
        discard;
    }
    let last = vec2<i32>(textureDimensions(sat_normal)) - vec2<i32>(2);
    let lo = clamp(vec2<i32>(floor(c - half + 0.5)), vec2<i32>(0), last);
    let side = i32(g.w) - 1;
    let hi = clamp(vec2<i32>(floor(c + half + 0.5)), lo, min(last, lo + vec2<i32>(side)));
    let count = f32((hi.x - lo.x + 1) * (hi.y - lo.y + 1));
    // 2^-20 per unit, over the box.
    let q = 1.0 / (count * 1048576.0);
    // SG_OMIT 1 (`bench shading`'s breakdown only): no footprint fetch, the drawn mesh's normal.
    var r = normalize(v.normal) * 0.999;
    if (SG_OMIT != 1u) {
        r = vec3<f32>(sg_normal_sum(lo, hi).xyz) * q * 2.0 - vec3<f32>(1.0);
    }
    sg_fetch_horizon(lo, hi, q);
    // sg_fog.wgsl, or the pass-through of sg_no_fog.wgsl in variants without fog.
    let colour = sg_fog(sg_shade(r, normalize(-v.rel), sg_scene), length(v.rel));
    return vec4<f32>(pow(clamp(colour, vec3<f32>(0.0), vec3<f32>(1.0)), vec3<f32>(1.0 / 2.2)), 1.0);
}
