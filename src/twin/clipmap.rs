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
    /// How far a conformant GLES 3.0 driver's `clip` may lie from this one, per component (derived in
    /// docs/real-drivers.md): highp arithmetic rounds each operation correctly, may fuse `a * b + c`
    /// and sum a dot product in any order, and its division may be 2.5 ulp off (GLSL ES 3.00 section
    /// 4.5.1).
    pub clip_bound: [f32; 4],
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
        let tx = glsl_rem(u.tex[0] + x, s);
        let ty = glsl_rem(u.tex[1] + y, s);
        ring.texels()[(ty * s + tx) as usize]
    };
    vertex_with(globals, u, &fetch, v)
}

/// `a % b` as the shaders write it: GLSL ES 3.00 (section 5.9) leaves the remainder undefined when an
/// operand is negative, so the twin panics there rather than agree with one driver (docs/real-drivers.md).
pub fn glsl_rem(a: i32, b: i32) -> i32 {
    assert!(
        a >= 0 && b > 0,
        "{a} % {b}: undefined in GLSL ES 3.00 with a negative operand"
    );
    a % b
}

/// `a / b` of integers as the shaders write it, for the non-negative operands whose quotient
/// [`glsl_rem`] pairs with (the twin panics on others).
pub fn glsl_div(a: i32, b: i32) -> i32 {
    assert!(
        a >= 0 && b > 0,
        "{a} / {b}: a negative or zero operand in an integer division"
    );
    a / b
}

/// [`cpu_vertex`] for a detail pool draw (`u.pool[0] > 0`): the heights come from its tile in
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
    if glsl_rem(qx, sn) != 0 || glsl_rem(qy, sn) != 0 {
        let pf = (qx + u.fine_origin[0], qy + u.fine_origin[1]);
        return cpu_snapped_vertex(globals, u, fetch, v, (qx, qy), pf);
    }
    let (px, py) = (glsl_div(qx, sn), glsl_div(qy, sn));
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
    // The morph weight's divisions and differences (a few ulp of the terms), then the blend.
    let w = u.morph_w[0];
    let terms = (px as f32 - u.morph[0])
        .abs()
        .max((py as f32 - u.morph[1]).abs())
        + u.morph[2].abs().max(u.morph[3].abs())
        + w
        + 1.0;
    // Without morphing alpha is multiplied by 0: exact on both sides.
    let d_alpha = if globals.params[0] != 0.0 {
        ULP * (4.0 * terms / w + 3.0)
    } else {
        0.0
    };
    let dz = d_alpha * (zc - z).abs() + 2.0 * gamma(3) * (z.abs() + zc.abs());
    placed(globals, v, u.anchor_rel, (px, py), zm, alpha, dz)
}

/// The unit roundoff of f32 (highp): half an ulp of 1.
const ULP: f32 = f32::EPSILON * 0.5;

/// The relative error bound of `n` rounded operations, n u / (1 - n u) (Higham, "Accuracy and Stability of
/// Numerical Algorithms", 2nd ed., section 3.1): any order of an n-term sum of products, fused or not.
#[expect(clippy::cast_precision_loss, reason = "n is a small count")]
fn gamma(n: u32) -> f32 {
    let nu = n as f32 * ULP;
    nu / (1.0 - nu)
}

/// The pixel bound of a clip-space difference: `clip` (this twin's) and `bound` ([`CpuVertex::clip_bound`])
/// on a viewport `width` x `height`: how far apart in pixels (x, y) a conformant driver's vertex and the
/// twin's may land, the perspective division's own rounding on each side included. `None` for a vertex
/// whose w may reach 0 within the bound (at or behind the eye).
pub fn pixel_bound(clip: [f32; 4], bound: [f32; 4], width: u32, height: u32) -> Option<[f64; 2]> {
    let w = f64::from(clip[3]);
    let bw = f64::from(bound[3]);
    if w - bw <= 0.0 {
        return None;
    }
    let u = f64::from(ULP);
    let side = [f64::from(width), f64::from(height)];
    Some(std::array::from_fn(|i| {
        let ndc = f64::from(clip[i]) / w;
        let d = (f64::from(bound[i]) + ndc.abs() * bw) / (w - bw) + 2.0 * u * ndc.abs();
        d * side[i] * 0.5
    }))
}

/// The bound of [`CpuVertex::clip_bound`] for clip = M (rel, 1), `rel` known to within `d_rel` (the
/// difference two conformant evaluations of it may have): each side's own dot-product error
/// (gamma(4) of the summed magnitudes) plus the inputs' through M.
fn clip_bound(m: &Mat4, rel: [f32; 3], d_rel: [f32; 3]) -> [f32; 4] {
    let p = [rel[0], rel[1], rel[2], 1.0];
    let dp = [d_rel[0], d_rel[1], d_rel[2], 0.0];
    std::array::from_fn(|i| {
        let row = m.row(i);
        let (mut mag, mut through) = (0.0f32, 0.0f32);
        for j in 0..4 {
            mag += (row[j] * p[j]).abs();
            through += row[j].abs() * dp[j];
        }
        through + 2.0 * gamma(4) * mag
    })
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
    dz: f32,
) -> CpuVertex {
    let h = if v[2] != 0 {
        z.min(globals.params[1])
    } else {
        z
    };
    let g = anchor[3];
    let (ox, oy) = (px as f32 * g, -(py as f32) * g);
    let rel = [anchor[0] + ox, anchor[1] + oy, anchor[2] + h];
    let m = Mat4::from_cols_array(&globals.view_proj);
    let clip = m * Vec4::new(rel[0], rel[1], rel[2], 1.0);
    // A product and a sum each (fused or not, on either side), and the height's own bound.
    let d_rel = [
        2.0 * gamma(2) * (anchor[0].abs() + ox.abs()),
        2.0 * gamma(2) * (anchor[1].abs() + oy.abs()),
        dz + 2.0 * gamma(1) * (anchor[2].abs() + h.abs()),
    ];
    CpuVertex {
        clip: clip.to_array(),
        clip_bound: clip_bound(&m, rel, d_rel),
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
    let (cx, cy) = (glsl_div(qx, s), glsl_div(qy, s));
    let (fx, fy) = (
        (qx - cx * s) as f32 / s as f32,
        (qy - cy * s) as f32 / s as f32,
    );
    let cmax = |b: i32, o: i32| glsl_div(b - o + s - 1, s);
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
    // f's division (2.5 ulp), the differences and the two products and sums.
    let dz = 3.0 * ULP * (dzx.abs() + dzy.abs())
        + 2.0
            * gamma(4)
            * (z00.abs() + (fx * dzx).abs() + (fy * dzy).abs() + dzx.abs() + dzy.abs());
    placed(globals, v, u.fine_rel, pf, z, 0.0, dz)
}
