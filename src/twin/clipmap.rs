//! CPU twin of `shaders_gles/clipmap.wgsl` (stage 3's vertex shader, on the CPU): `clip_vertex` +
//! `vs_main` and `snapped_vertex`, in f32, so tests compare the GPU's clip-space positions
//! ([`crate::gpu::renderer::VertexProbe`]) with these bit for bit or within a stated tolerance.

use glam::{Mat4, Vec4};

use crate::plan::clipmap::{morph_alpha, Ring};
use crate::plan::detail::stitch;
use crate::plan::frame::Rect;
use crate::plan::mesh::MeshVertex;
use crate::plan::uniforms::{DrawUniform, Globals};

/// One vertex as the vertex shader computes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CpuVertex {
    /// Clip-space position.
    pub clip: [f32; 4],
    /// Position relative to the eye (m).
    pub rel: [f32; 3],
    /// Morphed height z' (m).
    pub height: f32,
    /// Morph weight alpha.
    pub alpha: f32,
}

/// The CPU twin of `clip_vertex` + `vs_main` in `shaders_gles/clipmap.wgsl`, in f32, with the CPU's
/// [`morph_alpha`] evaluated in the same anchor-relative coordinates, `ring` the draw's level's ring.
pub fn cpu_vertex(globals: &Globals, u: &DrawUniform, ring: &Ring, v: MeshVertex) -> CpuVertex {
    let s = u.origin[3];
    let fetch = |x: i32, y: i32| {
        let tx = (u.tex[0] + x) % s;
        let ty = (u.tex[1] + y) % s;
        ring.texels()[(ty * s + tx) as usize]
    };
    vertex_with(globals, u, &fetch, v)
}

/// [`cpu_vertex`] for a detail pool draw (`u.pool[0] > 0`, issue 15): the heights come from its tile in
/// the draw's atlas layer, `layer` its `layer_side x layer_side` texels (row-major, each tile as
/// [`crate::plan::detail::fill_tile`] writes it at its [`crate::profile::DetailAtlas::place`]), read as
/// `clip_fetch` reads it: at the tile's first texel `u.pool[2..4]` plus the lattice offset (a stitched
/// unit's corners that coarse units touch read z_c, the others z).
pub fn cpu_detail_vertex(
    globals: &Globals,
    u: &DrawUniform,
    layer: &[[f32; 2]],
    layer_side: u32,
    v: MeshVertex,
) -> CpuVertex {
    let w = layer_side as i32;
    let fetch = |x: i32, y: i32| layer[((u.pool[3] + y) * w + u.pool[2] + x) as usize];
    vertex_with(globals, u, &fetch, v)
}

/// `clip_vertex` + `vs_main` with heights from `fetch` (anchor-relative lattice point to (z, z_c)).
#[expect(
    clippy::cast_precision_loss,
    reason = "anchor-relative lattice offsets are small integers, exact in f32"
)]
fn vertex_with(
    globals: &Globals,
    u: &DrawUniform,
    fetch: &dyn Fn(i32, i32) -> [f32; 2],
    v: MeshVertex,
) -> CpuVertex {
    let sn = u.fine[1];
    // `stitch_local`: a stitched pool unit's vertex rule (flags 0 leave every vertex as it is).
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "the flags are 8 bits"
    )]
    let (lx, ly, reads_zc) = stitch::local(u.fine[2] as u16, u32::from(v[0]), u32::from(v[1]));
    #[expect(clippy::cast_possible_wrap, reason = "mesh coordinates are u16")]
    let (lx, ly) = (lx as i32, ly as i32);
    let qx = (u.fine_origin[0] + (u.origin[0] + lx) * sn).clamp(u.fine_bounds[0], u.fine_bounds[2])
        - u.fine_origin[0];
    let qy = (u.fine_origin[1] + (u.origin[1] + ly) * sn).clamp(u.fine_bounds[1], u.fine_bounds[3])
        - u.fine_origin[1];
    if qx % sn != 0 || qy % sn != 0 {
        let pf = (qx + u.fine_origin[0], qy + u.fine_origin[1]);
        return cpu_snapped_vertex(globals, u, fetch, v, (qx, qy), pf);
    }
    let (px, py) = (qx / sn, qy / sn);
    let [mut z, zc] = fetch(px, py);
    if reads_zc {
        z = zc;
    }
    let active = Rect {
        x0: 0,
        y0: 0,
        w: (u.active[2] + 1) as u32,
        h: (u.active[3] + 1) as u32,
    };
    let alpha = morph_alpha(
        px as f32,
        py as f32,
        [u.morph[0], u.morph[1]],
        &active,
        #[expect(
            clippy::cast_possible_truncation,
            reason = "n is stored exactly as an f32"
        )]
        {
            u.morph_w[1] as u32
        },
    ) * globals.params[0];
    let zm = (1.0 - alpha) * z + alpha * zc;
    placed(globals, v, u.anchor_rel, (px, py), zm, alpha)
}

/// The vertex at lattice point `p` of the lattice anchored at `anchor` (xyz: position relative to the eye,
/// w: spacing) with height `z`, a skirt's lower vertex hanging to the floor, as `clip_vertex` places it.
#[expect(
    clippy::cast_precision_loss,
    reason = "anchor-relative lattice offsets are small integers, exact in f32"
)]
fn placed(
    globals: &Globals,
    v: MeshVertex,
    anchor: [f32; 4],
    (px, py): (i32, i32),
    z: f32,
    alpha: f32,
) -> CpuVertex {
    let h = if v[2] != 0 {
        z.min(globals.params[1])
    } else {
        z
    };
    let g = anchor[3];
    let rel = [
        anchor[0] + px as f32 * g,
        anchor[1] + -(py as f32) * g,
        anchor[2] + h,
    ];
    let clip = Mat4::from_cols_array(&globals.view_proj) * Vec4::new(rel[0], rel[1], rel[2], 1.0);
    CpuVertex {
        clip: clip.to_array(),
        rel,
        height: z,
        alpha,
    }
}

/// [`cpu_vertex`] on a snapped tile's edge: the level's piecewise-linear surface at `q` (level units
/// times s, anchor-relative), placed at fine point `pf`, as the shader's `snapped_vertex`.
#[expect(
    clippy::cast_precision_loss,
    reason = "anchor-relative lattice offsets are small integers, exact in f32"
)]
fn cpu_snapped_vertex(
    globals: &Globals,
    u: &DrawUniform,
    fetch: &dyn Fn(i32, i32) -> [f32; 2],
    v: MeshVertex,
    (qx, qy): (i32, i32),
    pf: (i32, i32),
) -> CpuVertex {
    let s = u.fine[1];
    let (cx, cy) = (qx / s, qy / s);
    let (fx, fy) = (
        (qx - cx * s) as f32 / s as f32,
        (qy - cy * s) as f32 / s as f32,
    );
    let cmax = |b: i32, o: i32| (b - o + s - 1) / s;
    let (c1x, c1y) = (
        (cx + 1).min(cmax(u.fine_bounds[2], u.fine_origin[0])),
        (cy + 1).min(cmax(u.fine_bounds[3], u.fine_origin[1])),
    );
    let z00 = fetch(cx, cy)[0];
    let z11 = fetch(c1x, c1y)[0];
    let (dzx, dzy) = if fx >= fy {
        let z10 = fetch(c1x, cy)[0];
        (z10 - z00, z11 - z10)
    } else {
        let z01 = fetch(cx, c1y)[0];
        (z11 - z01, z01 - z00)
    };
    let z = z00 + fx * dzx + fy * dzy;
    placed(globals, v, u.fine_rel, pf, z, 0.0)
}
