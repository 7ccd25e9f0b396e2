// Stage 3, the GPU: the brute-force reference. Every heightmap sample is a vertex; its x and y come from
// the vertex index, its height and normal from the vertex buffer. Positions are built relative to the eye
// from an integer anchor sample near it, so a large terrain keeps f32 precision where the viewer looks.
// Concatenated after basic_shading.wgsl (src/gpu/shaders.rs).

// Mirrors `clipsat::gpu::brute::Globals`.
struct Globals {
    // Camera-relative view-projection (Camera::view_proj_relative).
    view_proj: mat4x4<f32>,
    // x, y: grid column and row of the anchor sample; z: samples per row; w: unused.
    grid: vec4<i32>,
    // xyz: world position of the anchor sample at height 0, minus the eye (m); w: sample spacing (m).
    anchor_rel: vec4<f32>,
    shading: BasicShading,
}

@group(0) @binding(0) var<uniform> globals: Globals;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) rel: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) height: f32,
}

// height_normal: x = height (m), y, z = east and north components of the unit normal (up is positive).
@vertex
fn vs_main(@builtin(vertex_index) index: u32, @location(0) height_normal: vec3<f32>) -> VsOut {
    let w = u32(globals.grid.z);
    let col = i32(index % w) - globals.grid.x;
    let row = i32(index / w) - globals.grid.y;
    let s = globals.anchor_rel.w;
    // Row 0 is the north edge: going down a row goes south (Heightmap::grid_to_world).
    let rel = vec3<f32>(f32(col) * s, -f32(row) * s, height_normal.x) + globals.anchor_rel.xyz;
    let nxy = height_normal.yz;
    let nz = sqrt(max(1.0 - dot(nxy, nxy), 0.0));
    var out: VsOut;
    out.clip = globals.view_proj * vec4<f32>(rel, 1.0);
    out.rel = rel;
    out.normal = vec3<f32>(nxy, nz);
    out.height = height_normal.x;
    return out;
}

@fragment
fn fs_main(v: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(basic_shade(v.height, v.normal, length(v.rel), globals.shading), 1.0);
}
