// Stage 3, the GPU: reduced spherical-Gaussian shading (Li et al. 2021, the SAT paper, section 5,
// algorithms 2 and 3), the WGSL port of `clipsat::shading::shade`, line for line; `clipsat::sg` holds the
// same maths on the CPU. A library: no entry points. src/gpu/shaders.rs prepends `const SG_BANDS: u32`
// (M theta bands), the sky table's constants and its binding `sky_table` (the program's group), and
// appends one specular file (sg_specular.wgsl or sg_no_specular.wgsl) and a program, so each effect set
// is its own text.
//
// The horizon of the pixel (the sines of its D elevation angles, 4 to a vec4) is handed over in the
// private `sg_hz`, `sg_hz_count` (0: no visibility), which the program fills before calling `sg_shade`.
// Every loop over it has a constant bound and constant indices (llvmpipe keeps a dynamically indexed
// private array in memory and runs each access per lane); a D below 16 skips the rest under uniform
// branches.

const SG_PI: f32 = 3.14159265358979;
const SG_TAU: f32 = 6.28318530717959;
const SG_HALF_PI: f32 = 1.57079632679490;
// Mirrors clipsat::gpu::shaders::MAX_SG_LIGHTS (the desktop profile's max_sg_lights).
const SG_MAX_LIGHTS: u32 = 8u;
// clipsat::sg::COSINE_LAMBDA, COSINE_MU, R_MIN, R_MAX.
const SG_COSINE_LAMBDA: f32 = 2.133;
const SG_COSINE_MU: f32 = 1.170;
const SG_R_MIN: f32 = 1.0e-3;
const SG_R_MAX: f32 = 0.9999;
// clipsat::shading::sky_table::S_MIN, S_MAX.
const SG_SKY_S_MIN: f32 = 0.01;
const SG_SKY_S_MAX: f32 = 1.0;
// 1 / sqrt(3), the 2-point Gauss-Legendre node.
const SG_GAUSS_2: f32 = 0.5773503;

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
    // x: k_s, y: roughness, z: azimuths D (0: visibility off), w: fog extinction (1/m, 0: off)
    material: vec4<f32>,
    // rgb: fog colour (linear), w: unused
    fog: vec4<f32>,
    // x: the data's spacing (m); y: horizon layers per ring (sg_visibility.wgsl); z: the number of sharp
    // lights (suns), which come first in `lights`; w: unused
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

var<private> sg_hz: array<vec4<f32>, 4>;
var<private> sg_hz_count: u32;

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
    let e = exp(-0.5 * x * x);
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

// The pixel's cut (clipsat::shading::Cut): the mean normal and cos, sin of the plane's drop; the horizon
// is in sg_hz.
struct SgCut {
    n: vec3<f32>,
    cos_drop: f32,
    sin_drop: f32,
}

fn sg_cut(n: vec3<f32>, drop: f32) -> SgCut {
    return SgCut(n, cos(drop), sin(drop));
}

