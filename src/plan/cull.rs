//! Stage 2, the per-frame plan: the draw list. Each level's render region (active(l) minus active(l - 1),
//! GC section 3) is split into rectangles and tiled with blocks ([`crate::plan::mesh`]); blocks whose bounding box
//! misses the view frustum are dropped (GC section 6: view-frustum culling per block). Pure CPU and
//! allocation-free: the list is a fixed-capacity [`DrawList`] bounded by the profile's `max_draws`.

use glam::{DVec3, DVec4};

use crate::plan::clipmap::Clipmap;
use crate::plan::frame::Rect;
use crate::{Error, Result};
use crate::plan::camera::Camera;

// The limit lives with the budget it bounds, so that the profile depends on no stage.
pub use crate::profile::MAX_DRAWS;

/// What one draw renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DrawKind {
    /// The block mesh, clamped into `bounds`.
    Block,
    /// The ring skirt mesh, clamped onto the boundary of `bounds`.
    Skirt,
    /// The tile skirt mesh (around m quads), clamped onto the boundary of `bounds`: a SAT LOD tile's skirt.
    TileSkirt,
    /// A detail pool cell and its tile skirt in one draw (the pool cell mesh,
    /// [`crate::plan::mesh::pool_cells`]), clamped into `bounds`.
    PoolCell,
    /// A call of a stitched pool cell's units ([`crate::plan::detail::stitch`]), one unit mesh for every
    /// instance (its fan or its coarse quad); a call kind only: the draw list holds the cell.
    PoolUnit,
    /// A call of the skirts under stitched cells' unit sides on their borders; a call kind only.
    PoolUnitSkirt,
}

impl DrawKind {
    /// Whether it draws the terrain's surface (a block or pool cell), not only a skirt.
    pub fn surface(self) -> bool {
        matches!(self, Self::Block | Self::PoolCell)
    }
}

/// One draw call: a mesh placed at `origin` of a level's lattice, its vertices clamped into `bounds`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Draw {
    /// Level (array layer).
    pub level: u32,
    /// Which mesh.
    pub kind: DrawKind,
    /// Lattice position (level units) of the mesh's vertex (0, 0).
    pub origin: [i64; 2],
    /// Vertex rectangle the mesh's vertices are clamped into, in the lattice of level `fine`.
    pub bounds: Rect,
    /// The level whose lattice `bounds` is in: `level`, except for a SAT LOD snapped tile, whose mesh steps
    /// in `level` units while its edge vertices clamp onto the finer ring's lattice, on the level's
    /// piecewise-linear surface ([`build_lod_draws`]).
    pub fine: u32,
    /// Blocks: the top-left `quads x quads` of the block mesh are drawn (the whole mesh when it is the
    /// mesh's size; SAT LOD blocks of fewer quads draw a prefix, [`crate::plan::mesh::block_prefix`]). Tile
    /// skirts: the tile's side, picking the loop ([`crate::plan::mesh::skirt_loop_range`]). Ring skirts: 0.
    pub quads: u32,
    /// SAT LOD: the block's wanted level was finer than any held data covering it (the selection clamped).
    pub clamped: bool,
    /// The detail pool slot the heights come from ([`crate::plan::detail`]); None: the level's ring.
    pub pool: Option<u16>,
    /// A pool cell drawn stitched ([`crate::plan::detail::stitch`]): 1 + its mask's index in
    /// [`crate::plan::detail::DetailFrame::masks`]; 0 for every other draw.
    pub stitch: u16,
}

impl Draw {
    /// The vertices this draw really covers, in level `fine`'s lattice: its mesh footprint at `origin`
    /// clamped into `bounds`.
    pub fn covered(&self, block_quads: u32) -> Rect {
        match self.kind {
            DrawKind::Skirt
            | DrawKind::TileSkirt
            | DrawKind::PoolCell
            | DrawKind::PoolUnit
            | DrawKind::PoolUnitSkirt => self.bounds,
            DrawKind::Block => {
                let q = i64::from(block_quads);
                let shift = self.level - self.fine;
                Rect::from_bounds(
                    self.origin[0] << shift,
                    self.origin[1] << shift,
                    ((self.origin[0] + q) << shift) + 1,
                    ((self.origin[1] + q) << shift) + 1,
                )
                .intersect(&self.bounds)
            }
        }
    }
}

