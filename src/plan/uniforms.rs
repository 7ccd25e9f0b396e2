//! Stage 2, the per-frame plan: the packed uniforms of a frame (plan output, `#[repr(C)]` Pod, no wgpu).
//! [`Globals`] and [`DrawUniform`] mirror `shaders_gles/clipmap.wgsl`; [`draw_uniform`] and
//! [`lod_draw_uniform`] fill one draw's slot from the clipmap frame and the camera, the anchor's position
//! relative to the eye computed in f64 (GC 5.2's camera-relative precision).

use bytemuck::{Pod, Zeroable};

use crate::plan::clipmap::Clipmap;
use crate::plan::cull;
use crate::plan::frame::Rect;
use crate::profile::{GLOBALS_BYTES, MAX_LEVELS};
use crate::shading::basic::BasicShading;
use crate::plan::camera::Camera;

/// The renderer's global uniforms; mirrors `Globals` in `shaders_gles/clipmap.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Globals {
    /// Camera-relative view-projection.
    pub view_proj: [f32; 16],
    /// Basic shading parameters.
    pub shading: BasicShading,
    /// x: morph factor (1 on, 0 off); y: skirt floor (m); z, w: vertex-probe target size.
    pub params: [f32; 4],
    /// The data's horizontal extent relative to the eye (m): x min, y min, x max, y max. Fragments
    /// outside it are discarded.
    pub extent: [f32; 4],
    /// Where each ring holds data, for shading from the finest resident data (GC section 6's normal
    /// maps, [`shading_levels`]); levels past `level_info[0]` are unused.
    pub levels: [ShadeLevel; MAX_LEVELS as usize],
    /// x: levels in use; y: ring size S; z: the ring's n (GC 6.2's transition width is n / 10); w: the
    /// coarsest level whose clip region is 4 x 4 samples or more (-1: none), where SG shading reads a
    /// pixel that no ring holds (`sg_taps` in `shaders_gles/sg_clipmap.wgsl`).
    pub level_info: [i32; 4],
}
const _: () = assert!(std::mem::size_of::<Globals>() as u64 == GLOBALS_BYTES);

/// One ring's held data for the fragment shader's data lookup; mirrors `ShadeLevel` in
/// `shaders_gles/clipmap.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ShadeLevel {
    /// xy: world position of the clip region's first sample minus the eye (m); z: minus the eye's
    /// height (m), in every slot; w: the level's spacing (m).
    pub rel: [f32; 4],
    /// xy: texel of the clip region's first sample (mod S); z, w: the clip region's width and height
    /// (0 when the ring holds nothing).
    pub tex: [i32; 4],
    /// GC 6.2's transition for the shading, in this level's lattice units: xy the viewer relative to the
    /// clip region's first sample, zw (active width - 1) / 2 and (active height - 1) / 2 (-1e9 when the
    /// level draws nothing, so its alpha is 1 everywhere).
    pub morph: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<ShadeLevel>() == 48);

/// Where each ring of the clipmap's last frame holds valid data (its clip region), relative to the eye:
/// the fragment shader shades from the finest ring that holds the pixel's position, whatever level the
/// mesh under the pixel was drawn at (GC section 6: normal maps from the clipmap's data). Returns the
/// levels and `level_info`.
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_possible_wrap,
    reason = "clip sizes and texels are below the ring size; f64 -> f32 after subtracting the eye is the \
              intended GPU precision"
)]
pub fn shading_levels(
    clipmap: &Clipmap,
    camera: &Camera,
    size: u32,
) -> ([ShadeLevel; MAX_LEVELS as usize], [i32; 4]) {
    let mut out = [ShadeLevel::default(); MAX_LEVELS as usize];
    let p = clipmap.eye_lattice(camera.eye);
    let g0 = clipmap.g0();
    let s = i64::from(size);
    let levels = clipmap.frame().levels.iter().take(MAX_LEVELS as usize);
    let mut used = 0;
    let mut fallback = -1;
    for (l, (slot, lf)) in out.iter_mut().zip(levels).enumerate() {
        used = l + 1;
        // The eye's height goes in every slot, held data or not (the shader reads it from level 0).
        slot.rel[2] = (-camera.eye.z) as f32;
        let c = lf.clip;
        if c.is_empty() {
            continue;
        }
        if c.w >= 4 && c.h >= 4 {
            fallback = l as i32;
        }
        let k = f64::from(1u32 << l);
        #[expect(
            clippy::cast_precision_loss,
            reason = "lattice coordinates are below 2^48"
        )]
        let (fx, fy) = (c.x0 as f64, c.y0 as f64);
        *slot = ShadeLevel {
            rel: [
                ((fx * k - p.0) * g0) as f32,
                (-(fy * k - p.1) * g0) as f32,
                (-camera.eye.z) as f32,
                (g0 * k) as f32,
            ],
            tex: [
                c.x0.rem_euclid(s) as i32,
                c.y0.rem_euclid(s) as i32,
                c.w as i32,
                c.h as i32,
            ],
            morph: morph_params(p, k, (fx, fy), &lf.active),
        };
    }
    let n = i32::try_from(clipmap.n()).expect("n <= 511 (profile check)");
    (out, [used as i32, size as i32, n, fallback])
}

