//! Stage 2, the per-frame plan: the draw list. Each level's render region (active(l) minus active(l - 1),
//! GC section 3) is split into rectangles and tiled with blocks ([`crate::mesh`]); blocks whose bounding box
//! misses the view frustum are dropped (GC section 6: view-frustum culling per block). Pure CPU and
//! allocation-free: the list is a fixed-capacity [`DrawList`] bounded by the profile's `max_draws`.

use glam::{DMat4, DVec3, DVec4};

use crate::clipmap::Clipmap;
use crate::frame::Rect;
use crate::{Camera, Error, Result};

/// Most draws any profile may ask for (`budget.max_draws` is checked against it at start-up).
pub const MAX_DRAWS: usize = 2048;

/// What one draw renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DrawKind {
    /// The block mesh, clamped into `bounds`.
    Block,
    /// The ring skirt mesh, clamped onto the boundary of `bounds`.
    Skirt,
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
    /// Vertex rectangle (level units) the mesh's vertices are clamped into.
    pub bounds: Rect,
}

impl Draw {
    /// The vertices this draw really covers: its mesh footprint at `origin` clamped into `bounds`.
    pub fn covered(&self, block_quads: u32) -> Rect {
        match self.kind {
            DrawKind::Skirt => self.bounds,
            DrawKind::Block => {
                let q = i64::from(block_quads);
                Rect::from_bounds(
                    self.origin[0],
                    self.origin[1],
                    self.origin[0] + q + 1,
                    self.origin[1] + q + 1,
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
        let view = DMat4::look_to_rh(DVec3::ZERO, camera.forward(), DVec3::Z);
        let proj = DMat4::perspective_rh(
            camera.fov_y_deg.to_radians(),
            aspect,
            camera.near,
            camera.far,
        );
        let m = proj * view;
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
fn height_range(clipmap: &Clipmap, level: u32, r: &Rect) -> (f32, f32) {
    let ring = clipmap.ring(level);
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for j in r.y0..r.y1() {
        for i in r.x0..r.x1() {
            let [z, zc] = ring.get(i, j);
            lo = lo.min(z.min(zc));
            hi = hi.max(z.max(zc));
        }
    }
    (lo, hi)
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
    let push = |out: &mut DrawList, d: Draw| -> Result<()> {
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
    };
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

#[cfg(test)]
mod tests {
    use super::*;

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
