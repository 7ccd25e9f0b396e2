//! The embedding API: exact height and ray queries of the terrain ([`TerrainRenderer::height_at`],
//! [`TerrainRenderer::raycast`]) and the height of the surface drawn in the last frame
//! ([`TerrainRenderer::drawn_height_at`]), for placing objects, picking and collision.

use glam::DVec3;

use crate::package::query::{self, Level0, ResidentGrid};
use crate::package::ray::{self, GridHit, GridRay};
use crate::{Error, Result, TerrainRenderer};

use super::query_state::{to_grid, Queries};

/// Where a ray met the terrain ([`TerrainRenderer::raycast`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct RayHit {
    /// Distance from the ray's origin along its direction, metres.
    pub distance: f64,
    /// The point hit, world metres: origin + distance x the unit direction.
    pub point: [f64; 3],
    /// The surface's upward unit normal there (z > 0).
    pub normal: [f64; 3],
}

fn unavailable(reason: &str) -> Error {
    Error::Invalid {
        what: "the terrain's exact queries".into(),
        reason: reason.to_owned(),
    }
}

impl TerrainRenderer {
    /// The data's height at world (x, y), metres: the bilinear interpolation of the terrain's samples
    /// at full resolution (a package's level 0, decoded bit-exactly; within the bake's stated error of
    /// the source file), or None outside the terrain.
    ///
    /// Cost: a held terrain reads four samples (tens of nanoseconds). A streamed one reads them through
    /// a small tile cache of its own, allocated with the renderer from the profile's CPU budget (its
    /// query share): a query whose tile is resident costs about as much; a miss decodes the tile and the
    /// coarser tiles its prediction reads (a few hundred microseconds for a 64^2 tile, a few
    /// milliseconds when those must be decoded too). Nothing is allocated per query. Errors: a damaged
    /// tile ([`Error::Format`]), or a profile whose query share cannot hold the package's decode
    /// ([`Error::Invalid`]).
    pub fn height_at(&mut self, x: f64, y: f64) -> Result<Option<f64>> {
        let grid = &self.stand_in;
        match &mut self.queries {
            Queries::Resident(ranges) => {
                let (u, v) = grid.world_to_grid(x, y);
                query::height(&mut ResidentGrid { grid, ranges }, u, v)
            }
            Queries::Streamed { tiles, frame } => {
                let (u, v) = to_grid(*frame, x, y);
                tiles.begin();
                query::height(tiles.as_mut(), u, v)
            }
            Queries::Unavailable(reason) => Err(unavailable(reason)),
        }
    }

    /// The first point where the ray from `origin` along `dir` (world metres; any length, not zero) meets
    /// the data's surface (the bilinear surface [`TerrainRenderer::height_at`] reads), within `max_dist`
    /// metres (infinite: no limit), with the surface's normal there; None if it meets none. A ray from
    /// below the surface hits where it comes out.
    ///
    /// Cost: the ray is clipped to the terrain's box and walked over its tiles (64^2 samples), skipping
    /// those whose height range it passes above or below, then over the cells of the others, which it
    /// intersects exactly: a few microseconds when the tiles it crosses are resident (a held terrain, or
    /// a streamed one's query cache after earlier queries nearby). A streamed terrain decodes the tiles
    /// it needs that are not (as [`TerrainRenderer::height_at`]); a tile's height range is kept once it
    /// was decoded, so a later ray over it skips it without decoding. Nothing is allocated per query.
    /// Errors: a direction that is zero or not finite, an origin that is not finite, a negative or NaN
    /// `max_dist` ([`Error::Invalid`]), and those of [`TerrainRenderer::height_at`].
    pub fn raycast(
        &mut self,
        origin: [f64; 3],
        dir: [f64; 3],
        max_dist: f64,
    ) -> Result<Option<RayHit>> {
        let (o, d) = (DVec3::from(origin), DVec3::from(dir));
        let bad = |reason: String| Error::Invalid {
            what: "TerrainRenderer::raycast".into(),
            reason,
        };
        if !o.is_finite() {
            return Err(bad(format!("origin {origin:?} is not finite")));
        }
        let len = d.length();
        if !(d.is_finite() && len > 0.0 && len.is_finite()) {
            return Err(bad(format!("direction {dir:?} is zero or not finite")));
        }
        if max_dist.is_nan() || max_dist < 0.0 {
            return Err(bad(format!("max_dist {max_dist} is negative or NaN")));
        }
        let n = d / len;
        let grid_hm = &self.stand_in;
        let (frame, hit) = match &mut self.queries {
            Queries::Resident(ranges) => {
                let frame = (
                    grid_hm.origin(),
                    f64::from(grid_hm.spacing()),
                    grid_hm.height(),
                );
                let ray = grid_ray(frame, o, n, max_dist);
                let hit = ray::raycast(
                    &mut ResidentGrid {
                        grid: grid_hm,
                        ranges,
                    },
                    &ray,
                )?;
                (frame, hit)
            }
            Queries::Streamed { tiles, frame } => {
                tiles.begin();
                let ray = grid_ray(*frame, o, n, max_dist);
                (*frame, ray::raycast(tiles.as_mut(), &ray)?)
            }
            Queries::Unavailable(reason) => return Err(unavailable(reason)),
        };
        Ok(hit.map(|h| world_hit(frame, o, n, &h)))
    }

    /// The height of the surface drawn in the last prepared frame at world (x, y), metres: the level
    /// each block, pool cell or stitched unit there was drawn at (the highest where pieces meet), as the
    /// vertex shader places it, with distance LOD's transition morph in each ring's outer tenth; None
    /// where nothing was drawn, or before the first frame. A streamed terrain answers where the rings or
    /// their tile cache hold the samples (it decodes nothing; None otherwise).
    ///
    /// Cost: a pass over the frame's draw list (a few hundred entries) and a few sample reads; nothing
    /// is allocated.
    pub fn drawn_height_at(&self, x: f64, y: f64) -> Option<f64> {
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        let (u, v) = self.clipmap.eye_lattice(DVec3::new(x, y, 0.0));
        match crate::plan::drawn::drawn_height(
            &self.clipmap,
            &self.plan,
            self.block_quads,
            u,
            v,
        ) {
            crate::plan::drawn::Drawn::Height(h) => Some(h),
            _ => None,
        }
    }

    /// Bytes the exact queries hold beside the terrain: a streamed terrain's query cache (within the
    /// profile's CPU budget) or a held one's tile ranges.
    pub fn query_bytes(&self) -> u64 {
        self.queries.bytes()
    }
}

/// The world ray from `o` along unit `n` up to `max_dist` in grid units of `frame`.
fn grid_ray(frame: ((f64, f64), f64, u32), o: DVec3, n: DVec3, max_dist: f64) -> GridRay {
    let (u, v) = to_grid(frame, o.x, o.y);
    let s = frame.1;
    GridRay {
        o: [u, v, o.z],
        d: [n.x / s, -n.y / s, n.z],
        t: (0.0, max_dist),
    }
}

/// A grid hit in world terms.
fn world_hit(frame: ((f64, f64), f64, u32), o: DVec3, n: DVec3, h: &GridHit) -> RayHit {
    let s = frame.1;
    let p = o + n * h.t;
    // d height / d x = (d / d u) / s; rows run south, so d / d y = -(d / d v) / s.
    let normal = DVec3::new(-h.slope.0 / s, h.slope.1 / s, 1.0).normalize();
    RayHit {
        distance: h.t,
        point: p.to_array(),
        normal: normal.to_array(),
    }
}
