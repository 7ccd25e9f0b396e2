// Stage 3, the GPU: draped imagery, the colour clipmap (src/plan/color_rings.rs). Concatenated after
// clipmap.wgsl in its imagery variant only (src/gpu/shaders.rs `clipmap_imagery`): a terrain without
// imagery compiles and binds none of this.
//
// Ring l holds texels of pyramid level l at toroidal addresses (texel (i, j) at (i mod S, j mod S)), in
// one 2D array texture (RGBA8, BC1 or ETC2 RGB8) sampled bilinearly with wrapping (the sampler's repeat
// mode is the toroidal addressing; the CPU twin, `clipsat::twin::imagery`, filters as GLES 3.0 defines
// it). A pixel's level follows its footprint (texture clipmaps, Tanner et al. 1998; docs/guide.md
// "Imagery: --imagery"): lod = log2(footprint / level 0's spacing), the pixel blends level floor(lod) with
// the next over the upper half of the fraction (IMAGERY_BLEND). A ring that does not hold the pixel hands it to
// the next coarser ring, over IMAGERY_BORDER texels at its held region's border, so no seam shows where
// a ring ends, and a ring that has just become whole fades in over a few frames. Outside every ring
// (past the image) the terrain keeps its own albedo.

// Texels over which a ring's held region fades into the next coarser ring at its border.
const IMAGERY_BORDER: f32 = 4.0;

// The part of a level's footprint range (log2, 0 to 1) over which a pixel blends it with the next
// coarser level: the upper half. Below it the pixel takes its level alone, one ring sampled, as
// "brilinear" filtering does; the blend still runs from 0 to 1, so nothing jumps. Against a reference
// that averages the source over each pixel's footprint it is also the closer filter: full-range blending
// weighs the coarser level in from where the finer one alone is near the footprint, and blurs
// (docs/measurements.md, "Imagery's cost").
const IMAGERY_BLEND: f32 = 0.5;

// How far inside a ring's held region its taps are kept, texels: half a texel and a 256th.
const IMAGERY_TAP_IN: f32 = 0.50390625;

// Mirrors `clipsat::plan::color_rings::ImageryUniform`.
struct ImageryLevel {
    // xy: the eye's texel (column, row from the north-west corner) modulo the ring; zw: texels per metre
    // (east-west, north-south).
    eye: vec4<f32>,
    // The held region relative to the eye, texels: x0, y0, x1, y1 (x1 <= x0: the ring holds nothing).
    held: vec4<f32>,
    // x: the ring's fade-in weight, 0 to 1; yzw: unused.
    fade: vec4<f32>,
    // The region of the ring's weight relative to the eye, texels: `held` with each side on the level's
    // own edge (the image's) moved far out, so the ring stays whole up to the image's edge.
    inner: vec4<f32>,
}

struct Imagery {
    levels: array<ImageryLevel, 12>,
    // x: rings in use; y: ring side S (a power of two); zw: unused.
    info: vec4<i32>,
    // The image's extent relative to the eye, metres: west, south, east, north.
    image: vec4<f32>,
}

@group(2) @binding(0) var<uniform> imagery: Imagery;
@group(2) @binding(1) var imagery_rings: texture_2d_array<f32>;
// Bilinear with repeat: a ring's toroidal addressing is the sampler's wrap.
@group(2) @binding(2) var imagery_sampler: sampler;

// The pixel's footprint in metres: its largest step on the ground, taken before any discard.
var<private> imagery_fp: f32;

fn imagery_footprint(rel: vec3<f32>) -> f32 {
    let d = max(abs(dpdx(rel.xy)), abs(dpdy(rel.xy)));
    return max(d.x, d.y);
}

// Ring l's colour at `rel` (m from the eye), bilinear, premultiplied: alpha is the ring's weight there, 0
// outside its held region, rising over IMAGERY_BORDER texels inside it (inside `inner`: not at the
// image's edge), times its fade-in.
fn imagery_sample(l: i32, rel: vec2<f32>) -> vec4<f32> {
    let lv = imagery.levels[l];
    // Texels from the eye: columns east, rows south.
    let t = vec2<f32>(rel.x * lv.eye.z, -rel.y * lv.eye.w);
    // Inside by at least half a texel: the four taps are held.
    let lo = t - (lv.inner.xy + 0.5);
    let hi = (lv.inner.zw - 0.5) - t;
    let d = min(min(lo.x, lo.y), min(hi.x, hi.y));
    let w = clamp(d / IMAGERY_BORDER, 0.0, 1.0) * lv.fade.x;
    // The taps kept on held texels, as a clamp-to-edge sampler keeps them on the image (at the image's
    // edge, where the weight stays whole): a texel coordinate at least half a texel (and a 256th, the
    // filter's weight precision, against f32 rounding) inside. max then min, not clamp: an empty held
    // region's bounds cross.
    let tc = min(max(t, lv.held.xy + IMAGERY_TAP_IN), lv.held.zw - IMAGERY_TAP_IN);
    // The eye's texel modulo the ring plus the offset, over the ring: the sampler wraps it. Sampled
    // whatever w is (a weight of 0 zeroes it): a software rasteriser runs both sides of a branch anyway.
    let uv = (lv.eye.xy + tc) / f32(imagery.info.y);
    let c = textureSampleLevel(imagery_rings, imagery_sampler, uv, l, 0.0);
    return vec4<f32>(c.rgb * w, w);
}

