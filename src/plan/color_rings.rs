//! Stage 2, the plan: the colour clipmap of draped imagery (GC section 3's "additional images", at their
//! own resolution). Ring l holds up to `ring x ring` texels of pyramid level l (texel spacing
//! 2^l times the image's) around the viewer, at toroidal addresses (texel (i, j) at (i mod ring,
//! j mod ring), so the sampler's repeat mode wraps it). Each frame the rings move toward the viewer,
//! coarse to fine, writing only the texels that enter (the L-shaped, or at most four-sided, difference
//! of the new region and the held one) under `[imagery]`'s per-frame texel and tile budgets; a level whose
//! writes do not finish keeps drawing the texels it still holds (their region), and finer levels wait.
//! Nothing allocates after [`ColorRings::new`]: the staging of the frame's texels is sized once, the
//! upload list and the levels are fixed-capacity. A ring's region is clipped to its level's image, so
//! the coarsest level (at most 256 texels a side) is held whole; outside the image nothing is drawn
//! from the rings (the shader keeps the terrain's own albedo).
//!
//! In a block format ([`ColorFormat`]: BC1, ETC2 RGB8) every write is whole 4 x 4 blocks: regions start
//! at multiples of 4 (the [`SNAP`], and the clamp inside the image rounded up to it), a band of rows is
//! a multiple of 4 rows but at its rectangle's end, the ring, the tiles and the wrap are multiples of 4,
//! and a piece ending at the image's edge is padded to whole blocks (the tile's last column and row
//! repeated, written into ring texels outside the held region, never sampled). The texel budget is
//! charged the padded texels; the staging holds blocks (0.5 byte a texel).

use bytemuck::Zeroable as _;

use crate::hash::Hash64;
use crate::package::color_blocks::{self, BlockEncoder, ColorFormat};
use crate::package::imagery::ImageryPackage;
use crate::package::imagery_cache::ImageryCache;
use crate::profile::{ImageryBudget, MAX_COLOR_LEVELS};
use crate::{Error, Result};

/// Most texture writes a frame plans: a level's region difference is at most four rectangles, each cut
/// by tiles and by the ring's wrap.
pub const MAX_COLOR_UPLOADS: usize = 256;
/// Ring regions start at multiples of this many texels, so a slow camera moves a ring in steps of
/// whole tile-aligned strips instead of one column a frame.
pub const SNAP: i64 = 16;
/// Frames over which a level that has just become whole fades in (its blend weight rises linearly).
pub const FADE_FRAMES: u64 = 16;
/// Texels by which [`ColorLevelView::inner`] moves a side of the held region that lies on the level's
/// edge: past any pixel that the ring's weight could reach (the shader's border fade is 4 texels).
pub const IMAGE_EDGE_OUT: f64 = 65536.0;
/// Capacity of the fixed collections of levels.
const LEVELS: usize = MAX_COLOR_LEVELS as usize;

/// A rectangle of texels of one level: columns `x0 .. x0 + w`, rows `y0 .. y0 + h` (row 0 north).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct TexRect {
    /// First column.
    pub x0: i64,
    /// First row.
    pub y0: i64,
    /// Columns.
    pub w: i64,
    /// Rows.
    pub h: i64,
}

impl TexRect {
    /// Whether it holds no texel.
    pub fn is_empty(&self) -> bool {
        self.w <= 0 || self.h <= 0
    }

    /// The texels of both (empty where they share none).
    pub fn intersect(&self, o: &TexRect) -> TexRect {
        let x0 = self.x0.max(o.x0);
        let y0 = self.y0.max(o.y0);
        let x1 = (self.x0 + self.w).min(o.x0 + o.w);
        let y1 = (self.y0 + self.h).min(o.y0 + o.h);
        if x1 <= x0 || y1 <= y0 {
            TexRect::default()
        } else {
            TexRect {
                x0,
                y0,
                w: x1 - x0,
                h: y1 - y0,
            }
        }
    }