/// A frame's draws, finest level first.
pub type DrawList = heapless::Vec<Draw, MAX_DRAWS>;

/// How to build the draw list.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrawParams {
    /// Quads per block side (the block mesh's size), m = (n + 1) / 4.
    pub block_quads: u32,
    /// The profile's draw budget; more draws are an [`Error::Capacity`].
    pub max_draws: u32,
    /// Frustum-cull blocks (off: draw every block, the cross-check reference).
    pub cull: bool,
    /// Draw the skirts that close level boundaries (off only to show what they hide).
    pub skirts: bool,
    /// Viewport width / height.
    pub aspect: f64,
    /// The data's horizontal extent relative to the eye (m): x min, y min, x max, y max. The fragment
    /// shader discards everything outside it, so blocks wholly outside are culled.
    pub extent: [f64; 4],
}

/// What the draw list holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DrawStats {
    /// Blocks drawn.
    pub blocks: u32,
    /// Blocks dropped by the frustum test.
    pub culled: u32,
    /// Skirts drawn.
    pub skirts: u32,
    /// SAT LOD: block pieces drawn as snapped tiles, because the selected level's lattice does not meet
    /// their corners (a piece clipped by the active region or the hole at odd vertices).
    pub pieces_snapped: u32,
}

/// The finer level's active region in this level's units: vertices a.x0/2 ..= (a.x1 - 1)/2 (its corners are
/// even, constraint 3, so they land on this level's vertices).
pub fn hole(finer_active: &Rect) -> Rect {
    let a = finer_active;
    if a.is_empty() {
        return Rect::EMPTY;
    }
    Rect::from_bounds(
        a.x0.div_euclid(2),
        a.y0.div_euclid(2),
        (a.x1() - 1).div_euclid(2) + 1,
        (a.y1() - 1).div_euclid(2) + 1,
    )
}

/// The render region of a level as vertex rectangles: `active` alone, or `active` minus the interior of
/// `hole` as north and south bands and west and east strips. Neighbouring rectangles share their boundary
/// vertices, so their triangles meet exactly. `hole` lies at least one quad inside `active` (constraint 2).
pub fn render_rects(active: &Rect, hole: &Rect) -> heapless::Vec<Rect, 4> {
    let mut out = heapless::Vec::new();
    if active.is_empty() {
        return out;
    }
    if hole.is_empty() {
        out.push(*active).expect("one rectangle");
        return out;
    }
    assert!(
        active.contains(hole)
            && hole.x0 > active.x0
            && hole.y0 > active.y0
            && hole.x1() < active.x1()
            && hole.y1() < active.y1(),
        "hole {hole:?} is not strictly inside active region {active:?} (GC constraint 2)"
    );
    let (ax1, ay1) = (active.x1(), active.y1());
    let (hxl, hyl) = (hole.x1() - 1, hole.y1() - 1);
    for r in [
        Rect::from_bounds(active.x0, active.y0, ax1, hole.y0 + 1),
        Rect::from_bounds(active.x0, hyl, ax1, ay1),
        Rect::from_bounds(active.x0, hole.y0, hole.x0 + 1, hyl + 1),
        Rect::from_bounds(hxl, hole.y0, ax1, hyl + 1),
    ] {
        out.push(r).expect("four rectangles");
    }
    out
}

/// The six planes of the camera-relative view frustum (wgpu clip space: depth 0..1), inward-facing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    planes: [DVec4; 6],
}

