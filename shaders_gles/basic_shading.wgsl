// Stage 3, the GPU: the project's "basic" shading, shared by the brute-force reference and the clipmap
// renderer. It has no entry points: Rust concatenates it ahead of a program (naga has no #include), see
// src/gpu/shaders.rs.
//
// Colour ramp over the terrain's own height range (not absolute metres, so that a 30 m hummocky LiDAR tile
// and a 3700 m alpine one both use the whole ramp), water at or below 0 m, Lambert from a fixed sun plus a
// hemispherical sky term, and exponential distance fog. Colours are authored display-encoded (gamma 2.2)
// and decoded before use; the ramp, lighting and fog are done in linear light.

// Mirrors `clipsat::gpu::shaders::BasicShading` (all vec4, so the uniform layout has no padding rules).
struct BasicShading {
    // x: height (m) where the land ramp starts, y: where it ends (snow), z: fog density (1/m),
    // w: the hill shading's z-factor (vertical exaggeration of the normals, >= 1)
    ramp_fog: vec4<f32>,
    // xyz: unit vector toward the sun (x east, y north, z up), w: unused
    sun_dir: vec4<f32>,
    // rgb: fog colour (linear light), a: unused
    fog_colour: vec4<f32>,
}

// The ramp's stops, authored display-encoded and decoded (^2.2) at compile time: the ramp and the water
// interpolate in linear light, so a pixel pays one pow (the final encoding) instead of three.
const LOWLAND: vec3<f32> = pow(vec3<f32>(0.30, 0.50, 0.22), vec3<f32>(2.2));
const MEADOW: vec3<f32> = pow(vec3<f32>(0.45, 0.56, 0.28), vec3<f32>(2.2));
const SCRUB: vec3<f32> = pow(vec3<f32>(0.56, 0.49, 0.31), vec3<f32>(2.2));
const BROWN: vec3<f32> = pow(vec3<f32>(0.46, 0.37, 0.27), vec3<f32>(2.2));
const ROCK: vec3<f32> = pow(vec3<f32>(0.55, 0.54, 0.52), vec3<f32>(2.2));
const SNOW: vec3<f32> = pow(vec3<f32>(0.95, 0.96, 0.98), vec3<f32>(2.2));
const SHALLOW: vec3<f32> = pow(vec3<f32>(0.18, 0.40, 0.64), vec3<f32>(2.2));
const DEEP: vec3<f32> = pow(vec3<f32>(0.05, 0.16, 0.36), vec3<f32>(2.2));

// Linear-light albedo at height h (m). Branch-free: each stop is mixed in by its segment's clamped
// parameter (0 before the segment, 1 after), which is the piecewise-linear ramp; a software rasteriser
// runs every side of a branch anyway.
fn basic_albedo(h: f32, s: BasicShading) -> vec3<f32> {
    let lo = s.ramp_fog.x;
    let span = max(s.ramp_fog.y - lo, 1.0e-3);
    let t = clamp((h - lo) / span, 0.0, 1.0);
    var land = mix(LOWLAND, MEADOW, clamp(t / 0.25, 0.0, 1.0));
    land = mix(land, SCRUB, clamp((t - 0.25) / 0.20, 0.0, 1.0));
    land = mix(land, BROWN, clamp((t - 0.45) / 0.20, 0.0, 1.0));
    land = mix(land, ROCK, clamp((t - 0.65) / 0.15, 0.0, 1.0));
    land = mix(land, SNOW, clamp((t - 0.80) / 0.08, 0.0, 1.0));
    // Water at or below 0 m: deeper is darker, reaching the darkest blue a quarter of the land span below.
    let depth = clamp(-h / max(0.25 * span, 1.0), 0.0, 1.0);
    return select(land, mix(SHALLOW, DEEP, depth), h <= 0.0);
}

// Final display-encoded colour of a terrain point: height h (m), geometric normal n (need not be unit),
// distance to the eye dist (m).
fn basic_shade(h: f32, n: vec3<f32>, dist: f32, s: BasicShading) -> vec3<f32> {
    let albedo = basic_albedo(h, s);
    // The z-factor steepens a gentle terrain's normals (hill shading's vertical exaggeration).
    let nn = normalize(vec3<f32>(n.xy * (s.ramp_fog.w / max(n.z, 1.0e-6)), 1.0));
    // Hill shading: a strong Lambert sun over a weak sky whose light falls off on steep faces (a
    // hemisphere's share of the sky seen by a tilted plane, (1 + n.z) / 2), so slopes away from the sun
    // read dark and relief shows even where the height ramp is flat.
    let sun = max(dot(nn, s.sun_dir.xyz), 0.0);
    let sky = 0.5 + 0.5 * nn.z;
    let light = vec3<f32>(1.00, 0.95, 0.86) * (1.45 * sun) + vec3<f32>(0.50, 0.62, 0.80) * (0.30 * sky);
    let fog = 1.0 - exp(-dist * s.ramp_fog.z);
    let lit = mix(albedo * light, s.fog_colour.rgb, fog);
    return pow(clamp(lit, vec3<f32>(0.0), vec3<f32>(1.0)), vec3<f32>(1.0 / 2.2));
}
