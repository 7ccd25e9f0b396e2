// Stage 3, the GPU: the geometry clipmap renderer (Losasso & Hoppe 2004, "GC"). Concatenated after
// basic_shading.wgsl and debug_view.wgsl (src/gpu/shaders.rs).
//
// Every draw places one static mesh (a block or the ring skirt, src/mesh.rs) on a level's lattice: vertex
// (x, y) goes to lattice point origin + (x, y), clamped into the draw's rectangle. Heights come from one
// RG32F 2D array texture (layer = level, texel = lattice point mod S, toroidal), read with textureLoad
// because float textures are not filterable on GLES 3.0. Lattice coordinates are relative to the level's
// anchor (its active region's first vertex) and positions relative to the eye, both prepared in f64 on the
// CPU, so a terrain far from the origin loses no f32 precision.

// Mirrors `clipsat::renderer::Globals`.
struct Globals {
    // Camera-relative view-projection (Camera::view_proj_relative).
    view_proj: mat4x4<f32>,
    shading: BasicShading,
    // x: morph factor (1: GC 6.2 morphing, 0: off); y: skirt floor height (m); z, w: capture target size.
    params: vec4<f32>,
    // The data's horizontal extent relative to the eye (m): x min, y min, x max, y max.
    extent: vec4<f32>,
    // Where each ring holds data (its clip region), finest first; see `data_surface`.
    levels: array<ShadeLevel, 16>,
    // x: levels in use; y: ring size S; z: n; w: unused.
    level_info: vec4<i32>,
}

// Mirrors `clipsat::uniforms::ShadeLevel`.
struct ShadeLevel {
    // xy: world position of the clip region's first sample minus the eye (m); z: minus the eye's height;
    // w: the level's spacing (m).
    rel: vec4<f32>,
    // xy: texel of the clip region's first sample; zw: the clip region's width and height (0: empty).
    tex: vec4<i32>,
    // GC 6.2's transition in this level's lattice units: xy the viewer relative to the clip region's
    // first sample; zw (active width - 1) / 2, (active height - 1) / 2 (-1e9: the level draws nothing).
    morph: vec4<f32>,
}

// Mirrors `clipsat::renderer::DrawUniform`; one 256-byte slot per draw, bound with a dynamic offset.
struct DrawUniform {
    // xy: mesh origin (anchor-relative lattice units); z: array layer (level); w: ring size S.
    origin: vec4<i32>,
    // The clamp rectangle, inclusive, anchor-relative: x0, y0, x1, y1.
    bounds: vec4<i32>,
    // The level's active region, inclusive, anchor-relative: x0, y0, x1, y1.
    region: vec4<i32>,
    // xy: texel of the anchor (anchor mod S); zw: unused.
    tex: vec4<i32>,
    // xyz: world position of the anchor at height 0 minus the eye (m); w: level spacing g_l (m).
    anchor_rel: vec4<f32>,
    // xy: the viewer in the level's lattice units, anchor-relative; z, w: (active w - 1) / 2, (active h - 1) / 2.
    morph: vec4<f32>,
    // x: the transition width w = n / 10 (GC 6.2); yzw: unused.
    morph_w: vec4<f32>,
    // SAT LOD snapped tiles (`clipsat::cull::Draw::fine`): x: the fine level; y: s, this level's spacing in
    // fine lattice units (1: not snapped, and the fields below repeat the ones above); z: a stitched pool
    // unit's vertex flags (`clipsat::detail::stitch`, 0 otherwise); w: unused.
    fine: vec4<i32>,
    // The clamp rectangle in fine units, inclusive, fine-anchor-relative.
    fine_bounds: vec4<i32>,
    // xy: this level's anchor in fine units, fine-anchor-relative; zw: unused.
    fine_origin: vec4<i32>,
    // xyz: world position of the fine anchor at height 0 minus the eye (m); w: the fine spacing (m).
    fine_rel: vec4<f32>,
    // Detail pool draws (`clipsat::detail`): x: layer + 1 (0: the ring); y: samples per tile side; zw: the
    // tile's first texel in its layer (an atlas, `DetailAtlas`). A pool draw is anchored at its tile's
    // first sample, so lattice points are the tile's texels from there.
    pool: vec4<i32>,
}