impl Frustum {
    /// The frustum of `camera` (positions relative to the eye), in f64: Gribb and Hartmann's plane
    /// extraction from the view-projection rows.
    pub fn new(camera: &Camera, aspect: f64) -> Self {
        // Conventional depth whatever the camera's: its planes are the same. With an infinite far plane
        // the last row is (0, 0, 0, near): it culls nothing.
        let m = camera.projection_conventional(aspect) * camera.view_relative();
        let r = |i: usize| m.row(i);
        Self {
            planes: [
                r(3) + r(0),
                r(3) - r(0),
                r(3) + r(1),
                r(3) - r(1),
                r(2),
                r(3) - r(2),
            ],
        }
    }

    /// Whether the box [lo, hi] (relative to the eye) may intersect the frustum (conservative).
    pub fn intersects(&self, lo: DVec3, hi: DVec3) -> bool {
        self.planes.iter().all(|p| {
            let v = DVec3::new(
                if p.x > 0.0 { hi.x } else { lo.x },
                if p.y > 0.0 { hi.y } else { lo.y },
                if p.z > 0.0 { hi.z } else { lo.z },
            );
            p.x * v.x + p.y * v.y + p.z * v.z + p.w >= 0.0
        })
    }
}

/// The world box of lattice rectangle `r` of `level` relative to the eye at lattice point `eye_l` (level-0
/// units), heights `z` (m) and `eye_z`.
fn block_box(
    clipmap: &Clipmap,
    level: u32,
    r: &Rect,
    eye_l: (f64, f64),
    z: (f32, f32),
    eye_z: f64,
    extent: &[f64; 4],
) -> (DVec3, DVec3) {
    let g0 = clipmap.g0();
    let k = f64::from(1u32 << level);
    // Exact: lattice coordinates stay far below 2^53.
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48"
    )]
    let (x0, x1, y0, y1) = (
        (r.x0 as f64 * k - eye_l.0) * g0,
        ((r.x1() - 1) as f64 * k - eye_l.0) * g0,
        // Rows run south: the first row is the northern edge.
        -((r.y1() - 1) as f64 * k - eye_l.1) * g0,
        -(r.y0 as f64 * k - eye_l.1) * g0,
    );
    // The morphed height lies between z and z_c up to f32 rounding; pad by a centimetre and a relative bit.
    let pad = 0.01 + 1e-5 * f64::from(z.0.abs().max(z.1.abs()));
    // The fragment shader discards everything beyond the data: shrink the box to the part inside it (an
    // inverted box, lo > hi, means none is, and the frustum test then fails). The pad covers the f32
    // rounding of the shader's comparison.
    let hpad = 0.01 + 1e-6 * extent.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    (
        DVec3::new(
            x0.max(extent[0] - hpad),
            y0.max(extent[1] - hpad),
            f64::from(z.0) - eye_z - pad,
        ),
        DVec3::new(
            x1.min(extent[2] + hpad),
            y1.min(extent[3] + hpad),
            f64::from(z.1) - eye_z + pad,
        ),
    )
}