    /// Texels.
    pub fn texels(&self) -> u64 {
        if self.is_empty() {
            0
        } else {
            self.w.unsigned_abs() * self.h.unsigned_abs()
        }
    }

    /// `self` minus `hole` (a rectangle inside it, or empty): at most four rectangles, the rows above
    /// and below the hole across the whole width, then the columns beside it.
    fn minus(&self, hole: &TexRect) -> heapless::Vec<TexRect, 4> {
        let mut out = heapless::Vec::new();
        let h = self.intersect(hole);
        if h.is_empty() {
            let _ = out.push(*self);
            return out;
        }
        let parts = [
            TexRect { x0: self.x0, y0: self.y0, w: self.w, h: h.y0 - self.y0 },
            TexRect { x0: self.x0, y0: h.y0 + h.h, w: self.w, h: self.y0 + self.h - h.y0 - h.h },
            TexRect { x0: self.x0, y0: h.y0, w: h.x0 - self.x0, h: h.h },
            TexRect { x0: h.x0 + h.w, y0: h.y0, w: self.x0 + self.w - h.x0 - h.w, h: h.h },
        ];
        for p in parts.into_iter().filter(|p| !p.is_empty()) {
            let _ = out.push(p);
        }
        out
    }
}

/// One texture write of the frame: `w x h` texels at (x, y) of ring `level`'s layer, from `offset`
/// bytes into [`ColorRings::staging`], in the rings' [`ColorFormat`]: RGBA8 rows packed (`4 w` bytes a
/// row), or whole blocks row-major (x, y, w and h multiples of 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ColorUpload {
    /// Ring (layer).
    pub level: u32,
    /// Texture column.
    pub x: u32,
    /// Texture row.
    pub y: u32,
    /// Columns.
    pub w: u32,
    /// Rows.
    pub h: u32,
    /// Byte offset of its first texel in the staging.
    pub offset: usize,
}

/// A rectangle still to write, and how far its writing got: tiles row-major over it, rows within the
/// current tile's part.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Pending {
    rect: TexRect,
    tile: u32,
    row: i64,
}

/// One ring's state.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct Level {
    /// Texels the ring holds, all written (within `target`).
    held: TexRect,
    /// The region the ring moves to.
    target: TexRect,
    /// What of `target` minus `held` is still to write.
    pending: heapless::Vec<Pending, 4>,
    /// The frame `held` last became the whole target from empty (the fade-in starts there).
    whole_since: Option<u64>,
}

/// What a frame's colour update did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ColorFrameStats {
    /// Texels written into the rings.
    pub texels: u64,
    /// Texture writes.
    pub uploads: u32,
    /// Tiles decoded.
    pub tiles_decoded: u32,
    /// Rings whose region is not yet the one around the viewer.
    pub stale_levels: u32,
    /// The frame's hash: the rings' regions, the writes and the bits of every texel written.
    pub hash: u64,
}

/// What the shader needs of one ring this frame (see `shaders_gles/imagery.wgsl`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ColorLevelView {
    /// The eye's position in the level's texels (column, row), modulo the ring: the texture
    /// coordinate of the eye, times the ring.
    pub eye_mod: [f32; 2],
    /// The held region relative to the eye, in texels: (x0, y0, x1, y1); empty (x1 <= x0) when none.
    /// The shader's taps are clamped inside it (half a texel in, as a clamp-to-edge sampler reads).
    pub held: [f32; 4],
    /// The region over which the ring's weight is computed, relative to the eye, in texels: `held`, with
    /// each side that lies on the level's own edge moved [`IMAGE_EDGE_OUT`] texels out. A ring hands a
    /// pixel to the next coarser ring over its border inside the image, never at the image's edge
    /// (where there is no coarser texel to hand it to: the terrain's colour showed through the outer 4.5
    /// texels of the coarsest ring); the image's edge is cut by [`ImageryUniform::image`].
    pub inner: [f32; 4],
    /// Texels per metre, (east-west, north-south).
    pub per_m: [f32; 2],
    /// The level's blend weight, rising from 0 to 1 over [`FADE_FRAMES`] after it became whole.
    pub fade: f32,
}