@group(0) @binding(0) var<uniform> globals: Globals;
@group(0) @binding(1) var heights: texture_2d_array<f32>;
@group(0) @binding(2) var detail: texture_2d_array<f32>;
@group(1) @binding(0) var<uniform> draw: DrawUniform;

// Mirrors `clipsat::uniforms::PoolCell`: a detail pool cell of an instanced pool draw, one per instance
// (vertex buffer 1, instance step). The draw's slot holds its first cell's whole DrawUniform; the cells of
// one draw share level, mesh range and program, and differ in these fields. Draws that are not the pool's
// read instance 0 and ignore it.
struct PoolCellIn {
    // xy: mesh origin (tile-relative); z: pool layer + 1; w: a stitched unit's vertex flags.
    @location(1) origin: vec4<i32>,
    // The clamp rectangle, inclusive, tile-relative.
    @location(2) bounds: vec4<i32>,
    // xy: world position of the tile's first sample at height 0 minus the eye (m).
    @location(3) anchor: vec4<f32>,
    // xy: the tile's first texel in its layer.
    @location(4) texel: vec4<i32>,
}

// The uniforms the vertex stage reads: the draw's, with a pool cell's own fields put over them (`draw_of`).
var<private> dr: DrawUniform;

// Operation for operation as `clipsat::uniforms::PoolCell::over` (its CPU twin).
fn draw_of(c: PoolCellIn) -> DrawUniform {
    var d = draw;
    if (draw.pool.x > 0) {
        d.origin = vec4<i32>(c.origin.xy, draw.origin.zw);
        d.pool = vec4<i32>(c.origin.z, draw.pool.y, c.texel.xy);
        d.bounds = c.bounds;
        d.fine_bounds = c.bounds;
        d.anchor_rel = vec4<f32>(c.anchor.xy, draw.anchor_rel.zw);
        d.fine_rel = vec4<f32>(c.anchor.xy, draw.fine_rel.zw);
        d.fine = vec4<i32>(draw.fine.xy, c.origin.w, draw.fine.w);
    }
    return d;
}

// A stitched pool unit's vertex rule, operation for operation as `clipsat::detail::stitch::local`: mesh
// vertex v (0..=2 each) of a unit with flags f goes to xy; z is 1 where the vertex reads z_c. A fine
// unit's edge midpoint facing a coarse unit collapses onto the edge's end toward -x or -y (flag bits
// 0..4, sides -y, +x, +y, -x), and a corner a coarse unit touches reads z_c (bits 4..8, corners (0, 0),
// (2, 0), (2, 2), (0, 2)).
fn stitch_local(v: vec2<i32>, f: i32) -> vec3<i32> {
    var x = v.x;
    var y = v.y;
    if (y == 0 && x == 1 && (f & 1) != 0) {
        x = 0;
    } else if (x == 2 && y == 1 && (f & 2) != 0) {
        y = 0;
    } else if (y == 2 && x == 1 && (f & 4) != 0) {
        x = 0;
    } else if (x == 0 && y == 1 && (f & 8) != 0) {
        y = 0;
    }
    var corner = -1;
    if (x == 0 && y == 0) {
        corner = 0;
    } else if (x == 2 && y == 0) {
        corner = 1;
    } else if (x == 2 && y == 2) {
        corner = 2;
    } else if (x == 0 && y == 2) {
        corner = 3;
    }
    var zc = 0;
    if (corner >= 0 && (f & (16 << u32(corner))) != 0) {
        zc = 1;
    }
    return vec3<i32>(x, y, zc);
}

