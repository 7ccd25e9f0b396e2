// Stage 3, the GPU: reduced spherical-Gaussian shading (Li et al. 2021, the SAT paper, section 5,
// algorithms 2 and 3), the WGSL port of `clipsat::shading::shade_pixel`, line for line; `clipsat::sg` holds
// the same maths on the CPU. A library: no entry points. src/gpu/shaders.rs prepends `const SG_BANDS: u32`
// (M theta bands), `const SG_VISIBILITY: bool`, the sky table's constants and its binding `sky_table` (the
// program's group), and appends one specular file (sg_specular.wgsl or sg_no_specular.wgsl) and a
// program, so each effect set is its own text.
//
// With visibility the view-independent part of the shading (every light's diffuse term with the horizon
// applied: SAT paper algorithm 3) is computed on the CPU per texel of the per-level light table when the
// texel is written (`clipsat::shading::texel_light`); the program blends 4 texels into the private
// `sg_texel` (rgb: the diffuse radiance of every light but the first sun, a: the horizon's mean sine) and
// `sg_sun_sin` (the horizon's sine toward the first sun) before calling `sg_shade`, which adds the first
// sun's diffuse term, cut at that sine, and the view-dependent specular term. Without
// visibility `sg_shade` integrates the diffuse term itself: the suns one direction each, the broad lights
// from the sky table.

const SG_PI: f32 = 3.14159265358979;
const SG_HALF_PI: f32 = 1.57079632679490;
// Mirrors clipsat::gpu::shaders::MAX_SG_LIGHTS (the desktop profile's max_sg_lights).
const SG_MAX_LIGHTS: u32 = 8u;
// clipsat::sg::R_MIN, R_MAX.
const SG_R_MIN: f32 = 1.0e-3;
const SG_R_MAX: f32 = 0.9999;
// clipsat::shading::sky_table::S_MIN, S_MAX.
const SG_SKY_S_MIN: f32 = 0.01;
const SG_SKY_S_MAX: f32 = 1.0;

// One light lobe; mirrors clipsat::gpu::shaders::SgLightUniform.
struct SgLight {
    // xyz: unit axis (x east, y north, z up), w: sharpness lambda
    axis_lambda: vec4<f32>,
    // rgb: amplitude mu (linear), w: unused
    mu: vec4<f32>,
}

// Mirrors clipsat::gpu::shaders::SgSceneUniform.
struct SgScene {
    lights: array<SgLight, 8>,
    // rgb: diffuse albedo k_d (linear), w: number of lights
    kd_count: vec4<f32>,
    // x: k_s, y: roughness, z: azimuths D of the light table (0: visibility off; informative), w: fog
    // extinction (1/m, 0: off)
    material: vec4<f32>,
    // rgb: fog colour (linear), w: unused
    fog: vec4<f32>,
    // x: the data's spacing (m); y: unused; z: the number of sharp lights (suns), which come first in
    // `lights`; w: unused
    grid: vec4<f32>,
}

struct Sg {
    axis: vec3<f32>,
    lambda: f32,
    mu: vec3<f32>,
}

struct SgVmf {
    axis: vec3<f32>,
    kappa: f32,
    // |r| clamped into [R_MIN, R_MAX]: the vMF's mean resultant length.
    r_len: f32,
}

// The pixel's light-table texel: with visibility, the blend of the light table (sg_visibility.wgsl, or the
// probe's input): rgb the diffuse radiance (k_d / pi applied), a the mean of the horizon's sines; without,
// a = -2 (below any cut) and rgb unused. sg_sun_sin: the horizon's sine toward the first sun (the normal
// table's w), -2 without visibility.
var<private> sg_texel: vec4<f32>;
var<private> sg_sun_sin: f32;

// e^x - 1 without cancellation near 0 (clipsat::sg::expm1).
fn sg_expm1(x: f32) -> f32 {
    if (abs(x) < 1.0e-2) {
        return x * (1.0 + x * (0.5 + x * (1.0 / 6.0 + x * (1.0 / 24.0))));
    }
    return exp(x) - 1.0;
}

// (1 - e^-x) / x, exact as x -> 0 (clipsat::sg::one_minus_exp_over).
fn sg_one_minus_exp_over(x: f32) -> f32 {
    if (x < 1.0e-6) {
        return 1.0 - 0.5 * x;
    }
    return -sg_expm1(-x) / x;
}

// 2 pi (1 - e^(-2 lambda)) / lambda, the integral of a unit-amplitude SG.
fn sg_unit_integral(lambda: f32) -> f32 {
    return 4.0 * SG_PI * sg_one_minus_exp_over(2.0 * lambda);
}

// Product of two SGs (Wang et al. 2009 section 3); the exponent lambda - l1 - l2 <= 0 is combined before
// exp, so no raw exponent overflows.
fn sg_product(a: Sg, b: Sg) -> Sg {
    let s = a.axis * a.lambda + b.axis * b.lambda;
    let lambda = length(s);
    var axis = a.axis;
    if (lambda > 1.0e-20) {
        axis = s / lambda;
    }
    let e = min(lambda - (a.lambda + b.lambda), 0.0);
    return Sg(axis, lambda, a.mu * b.mu * exp(e));
}