/// The imagery program's uniform (`Imagery` in `shaders_gles/imagery.wgsl`): per ring (finest first) the
/// eye's texel modulo the ring and the texels per metre, the held region relative to the eye, the
/// fade-in weight, the region of the ring's weight; then the rings in use and the ring side, and the
/// image's extent relative to the eye.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ImageryUniform {
    /// Per ring: `eye` (xy, and texels per metre in zw), `held`, `fade` (x), `inner`
    /// ([`ColorLevelView`]).
    pub levels: [[[f32; 4]; 4]; LEVELS],
    /// x: rings in use; y: the ring side; zw: unused.
    pub info: [i32; 4],
    /// The image's extent relative to the eye, metres: (west, south, east, north) minus the eye's
    /// (x, y, x, y). Outside it the terrain keeps its own colour, whatever a coarser level's texels
    /// (which reach past an odd side) hold.
    pub image: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<ImageryUniform>() == LEVELS * 64 + 32);

/// The colour clipmap: rings, tile cache, the frame's writes.
#[derive(Debug)]
pub struct ColorRings {
    cache: ImageryCache,
    format: ColorFormat,
    budget: ImageryBudget,
    levels: heapless::Vec<Level, LEVELS>,
    staging: Vec<u8>,
    uploads: heapless::Vec<ColorUpload, MAX_COLOR_UPLOADS>,
    frame: u64,
    stats: ColorFrameStats,
}

impl ColorRings {
    /// Rings for `package` under `budget` (validated): as many as the profile's levels and the
    /// pyramid's, the tile cache of `budget.cache_bytes` and the staging of `texels_per_frame` RGBA8
    /// texels, all allocated now.
    pub fn new(package: ImageryPackage, budget: &ImageryBudget) -> Result<Self> {
        Self::with_format(package, budget, ColorFormat::Rgba8)
    }

    /// [`ColorRings::new`] in `format`: a block format's tiles are encoded when the cache decodes them,
    /// and its staging holds `texels_per_frame / 2` bytes of blocks. A block format that the budget
    /// cannot hold (a tile cache under [`ImageryCache::min_bytes`], or fewer than four rows of a tile a
    /// frame) falls back to RGBA8: [`ColorRings::format`] says which the rings took.
    pub fn with_format(
        package: ImageryPackage,
        budget: &ImageryBudget,
        format: ColorFormat,
    ) -> Result<Self> {
        budget.validate("imagery budget")?;
        let tile = package.header().tile;
        let format = if format.is_block()
            && (budget.texels_per_frame < 4 * tile
                || !tile.is_multiple_of(4)
                || budget.cache_bytes < ImageryCache::min_bytes(&package, format))
        {
            ColorFormat::Rgba8
        } else {
            format
        };
        let count = package.header().levels.len().min(budget.levels as usize);
        let cache = ImageryCache::with_format(package, budget.cache_bytes, format)?;
        let mut levels = heapless::Vec::new();
        for _ in 0..count {
            levels.push(Level::default()).map_err(|_| Error::Capacity {
                what: "colour rings",
                capacity: LEVELS,
            })?;
        }
        let staging = usize::try_from(
            u64::from(budget.texels_per_frame) * format.bytes_per_16_texels() / 16,
        )
        .unwrap_or(usize::MAX);
        Ok(Self {
            cache,
            format,
            budget: *budget,
            levels,
            staging: vec![0; staging],
            uploads: heapless::Vec::new(),
            frame: 0,
            stats: ColorFrameStats::default(),
        })
    }

    /// Rings kept (at most the profile's `imagery.levels`).
    pub fn level_count(&self) -> u32 {
        u32::try_from(self.levels.len()).unwrap_or(u32::MAX)
    }