// (z, z_c) at anchor-relative lattice point p (p >= 0 inside the active region); a pool draw's from its
// tile (pool draws never morph, alpha 0, so z_c counts only at a stitched unit's corners, `clip_vertex`).
fn clip_fetch(p: vec2<i32>) -> vec2<f32> {
    if (dr.pool.x > 0) {
        return textureLoad(detail, dr.pool.zw + p, dr.pool.x - 1, 0).xy;
    }
    let t = (dr.tex.xy + p) % vec2<i32>(dr.origin.w);
    return textureLoad(heights, t, dr.origin.z, 0).xy;
}

// GC section 6.2's alpha, operation for operation as `clipsat::clipmap::morph_alpha`.
fn clip_morph_alpha(x: f32, y: f32) -> f32 {
    let w = dr.morph_w.x;
    let ax = clamp((abs(x - dr.morph.x) - (dr.morph.z - w - 1.0)) / w, 0.0, 1.0);
    let ay = clamp((abs(y - dr.morph.y) - (dr.morph.w - w - 1.0)) / w, 0.0, 1.0);
    return max(ax, ay);
}

struct TerrainVertex {
    // Position relative to the eye (m).
    rel: vec3<f32>,
    // Geometric normal (not unit).
    normal: vec3<f32>,
    // Height (m).
    height: f32,
}

// v: mesh vertex (x, y, skirt flag, unused). The vertex is placed on the fine lattice and clamped into the
// fine bounds; where that lands on this level's lattice it is this level's vertex, else (the edge of a
// snapped SAT LOD tile) a point of this level's surface between its vertices.
fn clip_vertex(v: vec4<u32>) -> TerrainVertex {
    let s = dr.fine.y;
    let st = stitch_local(vec2<i32>(v.xy), dr.fine.z);
    let pf = clamp(
        dr.fine_origin.xy + (dr.origin.xy + st.xy) * s,
        dr.fine_bounds.xy,
        dr.fine_bounds.zw,
    );
    let q = pf - dr.fine_origin.xy;
    if (any(q % vec2<i32>(s) != vec2<i32>(0))) {
        return snapped_vertex(v, q, pf);
    }
    let p = q / s;
    var zz = clip_fetch(p);
    if (st.z != 0) {
        // A stitched unit's corner that a coarse unit touches: the coarser level's height there.
        zz = vec2<f32>(zz.y, zz.y);
    }
    let alpha = clip_morph_alpha(f32(p.x), f32(p.y)) * globals.params.x;
    // GC 6.2: z' = (1 - alpha) z + alpha z_c.
    let z = (1.0 - alpha) * zz.x + alpha * zz.y;
    // GC 6.3: normals from the geometry, central differences of z and z_c blended with the same alpha;
    // one-sided at the active region's edge.
    let xm = max(p.x - 1, dr.region.x);
    let xp = min(p.x + 1, dr.region.z);
    let yn = max(p.y - 1, dr.region.y);
    let ys = min(p.y + 1, dr.region.w);
    let g = dr.anchor_rel.w;
    let dx = (clip_fetch(vec2<i32>(xp, p.y)) - clip_fetch(vec2<i32>(xm, p.y))) / (f32(xp - xm) * g);
    // Rows run south, so north minus south is the gradient along +y (north).
    let dy = (clip_fetch(vec2<i32>(p.x, yn)) - clip_fetch(vec2<i32>(p.x, ys))) / (f32(ys - yn) * g);
    let gx = (1.0 - alpha) * dx.x + alpha * dx.y;
    let gy = (1.0 - alpha) * dy.x + alpha * dy.y;
    var h = z;
    if (v.z != 0u) {
        // The skirt's lower edge hangs to the floor below every height.
        h = min(z, globals.params.y);
    }
    var out: TerrainVertex;
    out.rel = dr.anchor_rel.xyz + vec3<f32>(f32(p.x) * g, -f32(p.y) * g, h);
    out.normal = vec3<f32>(-gx, -gy, 1.0);
    out.height = z;
    return out;
}

