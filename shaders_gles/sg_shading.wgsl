// Stage 3, the GPU: reduced spherical-Gaussian shading (Li et al. 2021, the SAT paper, section 5,
// algorithms 2 and 3), the WGSL port of `clipsat::shading::shade`, line for line; `clipsat::sg` holds the
// same maths on the CPU. A library: no entry points, no bindings. src/gpu/shaders.rs prepends
// `const SG_BANDS: u32` (M theta bands; N = 2 M phi sectors) and appends one specular file
// (sg_specular.wgsl or sg_no_specular.wgsl) and a program, so each effect set is its own text.
//
// The horizon of the pixel (box-averaged angles, radians, D of them) is handed over in the private
// `sg_hz`, `sg_hz_count` (0: no visibility), which the program fills before calling `sg_shade`.

const SG_PI: f32 = 3.14159265358979;
const SG_TAU: f32 = 6.28318530717959;
const SG_HALF_PI: f32 = 1.57079632679490;
// Mirrors clipsat::gpu::shaders::MAX_SG_LIGHTS (the desktop profile's max_sg_lights).
const SG_MAX_LIGHTS: u32 = 8u;
// Mirrors clipsat::shading::MAX_SECTORS: the row stride of the edge table.
const SG_MAX_SECTORS: u32 = 16u;
// clipsat::sg::COSINE_LAMBDA, COSINE_MU, R_MIN, R_MAX.
const SG_COSINE_LAMBDA: f32 = 2.133;
const SG_COSINE_MU: f32 = 1.170;
const SG_R_MIN: f32 = 1.0e-3;
const SG_R_MAX: f32 = 0.9999;

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
    // x, y: shading grid samples (width, height); z: data samples per grid sample; w: max box side
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
}

var<private> sg_hz: array<f32, 16>;
var<private> sg_hz_count: u32;

// e^x - 1 without cancellation near 0 (clipsat::sg::expm1).
fn sg_expm1(x: f32) -> f32 {
    if (abs(x) < 1.0e-2) {
        return x * (1.0 + x * (0.5 + x * (1.0 / 6.0 + x * (1.0 / 24.0))));
    }
    return exp(x) - 1.0;
}

// ln(1 + x) without cancellation near 0 (clipsat::sg::ln_1p).
fn sg_ln_1p(x: f32) -> f32 {
    if (abs(x) < 1.0e-2) {
        return x * (1.0 - x * (0.5 - x * (1.0 / 3.0 - x * 0.25)));
    }
    return log(1.0 + x);
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
    return SgVmf(axis, rl * (3.0 - rl * rl) / ((1.0 - rl) * (1.0 + rl)));
}

// Orthonormal (t, b) completing unit n (Duff et al. 2017, listing 3), as columns 0 and 1.
fn sg_basis(n: vec3<f32>) -> mat2x3<f32> {
    var sign = 1.0;
    if (n.z < 0.0) {
        sign = -1.0;
    }
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return mat2x3<f32>(
        vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        vec3<f32>(b, sign + n.y * n.y * a, -n.y),
    );
}

// How far the cosine's cut-off plane drops for the vMF's spread (clipsat::shading::plane_drop).
fn sg_plane_drop(kappa: f32) -> f32 {
    return min(sqrt(2.0 / max(kappa, 1.0e-12)), SG_HALF_PI);
}

// The horizon at world azimuth a, linear between the D baked azimuths (clipsat::horizon::interpolate).
fn sg_horizon_at(a: f32) -> f32 {
    let d = sg_hz_count;
    let t = fract(a / SG_TAU) * f32(d);
    let k0 = min(u32(floor(t)), d - 1u);
    let f = t - f32(k0);
    return sg_hz[k0] * (1.0 - f) + sg_hz[(k0 + 1u) % d] * f;
}

// TransferVis + PatchVis (SAT paper algorithm 3): the elevation below which direction at world azimuth a
// is cut, the higher of the horizon and the mean normal's lowered tangent plane.
fn sg_cut_elevation(n: vec3<f32>, drop: f32, a: f32) -> f32 {
    let plane = atan2(-(n.x * cos(a) + n.y * sin(a)), n.z) - drop;
    if (sg_hz_count == 0u) {
        return plane;
    }
    return max(plane, sg_horizon_at(a));
}

// Band edge holding energy fraction f, as u = 1 - cos theta (clipsat::shading::band_edge).
fn sg_band_edge(lambda: f32, f: f32) -> f32 {
    if (f >= 1.0) {
        return 2.0;
    }
    if (lambda < 1.0e-6) {
        return 2.0 * f;
    }
    return -sg_ln_1p(f * sg_expm1(-2.0 * lambda)) / lambda;
}