// The SG convolved with a unit-mass vMF of concentration kappa (clipsat::sg::Sg::convolve_vmf).
fn sg_convolve_vmf(g: Sg, kappa: f32) -> Sg {
    let lambda = g.lambda * kappa / max(g.lambda + kappa, 1.0e-30);
    return Sg(g.axis, lambda, g.mu * (sg_unit_integral(g.lambda) / sg_unit_integral(lambda)));
}

// SAT paper algorithm 2: the vMF from the mean normal r, kappa = (3|r| - |r|^3) / (1 - |r|^2)
// (Banerjee et al. 2005), |r| clamped into [R_MIN, R_MAX].
fn sg_vmf(r: vec3<f32>) -> SgVmf {
    let len = length(r);
    var axis = vec3<f32>(0.0, 0.0, 1.0);
    if (len > 1.0e-30) {
        axis = r / len;
    }
    let rl = clamp(len, SG_R_MIN, SG_R_MAX);
    return SgVmf(axis, rl * (3.0 - rl * rl) / ((1.0 - rl) * (1.0 + rl)), rl);
}

// How far the cosine's cut-off plane drops for the vMF's spread (clipsat::shading::plane_drop).
fn sg_plane_drop(kappa: f32) -> f32 {
    return min(sqrt(2.0 / max(kappa, 1.0e-12)), SG_HALF_PI);
}

// E[max(n' . i, 0)] over the vMF for a direction at cosine t from the mean normal, n' . i taken as
// Gaussian with the vMF's first two moments (clipsat::shading::vmf_cosine, which cites the moments and
// the erfc approximation).
fn sg_vmf_cosine(t: f32, vmf: SgVmf) -> f32 {
    let a = vmf.r_len;
    let ak = a / vmf.kappa;
    let m = a * t;
    let t2 = t * t;
    let v = max(t2 * ((1.0 - a) * (1.0 + a) - 2.0 * ak) + (1.0 - t2) * ak, 0.0);
    if (v < 1.0e-14) {
        return max(m, 0.0);
    }
    let s = sqrt(v);
    let x = m / s;
    let e = exp(max(-0.5 * x * x, -80.0));
    let z = abs(x) * 0.70710678;
    let tau = 1.0 / (1.0 + 0.3275911 * z);
    let poly = tau
        * (0.2548296 + tau * (-0.28449674 + tau * (1.4214137 + tau * (-1.4531521 + tau * 1.0614054))));
    let tail = 0.5 * poly * e;
    var cdf = tail;
    if (x >= 0.0) {
        cdf = 1.0 - tail;
    }
    return max(m * cdf + s * e * 0.3989423, 0.0);
}

// The pixel's cut (clipsat::shading::Cut): the mean normal and cos, sin of the plane's drop.
struct SgCut {
    n: vec3<f32>,
    cos_drop: f32,
    sin_drop: f32,
}

fn sg_cut(n: vec3<f32>, drop: f32) -> SgCut {
    return SgCut(n, cos(drop), sin(drop));
}

// The sine of the lowered plane's elevation toward unit horizontal direction (ux, uy)
// (clipsat::shading::Cut::plane_sin, which says why n_z is floored).
fn sg_plane_sin(c: SgCut, ux: f32, uy: f32) -> f32 {
    let p = -(c.n.x * ux + c.n.y * uy);
    let q = max(c.n.z, 1.0e-4);
    let inv = 1.0 / sqrt(max(p * p + q * q, 1.0e-30));
    var plane = (p * c.cos_drop - q * c.sin_drop) * inv;
    if ((q * c.cos_drop + p * c.sin_drop) * inv < 0.0) {
        plane = -1.0;
    }
    return plane;
}

// The fraction of a lobe about `axis` of radius sigma above the cut: the higher of the lowered plane and
// `hs`, the horizon's sine toward it (TransferVis + PatchVis, SAT paper algorithm 3;
// clipsat::shading::Cut::soft_visible).
fn sg_soft_visible(c: SgCut, axis: vec3<f32>, sigma: f32, hs: f32) -> f32 {
    let inv_d = 1.0 / sqrt(max(axis.x * axis.x + axis.y * axis.y, 1.0e-30));
    let plane = sg_plane_sin(c, axis.x * inv_d, axis.y * inv_d);
    return sg_above_cut(axis.z, sigma, max(plane, hs));
}

// The fraction of a lobe whose axis has height `z` (the sine of its elevation), of radius sigma, above a
// cut of sine `cut_sin` (-2: none): linear in the elevation over +/- sigma (clipsat::shading's above_cut).
fn sg_above_cut(z: f32, sigma: f32, cut_sin: f32) -> f32 {
    let cut = asin(clamp(cut_sin, -1.0, 1.0));
    let el = asin(clamp(z, -1.0, 1.0));
    return clamp((el + sigma - cut) / (2.0 * sigma), 0.0, 1.0);
}

fn sg_sky_texel(l: i32, i: i32, j: i32) -> vec3<f32> {
    return textureLoad(sky_table, vec2<i32>(l * SG_SKY_SIDE + i, j), 0).xyz;
}