// The rings reach far past a small terrain, where the edge-clamped heights would draw as streaks: every
// level is cut at the same vertical planes, the data's border, as the brute-force reference ends there.
// The cut is inset by a few f32 ulps of the extent, so a skirt hanging exactly on the border (a SAT LOD
// tile edge on lattice line 0) is cut away whole rather than speckled by rounding, plus 2 cm, or a
// ten-thousandth of the data's narrower side on a terrain under 200 m across (`border_inset_m`).
fn outside_data(rel: vec2<f32>) -> bool {
    let e = globals.extent;
    let inset = clamp(1.0e-4 * min(e.z - e.x, e.w - e.y), 0.0, 0.02);
    let tol = inset + 4.0e-6 * max(max(abs(e.x), abs(e.y)), max(abs(e.z), abs(e.w)));
    return any(rel < e.xy + vec2<f32>(tol)) || any(rel > e.zw - vec2<f32>(tol));
}

// A snapped tile's edge vertex, at q in this level's units times s (anchor-relative): the point of this
// level's piecewise-linear surface there, split along the (i, j)-(i+1, j+1) diagonal as everywhere, so the
// tile is exactly this level's surface cut at the piece's edge (SAT LOD draws do not morph). The normal is
// the triangle's. Positions use the fine lattice (`fine_rel`), where the neighbouring pieces' vertices lie.
fn snapped_vertex(v: vec4<u32>, q: vec2<i32>, pf: vec2<i32>) -> TerrainVertex {
    let s = dr.fine.y;
    let c = q / s;
    let f = vec2<f32>(q - c * s) / f32(s);
    // The cell's far corner, kept on the tile (a point on its last lattice line has weight 0 there).
    let cmax = (dr.fine_bounds.zw - dr.fine_origin.xy + vec2<i32>(s - 1)) / s;
    let c1 = min(c + vec2<i32>(1), cmax);
    let z00 = clip_fetch(c).x;
    let z11 = clip_fetch(c1).x;
    var dzx: f32;
    var dzy: f32;
    if (f.x >= f.y) {
        let z10 = clip_fetch(vec2<i32>(c1.x, c.y)).x;
        dzx = z10 - z00;
        dzy = z11 - z10;
    } else {
        let z01 = clip_fetch(vec2<i32>(c.x, c1.y)).x;
        dzx = z11 - z01;
        dzy = z01 - z00;
    }
    let z = z00 + f.x * dzx + f.y * dzy;
    var h = z;
    if (v.z != 0u) {
        h = min(z, globals.params.y);
    }
    let g = dr.anchor_rel.w;
    let gf = dr.fine_rel.w;
    var out: TerrainVertex;
    out.rel = dr.fine_rel.xyz + vec3<f32>(f32(pf.x) * gf, -f32(pf.y) * gf, h);
    // Rows run south: the gradient along +y (north) is minus the one along the rows.
    out.normal = vec3<f32>(-dzx / g, dzy / g, 1.0);
    out.height = z;
    return out;
}

// The data under a pixel: height and geometric normal (not unit) from the finest ring holding it.
struct DataSurface {
    found: bool,
    height: f32,
    normal: vec3<f32>,
    weight: f32,
}

// Height z of level l at clip-relative lattice point p (p >= 0 inside the clip region).
fn level_fetch(l: i32, p: vec2<i32>) -> f32 {
    let t = (globals.levels[l].tex.xy + p) % vec2<i32>(globals.level_info.y);
    return textureLoad(heights, t, l, 0).x;
}

// Level lv's lattice coordinates of eye-relative rel (lattice x grows east, y south).
fn level_uv(lv: ShadeLevel, rel: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(rel.x - lv.rel.x, lv.rel.y - rel.y) / lv.rel.w;
}

// Whether cell i lies in the level's clip region with a one-sample margin (the central differences).
fn level_holds(lv: ShadeLevel, i: vec2<i32>) -> bool {
    return all(i >= vec2<i32>(1)) && all(i <= lv.tex.zw - vec2<i32>(3));
}

// Lattice cells past this are outside every ring (S <= 2048); clamping to it keeps the float-to-int
// conversion in range (a float outside the int range converts to an undefined value in GLSL ES 3.00).
const CELL_LIMIT: f32 = 65536.0;

