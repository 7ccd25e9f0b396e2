// Stage 3, the GPU: the clipmap renderer's debug views (`render --debug`, `clipsat view`). Concatenated
// between basic_shading.wgsl and clipmap.wgsl; src/gpu/shaders.rs appends `const DEBUG_VIEW: u32 = K;`
// (0 normal, 1 levels, 2 wireframe), so each view is its own program and pipeline and the normal one
// returns the shaded colour untouched. Reads the draw's uniform (`draw`, clipmap.wgsl) in the fragment
// stage; the Globals layout is not touched.

// One colour per drawn level, like the SAT paper's figure 3; mirrors `clipsat::debug_view::LEVEL_COLOURS`.
// Hues 30 degrees apart (HSV s 0.8, v 0.95), ordered so that neighbouring levels contrast.
const DEBUG_LEVEL_COLOURS = array<vec3<f32>, 12>(
    vec3<f32>(0.95, 0.19, 0.19),
    vec3<f32>(0.19, 0.95, 0.19),
    vec3<f32>(0.19, 0.19, 0.95),
    vec3<f32>(0.95, 0.95, 0.19),
    vec3<f32>(0.19, 0.95, 0.95),
    vec3<f32>(0.95, 0.19, 0.95),
    vec3<f32>(0.95, 0.57, 0.19),
    vec3<f32>(0.19, 0.95, 0.57),
    vec3<f32>(0.57, 0.19, 0.95),
    vec3<f32>(0.57, 0.95, 0.19),
    vec3<f32>(0.19, 0.57, 0.95),
    vec3<f32>(0.95, 0.19, 0.57),
);

fn debug_level_colour(level: i32) -> vec3<f32> {
    return DEBUG_LEVEL_COLOURS[clamp(level, 0, 11)];
}

// The wireframe's lattice coordinates (level units, anchor-relative) of eye-relative position rel.
// A pool draw's slot is its first cell's: its cells share the level, and their anchors differ by whole
// lattice steps, so the fraction below is the same.
fn debug_lattice(rel: vec3<f32>) -> vec2<f32> {
    let g = draw.anchor_rel.w;
    return vec2<f32>(rel.x - draw.anchor_rel.x, draw.anchor_rel.y - rel.y) / g;
}

// The lattice's rate on screen (fwidth) for the wireframe, 1 in the other views. Every fragment entry
// point takes it first, before any discard: a derivative after a discard is undefined in GLSL ES 3.00,
// whose discard may end the invocation its quad's neighbours difference against (docs/real-drivers.md).
fn debug_rate(rel: vec3<f32>) -> vec2<f32> {
    if (DEBUG_VIEW != 2u) {
        return vec2<f32>(1.0);
    }
    return fwidth(debug_lattice(rel));
}

// The fragment's colour under DEBUG_VIEW: `shaded` is the normal colour, `rel` the position relative to the
// eye (m), `normal` the geometric normal, `rate` the fragment's `debug_rate`.
fn debug_view(shaded: vec3<f32>, rel: vec3<f32>, normal: vec3<f32>, rate: vec2<f32>) -> vec3<f32> {
    if (DEBUG_VIEW == 0u) {
        return shaded;
    }
    let level = draw.origin.z;
    // A plain Lambert factor keeps the relief readable and scales all channels alike, so the level stays
    // recognisable by its chromaticity.
    let sun = max(dot(normalize(normal), globals.shading.sun_dir.xyz), 0.0);
    let lit = debug_level_colour(level) * (0.4 + 0.6 * sun);
    if (DEBUG_VIEW == 1u) {
        return lit;
    }
    // Wireframe: GLES 3.0 has no line polygon mode, so draw the lattice lines here. A line is where the
    // lattice coordinate is within about one pixel (its rate) of an integer.
    let lattice = debug_lattice(rel);
    let dist = abs(fract(lattice - vec2<f32>(0.5)) - vec2<f32>(0.5)) / max(rate, vec2<f32>(1.0e-6));
    let line = 1.0 - clamp(min(dist.x, dist.y) - 0.5, 0.0, 1.0);
    return mix(0.3 * shaded, lit, line);
}