/// Lowest and highest of z and z_c over `r` of ring `level` (the morphed surface lies between them).
///
/// A row's texels are read as at most two contiguous runs (the toroidal wrap), not texel by texel through
/// [`crate::plan::ring::Ring::index`]'s two divisions: this was a fifth of a SAT LOD flight's plan time.
fn height_range(clipmap: &Clipmap, level: u32, r: &Rect) -> (f32, f32) {
    let ring = clipmap.ring(level);
    let texels = ring.texels();
    let size = ring.size() as usize;
    // Eight running minima and maxima, not one: one chain of dependent min/max was latency-bound. The
    // result is the same (min and max ignore order).
    let (mut lo, mut hi) = ([f32::INFINITY; 8], [f32::NEG_INFINITY; 8]);
    let mut take = |run: &[[f32; 2]]| {
        let flat: &[f32] = bytemuck::cast_slice(run);
        let mut chunks = flat.chunks_exact(8);
        for c in &mut chunks {
            for k in 0..8 {
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
        }
        for &v in chunks.remainder() {
            lo[0] = lo[0].min(v);
            hi[0] = hi[0].max(v);
        }
    };
    let w = r.w as usize;
    for j in r.y0..r.y1() {
        let start = ring.index(r.x0, j);
        if w <= size {
            let row = start - start % size;
            let first = w.min(row + size - start);
            take(&texels[start..start + first]);
            take(&texels[row..row + (w - first)]);
        } else {
            for i in r.x0..r.x1() {
                take(std::slice::from_ref(&texels[ring.index(i, j)]));
            }
        }
    }
    (
        lo.iter().copied().fold(f32::INFINITY, f32::min),
        hi.iter().copied().fold(f32::NEG_INFINITY, f32::max),
    )
}

/// Appends `d` unless the list already holds `cap` draws (the profile's `max_draws`, at most
/// [`MAX_DRAWS`]): overflow is an [`Error::Capacity`], never a silent drop.
pub(crate) fn push_capped(out: &mut DrawList, d: Draw, cap: usize) -> Result<()> {
    if out.len() >= cap {
        return Err(Error::Capacity {
            what: "draws per frame (budget.max_draws)",
            capacity: cap,
        });
    }
    out.push(d).map_err(|_| Error::Capacity {
        what: "draws per frame",
        capacity: MAX_DRAWS,
    })
}

/// Builds the draw list of the clipmap's last frame seen from `camera` into `out` (cleared first).
///
/// Per enabled level, finest first: the render region's rectangles tiled by blocks (each frustum-culled
/// against its box from the ring's z and z_c when `params.cull`), then a skirt hanging from the level's
/// outer boundary (not on the coarsest enabled level, whose edge is the terrain's silhouette) and one from
/// the finer level's boundary (the hole). Skirts are never culled. More than `params.max_draws` draws is an
/// [`Error::Capacity`].
pub fn build_draws(
    clipmap: &Clipmap,
    camera: &Camera,
    params: &DrawParams,
    out: &mut DrawList,
) -> Result<DrawStats> {
    out.clear();
    let frame = clipmap.frame();
    let frustum = Frustum::new(camera, params.aspect);
    let eye_l = clipmap.eye_lattice(camera.eye);
    let cap = (params.max_draws as usize).min(MAX_DRAWS);
    let mut stats = DrawStats::default();
    let push = |out: &mut DrawList, d: Draw| push_capped(out, d, cap);
    let coarsest_enabled = frame.levels.iter().rposition(|l| !l.active.is_empty());
    let q = i64::from(params.block_quads);
    for (li, lf) in frame.levels.iter().enumerate() {
        let level = u32::try_from(li).expect("level < MAX_LEVELS");
        let active = lf.active;
        if active.is_empty() {
            continue;
        }
        let finer = if li > 0 {
            frame.levels[li - 1].active
        } else {
            Rect::EMPTY
        };
        let hole = hole(&finer);
        for r in render_rects(&active, &hole) {
            let (qw, qh) = (i64::from(r.w) - 1, i64::from(r.h) - 1);
            let mut by = 0;
            while by < qh {
                let mut bx = 0;
                while bx < qw {
                    let d = Draw {
                        level,
                        kind: DrawKind::Block,
                        origin: [r.x0 + bx, r.y0 + by],
                        bounds: r,
                        fine: level,
                        quads: params.block_quads,
                        clamped: false,
                        pool: None,
                        stitch: 0,
                    };
                    let visible = !params.cull || {
                        let c = d.covered(params.block_quads);
                        let z = height_range(clipmap, level, &c);
                        let (lo, hi) =
                            block_box(clipmap, level, &c, eye_l, z, camera.eye.z, &params.extent);
                        lo.x <= hi.x && lo.y <= hi.y && frustum.intersects(lo, hi)
                    };
                    if visible {
                        push(out, d)?;
                        stats.blocks += 1;
                    } else {
                        stats.culled += 1;
                    }
                    bx += q;
                }
                by += q;
            }
        }
        let mut skirt = |bounds: Rect| -> Result<()> {
            push(
                out,
                Draw {
                    level,
                    kind: DrawKind::Skirt,
                    origin: [bounds.x0, bounds.y0],
                    bounds,
                    fine: level,
                    quads: 0,
                    clamped: false,
                    pool: None,
                    stitch: 0,
                },
            )?;
            stats.skirts += 1;
            Ok(())
        };
        if params.skirts && Some(li) != coarsest_enabled {
            skirt(active)?;
        }
        if params.skirts && !hole.is_empty() {
            skirt(hole)?;
        }
    }
    Ok(stats)
}

/// The pieces of a LOD block: its vertex rectangle `r` minus the quads inside `hole` (the finer ring's
/// active region, drawn by that ring), as at most four rectangles sharing boundary vertices.
pub fn block_pieces(r: &Rect, hole: &Rect) -> heapless::Vec<Rect, 4> {
    let mut out = heapless::Vec::new();
    // Quad ranges [x0, x1) x [y0, y1).
    let (qx0, qy0, qx1, qy1) = (r.x0, r.y0, r.x1() - 1, r.y1() - 1);
    let (hx0, hy0, hx1, hy1) = if hole.is_empty() {
        (0, 0, 0, 0)
    } else {
        (
            hole.x0.max(qx0),
            hole.y0.max(qy0),
            (hole.x1() - 1).min(qx1),
            (hole.y1() - 1).min(qy1),
        )
    };
    let quads = |x0: i64, y0: i64, x1: i64, y1: i64| Rect::from_bounds(x0, y0, x1 + 1, y1 + 1);
    if hx0 >= hx1 || hy0 >= hy1 {
        if qx1 > qx0 && qy1 > qy0 {
            out.push(*r).expect("one piece");
        }
        return out;
    }
    for (x0, y0, x1, y1) in [
        (qx0, qy0, qx1, hy0),
        (qx0, hy1, qx1, qy1),
        (qx0, hy0, hx0, hy1),
        (hx1, hy0, qx1, hy1),
    ] {
        if x1 > x0 && y1 > y0 {
            out.push(quads(x0, y0, x1, y1)).expect("four pieces");
        }
    }
    out
}

/// The level-`level` vertex rectangle of ring `ring`'s vertex rectangle `p`, and whether it is exact (the
/// corners of `p` are vertices of `level`; always for `level <= ring`).
fn at_level(p: &Rect, ring: u32, level: u32) -> (Rect, bool) {
    let conv = |v: i64| (v << ring) >> level;
    let exact = [p.x0, p.x1() - 1, p.y0, p.y1() - 1]
        .iter()
        .all(|&v| (v << ring) == (conv(v) << level));
    (
        Rect::from_bounds(
            conv(p.x0),
            conv(p.y0),
            conv(p.x1() - 1) + 1,
            conv(p.y1() - 1) + 1,
        ),
        exact,
    )
}

/// The level a piece of a ring-`ring` block selected at `selected` is drawn at: `selected` when finer or
/// equal; when coarser, the coarsest level up to `selected` whose lattice meets the piece's corners and whose
/// clip region holds it (a block mesh of that level then covers the piece exactly).
fn piece_level(frame: &crate::plan::frame::Frame, ring: u32, selected: u32, p: &Rect) -> u32 {
    if selected <= ring {
        return selected;
    }
    let mut level = selected;
    while level > ring {
        let (r, exact) = at_level(p, ring, level);
        let clip = frame.levels[level as usize].clip;
        if exact && r.w >= 2 && r.h >= 2 && !clip.is_empty() && clip.contains(&r) {
            break;
        }
        level -= 1;
    }
    level
}

/// Builds the SAT LOD draw list (docs/design.md "SAT LOD" 6-7) into `out` (cleared first): every block of `lod`
/// minus the finer ring's active region, drawn at the level the selection chose, as tiles of at most m x m
/// quads of that level (one block-mesh draw each, a prefix of its indices when smaller). Blocks are culled
/// like [`build_draws`]'s. Skirts (the smallest tile skirt loop that spans the tile, culled with it): around
/// each tile of a block that is drawn at another level than its ring, is edge-adjacent to such a block of the
/// same ring, or lies on its ring's outer or hole boundary, so every boundary between different levels has a
/// skirt on both sides. Blocks listed in `skip` (drawn from the detail pool, [`crate::plan::detail`]) are
/// left out but still count as drawn at their level for their neighbours' skirts. The tiles' height
/// ranges come through `heights` (kept while their texels are unchanged). More than `params.max_draws`
/// draws is an [`Error::Capacity`].
pub fn build_lod_draws(
    clipmap: &Clipmap,
    camera: &Camera,
    params: &DrawParams,
    lod: &crate::plan::lod::LodFrame,
    skip: &[(u16, u32)],
    heights: &crate::plan::heights::TileHeights,
    out: &mut DrawList,
) -> Result<DrawStats> {
    out.clear();
    let frame = clipmap.frame();
    let frustum = Frustum::new(camera, params.aspect);
    let eye_l = clipmap.eye_lattice(camera.eye);
    let cap = (params.max_draws as usize).min(MAX_DRAWS);
    let mut stats = DrawStats::default();
    let push = |out: &mut DrawList, d: Draw| push_capped(out, d, cap);
    let m = i64::from(params.block_quads);
    let hole_of = |ring: u32| -> Rect {
        match ring.checked_sub(1) {
            Some(f) => hole(&frame.levels[f as usize].active),
            None => Rect::EMPTY,
        }
    };
    let cell = |r: &Rect| (r.x0.div_euclid(m), r.y0.div_euclid(m));
    // Every piece of a block is drawn at the block's level (snapped where its corners need it), so a block
    // differs from its ring exactly when its level does.
    let differs = |b: &crate::plan::lod::BlockLod| b.level != b.ring;
    let blocks = &lod.blocks;
    // The blocks of each ring (listed ring by ring), for the neighbour test, and the skipped blocks.
    let mut rings = [(0usize, 0usize); crate::plan::frame::MAX_LEVELS];
    for (bi, b) in blocks.iter().enumerate() {
        let r = &mut rings[(b.ring as usize).min(crate::plan::frame::MAX_LEVELS - 1)];
        if r.1 == 0 {
            r.0 = bi;
        }
        r.1 = bi + 1;
    }
    let mut skipped = [0u64; crate::plan::lod::MAX_LOD_BLOCKS / 64];
    for &(i, _) in skip {
        if let Some(w) = skipped.get_mut(usize::from(i) / 64) {
            *w |= 1 << (i % 64);
        }
    }
    for (bi, b) in blocks.iter().enumerate() {
        if skipped[bi / 64] >> (bi % 64) & 1 == 1 {
            continue;
        }
        let (cx, cy) = cell(&b.rect);
        let (r0, r1) = rings[(b.ring as usize).min(crate::plan::frame::MAX_LEVELS - 1)];
        // A block on its ring's outer boundary or on the hole borders another ring, drawn at another level.
        let a = frame.levels[b.ring as usize].active;
        let r = &b.rect;
        let on_ring_edge = r.x0 == a.x0 || r.y0 == a.y0 || r.x1() == a.x1() || r.y1() == a.y1();
        let needs_skirt = params.skirts
            && (differs(b)
                || on_ring_edge
                || !r.intersect(&hole_of(b.ring)).is_empty()
                || blocks[r0..r1].iter().any(|o| {
                    let (ox, oy) = cell(&o.rect);
                    differs(o) && o.ring == b.ring && (ox - cx).abs() + (oy - cy).abs() == 1
                }));
        for p in block_pieces(&b.rect, &hole_of(b.ring)) {
            let whole = piece_level(frame, b.ring, b.level, &p);
            // A piece whose corners the selected level's lattice meets is tiled at that level exactly.
            // Otherwise (clipped by the ring's edge or the hole at odd vertices) it is still drawn at the
            // selected level, as snapped tiles: the mesh steps in that level's units over the piece's
            // outward-rounded extent, and the vertices clamp onto the piece's edge in the ring's lattice,
            // where they take the level's piecewise-linear surface. The tile is that level's surface cut
            // at the piece's edge; skirts close the step to the neighbours, as between any two levels.
            let (level, fine) = if whole == b.level {
                (whole, whole)
            } else {
                stats.pieces_snapped += 1;
                (b.level, b.ring)
            };
            let shift = level - fine;
            let ceil_shr = |v: i64| -((-v) >> shift);
            let (ring_p, _) = at_level(&p, b.ring, fine);
            let span = Rect::from_bounds(
                ring_p.x0 >> shift,
                ring_p.y0 >> shift,
                ceil_shr(ring_p.x1() - 1) + 1,
                ceil_shr(ring_p.y1() - 1) + 1,
            );
            let (qw, qh) = (i64::from(span.w) - 1, i64::from(span.h) - 1);
            let mut by = 0;
            while by < qh {
                let mut bx = 0;
                while bx < qw {
                    let tile = Rect::from_bounds(
                        span.x0 + bx,
                        span.y0 + by,
                        (span.x0 + bx + m).min(span.x1() - 1) + 1,
                        (span.y0 + by + m).min(span.y1() - 1) + 1,
                    );
                    bx += m;
                    // The tile's vertices in the fine lattice, clamped to the piece.
                    let bounds = Rect::from_bounds(
                        tile.x0 << shift,
                        tile.y0 << shift,
                        ((tile.x1() - 1) << shift) + 1,
                        ((tile.y1() - 1) << shift) + 1,
                    )
                    .intersect(&ring_p);
                    if bounds.w < 2 || bounds.h < 2 {
                        continue;
                    }
                    let d = Draw {
                        level,
                        kind: DrawKind::Block,
                        origin: [tile.x0, tile.y0],
                        bounds,
                        fine,
                        quads: tile.w.max(tile.h) - 1,
                        clamped: b.wanted < b.level,
                        pool: None,
                        stitch: 0,
                    };
                    let visible = !params.cull || {
                        // Every vertex is a point of the level's surface over the tile's cells.
                        let z = heights.range(clipmap, level, &tile, || {
                            height_range(clipmap, level, &tile)
                        });
                        let (lo, hi) = block_box(
                            clipmap,
                            fine,
                            &bounds,
                            eye_l,
                            z,
                            camera.eye.z,
                            &params.extent,
                        );
                        frustum.intersects(lo, hi)
                    };
                    if visible {
                        push(out, d)?;
                        stats.blocks += 1;
                        if needs_skirt {
                            push(
                                out,
                                Draw {
                                    kind: DrawKind::TileSkirt,
                                    ..d
                                },
                            )?;
                            stats.skirts += 1;
                        }
                    } else {
                        stats.culled += 1;
                    }
                }
                by += m;
            }
        }
    }
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kept_tile_ranges_are_the_texels_while_the_rings_move() {
        use crate::plan::clipmap::ClipmapOptions;
        use crate::source::procedural::{generate, ProceduralParams};
        let hm = generate(&ProceduralParams {
            size: 257,
            ..ProceduralParams::default()
        })
        .expect("terrain");
        let profile = crate::profile::Profile::load("gles3-low").expect("profile");
        let mut cm = Clipmap::new(&hm, &profile, ClipmapOptions::default()).expect("clipmap");
        let start = crate::plan::camera::Camera::default_for(&hm).expect("camera").eye;
        let heights = crate::plan::heights::TileHeights::default();
        let mut kept = 0;
        let mut first: Vec<Rect> = Vec::new();
        for f in 0..48_u32 {
            // Still for a while, then moving: kept entries are taken both ways.
            let step = f64::from(f.saturating_sub(8));
            cm.update(start + glam::DVec3::new(23.0 * step, 9.0 * step, 0.0))
                .expect("update");
            if f == 0 {
                first = cm.frame().levels.iter().map(|l| l.clip).collect();
            }
            for (level, clip) in (0..cm.levels()).zip(&first) {
                // Tiles fixed on the lattice across the first clip region's moving edge: the part
                // outside it is written as the ring moves over it.
                for ty in 0..4 {
                    for tx in 0..4 {
                        let (x0, y0) = (clip.x1() - 16 + tx * 8, clip.y0 + 20 + ty * 12);
                        let tile = Rect::from_bounds(x0, y0, x0 + 13, y0 + 13);
                        let fresh = height_range(&cm, level, &tile);
                        let mut read = false;
                        let got = heights.range(&cm, level, &tile, || {
                            read = true;
                            height_range(&cm, level, &tile)
                        });
                        kept += u32::from(!read);
                        assert_eq!(got, fresh, "frame {f}, level {level}, tile {tile:?}");
                    }
                }
            }
        }
        assert!(kept > 100, "ranges were kept ({kept})");
    }

    #[test]
    fn render_rects_tile_the_ring_exactly() {
        let active = Rect::from_bounds(-10, 4, 53, 67);
        let h = hole(&Rect::from_bounds(12, 40, 75, 103));
        assert_eq!(h, Rect::from_bounds(6, 20, 38, 52));
        let rects = render_rects(&active, &h);
        // Every quad of active outside the hole's quads is covered exactly once.
        for j in active.y0..active.y1() - 1 {
            for i in active.x0..active.x1() - 1 {
                let in_hole = i >= h.x0 && i < h.x1() - 1 && j >= h.y0 && j < h.y1() - 1;
                let n = rects
                    .iter()
                    .filter(|r| i >= r.x0 && i < r.x1() - 1 && j >= r.y0 && j < r.y1() - 1)
                    .count();
                assert_eq!(n, usize::from(!in_hole), "quad ({i}, {j})");
            }
        }
    }

    #[test]
    fn block_pieces_cover_the_block_minus_the_hole() {
        let r = Rect::from_bounds(0, 0, 9, 9);
        for h in [
            Rect::EMPTY,
            Rect::from_bounds(3, 4, 20, 20),
            Rect::from_bounds(-5, -5, 4, 30),
            Rect::from_bounds(2, 2, 6, 6),
            Rect::from_bounds(-5, -5, 30, 30),
        ] {
            let pieces = block_pieces(&r, &h);
            for j in 0..8 {
                for i in 0..8 {
                    let in_hole =
                        !h.is_empty() && i >= h.x0 && i < h.x1() - 1 && j >= h.y0 && j < h.y1() - 1;
                    let n = pieces
                        .iter()
                        .filter(|p| i >= p.x0 && i < p.x1() - 1 && j >= p.y0 && j < p.y1() - 1)
                        .count();
                    assert_eq!(n, usize::from(!in_hole), "hole {h:?} quad ({i}, {j})");
                }
            }
        }
    }

    #[test]
    fn at_level_is_exact_on_aligned_corners() {
        let p = Rect::from_bounds(8, 4, 17, 13);
        assert_eq!(at_level(&p, 1, 3), (Rect::from_bounds(2, 1, 5, 4), true));
        assert!(!at_level(&p, 1, 4).1);
        assert_eq!(at_level(&p, 1, 0), (Rect::from_bounds(16, 8, 33, 25), true));
    }

    #[test]
    fn frustum_keeps_what_is_ahead() {
        let cam = Camera::new(DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0), 60.0)
            .and_then(|c| c.with_clip(1.0, 1000.0))
            .expect("camera");
        let f = Frustum::new(&cam, 1.0);
        assert!(f.intersects(DVec3::new(10.0, -1.0, -1.0), DVec3::new(11.0, 1.0, 1.0)));
        assert!(!f.intersects(DVec3::new(-11.0, -1.0, -1.0), DVec3::new(-10.0, 1.0, 1.0)));
        assert!(!f.intersects(DVec3::new(10.0, 50.0, -1.0), DVec3::new(11.0, 60.0, 1.0)));
        assert!(!f.intersects(DVec3::new(2000.0, -1.0, -1.0), DVec3::new(2001.0, 1.0, 1.0)));
    }
}