// The cell of level lv's lattice under eye-relative rel, for level_holds. A level without data (tex.zw 0,
// spacing 0: a ring not yet filled, or disabled) is not divided by its zero spacing: (-1, -1), held by
// nothing (docs/real-drivers.md).
fn level_cell(lv: ShadeLevel, rel: vec2<f32>) -> vec2<i32> {
    if (lv.tex.z <= 0 || lv.tex.w <= 0) {
        return vec2<i32>(-1);
    }
    return vec2<i32>(clamp(floor(level_uv(lv, rel)), vec2<f32>(-CELL_LIMIT), vec2<f32>(CELL_LIMIT)));
}

// GC 6.2's alpha of level l at eye-relative rel, as clip_morph_alpha for that level's active region:
// 0 inside, 1 from its outer edge on (and everywhere for a level that draws nothing).
fn shade_morph_alpha(l: i32, rel: vec2<f32>) -> f32 {
    let lv = globals.levels[l];
    let u = level_uv(lv, rel);
    let w = f32(globals.level_info.z) / 10.0;
    let ax = clamp((abs(u.x - lv.morph.x) - (lv.morph.z - w - 1.0)) / w, 0.0, 1.0);
    let ay = clamp((abs(u.y - lv.morph.y) - (lv.morph.w - w - 1.0)) / w, 0.0, 1.0);
    return max(ax, ay);
}

// The finest ring whose clip region holds rel (level_holds), or -1: no texture fetch, a few ALU
// operations per level. `clipsat::twin::shading::finest_level` is the CPU twin.
fn finest_level(rel: vec2<f32>) -> i32 {
    for (var l = 0; l < globals.level_info.x; l = l + 1) {
        let lv = globals.levels[l];
        if (level_holds(lv, level_cell(lv, rel))) {
            return l;
        }
    }
    return -1;
}

// The data of level l at eye-relative rel: bilinear height and the central-difference gradient at the
// cell's 4 corners (12 fetches), bilinearly blended; `found` is false unless the level's clip region holds
// rel with a one-sample margin. `weight` is 1 inside and falls to 0 over the last DATA_BLEND cells before
// the margin, where the caller blends in the next coarser level (GC 6.2's transition, for the shading).
fn level_surface(l: i32, rel: vec2<f32>) -> DataSurface {
    var out: DataSurface;
    out.found = false;
    let lv = globals.levels[l];
    let g = lv.rel.w;
    let i = level_cell(lv, rel);
    if (!level_holds(lv, i)) {
        return out;
    }
    let u = level_uv(lv, rel);
    let f = u - vec2<f32>(i);
    let z00 = level_fetch(l, i);
    let z10 = level_fetch(l, i + vec2<i32>(1, 0));
    let z01 = level_fetch(l, i + vec2<i32>(0, 1));
    let z11 = level_fetch(l, i + vec2<i32>(1, 1));
    let zw0 = level_fetch(l, i + vec2<i32>(-1, 0));
    let zw1 = level_fetch(l, i + vec2<i32>(-1, 1));
    let ze0 = level_fetch(l, i + vec2<i32>(2, 0));
    let ze1 = level_fetch(l, i + vec2<i32>(2, 1));
    let zn0 = level_fetch(l, i + vec2<i32>(0, -1));
    let zn1 = level_fetch(l, i + vec2<i32>(1, -1));
    let zs0 = level_fetch(l, i + vec2<i32>(0, 2));
    let zs1 = level_fetch(l, i + vec2<i32>(1, 2));
    // East gradient at the 4 corners (x2 g), then north (rows run south: north minus south).
    let gx = mix(mix(z10 - zw0, ze0 - z00, f.x), mix(z11 - zw1, ze1 - z01, f.x), f.y);
    let gy = mix(mix(zn0 - z01, zn1 - z11, f.x), mix(z00 - zs0, z10 - zs1, f.x), f.y);
    out.found = true;
    // The height on the drawn triangles (split along the (i, j)-(i+1, j+1) diagonal, as the mesh and the
    // SAT LOD error tables): a bilinear height differs from the drawn surface by up to a quarter of the
    // cell's twist, so a block shaded from the vertices beside one shaded from here showed a step, and
    // the ramp's water line (0 m beside 1 m, as SRTM coasts) filled whole cells: a staircase coast.
    var dz = vec2<f32>(z11 - z01, z01 - z00);
    if (f.x >= f.y) {
        dz = vec2<f32>(z10 - z00, z11 - z10);
    }
    out.height = z00 + f.x * dz.x + f.y * dz.y;
    out.normal = vec3<f32>(-gx / (2.0 * g), -gy / (2.0 * g), 1.0);
    // Cells to the margin, on the nearer side of either axis.
    let room = min(u - vec2<f32>(1.0), vec2<f32>(lv.tex.zw) - vec2<f32>(2.0) - u);
    out.weight = clamp(min(room.x, room.y) / DATA_BLEND, 0.0, 1.0);
    return out;
}