fn sg_frame_dir(axis: vec3<f32>, tb: mat2x3<f32>, u: f32, phi: f32) -> vec3<f32> {
    let sin_theta = sqrt(max(u * (2.0 - u), 0.0));
    return axis * (1.0 - u) + (tb[0] * cos(phi) + tb[1] * sin(phi)) * sin_theta;
}

// SAT paper eq. 11 over M x N patches of the lobe's frame, each weighted by its visible energy
// (clipsat::shading::integrate_patches, which derives the per-patch closed form).
fn sg_integrate_patches(p: Sg, n: vec3<f32>, drop: f32) -> vec3<f32> {
    let bands = SG_BANDS;
    let sectors = 2u * SG_BANDS;
    let tb = sg_basis(p.axis);
    let dphi = SG_TAU / f32(sectors);
    // Flat (MAX_BANDS + 1) x MAX_SECTORS: GLSL ES 3.00 has no arrays of arrays.
    var edge_z: array<f32, 144>;
    var edge_u: array<f32, 9>;
    for (var i = 0u; i <= bands; i++) {
        edge_u[i] = sg_band_edge(p.lambda, f32(i) / f32(bands));
        for (var k = 0u; k < sectors; k++) {
            edge_z[i * SG_MAX_SECTORS + k] = sg_frame_dir(p.axis, tb, edge_u[i], f32(k) * dphi).z;
        }
    }
    var total = 0.0;
    for (var i = 0u; i < bands; i++) {
        let u1 = edge_u[i];
        let du = edge_u[i + 1u] - u1;
        let whole = sg_one_minus_exp_over(p.lambda * du);
        let band = exp(-p.lambda * u1) * du * whole;
        let u_mid = sg_band_edge(p.lambda, (f32(i) + 0.5) / f32(bands));
        for (var k = 0u; k < sectors; k++) {
            let centre = sg_frame_dir(p.axis, tb, u_mid, (f32(k) + 0.5) * dphi);
            let k2 = (k + 1u) % sectors;
            let z00 = edge_z[i * SG_MAX_SECTORS + k];
            let z01 = edge_z[i * SG_MAX_SECTORS + k2];
            let z10 = edge_z[(i + 1u) * SG_MAX_SECTORS + k];
            let z11 = edge_z[(i + 1u) * SG_MAX_SECTORS + k2];
            let inner = z00 + z01;
            let outer = z10 + z11;
            let lo = min(min(centre.z, min(z00, z01)), min(z10, z11));
            let hi = max(max(centre.z, max(z00, z01)), max(z10, z11));
            let cut = sin(max(sg_cut_elevation(n, drop, atan2(centre.y, centre.x)), -SG_HALF_PI));
            var s = 0.0;
            if (hi - lo > 1.0e-7) {
                s = clamp((hi - cut) / (hi - lo), 0.0, 1.0);
            } else if (centre.z > cut) {
                s = 1.0;
            }
            let part = s * sg_one_minus_exp_over(p.lambda * s * du) / whole;
            var visible = part;
            if (inner < outer) {
                visible = exp(-p.lambda * (1.0 - s) * du) * part;
            }
            total += band * visible;
        }
    }
    return p.mu * (total * dphi);
}

// Outgoing linear radiance toward `view` (unit, surface to eye) for mean normal r: the diffuse SG
// integration of every light, plus the variant's specular term (clipsat::shading::shade).
fn sg_shade(r: vec3<f32>, view: vec3<f32>, s: SgScene) -> vec3<f32> {
    let vmf = sg_vmf(r);
    let n = vmf.axis;
    let drop = sg_plane_drop(vmf.kappa);
    let cosine = sg_convolve_vmf(Sg(n, SG_COSINE_LAMBDA, vec3<f32>(SG_COSINE_MU)), vmf.kappa);
    var diffuse = vec3<f32>(0.0);
    let count = min(u32(s.kd_count.w), SG_MAX_LIGHTS);
    for (var i = 0u; i < count; i++) {
        let l = s.lights[i];
        let light = Sg(l.axis_lambda.xyz, l.axis_lambda.w, l.mu.xyz);
        diffuse += sg_integrate_patches(sg_product(light, cosine), n, drop);
    }
    return s.kd_count.rgb * diffuse / SG_PI + sg_specular(vmf, view, drop, s);
}
