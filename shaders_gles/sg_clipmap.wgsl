// Stage 3, the GPU: the clipmap renderer's SG fragment shader. Appended after basic_shading.wgsl,
// clipmap.wgsl, sg_shading.wgsl, one specular file, one visibility file and one fog file (src/gpu/shaders.rs).
//
// SAT paper algorithm 2, on per-level tables (docs/design.md "Memory model"; src/gpu/renderer/sg_tables.rs): the
// pixel's footprint from dpdx/dpdy of its data coordinates picks the level k whose spacing 2^k data
// samples matches it, as the SAT paper picks its box; the finest ring at or above that level holding the
// pixel is read, 4 textureLoads (float textures are not filterable on GLES 3.0) blended bilinearly. Each
// texel holds the box mean of the data's normals over 2^k + 1 samples centred on it, so the blend is a
// tent filter about 2^(k+1) samples wide (its w: the horizon's sine toward the first sun). With visibility
// the light table is read at the same taps (sg_visibility.wgsl). `clipsat::twin::shading::sg_taps` and
// `sg_light` are the CPU twins.

@group(2) @binding(0) var<uniform> sg_scene: SgScene;
@group(2) @binding(1) var level_normal: texture_2d_array<f32>;

// Where a pixel's shading inputs are read: ring `level`'s texels t00, t10, t01, t11 and the bilinear
// weights f; level < 0: no ring holds the pixel.
struct SgTaps {
    level: i32,
    t00: vec2<i32>,
    t10: vec2<i32>,
    t01: vec2<i32>,
    t11: vec2<i32>,
    f: vec2<f32>,
}

// Level table `tex` at the taps' 4 texels, blended bilinearly.
fn sg_blend(tex: texture_2d_array<f32>, t: SgTaps) -> vec4<f32> {
    let a = textureLoad(tex, t.t00, t.level, 0);
    let b = textureLoad(tex, t.t10, t.level, 0);
    let c = textureLoad(tex, t.t01, t.level, 0);
    let d = textureLoad(tex, t.t11, t.level, 0);
    return mix(mix(a, b, t.f.x), mix(c, d, t.f.x), t.f.y);
}

// The taps of eye-relative point rel for a footprint of `w` data samples (the larger side of the pixel's
// box): the first ring from level synth + round(log2 w) on that holds rel (level_holds, clipmap.wgsl),
// which is the finest ring holding rel if that is coarser (finest_level need not run first: the rings
// between do not hold rel). Where none does (a pixel at the data's border, or a
// footprint coarser than every ring), the coarsest ring of 4 x 4 samples or more (level_info.w), its cell
// clamped into the held ones: every pixel reads a table, with no branch to a second shading path (which
// llvmpipe would run at every pixel). level < 0 only for a clipmap without such a ring.
//
// synth, the level of the tables' data spacing: rings finer than it (synthesised, or finer than a bake on
// a coarser pyramid level) are never read. It comes from the fallback ring's spacing, which holds data,
// not from level 0's, which is 0 while level 0 holds none (not yet filled, or disabled with the eye high):
// log2 of an infinity then converted to int was undefined in GLSL ES 3.00, and NVIDIA's saturating
// conversion started the ring loop past the uniform array (docs/real-drivers.md). Every float-to-int
// conversion converts a clamped value.
fn sg_taps(rel: vec2<f32>, w: f32) -> SgTaps {
    var t: SgTaps;
    t.level = -1;
    let n = globals.level_info.x;
    let fallback = globals.level_info.w;
    if (fallback < 0 || fallback >= n) {
        return t;
    }
    let g = globals.levels[fallback].rel.w;
    let synth = max(fallback + i32(clamp(round(log2(sg_scene.grid.x / g)), -32.0, 32.0)), 0);
    // A NaN footprint compares false: one sample.
    let side = select(1.0, min(w, 1.0e9), w > 1.0);
    let k = i32(clamp(round(log2(side)), 0.0, 32.0));
    var pick = fallback;
    for (var l = synth + k; l < n; l = l + 1) {
        let lv = globals.levels[l];
        if (level_holds(lv, level_cell(lv, rel))) {
            pick = l;
            break;
        }
    }
    let lv = globals.levels[pick];
    let u = level_uv(lv, rel);
    let i = vec2<i32>(clamp(floor(u), vec2<f32>(1.0), vec2<f32>(lv.tex.zw - vec2<i32>(3))));
    // Toroidal texels mod S without an integer division (llvmpipe has no vector one: 8 scalar divisions
    // a lane): tex.xy < S and i + 1 <= S - 2, so one subtraction wraps (GLSL ES 3.0 has no integer mix
    // for a select: the comparison as 0 or 1, a conversion GLSL ES 3.00 defines).
    let s = vec2<i32>(globals.level_info.y);
    let a = lv.tex.xy + i;
    let t0 = a - s * vec2<i32>(a >= s);
    let b = a + vec2<i32>(1);
    let t1 = b - s * vec2<i32>(b >= s);
    t.level = pick;
    t.t00 = t0;
    t.t10 = vec2<i32>(t1.x, t0.y);
    t.t01 = vec2<i32>(t0.x, t1.y);
    t.t11 = t1;
    t.f = clamp(u - vec2<f32>(i), vec2<f32>(0.0), vec2<f32>(1.0));
    return t;
}