// Cells over which the shading blends from a level to the next coarser one at its clip region's edge.
const DATA_BLEND: f32 = 8.0;

// GC section 6's normal maps, computed on the fly: the surface under eye-relative point rel from the finest
// ring whose clip region holds it, whatever level the mesh there was drawn at, so a block drawn coarse keeps
// the data's relief shading; near that ring's edge it blends into the next coarser ring, so level changes
// leave no seam. `clipsat::twin::shading::data_surface` is the CPU twin.
fn data_surface(rel: vec2<f32>) -> DataSurface {
    var out: DataSurface;
    out.found = false;
    for (var l = finest_level(rel); l >= 0 && l < globals.level_info.x; l = l + 1) {
        let fine = level_surface(l, rel);
        if (!fine.found) {
            continue;
        }
        out = fine;
        if (fine.weight < 1.0) {
            for (var c = l + 1; c < globals.level_info.x; c = c + 1) {
                let coarse = level_surface(c, rel);
                if (coarse.found) {
                    out.height = mix(coarse.height, fine.height, fine.weight);
                    out.normal = mix(coarse.normal, fine.normal, fine.weight);
                    break;
                }
            }
        }
        out.weight = 1.0;
        return out;
    }
    return out;
}

// A skirt fragment seen through the data's side: the ray from the eye enters the data's vertical prism
// below the data there, where a solid terrain would hide it. Such fragments are discarded, so no curtain
// shows from outside the terrain; skirts that close cracks are seen from above and stay.
fn through_side(rel: vec3<f32>) -> bool {
    let e = globals.extent;
    // Slab entry of the segment eye -> rel into the extent rectangle (eye at the origin).
    var t0 = 0.0;
    for (var a = 0; a < 2; a = a + 1) {
        let d = rel[a];
        let lo = e[a];
        let hi = e[a + 2];
        if (abs(d) > 1.0e-9) {
            t0 = max(t0, min(lo / d, hi / d));
        }
    }
    if (t0 <= 0.0 || t0 >= 1.0) {
        return false;
    }
    // Just inside the border, where the rings hold data.
    let p = rel * min(t0 + 1.0e-4, 1.0);
    let s = data_surface(p.xy);
    // Ring heights are absolute: the eye is at -levels[0].rel.z.
    return s.found && p.z < s.height + globals.levels[0].rel.z;
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) rel: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) height: f32,
    // 1 at a skirt's lower edge, 0 on the surface.
    @location(3) skirt: f32,
    // The level the block is drawn at.
    @location(4) @interpolate(flat) level: i32,
}

@vertex
fn vs_main(@location(0) v: vec4<u32>, cell: PoolCellIn) -> VsOut {
    dr = draw_of(cell);
    let t = clip_vertex(v);
    var out: VsOut;
    out.clip = globals.view_proj * vec4<f32>(t.rel, 1.0);
    out.rel = t.rel;
    out.normal = t.normal;
    out.height = t.height;
    out.skirt = f32(v.z);
    out.level = dr.origin.z;
    return out;
}