    /// The imagery package.
    pub fn package(&self) -> &ImageryPackage {
        self.cache.package()
    }

    /// The tile cache.
    pub fn cache(&self) -> &ImageryCache {
        &self.cache
    }

    /// Bytes of CPU memory held: the tile cache and the staging.
    pub fn cpu_bytes(&self) -> u64 {
        self.cache.bytes() + self.staging.len() as u64
    }

    /// The frame's writes, in order.
    pub fn uploads(&self) -> &[ColorUpload] {
        &self.uploads
    }

    /// The rings' texel format.
    pub fn format(&self) -> ColorFormat {
        self.format
    }

    /// The frame's texels (RGBA8, or blocks), as the uploads address them.
    pub fn staging(&self) -> &[u8] {
        &self.staging
    }

    /// The last frame's statistics.
    pub fn stats(&self) -> ColorFrameStats {
        self.stats
    }

    /// The region ring `level` should hold with the eye at texel (cx, cy) of that level: a `ring`
    /// square centred there, snapped to [`SNAP`], moved inside the level's image where it fits and
    /// clipped to it.
    fn want(&self, level: usize, cx: i64, cy: i64) -> TexRect {
        let ring = i64::from(self.budget.ring);
        let l = &self.package().header().levels[level];
        let (w, h) = (i64::from(l.width), i64::from(l.height));
        // Kept inside the level where it fits (a level no larger than the ring is held whole and never
        // moves), so that a ring near the image's edge holds as much of it as it can.
        let inside = |c: i64| (c - ring / 2).div_euclid(SNAP) * SNAP;
        // In a block format the clamp is rounded up to whole blocks: the region may then end at the
        // image's edge less than `ring` texels on, its padded blocks still inside the ring's span.
        let b = i64::from(self.format.block());
        let fit = |v: i64, size: i64| {
            if size <= ring {
                0
            } else {
                v.clamp(0, (size - ring + b - 1).div_euclid(b) * b)
            }
        };
        let x0 = fit(inside(cx), w);
        let y0 = fit(inside(cy), h);
        TexRect { x0, y0, w: ring, h: ring }.intersect(&TexRect { x0: 0, y0: 0, w, h })
    }

    /// The eye's position in texels of `level` (column, row from the north-west corner), exact in f64.
    fn eye_texel(&self, level: usize, x: f64, y: f64) -> (f64, f64) {
        let h = self.package().header();
        let (sx, sy) = h.texel_spacing(level);
        ((x - h.extent.west) / sx, (h.extent.north - y) / sy)
    }