// The sky table (clipsat::shading::SkyTable::lookup, which gives the parametrisation): the broad lights'
// unshadowed diffuse integral at unit n and mean resultant length r_len, bilinear in the two nearest
// layers and linear between them (8 textureLoads: RGBA32F is not filterable on GLES 3.0).
fn sg_sky(n: vec3<f32>, r_len: f32) -> vec3<f32> {
    let inv = 1.0 / max(abs(n.x) + abs(n.y) + max(n.z, 0.0), 1.0e-30);
    let px = n.x * inv;
    let py = n.y * inv;
    let half = 0.5 * f32(SG_SKY_SIDE - 1);
    let top = f32(SG_SKY_SIDE - 1);
    let x = clamp((px + py) * half + half, 0.0, top);
    let y = clamp((px - py) * half + half, 0.0, top);
    let s = sqrt(1.0 - clamp(r_len, SG_R_MIN, SG_R_MAX));
    let lt = f32(SG_SKY_LAYERS - 1);
    let l = clamp((s - SG_SKY_S_MIN) * (lt / (SG_SKY_S_MAX - SG_SKY_S_MIN)), 0.0, lt);
    let i = min(i32(floor(x)), SG_SKY_SIDE - 2);
    let j = min(i32(floor(y)), SG_SKY_SIDE - 2);
    let k = min(i32(floor(l)), SG_SKY_LAYERS - 2);
    let fx = x - f32(i);
    let fy = y - f32(j);
    let fl = l - f32(k);
    let a = mix(
        mix(sg_sky_texel(k, i, j), sg_sky_texel(k, i + 1, j), fx),
        mix(sg_sky_texel(k, i, j + 1), sg_sky_texel(k, i + 1, j + 1), fx),
        fy,
    );
    let b = mix(
        mix(sg_sky_texel(k + 1, i, j), sg_sky_texel(k + 1, i + 1, j), fx),
        mix(sg_sky_texel(k + 1, i, j + 1), sg_sky_texel(k + 1, i + 1, j + 1), fx),
        fy,
    );
    return mix(a, b, fl);
}

// Outgoing linear radiance toward `view` (unit, surface to eye) for mean normal r: the diffuse term from
// `sg_texel` with visibility, else the suns one direction each and the broad lights from the sky table;
// plus the variant's specular term (clipsat::shading::shade_pixel). SG_OMIT (a benchmark knob, `clipsat
// bench shading`'s breakdown; 0 in every rendering variant) drops one term: 2 the vMF (a single normal),
// 3 the light table and the sky table (every lobe as one direction, unshadowed).
fn sg_shade(r: vec3<f32>, view: vec3<f32>, s: SgScene) -> vec3<f32> {
    var vmf = sg_vmf(r);
    var cut = SgCut(vmf.axis, 1.0, 0.0);
    if (SG_OMIT == 2u) {
        vmf.kappa = 1.0e4;
        vmf.r_len = SG_R_MAX;
    } else {
        cut = sg_cut(vmf.axis, sg_plane_drop(vmf.kappa));
    }
    // Small whole numbers in f32, clamped before the conversion (docs/real-drivers.md).
    let count = u32(clamp(s.kd_count.w, 0.0, f32(SG_MAX_LIGHTS)));
    // Suns come first (SgSceneUniform::new).
    let suns = min(u32(clamp(s.grid.z, 0.0, f32(SG_MAX_LIGHTS))), count);
    var diffuse = sg_texel.rgb;
    // Constant per variant: the other side is not compiled.
    if (!SG_VISIBILITY || SG_OMIT == 3u) {
        // One loop per kind rather than a branch per light, which llvmpipe would run both ways.
        var direct = suns;
        if (SG_OMIT == 3u) {
            direct = count;
        }
        var d = vec3<f32>(0.0);
        for (var i = 0u; i < direct; i++) {
            // A sun: one direction (clipsat::shading::SHARP_LAMBDA).
            let l = s.lights[i];
            let t = dot(vmf.axis, l.axis_lambda.xyz);
            d += l.mu.xyz * (sg_unit_integral(l.axis_lambda.w) * sg_vmf_cosine(t, vmf));
        }
        // Uniform: the scene's light counts.
        if (direct < count) {
            d += sg_sky(vmf.axis, vmf.r_len);
        }
        diffuse = s.kd_count.rgb * d / SG_PI;
    } else if (suns > 0u) {
        // The first sun is the pixel's own (clipsat::shading::shade_pixel): cut at the blended horizon
        // sine toward it, its shadow edge stays sharp within a texel. Uniform: the scene's sun count.
        let l = s.lights[0];
        let vis = sg_above_cut(l.axis_lambda.z, sqrt(2.0 / l.axis_lambda.w), sg_sun_sin);
        let t = dot(vmf.axis, l.axis_lambda.xyz);
        let sun = l.mu.xyz * (sg_unit_integral(l.axis_lambda.w) * (sg_vmf_cosine(t, vmf) * vis));
        diffuse += s.kd_count.rgb * sun / SG_PI;
    }
    return diffuse + sg_specular(vmf, view, cut, suns, count, s);
}