// Four fragment programs; the plan picks one per draw (`clipsat::plan::fragment`), the cheapest that
// gives the same pixels, because llvmpipe runs both sides of a branch under an execution mask: the ring
// reads and the skirt test below cost every pixel as much as a pixel that uses them.

// Blocks that no finer ring's data reaches: the drawn vertices' values, which under distance LOD with every
// level active are the finest data (central differences of the same ring, interpolated across the cell as
// level_surface blends them).
fn plain_colour(v: VsOut, rate: vec2<f32>) -> vec4<f32> {
    let shaded = basic_shade(v.height, v.normal, length(v.rel), globals.shading);
    // debug_view.wgsl: the level-colour and wireframe views (the normal view returns `shaded`).
    return target_colour(vec4<f32>(debug_view(shaded, v.rel, v.normal, rate), 1.0));
}

// What a fragment writes for the colour target. The shading computes display-encoded colour (gamma 2.2,
// what a linear-format target stores as it is). An sRGB target encodes what it is given with sRGB's curve
// (globals.shading.sun_dir.w = 1): write the linear value whose encoding is that colour, so that both
// targets store the same bytes and blending in an sRGB target works in linear light.
fn target_colour(c: vec4<f32>) -> vec4<f32> {
    if (globals.shading.sun_dir.w == 0.0) {
        return c;
    }
    let lo = c.rgb / 12.92;
    let hi = pow((c.rgb + vec3<f32>(0.055)) / 1.055, vec3<f32>(2.4));
    return vec4<f32>(select(hi, lo, c.rgb <= vec3<f32>(0.04045)), c.a);
}

// Such blocks inside the data's border: no discard, so hidden fragments can be rejected before shading.
@fragment
fn fs_interior(v: VsOut) -> @location(0) vec4<f32> {
    return plain_colour(v, debug_rate(v.rel));
}

// Such blocks crossing the data's border.
@fragment
fn fs_plain(v: VsOut) -> @location(0) vec4<f32> {
    let rate = debug_rate(v.rel);
    if (outside_data(v.rel.xy)) {
        discard;
    }
    return plain_colour(v, rate);
}

// Shade from the finest data under the pixel. Only a block drawn coarser than the finest ring holding the
// pixel (SAT LOD, or finer rings not drawn) reads that ring here, 12 fetches a pixel, blended over its last
// DATA_BLEND cells into the next coarser ring's data (or the vertex values where that ring is the block's
// own) so nothing jumps where it ends. With morphing (distance LOD) it also fades out over GC 6.2's
// transition band of that ring's active region, as its geometry does, so the finer detail never shows past
// the ring's drawn edge, where it would pop as the ring moves; SAT LOD does not morph and keeps it.
fn ring_data_colour(v: VsOut, rate: vec2<f32>) -> vec4<f32> {
    let d = ring_data_inputs(v);
    let shaded = basic_shade(d.x, d.yzw, length(v.rel), globals.shading);
    return target_colour(vec4<f32>(debug_view(shaded, v.rel, v.normal, rate), 1.0));
}

// What ring_data_colour shades with: x the height, yzw the normal.
fn ring_data_inputs(v: VsOut) -> vec4<f32> {
    var h = v.height;
    var n = v.normal;
    let fine = finest_level(v.rel.xy);
    if (fine >= 0 && fine < v.level) {
        let d = level_surface(fine, v.rel.xy);
        let w = d.weight * (1.0 - globals.params.x * shade_morph_alpha(fine, v.rel.xy));
        if (w < 1.0) {
            // The band blends into the next coarser ring's data while that is still finer than the block.
            for (var c = fine + 1; c < v.level; c = c + 1) {
                let coarse = level_surface(c, v.rel.xy);
                if (coarse.found) {
                    h = coarse.height;
                    n = coarse.normal;
                    break;
                }
            }
        }
        h = mix(h, d.height, w);
        n = mix(n, d.normal, w);
    }
    return vec4<f32>(h, n);
}