/// GC 6.2's transition parameters of a level with active region `active`, in its lattice units relative to
/// `origin` (a lattice point of the level; `p` the eye in level-0 lattice units, `k` = 2^level): xy the
/// viewer, zw (active width - 1) / 2 and (active height - 1) / 2, or -1e9 for an empty region (alpha 1
/// everywhere).
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_precision_loss,
    reason = "anchor-relative lattice offsets are below the ring size; active widths are at most 2048, \
              exact in f32"
)]
fn morph_params(p: (f64, f64), k: f64, origin: (f64, f64), active: &Rect) -> [f32; 4] {
    let half = if active.is_empty() {
        [-1.0e9, -1.0e9]
    } else {
        [(active.w as f32 - 1.0) * 0.5, (active.h as f32 - 1.0) * 0.5]
    };
    [
        (p.0 / k - origin.0) as f32,
        (p.1 / k - origin.1) as f32,
        half[0],
        half[1],
    ]
}

/// One draw's uniforms; mirrors `DrawUniform` in `shaders_gles/clipmap.wgsl`. Lattice values are relative
/// to the level's anchor, the first vertex of its active region.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct DrawUniform {
    /// xy: mesh origin; z: array layer; w: ring size S.
    pub origin: [i32; 4],
    /// Clamp rectangle, inclusive: x0, y0, x1, y1.
    pub bounds: [i32; 4],
    /// Active region, inclusive: x0, y0, x1, y1.
    pub active: [i32; 4],
    /// xy: texel of the anchor (anchor mod S).
    pub tex: [i32; 4],
    /// xyz: world position of the anchor at height 0 minus the eye (m); w: level spacing (m).
    pub anchor_rel: [f32; 4],
    /// xy: viewer (level units); z, w: (active w - 1) / 2, (active h - 1) / 2.
    pub morph: [f32; 4],
    /// x: transition width n / 10; y: n; zw: unused.
    pub morph_w: [f32; 4],
    /// SAT LOD snapped tiles ([`cull::Draw::fine`]): x: fine level; y: s, this level's spacing in fine
    /// lattice units (1: not snapped, and the fine fields repeat the ones above); z: a stitched pool
    /// unit's vertex flags (`crate::plan::detail::stitch`, 0 otherwise); w: unused.
    pub fine: [i32; 4],
    /// Clamp rectangle in fine units, inclusive, fine-anchor-relative.
    pub fine_bounds: [i32; 4],
    /// xy: this level's anchor in fine units, fine-anchor-relative; zw: unused.
    pub fine_origin: [i32; 4],
    /// xyz: world position of the fine anchor at height 0 minus the eye (m); w: fine spacing (m).
    pub fine_rel: [f32; 4],
    /// x: detail pool layer + 1 (0: the heights come from the ring); y: samples per tile side; zw: the
    /// tile's first texel in that layer ([`crate::profile::DetailAtlas::place`]).
    pub pool: [i32; 4],
}
const _: () = assert!(std::mem::size_of::<DrawUniform>() == 192);