    /// Moves the rings toward the eye at world (x, y), coarse to fine, writing the texels that enter
    /// under the profile's per-frame budgets; the writes are then in [`ColorRings::uploads`].
    pub fn update(&mut self, x: f64, y: f64) -> Result<ColorFrameStats> {
        if !(x.is_finite() && y.is_finite()) {
            return Err(Error::camera(format!("imagery: eye ({x}, {y}) is not finite")));
        }
        self.frame += 1;
        self.cache.begin_frame();
        self.uploads.clear();
        let mut texels_left = u64::from(self.budget.texels_per_frame);
        let mut tiles_left = self.budget.tiles_per_frame;
        let mut staged = 0usize;
        let mut stale = 0u32;
        let mut blocked = false;
        for level in (0..self.levels.len()).rev() {
            let (ex, ey) = self.eye_texel(level, x, y);
            // Within the lattice: a coordinate past 2^52 texels has no integer part to snap.
            if !(ex.abs() < 4.5e15 && ey.abs() < 4.5e15) {
                return Err(Error::camera(format!("imagery: eye ({x}, {y}) is beyond the lattice")));
            }
            #[expect(clippy::cast_possible_truncation, reason = "checked above to fit i64")]
            let want = self.want(level, ex.floor() as i64, ey.floor() as i64);
            let state = &mut self.levels[level];
            // A ring still writing toward its target keeps it while the new one shares three quarters
            // of it (else a moving eye would restart a large fill every frame and it would never end).
            let far = want.intersect(&state.target).texels() * 4 < state.target.texels() * 3;
            if want != state.target && (state.pending.is_empty() || far) {
                state.held = state.held.intersect(&want);
                state.target = want;
                state.pending.clear();
                for rect in want.minus(&state.held) {
                    let _ = state.pending.push(Pending { rect, tile: 0, row: 0 });
                }
                if state.held.is_empty() {
                    state.whole_since = None;
                }
            }
            if !state.pending.is_empty() && !blocked {
                self.write_level(level, &mut texels_left, &mut tiles_left, &mut staged)?;
            }
            let state = &mut self.levels[level];
            if state.pending.is_empty() {
                state.held = state.target;
                if state.whole_since.is_none() && !state.held.is_empty() {
                    state.whole_since = Some(self.frame);
                }
            } else {
                stale += 1;
                // Coarse to fine: a level that did not finish keeps the finer ones waiting.
                blocked = true;
            }
        }
        self.stats = ColorFrameStats {
            texels: u64::from(self.budget.texels_per_frame) - texels_left,
            uploads: u32::try_from(self.uploads.len()).unwrap_or(u32::MAX),
            tiles_decoded: self.budget.tiles_per_frame - tiles_left,
            stale_levels: stale,
            hash: self.hash(staged),
        };
        Ok(self.stats)
    }

    /// Writes what it can of `level`'s pending rectangles: tile by tile, a band of rows at a time,
    /// until a budget, the staging or the upload list runs out.
    fn write_level(
        &mut self,
        level: usize,
        texels_left: &mut u64,
        tiles_left: &mut u32,
        staged: &mut usize,
    ) -> Result<()> {
        let tile = i64::from(self.package().header().tile);
        let ring = i64::from(self.budget.ring);
        while let Some(p) = self.levels[level].pending.first().copied() {
            let r = p.rect;
            let (tx0, ty0) = (r.x0.div_euclid(tile), r.y0.div_euclid(tile));
            let tiles_x = (r.x0 + r.w - 1).div_euclid(tile) - tx0 + 1;
            let tiles_y = (r.y0 + r.h - 1).div_euclid(tile) - ty0 + 1;
            let (mut t, mut row) = (i64::from(p.tile), p.row);
            while t < tiles_x * tiles_y {
                let (tx, ty) = (tx0 + t % tiles_x, ty0 + t / tiles_x);
                let part = r.intersect(&TexRect { x0: tx * tile, y0: ty * tile, w: tile, h: tile });
                // Padded to whole blocks (RGBA8: as they are); a band short of the part's end is
                // whole block rows.
                let b = i64::from(self.format.block());
                let pad = |v: i64| (v + b - 1).div_euclid(b) * b;
                let rows_fit = i64::try_from(*texels_left / pad(part.w).unsigned_abs().max(1)).unwrap_or(i64::MAX);
                let mut rows = (part.h - row).min(rows_fit);
                if rows < part.h - row {
                    rows = rows.div_euclid(b) * b;
                }
                let charged = pad(part.w) * pad(rows);
                let bytes = usize::try_from(
                    self.format.bytes(u32::try_from(part.w).unwrap_or(0), u32::try_from(rows).unwrap_or(0)),
                )
                .unwrap_or(usize::MAX);
                let room = self.uploads.capacity() - self.uploads.len() >= 4
                    && *staged + bytes <= self.staging.len();
                if rows <= 0 || !room {
                    self.save(level, t, row);
                    return Ok(());
                }
                let (ux, uy) = (
                    u32::try_from(tx).unwrap_or(u32::MAX),
                    u32::try_from(ty).unwrap_or(u32::MAX),
                );
                // A resident tile costs nothing; each decode (a residual tile's parent's too) takes one
                // of the frame's tiles.
                let mut decode = u64::MAX;
                let resident = self.cache.fetch_counted(level, ux, uy, &mut decode, tiles_left)?;
                let Some((tw, _, texels)) = resident else {
                    self.save(level, t, row);
                    return Ok(());
                };
                // Copy rows [row, row + rows) of the part, cut at the ring's wrap.
                let band = TexRect { x0: part.x0, y0: part.y0 + row, w: part.w, h: rows };
                for piece in wrap_pieces(&band, ring) {
                    let offset = *staged;
                    let (upload, n) =
                        stage_piece(self.format, level, texels, tw, (tx * tile, ty * tile), &piece, ring, &mut self.staging[offset..]);
                    *staged += n;
                    let _ = self.uploads.push(ColorUpload { offset, ..upload });
                }
                *texels_left -= charged.unsigned_abs();
                row += rows;
                if row >= part.h {
                    t += 1;
                    row = 0;
                }
            }
            self.levels[level].pending.remove(0);
        }
        Ok(())
    }