// The footprint's side in data samples, from the derivatives, so it must be called in uniform control
// flow (before any discard).
fn sg_footprint(v: VsOut) -> f32 {
    let c = v.rel.xy / sg_scene.grid.x;
    let d = max(abs(dpdx(c)), abs(dpdy(c)));
    return max(d.x, d.y);
}

// What a kept fragment of footprint w reads: its taps, and r.
struct SgRead {
    taps: SgTaps,
    // The vMF input r, w: the horizon's sine toward the first sun (visibility only).
    r: vec4<f32>,
}

fn sg_read(v: VsOut, w: f32) -> SgRead {
    let taps = sg_taps(v.rel.xy, w);
    // SG_OMIT 1 (`bench shading`'s breakdown only): no footprint fetch, the drawn mesh's normal; so too
    // where no ring holds the pixel.
    var r = vec4<f32>(normalize(v.normal) * 0.999, -2.0);
    if (SG_OMIT != 1u && taps.level >= 0) {
        r = sg_blend(level_normal, taps);
    }
    return SgRead(taps, r);
}

// The SG colour of a kept fragment of footprint w (sg_footprint).
fn sg_colour(v: VsOut, w: f32) -> vec4<f32> {
    let read = sg_read(v, w);
    let r = read.r;
    // sg_visibility.wgsl, or the stub of sg_no_visibility.wgsl. SG_OMIT 3 does not read the table.
    if (SG_OMIT != 3u) {
        sg_fetch_light(read.taps, r.w);
    }
    // sg_fog.wgsl, or the pass-through of sg_no_fog.wgsl in variants without fog.
    let colour = sg_fog(sg_shade(r.xyz, normalize(-v.rel), sg_scene), length(v.rel));
    return target_colour(vec4<f32>(pow(clamp(colour, vec3<f32>(0.0), vec3<f32>(1.0)), vec3<f32>(1.0 / 2.2)), 1.0));
}

// Blocks. The skirt test (through_side, which walks the rings) is a separate program for skirt draws,
// as in clipmap.wgsl: llvmpipe would run it under a mask at every pixel.
@fragment
fn fs_sg(v: VsOut) -> @location(0) vec4<f32> {
    let w = sg_footprint(v);
    if (outside_data(v.rel.xy)) {
        discard;
    }
    return sg_colour(v, w);
}

// Skirts: also hidden where seen through the data's side.
@fragment
fn fs_sg_skirt(v: VsOut) -> @location(0) vec4<f32> {
    let w = sg_footprint(v);
    if (outside_data(v.rel.xy) || (v.skirt > 0.0 && through_side(v.rel))) {
        discard;
    }
    return sg_colour(v, w);
}

// The shading probe's SG programs (clipmap.wgsl's `ProbeOut`): the footprint w in data samples and r.
@fragment
fn fs_sg_probe(v: VsOut) -> ProbeOut {
    let w = sg_footprint(v);
    if (outside_data(v.rel.xy)) {
        discard;
    }
    return probe_out(v, w, sg_read(v, w).r);
}

@fragment
fn fs_sg_probe_skirt(v: VsOut) -> ProbeOut {
    let w = sg_footprint(v);
    if (outside_data(v.rel.xy) || (v.skirt > 0.0 && through_side(v.rel))) {
        discard;
    }
    return probe_out(v, w, sg_read(v, w).r);
}