impl DrawUniform {
    /// Fills the fine fields for a draw that is not snapped: the fine level is the draw's own.
    fn unsnapped(mut self) -> Self {
        self.fine = [self.origin[2], 1, 0, 0];
        self.fine_bounds = self.bounds;
        self.fine_origin = [0; 4];
        self.fine_rel = self.anchor_rel;
        self
    }
}

/// The uniforms of draw `d`: lattice values relative to the level's anchor (its active region's first
/// vertex), the anchor's position relative to the eye computed in f64.
#[expect(
    clippy::cast_possible_truncation,
    reason = "anchor-relative lattice offsets are below the ring size; f64 -> f32 after subtracting the eye \
              is the intended GPU precision"
)]
pub fn draw_uniform(
    clipmap: &Clipmap,
    camera: &Camera,
    d: &cull::Draw,
    n: u32,
    size: u32,
) -> DrawUniform {
    let a = clipmap.frame().levels[d.level as usize].active;
    let (ax, ay) = (a.x0, a.y0);
    let rel = |v: i64, o: i64| (v - o) as i32;
    let k = f64::from(1u32 << d.level);
    let p = clipmap.eye_lattice(camera.eye);
    let g0 = clipmap.g0();
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48"
    )]
    let (fx, fy) = (ax as f64, ay as f64);
    let s = i64::from(size);
    DrawUniform {
        origin: [
            rel(d.origin[0], ax),
            rel(d.origin[1], ay),
            d.level as i32,
            size as i32,
        ],
        bounds: [
            rel(d.bounds.x0, ax),
            rel(d.bounds.y0, ay),
            rel(d.bounds.x1() - 1, ax),
            rel(d.bounds.y1() - 1, ay),
        ],
        active: [0, 0, a.w as i32 - 1, a.h as i32 - 1],
        tex: [ax.rem_euclid(s) as i32, ay.rem_euclid(s) as i32, 0, 0],
        anchor_rel: [
            ((fx * k - p.0) * g0) as f32,
            (-(fy * k - p.1) * g0) as f32,
            (-camera.eye.z) as f32,
            (g0 * k) as f32,
        ],
        morph: morph_params(p, k, (fx, fy), &a),
        morph_w: [n as f32 / 10.0, n as f32, 0.0, 0.0],
        ..DrawUniform::default()
    }
    .unsnapped()
}

/// The uniforms of SAT LOD draw `d`: like [`draw_uniform`], but anchored at the level's clip region (a block
/// drawn finer than its ring lies outside that level's active region, inside its held data), with the
/// region for one-sided normals the clip region and no morph.
#[expect(
    clippy::cast_possible_truncation,
    reason = "clip-relative lattice offsets are below the ring size; f64 -> f32 after subtracting the eye \
              is the intended GPU precision"
)]
pub fn lod_draw_uniform(
    clipmap: &Clipmap,
    camera: &Camera,
    d: &cull::Draw,
    n: u32,
    size: u32,
) -> DrawUniform {
    let c = clipmap.frame().levels[d.level as usize].clip;
    let mut u = draw_uniform(clipmap, camera, d, n, size);
    let (ax, ay) = (c.x0, c.y0);
    let rel = |v: i64, o: i64| (v - o) as i32;
    let k = f64::from(1u32 << d.level);
    let p = clipmap.eye_lattice(camera.eye);
    let g0 = clipmap.g0();
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48"
    )]
    let (fx, fy) = (ax as f64, ay as f64);
    let s = i64::from(size);
    u.origin[0] = rel(d.origin[0], ax);
    u.origin[1] = rel(d.origin[1], ay);
    u.bounds = [
        rel(d.bounds.x0, ax),
        rel(d.bounds.y0, ay),
        rel(d.bounds.x1() - 1, ax),
        rel(d.bounds.y1() - 1, ay),
    ];
    u.active = [0, 0, c.w as i32 - 1, c.h as i32 - 1];
    u.tex = [ax.rem_euclid(s) as i32, ay.rem_euclid(s) as i32, 0, 0];
    u.anchor_rel[0] = ((fx * k - p.0) * g0) as f32;
    u.anchor_rel[1] = (-(fy * k - p.1) * g0) as f32;
    // alpha = 0 everywhere: the transition band starts past any lattice point.
    u.morph = [0.0, 0.0, 1.0e9, 1.0e9];
    if d.fine == d.level {
        return u.unsnapped();
    }
    // A snapped tile: `d.bounds` is in the fine level's lattice, anchored at that level's clip region; the
    // shader clamps to `fine_bounds` only, so `bounds` above is not used.
    let f = clipmap.frame().levels[d.fine as usize].clip;
    let shift = d.level - d.fine;
    let kf = f64::from(1u32 << d.fine);
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48"
    )]
    let (gx, gy) = (f.x0 as f64, f.y0 as f64);
    u.fine = [d.fine as i32, 1 << shift, 0, 0];
    u.fine_bounds = [
        rel(d.bounds.x0, f.x0),
        rel(d.bounds.y0, f.y0),
        rel(d.bounds.x1() - 1, f.x0),
        rel(d.bounds.y1() - 1, f.y0),
    ];
    u.fine_origin = [rel(ax << shift, f.x0), rel(ay << shift, f.y0), 0, 0];
    u.fine_rel = [
        ((gx * kf - p.0) * g0) as f32,
        (-(gy * kf - p.1) * g0) as f32,
        (-camera.eye.z) as f32,
        (g0 * kf) as f32,
    ];
    u
}