    /// Records how far `level`'s first pending rectangle got.
    fn save(&mut self, level: usize, tile: i64, row: i64) {
        if let Some(p) = self.levels[level].pending.first_mut() {
            p.tile = u32::try_from(tile).unwrap_or(0);
            p.row = row;
        }
    }

    /// The frame's hash: frame, each ring's held and target regions, the writes, and the bits of the
    /// first `staged` bytes of the staging.
    fn hash(&self, staged: usize) -> u64 {
        let mut h = Hash64::new();
        h.write_u64(self.frame);
        for l in &self.levels {
            for r in [l.held, l.target] {
                for v in [r.x0, r.y0, r.w, r.h] {
                    h.write_u64(v as u64);
                }
            }
        }
        for u in &self.uploads {
            for v in [u.level, u.x, u.y, u.w, u.h] {
                h.write_u64(u64::from(v));
            }
        }
        h.write_bytes(&self.staging[..staged]);
        h.finish()
    }

    /// What the shader needs of each ring with the eye at world (x, y) (unused rings empty).
    pub fn views(&self, x: f64, y: f64) -> [ColorLevelView; LEVELS] {
        let none = ColorLevelView {
            held: [0.0, 0.0, -1.0, -1.0],
            inner: [0.0, 0.0, -1.0, -1.0],
            ..ColorLevelView::default()
        };
        let mut out = [none; LEVELS];
        let ring = f64::from(self.budget.ring);
        for (level, (l, v)) in self.levels.iter().zip(out.iter_mut()).enumerate() {
            let (ex, ey) = self.eye_texel(level, x, y);
            let (sx, sy) = self.package().header().texel_spacing(level);
            let held = l.held;
            let size = &self.package().header().levels[level];
            // A side on the level's own edge: the image's edge, where the ring's weight stays whole.
            let out_at = |on_edge: bool| if on_edge { IMAGE_EDGE_OUT } else { 0.0 };
            #[expect(clippy::cast_possible_truncation, reason = "f32 uniforms, near the eye")]
            {
                v.eye_mod = [ex.rem_euclid(ring) as f32, ey.rem_euclid(ring) as f32];
                v.per_m = [(1.0 / sx) as f32, (1.0 / sy) as f32];
                v.held = if held.is_empty() {
                    [0.0, 0.0, -1.0, -1.0]
                } else {
                    [
                        (held.x0 as f64 - ex) as f32,
                        (held.y0 as f64 - ey) as f32,
                        ((held.x0 + held.w) as f64 - ex) as f32,
                        ((held.y0 + held.h) as f64 - ey) as f32,
                    ]
                };
                v.inner = if held.is_empty() {
                    v.held
                } else {
                    [
                        (held.x0 as f64 - ex - out_at(held.x0 <= 0)) as f32,
                        (held.y0 as f64 - ey - out_at(held.y0 <= 0)) as f32,
                        ((held.x0 + held.w) as f64 - ex
                            + out_at(held.x0 + held.w >= i64::from(size.width)))
                            as f32,
                        ((held.y0 + held.h) as f64 - ey
                            + out_at(held.y0 + held.h >= i64::from(size.height)))
                            as f32,
                    ]
                };
            }
            v.fade = match l.whole_since {
                Some(f) => {
                    #[expect(clippy::cast_precision_loss, reason = "a count of at most FADE_FRAMES")]
                    let t = (self.frame - f + 1).min(FADE_FRAMES) as f32 / FADE_FRAMES as f32;
                    t
                }
                None => 0.0,
            };
        }
        out
    }