// The sine of the horizon at world azimuth a, linear between the D baked azimuths
// (clipsat::shading::Cut::horizon_sin_at): the two neighbours picked by selects over the four vec4s, not by
// a dynamic index.
fn sg_horizon_sin_at(a: f32) -> f32 {
    let d = sg_hz_count;
    let t = fract(a / SG_TAU) * f32(d);
    let k0 = min(u32(floor(t)), d - 1u);
    let f = t - f32(k0);
    let k1 = (k0 + 1u) % d;
    let w0 = vec4<f32>(1.0 - f);
    let w1 = vec4<f32>(f);
    let zero = vec4<f32>(0.0);
    var h = 0.0;
    for (var j = 0u; j < 4u; j++) {
        let idx = vec4<u32>(4u * j) + vec4<u32>(0u, 1u, 2u, 3u);
        let w = select(zero, w0, idx == vec4<u32>(k0)) + select(zero, w1, idx == vec4<u32>(k1));
        h += dot(sg_hz[j], w);
    }
    return h;
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

// The sine of the horizon toward horizontal direction (dx, dy), or -2 (below any cut) without visibility.
fn sg_horizon_sin_toward(dx: f32, dy: f32) -> f32 {
    if (sg_hz_count == 0u) {
        return -2.0;
    }
    return sg_horizon_sin_at(atan2(dy, dx));
}

// TransferVis + PatchVis (SAT paper algorithm 3): the sine of the elevation below which horizontal
// direction (dx, dy) is cut, the higher of the horizon's sine `hs` there and the mean normal's lowered
// tangent plane, the plane's without trigonometry (clipsat::shading::Cut::sin_at).
fn sg_cut_sin(c: SgCut, dx: f32, dy: f32, hs: f32) -> f32 {
    let inv_d = 1.0 / sqrt(max(dx * dx + dy * dy, 1.0e-30));
    return max(sg_plane_sin(c, dx * inv_d, dy * inv_d), hs);
}

// The fraction of a light about `axis` of radius sigma above the horizon alone, `hs` the horizon's sine
// toward it (clipsat::shading::Cut::horizon_visible).
fn sg_horizon_visible(axis: vec3<f32>, sigma: f32, hs: f32) -> f32 {
    if (sg_hz_count == 0u) {
        return 1.0;
    }
    let h = asin(clamp(hs, -1.0, 1.0));
    let el = asin(clamp(axis.z, -1.0, 1.0));
    return clamp((el + sigma - h) / (2.0 * sigma), 0.0, 1.0);
}

// The fraction of a lobe about `axis` of radius sigma above the cut, `hs` the horizon's sine toward it
// (clipsat::shading::Cut::soft_visible).
fn sg_soft_visible(c: SgCut, axis: vec3<f32>, sigma: f32, hs: f32) -> f32 {
    let cut = asin(clamp(sg_cut_sin(c, axis.x, axis.y, hs), -1.0, 1.0));
    let el = asin(clamp(axis.z, -1.0, 1.0));
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

// One wedge of `sg_occluded`: direction (ca, sa), horizon sine hi; the lobe's energy between the plane's
// and the horizon's sines times the half span (2-point Gauss-Legendre over z = sin(elevation)).
fn sg_wedge(p: Sg, c: SgCut, ca: f32, sa: f32, hi: f32) -> f32 {
    let lo = sg_plane_sin(c, ca, sa);
    let half = 0.5 * max(hi - lo, 0.0);
    let mid = 0.5 * (hi + lo);
    let horizontal = p.axis.x * ca + p.axis.y * sa;
    let z0 = mid - SG_GAUSS_2 * half;
    let z1 = mid + SG_GAUSS_2 * half;
    let rho0 = sqrt(max(1.0 - z0 * z0, 0.0));
    let rho1 = sqrt(max(1.0 - z1 * z1, 0.0));
    let w0 = exp(p.lambda * (horizontal * rho0 + p.axis.z * z0 - 1.0));
    let w1 = exp(p.lambda * (horizontal * rho1 + p.axis.z * z1 - 1.0));
    return (w0 + w1) * half;
}

// Two wedges, each over a pair of baked azimuths (h.xy, h.zw): at the pair's middle direction `rot`
// (cos, sin), the horizon there (the pair's mean sine), width 2 dphi; `rot` steps by two azimuths.
fn sg_wedges4(p: Sg, c: SgCut, h: vec4<f32>, rot: ptr<function, vec2<f32>>, step: vec2<f32>) -> f32 {
    let r0 = *rot;
    let r1 = vec2<f32>(r0.x * step.x - r0.y * step.y, r0.y * step.x + r0.x * step.y);
    *rot = vec2<f32>(r1.x * step.x - r1.y * step.y, r1.y * step.x + r1.x * step.y);
    return sg_wedge(p, c, r0.x, r0.y, 0.5 * (h.x + h.y)) + sg_wedge(p, c, r1.x, r1.y, 0.5 * (h.z + h.w));
}

// What the horizon hides of product lobe p above the lowered plane: per pair of baked azimuths, the wedge
// between the plane's and the horizon's sines, 2-point Gauss-Legendre over z = sin(elevation)
// (clipsat::shading::occluded, which says why). Two wedges a vec4, each group under a uniform branch.
fn sg_occluded(p: Sg, c: SgCut) -> vec3<f32> {
    let d = sg_hz_count;
    let dphi = SG_TAU / f32(d);
    // Pair middles: from half an azimuth, two azimuths apart.
    let step = vec2<f32>(cos(2.0 * dphi), sin(2.0 * dphi));
    var rot = vec2<f32>(cos(0.5 * dphi), sin(0.5 * dphi));
    var sum = sg_wedges4(p, c, sg_hz[0], &rot, step);
    if (d > 4u) {
        sum += sg_wedges4(p, c, sg_hz[1], &rot, step);
    }
    if (d > 8u) {
        sum += sg_wedges4(p, c, sg_hz[2], &rot, step);
    }
    if (d > 12u) {
        sum += sg_wedges4(p, c, sg_hz[3], &rot, step);
    }
    return p.mu * (sum * 2.0 * dphi);
}

// Outgoing linear radiance toward `view` (unit, surface to eye) for mean normal r: the suns one direction
// each, the broad lights from the sky table less what the horizon hides, plus the variant's specular term
// (clipsat::shading::shade). SG_OMIT (a benchmark knob, `clipsat bench shading`'s breakdown; 0 in every
// rendering variant) drops one term: 2 the vMF (a single normal), 3 the sky table and its horizon wedges
// (every lobe as one direction).
fn sg_shade(r: vec3<f32>, view: vec3<f32>, s: SgScene) -> vec3<f32> {
    var vmf = sg_vmf(r);
    var cosine = Sg(vmf.axis, SG_COSINE_LAMBDA, vec3<f32>(SG_COSINE_MU));
    var cut = SgCut(vmf.axis, 1.0, 0.0);
    if (SG_OMIT == 2u) {
        vmf.kappa = 1.0e4;
        vmf.r_len = SG_R_MAX;
    } else {
        cosine = sg_convolve_vmf(cosine, vmf.kappa);
        cut = sg_cut(vmf.axis, sg_plane_drop(vmf.kappa));
    }
    var diffuse = vec3<f32>(0.0);
    let count = min(u32(s.kd_count.w), SG_MAX_LIGHTS);
    // Suns come first (SgSceneUniform::new): one loop per kind rather than a branch per light, which
    // llvmpipe would run both ways. SG_OMIT 3 (`bench shading`'s breakdown): every lobe as one direction.
    var suns = min(u32(s.grid.z), count);
    if (SG_OMIT == 3u) {
        suns = count;
    }
    // The variant's specular lobe (sg_specular.wgsl; a stub without specular).
    let lobe = sg_specular_lobe(vmf, view, s);
    var spec = vec3<f32>(0.0);
    for (var i = 0u; i < suns; i++) {
        // A sun: one direction (clipsat::shading::SHARP_LAMBDA). Its horizon is looked up once, for its
        // diffuse and its specular term.
        let l = s.lights[i];
        let light = Sg(l.axis_lambda.xyz, l.axis_lambda.w, l.mu.xyz);
        let sigma = sqrt(2.0 / max(light.lambda, 1.0e-6));
        let hs = sg_horizon_sin_toward(light.axis.x, light.axis.y);
        let f = sg_vmf_cosine(dot(vmf.axis, light.axis), vmf) * sg_horizon_visible(light.axis, sigma, hs);
        diffuse += light.mu * (sg_unit_integral(light.lambda) * f);
        spec += sg_sun_specular(lobe, vmf.axis, cut, light, hs, s);
    }
    // Uniform: the scene's light counts.
    if (suns < count) {
        var hidden = vec3<f32>(0.0);
        if (sg_hz_count > 0u) {
            for (var i = suns; i < count; i++) {
                let l = s.lights[i];
                let light = Sg(l.axis_lambda.xyz, l.axis_lambda.w, l.mu.xyz);
                hidden += sg_occluded(sg_product(light, cosine), cut);
            }
        }
        diffuse += max(sg_sky(vmf.axis, vmf.r_len) - hidden, vec3<f32>(0.0));
    }
    spec += sg_broad_specular(lobe, vmf.axis, cut, suns, count, s);
    return s.kd_count.rgb * diffuse / SG_PI + spec;
}