/// The uniforms of detail-pool draw `d` ([`crate::plan::detail`]): anchored at the first held
/// sample of its tile (`first`, level units), so lattice offsets are the tile's texels; the region for
/// one-sided normals is the whole tile (its border included), no morph, no snapping.
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_possible_wrap,
    reason = "tile-relative lattice offsets are below the tile side; f64 -> f32 after subtracting the eye \
              is the intended GPU precision"
)]
pub fn detail_draw_uniform(
    clipmap: &Clipmap,
    camera: &Camera,
    d: &cull::Draw,
    place: (u32, u32, u32),
    first: (i64, i64),
    side: u32,
    n: u32,
) -> DrawUniform {
    let (ax, ay) = first;
    let rel = |v: i64, o: i64| (v - o) as i32;
    let k = f64::from(1u32 << d.level);
    let p = clipmap.eye_lattice(camera.eye);
    let g0 = clipmap.g0();
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48"
    )]
    let (fx, fy) = (ax as f64, ay as f64);
    let last = side as i32 - 1;
    DrawUniform {
        origin: [
            rel(d.origin[0], ax),
            rel(d.origin[1], ay),
            d.level as i32,
            0,
        ],
        bounds: [
            rel(d.bounds.x0, ax),
            rel(d.bounds.y0, ay),
            rel(d.bounds.x1() - 1, ax),
            rel(d.bounds.y1() - 1, ay),
        ],
        active: [0, 0, last, last],
        anchor_rel: [
            ((fx * k - p.0) * g0) as f32,
            (-(fy * k - p.1) * g0) as f32,
            (-camera.eye.z) as f32,
            (g0 * k) as f32,
        ],
        // alpha = 0 everywhere: the transition band starts past any lattice point.
        morph: [0.0, 0.0, 1.0e9, 1.0e9],
        morph_w: [n as f32 / 10.0, n as f32, 0.0, 0.0],
        pool: [
            place.0 as i32 + 1,
            side as i32,
            place.1 as i32,
            place.2 as i32,
        ],
        ..DrawUniform::default()
    }
    .unsnapped()
}

/// One detail pool cell of an instanced pool draw: the fields of its [`detail_draw_uniform`]
/// that differ between the cells of one draw (a draw's cells share level, mesh range and program), read
/// per instance from the cell buffer; mirrors `PoolCellIn` in `shaders_gles/clipmap.wgsl`. The draw's
/// uniform slot holds its first cell's whole [`DrawUniform`]; `draw_of` there, and its CPU twin
/// [`PoolCell::over`], put a cell's fields over it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PoolCell {
    /// xy: mesh origin (tile-relative lattice units); z: pool layer + 1; w: a stitched unit's vertex
    /// flags (`DrawUniform::fine` z; 0 for a whole cell).
    pub origin: [i32; 4],
    /// Clamp rectangle, inclusive, tile-relative: x0, y0, x1, y1.
    pub bounds: [i32; 4],
    /// xy: world position of the tile's first sample at height 0 minus the eye (m); zw: unused.
    pub anchor: [f32; 4],
    /// xy: the tile's first texel in its layer ([`crate::profile::DetailAtlas::place`]); zw: unused.
    pub texel: [i32; 4],
}
const _: () = assert!(std::mem::size_of::<PoolCell>() as u64 == crate::profile::POOL_CELL_BYTES);