    /// The uniform of the imagery program with the eye at world (x, y): [`ColorRings::views`] packed.
    pub fn uniform(&self, x: f64, y: f64) -> ImageryUniform {
        let mut u = ImageryUniform::zeroed();
        for (dst, v) in u.levels.iter_mut().zip(self.views(x, y)) {
            *dst = [
                [v.eye_mod[0], v.eye_mod[1], v.per_m[0], v.per_m[1]],
                v.held,
                [v.fade, 0.0, 0.0, 0.0],
                v.inner,
            ];
        }
        let e = self.package().header().extent;
        #[expect(clippy::cast_possible_truncation, reason = "f32 uniforms, relative to the eye")]
        {
            u.image = [
                (e.west - x) as f32,
                (e.south - y) as f32,
                (e.east - x) as f32,
                (e.north - y) as f32,
            ];
        }
        u.info = [
            i32::try_from(self.levels.len()).unwrap_or(0),
            i32::try_from(self.budget.ring).unwrap_or(0),
            0,
            0,
        ];
        u
    }

    /// Every texel the rings' texture holds, for a texture made again after a lost device
    /// (`TerrainRenderer::rebuild`): each level's held region, and what its unfinished write has written
    /// (the tiles before its first pending rectangle's current one, and that tile's rows before its
    /// current row). Each piece goes to `write` as an upload in the rings' format, in ring coordinates. The
    /// tiles are decoded from the package into buffers of this call, not through the tile cache, so the
    /// rings' state and the cache's, which the next frames depend on, are unchanged: those frames are
    /// the same as without the loss. Allocates (a tile and a piece, once): it runs once per rebuild.
    pub fn restore(&self, mut write: impl FnMut(&ColorUpload, &[u8]) -> Result<()>) -> Result<()> {
        let package = self.cache.package();
        let tile = i64::from(package.header().tile);
        let ring = i64::from(self.budget.ring);
        let side = usize::try_from(tile).unwrap_or(0);
        let t = package.header().tile;
        let mut rgb = vec![0u8; side * side * 3];
        let mut parent = vec![0u8; side * side * 3];
        let block_bytes = if self.format.is_block() { self.format.bytes(t, t) } else { 0 };
        let mut blocks = vec![0u8; usize::try_from(block_bytes).unwrap_or(0)];
        let mut encoder = BlockEncoder::new(self.format, t);
        let mut out = vec![0u8; usize::try_from(self.format.bytes(t, t).max(4 * u64::from(t) * u64::from(t))).unwrap_or(0)];
        for (level, l) in self.levels.iter().enumerate() {
            // (rectangle, tiles written whole, rows of the next tile written)
            let mut parts: heapless::Vec<(TexRect, i64, i64), 2> = heapless::Vec::new();
            let _ = parts.push((l.held, i64::MAX, 0));
            if let Some(p) = l.pending.first() {
                let _ = parts.push((p.rect, i64::from(p.tile), p.row));
            }
            for (r, whole, rows_next) in parts {
                if r.is_empty() {
                    continue;
                }
                let (tx0, ty0) = (r.x0.div_euclid(tile), r.y0.div_euclid(tile));
                let tiles_x = (r.x0 + r.w - 1).div_euclid(tile) - tx0 + 1;
                let tiles_y = (r.y0 + r.h - 1).div_euclid(tile) - ty0 + 1;
                for t in 0..(tiles_x * tiles_y).min(whole.saturating_add(1)) {
                    let (tx, ty) = (tx0 + t % tiles_x, ty0 + t / tiles_x);
                    let part = r.intersect(&TexRect { x0: tx * tile, y0: ty * tile, w: tile, h: tile });
                    let rows = if t < whole { part.h } else { rows_next.min(part.h) };
                    if part.is_empty() || rows <= 0 {
                        continue;
                    }
                    let (tw, th) = package.decode_texels(
                        level,
                        u32::try_from(tx).unwrap_or(u32::MAX),
                        u32::try_from(ty).unwrap_or(u32::MAX),
                        &mut rgb,
                        &mut parent,
                    )?;
                    let data = if self.format.is_block() {
                        let n = usize::try_from(self.format.bytes(tw, th)).unwrap_or(0);
                        encoder.encode(&rgb, tw, th, &mut blocks[..n])?;
                        &blocks[..n]
                    } else {
                        &rgb[..]
                    };
                    let band = TexRect { x0: part.x0, y0: part.y0, w: part.w, h: rows };
                    for piece in wrap_pieces(&band, ring) {
                        let (upload, n) = stage_piece(self.format, level, data, tw, (tx * tile, ty * tile), &piece, ring, &mut out);
                        write(&upload, &out[..n])?;
                    }
                }
            }
        }
        Ok(())
    }