// Blocks some finer ring's data reaches.
@fragment
fn fs_ring_data(v: VsOut) -> @location(0) vec4<f32> {
    let rate = debug_rate(v.rel);
    if (outside_data(v.rel.xy)) {
        discard;
    }
    return ring_data_colour(v, rate);
}

// Skirts: also hidden where seen through the data's side.
@fragment
fn fs_skirt(v: VsOut) -> @location(0) vec4<f32> {
    let rate = debug_rate(v.rel);
    if (outside_data(v.rel.xy) || (v.skirt > 0.0 && through_side(v.rel))) {
        discard;
    }
    return ring_data_colour(v, rate);
}

// The shading probe (test and self-test instrument, `clipsat::gpu::renderer::ShadingProbe`): the same
// draws and discards as the four programs above, writing per pixel the exact bits of what the program
// shaded the fragment with, for the CPU twins to recompute its colour from.
struct ProbeOut {
    // xyz: the eye-relative position; w: the footprint's side (m for basic shading, data samples for SG).
    @location(0) position: vec4<u32>,
    // Basic shading: the height and the normal; SG: the normal table's blend r (w: the sun's horizon).
    @location(1) inputs: vec4<u32>,
}

fn probe_out(v: VsOut, side: f32, inputs: vec4<f32>) -> ProbeOut {
    return ProbeOut(bitcast<vec4<u32>>(vec4<f32>(v.rel, side)), bitcast<vec4<u32>>(inputs));
}

// The pixel's footprint in metres, before any discard.
fn probe_side(v: VsOut) -> f32 {
    let d = max(abs(dpdx(v.rel.xy)), abs(dpdy(v.rel.xy)));
    return max(d.x, d.y);
}

@fragment
fn fs_probe_interior(v: VsOut) -> ProbeOut {
    return probe_out(v, probe_side(v), vec4<f32>(v.height, v.normal));
}

@fragment
fn fs_probe_plain(v: VsOut) -> ProbeOut {
    let side = probe_side(v);
    if (outside_data(v.rel.xy)) {
        discard;
    }
    return probe_out(v, side, vec4<f32>(v.height, v.normal));
}

@fragment
fn fs_probe_ring_data(v: VsOut) -> ProbeOut {
    let side = probe_side(v);
    if (outside_data(v.rel.xy)) {
        discard;
    }
    return probe_out(v, side, ring_data_inputs(v));
}

@fragment
fn fs_probe_skirt(v: VsOut) -> ProbeOut {
    let side = probe_side(v);
    if (outside_data(v.rel.xy) || (v.skirt > 0.0 && through_side(v.rel))) {
        discard;
    }
    return probe_out(v, side, ring_data_inputs(v));
}

// The vertex probe: draws the mesh as points, vertex k on pixel (k mod W, k / W) of a W x H Rgba32Uint
// target, carrying the exact bits of its clip-space position (tests compare them with the CPU twin).
struct CaptureOut {
    @builtin(position) pixel: vec4<f32>,
    @location(0) @interpolate(flat) clip: vec4<f32>,
}

@vertex
fn vs_capture(@builtin(vertex_index) k: u32, @location(0) v: vec4<u32>, cell: PoolCellIn) -> CaptureOut {
    dr = draw_of(cell);
    let t = clip_vertex(v);
    let size = globals.params.zw;
    let width = u32(clamp(size.x, 1.0, 16384.0));
    let px = vec2<f32>(f32(k % width), f32(k / width)) + vec2<f32>(0.5);
    var out: CaptureOut;
    out.pixel = vec4<f32>(px.x / size.x * 2.0 - 1.0, 1.0 - px.y / size.y * 2.0, 0.5, 1.0);
    out.clip = globals.view_proj * vec4<f32>(t.rel, 1.0);
    return out;
}

@fragment
fn fs_capture(v: CaptureOut) -> @location(0) vec4<u32> {
    return bitcast<vec4<u32>>(v.clip);
}