// x^2.2 on [0, 1] (the imagery's display encoding decoded, as the basic ramp's stops are): x^2 (a + b
// sqrt(x) + (1 - a - b) x), fitted minimax in display space, exact at 0 and 1, monotonic, and within 0.2
// of an 8-bit code of x when encoded again (^1/2.2). pow costs a software rasteriser a log and an exp a
// channel, a third of what the imagery adds to a basic frame on llvmpipe.
fn imagery_decode(x: vec3<f32>) -> vec3<f32> {
    return x * x * (0.3783 + 0.8759 * sqrt(x) - 0.2542 * x);
}

// The albedo of a pixel at `rel` whose terrain albedo is `base` (linear light): the imagery's colour,
// display-encoded as stored and decoded (^2.2) as the basic ramp's stops are, over `base` by its weight.
fn imagery_albedo(rel: vec2<f32>, base: vec3<f32>) -> vec3<f32> {
    let n = imagery.info.x;
    let lod = clamp(log2(max(imagery_fp * imagery.levels[0].eye.z, 1.0e-6)), 0.0, f32(n - 1));
    let l0 = i32(lod);
    let t = clamp((lod - f32(l0) - (1.0 - IMAGERY_BLEND)) / IMAGERY_BLEND, 0.0, 1.0);
    // Fine to coarse, front to back: a is ring l0 over the coarser rings, b ring l0 + 1 over those
    // coarser than it, each ring sampled once; a pixel stops once a is whole and b is (or is not
    // blended: t = 0), so most take one ring or two.
    var a = vec4<f32>(0.0);
    var b = vec4<f32>(0.0);
    for (var l = l0; l < n; l = l + 1) {
        let s = imagery_sample(l, rel);
        a = a + (1.0 - a.a) * s;
        b = b + select(0.0, 1.0 - b.a, l > l0) * s;
        if (a.a >= 1.0 && (b.a >= 1.0 || t <= 0.0)) {
            break;
        }
    }
    let c = a;
    let coarse = b;
    let m = select(c, mix(c, coarse, t), l0 + 1 < n);
    let img = imagery_decode(m.rgb / max(m.a, 1.0e-6));
    // The image's own edge, cut at its extent (pixel-is-area) and smoothed over the pixel's footprint.
    let im = imagery.image;
    let inside = min(min(rel.x - im.x, rel.y - im.y), min(im.z - rel.x, im.w - rel.y));
    let cover = clamp(inside / max(imagery_fp, 1.0e-6) + 0.5, 0.0, 1.0);
    return mix(base, img, m.a * cover);
}

// basic_shade (basic_shading.wgsl) with the imagery's albedo: the same light and fog, in the same
// arithmetic (keep the two in step; `clipsat::twin::imagery::shade` mirrors this one).
fn imagery_shade(v: VsOut, h: f32, n: vec3<f32>, s: BasicShading) -> vec3<f32> {
    let albedo = imagery_albedo(v.rel.xy, basic_albedo(h, s));
    let nn = normalize(vec3<f32>(n.xy * (s.ramp_fog.w / max(n.z, 1.0e-6)), 1.0));
    let sun = max(dot(nn, s.sun_dir.xyz), 0.0);
    let sky = 0.5 + 0.5 * nn.z;
    let light = vec3<f32>(1.00, 0.95, 0.86) * (1.45 * sun) + vec3<f32>(0.50, 0.62, 0.80) * (0.30 * sky);
    let fog = 1.0 - exp(-length(v.rel) * s.ramp_fog.z);
    let lit = mix(albedo * light, s.fog_colour.rgb, fog);
    return pow(clamp(lit, vec3<f32>(0.0), vec3<f32>(1.0)), vec3<f32>(1.0 / 2.2));
}