    /// The ring side, texels.
    pub fn ring(&self) -> u32 {
        self.budget.ring
    }

    /// The region ring `level` holds (empty when none), for tests and the twin.
    pub fn held(&self, level: usize) -> TexRect {
        self.levels.get(level).map_or_else(TexRect::default, |l| l.held)
    }
}

/// Stages `piece` (level texels, inside the tile at level texel `origin`, `tw` texels wide, held in the
/// cache's layout `data`) into `out` in `format`; the upload that writes it (offset 0) and its bytes.
#[expect(clippy::too_many_arguments, reason = "one piece's whole address: a private helper")]
fn stage_piece(
    format: ColorFormat,
    level: usize,
    data: &[u8],
    tw: u32,
    origin: (i64, i64),
    piece: &TexRect,
    ring: i64,
    out: &mut [u8],
) -> (ColorUpload, usize) {
    let b = i64::from(format.block());
    let pad = |v: i64| u32::try_from((v + b - 1).div_euclid(b) * b).unwrap_or(0);
    let local = (
        u32::try_from(piece.x0 - origin.0).unwrap_or(0),
        u32::try_from(piece.y0 - origin.1).unwrap_or(0),
        u32::try_from(piece.w).unwrap_or(0),
        u32::try_from(piece.h).unwrap_or(0),
    );
    let n = color_blocks::stage(format, data, tw, local, out);
    let upload = ColorUpload {
        level: u32::try_from(level).unwrap_or(u32::MAX),
        x: u32::try_from(piece.x0.rem_euclid(ring)).unwrap_or(0),
        y: u32::try_from(piece.y0.rem_euclid(ring)).unwrap_or(0),
        w: pad(piece.w),
        h: pad(piece.h),
        offset: 0,
    };
    (upload, n)
}

/// `r` cut where it crosses a multiple of `ring` (the ring's wrap), each way: at most four pieces (`r`
/// is at most `ring` a side).
fn wrap_pieces(r: &TexRect, ring: i64) -> heapless::Vec<TexRect, 4> {
    let mut out = heapless::Vec::new();
    let split = |a0: i64, n: i64| -> [(i64, i64); 2] {
        let first = (ring - a0.rem_euclid(ring)).min(n);
        [(a0, first), (a0 + first, n - first)]
    };
    for (y0, h) in split(r.y0, r.h) {
        for (x0, w) in split(r.x0, r.w) {
            if w > 0 && h > 0 {
                let _ = out.push(TexRect { x0, y0, w, h });
            }
        }
    }
    out
}