impl PoolCell {
    /// The per-cell fields of pool draw uniform `u` ([`detail_draw_uniform`]).
    pub fn of(u: &DrawUniform) -> Self {
        Self {
            origin: [u.origin[0], u.origin[1], u.pool[0], u.fine[2]],
            bounds: u.bounds,
            anchor: [u.anchor_rel[0], u.anchor_rel[1], 0.0, 0.0],
            texel: [u.pool[2], u.pool[3], 0, 0],
        }
    }

    /// The CPU twin of `draw_of` in `shaders_gles/clipmap.wgsl`: the uniforms this cell's vertices see in
    /// a pool draw whose slot is `slot` (its first cell's uniforms: the fields its cells share). A slot
    /// that is not a pool draw's is returned as it is.
    pub fn over(&self, slot: &DrawUniform) -> DrawUniform {
        if slot.pool[0] <= 0 {
            return *slot;
        }
        let mut d = *slot;
        d.origin[0] = self.origin[0];
        d.origin[1] = self.origin[1];
        d.pool[0] = self.origin[2];
        d.pool[2] = self.texel[0];
        d.pool[3] = self.texel[1];
        d.bounds = self.bounds;
        d.fine_bounds = self.bounds;
        d.anchor_rel[0] = self.anchor[0];
        d.anchor_rel[1] = self.anchor[1];
        d.fine_rel[0] = self.anchor[0];
        d.fine_rel[1] = self.anchor[1];
        d.fine[2] = self.origin[3];
        d
    }
}

/// The data's horizontal extent relative to the eye (m), for [`Globals::extent`]: lattice x grows east and
/// lattice y south, so the north edge (lattice y 0) is the largest y.
pub(crate) fn data_extent_rel(
    clipmap: &Clipmap,
    camera: &Camera,
    data_lattice: (f64, f64),
) -> [f64; 4] {
    let p = clipmap.eye_lattice(camera.eye);
    let g0 = clipmap.g0();
    [
        -p.0 * g0,
        -(data_lattice.1 - p.1) * g0,
        (data_lattice.0 - p.0) * g0,
        p.1 * g0,
    ]
}

#[expect(
    clippy::cast_possible_truncation,
    reason = "eye-relative metre offsets as f32, like every position the GPU sees"
)]
pub(crate) fn to_f32x4(v: [f64; 4]) -> [f32; 4] {
    v.map(|e| e as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pool draw's slot with another cell of its call put over it gives that cell's own uniforms
    /// (the fields the cells share are the slot's); a slot that is not the pool's is left alone.
    #[test]
    fn a_pool_cell_over_its_call_slot_gives_its_own_uniforms() {
        let cell_uniform = |ox: i32, rel: f32, layer: i32, tx: i32| {
            DrawUniform {
                origin: [ox, 3, 1, 0],
                bounds: [ox, 3, ox + 8, 11],
                active: [0, 0, 34, 34],
                anchor_rel: [rel, -rel, -120.0, 60.0],
                morph: [0.0, 0.0, 1.0e9, 1.0e9],
                morph_w: [6.3, 63.0, 0.0, 0.0],
                pool: [layer, 35, tx, 35],
                ..DrawUniform::default()
            }
            .unsnapped()
        };
        let first = cell_uniform(0, 1500.5, 3, 0);
        let other = cell_uniform(16, -250.25, 7, 35);
        assert_eq!(PoolCell::of(&other).over(&first), other);
        assert_eq!(PoolCell::of(&first).over(&first), first);
        let ring = DrawUniform {
            origin: [4, 5, 2, 256],
            ..DrawUniform::default()
        }
        .unsnapped();
        assert_eq!(PoolCell::of(&other).over(&ring), ring);
    }
}
