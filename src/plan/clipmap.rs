//! Stage 2, the per-frame plan: the geometry clipmap on the CPU (Losasso & Hoppe 2004, "GC").
//!
//! [`Clipmap::new`] bakes the pyramid and allocates every ring; [`Clipmap::update`] then runs one frame
//! without allocating: desired regions from the eye, a budgeted coarse-to-fine update (GC section 5), the
//! fill from the pyramid or by synthesis (GC sections 4 and 8), active-region cropping and the frame record.
//!
//! Lattice conventions: sample (i, j) of level l sits at level-0 lattice point (i 2^l, j 2^l); i is the
//! column (east), j the row (south, like the heightmap's rows). Level-0 spacing is g_0 = data spacing /
//! 2^synth_levels, so data sample (u, v) is level-0 lattice point (u 2^s, v 2^s).

use glam::DVec3;

use crate::bake::pyramid::Pyramid;
use crate::package::{Package, TileCache};
use crate::plan::stream::HeightSource;

use crate::hash::Hash64;
use crate::plan::budget::{needed_samples, plan_level};
pub use crate::plan::constraints::ConstraintViolation;
use crate::plan::frame::{Frame, LevelFrame, LevelState, Rect, MAX_LEVELS};
pub use crate::plan::morph::morph_alpha;
pub use crate::plan::ring::Ring;
use crate::plan::synthesis::{extrapolate_sigmas, synthesize, NoiseTable};
use crate::plan::uploads::UploadStamps;
use crate::{Error, Param, Result};
use crate::source::Heightmap;
use crate::profile::Profile;

mod data;

/// Options beyond the profile.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClipmapOptions {
    /// Rings finer than the data, synthesised (GC section 8); 0 by default. Must be below the level count.
    pub synth_levels: u32,
}

/// The next clipmap's [`Clipmap::id`].
static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

/// The narrowest active region (vertices per side) still rendered; narrower cropped levels are disabled.
pub const MIN_ACTIVE: u32 = 5;

/// Largest |lattice coordinate| of an eye, 2^48 level-0 samples (2.8e15 m at 10 m spacing).
const MAX_LATTICE: f64 = (1u64 << 48) as f64;

/// The viewer-height rule: level l is disabled above 0.4 n g_l over the terrain (docs/design.md).
pub const HEIGHT_FACTOR: f64 = 0.4;

/// The geometry clipmap: pyramid, rings, clip regions and the last frame's record.
#[derive(Debug)]
pub struct Clipmap {
    /// This clipmap among all built in the process: what keys caches of its contents (never 0).
    id: u64,
    source: HeightSource,
    /// Samples decoded from the package in the last frame (0 for a resident pyramid).
    decoded: u32,
    /// A streamed package's mean slope, from its coarse level at construction (unused when resident).
    streamed_slope: f64,
    /// GC section 8's noise table, only when rings are synthesised (a scene without `synthesis` has none).
    noise: Option<NoiseTable>,
    /// Noise amplitude per synthesised ring (index l < synth_levels); 0 elsewhere.
    sigmas: [f32; MAX_LEVELS],
    rings: Vec<Ring>,
    /// Clip regions (valid data), per level.
    valid: [Rect; MAX_LEVELS],
    n: u32,
    size: u32,
    margin: u32,
    levels: u32,
    synth: u32,
    budget: u32,
    g0: f64,
    data_spacing: f64,
    data_rows: u32,
    /// The terrain's world origin ([`Heightmap::origin`]), subtracted in f64 before any lattice maths.
    origin: (f64, f64),
    frame: Frame,
    next_index: u64,
    /// Which frame last wrote each texel column and row ([`Clipmap::upload_stamps`]).
    stamps: UploadStamps,
    /// Samples the next update makes readable after the rings ([`Clipmap::request_samples`]).
    requests: heapless::Vec<(u32, Rect), { crate::profile::MAX_DETAIL_TILES as usize }>,
}

impl Clipmap {
    /// Bakes the pyramid and allocates every ring from the profile; the only place that allocates.
    pub fn new(terrain: &Heightmap, profile: &Profile, opts: ClipmapOptions) -> Result<Self> {
        let pyramid = Pyramid::build(terrain);
        let mut sigmas = [0.0f32; MAX_LEVELS];
        if opts.synth_levels > 0 {
            let stds = [pyramid.residual_std(0), pyramid.residual_std(1)];
            for (o, s) in sigmas
                .iter_mut()
                .zip(extrapolate_sigmas(&stds, opts.synth_levels))
            {
                *o = s;
            }
        }
        let geometry = (terrain.spacing(), terrain.height(), terrain.origin());
        Self::with_source(
            HeightSource::Resident(pyramid),
            geometry,
            sigmas,
            profile,
            opts,
        )
    }

    /// A clipmap streamed from a package: a tile cache allocated once from the profile's
    /// `budget.cpu_memory_bytes` (less the rings), decoding under the per-frame sample budget. No
    /// terrain-sized memory is allocated. Synthesised rings need the residual statistics of a resident
    /// pyramid and are refused.
    pub fn streamed(package: Package, profile: &Profile, opts: ClipmapOptions) -> Result<Self> {
        profile.validate(&profile.name)?;
        if opts.synth_levels > 0 {
            return Err(Error::param(
                Param::SynthLevels,
                "synthesised rings are not available on a streamed package",
            ));
        }
        let h = package.header();
        let tile = u64::from(h.tile) * u64::from(h.tile);
        if u64::from(profile.budget.update_samples_per_frame) < tile {
            return Err(Error::config(
                &profile.name,
                "budget.update_samples_per_frame",
                format!(
                    "{} samples cannot decode one {}-sample tile of {} in a frame",
                    profile.budget.update_samples_per_frame,
                    tile,
                    package.path().display()
                ),
            ));
        }
        let geometry = (h.spacing, h.height, h.origin);
        let coarse = package.coarse_heightmap(1 << 20)?;
        let slope = crate::shading::basic::mean_slope(
            coarse.heights(),
            coarse.width() as usize,
            f64::from(coarse.spacing()),
        );
        let cache = TileCache::new(package, profile.cpu_split().tile_cache, &profile.name)?;
        let source = HeightSource::Streamed(Box::new(cache));
        let mut clipmap = Self::with_source(source, geometry, [0.0; MAX_LEVELS], profile, opts)?;
        clipmap.streamed_slope = slope;
        Ok(clipmap)
    }

    /// The shared part of [`Clipmap::new`] and [`Clipmap::streamed`]: validation and the rings.
    fn with_source(
        source: HeightSource,
        (spacing, rows, origin): (f32, u32, (f64, f64)),
        sigmas: [f32; MAX_LEVELS],
        profile: &Profile,
        opts: ClipmapOptions,
    ) -> Result<Self> {
        profile.validate(&profile.name)?;
        let levels = profile.clipmap.levels;
        let size = profile.clip_size();
        if opts.synth_levels >= levels {
            return Err(Error::Invalid {
                what: "synth_levels".into(),
                reason: format!(
                    "{} synthesised rings leave no data ring among the profile's {levels}",
                    opts.synth_levels
                ),
            });
        }
        if profile.budget.update_samples_per_frame < size {
            return Err(Error::config(
                &profile.name,
                "budget.update_samples_per_frame",
                format!(
                    "{} is less than one ring row ({size} samples): no ring could ever be filled",
                    profile.budget.update_samples_per_frame
                ),
            ));
        }
        let texels = size as usize * size as usize;
        let rings = (0..levels).map(|_| Ring::new(size, texels)).collect();
        let data_spacing = f64::from(spacing);
        Ok(Self {
            source,
            decoded: 0,
            streamed_slope: 0.0,
            noise: (opts.synth_levels > 0).then(NoiseTable::default),
            sigmas,
            rings,
            valid: [Rect::EMPTY; MAX_LEVELS],
            n: profile.clipmap.n,
            size,
            margin: profile.clipmap.clip_margin,
            levels,
            synth: opts.synth_levels,
            budget: profile.budget.update_samples_per_frame,
            g0: data_spacing / f64::from(1u32 << opts.synth_levels),
            data_spacing,
            data_rows: rows,
            origin,
            frame: Frame::default(),
            next_index: 0,
            stamps: UploadStamps::new(levels, size),
            requests: heapless::Vec::new(),
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        })
    }

    /// This clipmap's identity among those built in the process (a key for caches of its contents, such
    /// as the planner's tile height ranges; never 0, never reused).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// World (x, y) of the terrain's south-west sample (`Heightmap::origin`), metres.
    pub fn origin(&self) -> (f64, f64) {
        self.origin
    }

    /// Level-0 grid spacing, metres.
    pub fn g0(&self) -> f64 {
        self.g0
    }

    /// Number of rings.
    pub fn levels(&self) -> u32 {
        self.levels
    }

    /// Vertices per active-region side, n.
    pub fn n(&self) -> u32 {
        self.n
    }

    /// Rings finer than the data.
    pub fn synth_levels(&self) -> u32 {
        self.synth
    }

    /// Whether synthesis exists at all: its noise table is made only for synthesised rings.
    pub fn has_synthesis(&self) -> bool {
        self.noise.is_some()
    }

    fn noise(&self) -> &NoiseTable {
        self.noise
            .as_ref()
            .expect("a synthesised ring has its noise table (synth_levels > 0)")
    }

    /// Which frame last wrote each texel column and row of every ring: the rectangles a plan uploads
    /// after skipped frames ([`UploadStamps::since`]).
    pub fn upload_stamps(&self) -> &UploadStamps {
        &self.stamps
    }

    /// The last frame's record.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// Ring `level`'s storage; panics past the coarsest level.
    pub fn ring(&self, level: u32) -> &Ring {
        &self.rings[level as usize]
    }

    /// The eye's position in level-0 lattice units (column east, row south), relative to the terrain's
    /// origin (subtracted first, in f64, so a far-placed terrain keeps its precision).
    pub fn eye_lattice(&self, eye: DVec3) -> (f64, f64) {
        let (u, v) = self.eye_grid(eye);
        let k = f64::from(1u32 << self.synth);
        (u * k, v * k)
    }

    /// The desired active region of `level` for an eye at level-0 lattice point `p`: n x n vertices, its
    /// corners on the coarser lattice (even coordinates), centred on the eye to within one coarse cell.
    ///
    /// x0 = 2 floor(p_l / 2) - (n - 1)/2 + 1 with p_l = p / 2^l: the eye lies in the middle two cells, and the
    /// finer level then sits m - 1 or m coarse cells from the coarser level's edge (m = (n + 1)/4), the
    /// nesting of GC section 3 with its one-cell L-shaped strip.
    pub fn desired_active(&self, level: u32, p: (f64, f64)) -> Rect {
        let scale = f64::from(1u32 << (level + 1));
        let half = i64::from((self.n - 1) / 2);
        #[expect(
            clippy::cast_possible_truncation,
            reason = "floor of a finite lattice coordinate within i64"
        )]
        let snap = |c: f64| 2 * (c / scale).floor() as i64 - half + 1;
        Rect {
            x0: snap(p.0),
            y0: snap(p.1),
            w: self.n,
            h: self.n,
        }
    }

    /// The desired clip region: `size x size` around the desired active region, `margin` samples to the
    /// west and north, `margin + 1` to the east and south (n + 1 + 2 margin is even, n odd).
    pub fn desired_clip(&self, active: &Rect) -> Rect {
        let m = i64::from(self.margin);
        Rect {
            x0: active.x0 - m,
            y0: active.y0 - m,
            w: self.size,
            h: self.size,
        }
    }

    /// The height of ring `level` at its lattice sample (i, j): a pure function, evaluated directly (no ring
    /// storage). This is the CPU twin every filled texel must equal bit for bit.
    pub fn sample(&self, level: u32, i: i64, j: i64) -> [f32; 2] {
        let coarse = |a: i64, b: i64| self.direct_z(level + 1, a, b);
        self.texel(level, i, j, &coarse)
    }

    fn direct_z(&self, level: u32, i: i64, j: i64) -> f32 {
        if level >= self.synth {
            self.source.at(level - self.synth, i, j)
        } else {
            let coarse = |a: i64, b: i64| self.direct_z(level + 1, a, b);
            synthesize(
                coarse,
                self.noise(),
                self.sigmas[level as usize],
                level,
                i,
                j,
            )
        }
    }

    /// (z, z_c) of `level` at (i, j), given the next coarser ring's z through `coarse`.
    #[inline]
    fn texel(&self, level: u32, i: i64, j: i64, coarse: &impl Fn(i64, i64) -> f32) -> [f32; 2] {
        let z = if level >= self.synth {
            self.source.at(level - self.synth, i, j)
        } else {
            synthesize(
                coarse,
                self.noise(),
                self.sigmas[level as usize],
                level,
                i,
                j,
            )
        };
        if level + 1 >= self.levels {
            return [z, z];
        }
        [z, coarse_surface(coarse, i, j)]
    }

    /// Samples still to write before every enabled-by-height level reaches its desired clip region for an
    /// eye at `eye`, with an unlimited budget (what [`Clipmap::update`] would write in total if the eye
    /// stayed there).
    pub fn pending_samples(&self, eye: DVec3) -> u64 {
        let p = self.eye_lattice(eye);
        let h = self.height_above_terrain(eye);
        (0..self.levels)
            .filter(|&l| self.height_enabled(l, h))
            .map(|l| {
                let d = self.desired_clip(&self.desired_active(l, p));
                needed_samples(&self.valid[l as usize], &d, self.size)
            })
            .sum()
    }

    /// The eye's height above the terrain (bilinear in the data, clamped at its edges), metres, >= 0.
    pub fn height_above_terrain(&self, eye: DVec3) -> f64 {
        let (u, v) = self.eye_grid(eye);
        (eye.z - self.source.ground(u, v)).max(0.0)
    }

    /// Height (m) of the surface the last frame draws under the eye's xy: the finest enabled level whose
    /// active region holds the eye, piecewise linear with the project's diagonal ((i, j)-(i+1, j+1)), before
    /// the morph. `None` when no level holds it.
    ///
    /// While the budget has filled only coarse rings, their smoothed surface can lie hundreds of metres
    /// above a steep valley floor: keep a camera above this, not only above the data, or it sees the
    /// surface's back faces.
    pub fn surface_height(&self, eye: DVec3) -> Option<f32> {
        let p = self.eye_lattice(eye);
        self.frame.levels.iter().enumerate().find_map(|(l, lf)| {
            let a = lf.active;
            let k = f64::from(1u32 << l);
            let (x, y) = (p.0 / k, p.1 / k);
            let (x0, y0) = (x.floor(), y.floor());
            #[expect(
                clippy::cast_possible_truncation,
                reason = "the eye is validated finite and its lattice range checked by update"
            )]
            let (i, j) = (x0 as i64, y0 as i64);
            let inside =
                !a.is_empty() && i >= a.x0 && j >= a.y0 && i + 1 < a.x1() && j + 1 < a.y1();
            if !inside {
                return None;
            }
            let ring = &self.rings[l];
            let z = |di: i64, dj: i64| f64::from(ring.get(i + di, j + dj)[0]);
            let (fx, fy) = (x - x0, y - y0);
            // The two triangles of quad (i, j) split along (i, j)-(i+1, j+1).
            let h = if fx >= fy {
                z(0, 0) + fx * (z(1, 0) - z(0, 0)) + fy * (z(1, 1) - z(1, 0))
            } else {
                z(0, 0) + fy * (z(0, 1) - z(0, 0)) + fx * (z(1, 1) - z(0, 1))
            };
            #[expect(clippy::cast_possible_truncation, reason = "a height in metres")]
            Some(h as f32)
        })
    }

    /// The eye in fractional data-grid units (column, row), as [`Heightmap::world_to_grid`].
    fn eye_grid(&self, eye: DVec3) -> (f64, f64) {
        let u = (eye.x - self.origin.0) / self.data_spacing;
        let v = f64::from(self.data_rows - 1) - (eye.y - self.origin.1) / self.data_spacing;
        (u, v)
    }

    /// The viewer-height rule; the coarsest level always stays, so something is always drawn (GPU Gems 2
    /// ch. 2 likewise keeps at least one level).
    fn height_enabled(&self, level: u32, h: f64) -> bool {
        level + 1 == self.levels
            || h <= HEIGHT_FACTOR * f64::from(self.n) * self.g0 * f64::from(1u32 << level)
    }

    /// Updates at a still eye until no level is stale and nothing is pending there, at most `max_frames`
    /// frames, each under the budget: the warm-up before a first frame (a camera placed, a teleport).
    /// Returns the frames run.
    pub fn fill_at(&mut self, eye: DVec3, max_frames: u32) -> Result<u32> {
        let mut frames = 0;
        while frames < max_frames {
            frames += 1;
            if self.update(eye)?.stale_levels == 0 && self.pending_samples(eye) == 0 {
                break;
            }
        }
        Ok(frames)
    }

    /// One frame: plan under the budget (coarse to fine), fill, crop, disable; allocation-free.
    pub fn update(&mut self, eye: DVec3) -> Result<&Frame> {
        if !eye.is_finite() {
            return Err(Error::camera(format!("eye position {eye} is not finite")));
        }
        let p = self.eye_lattice(eye);
        // Lattice coordinates stay far inside i64 (and doubled corners cannot overflow).
        if !(p.0.abs() < MAX_LATTICE && p.1.abs() < MAX_LATTICE) {
            return Err(Error::camera(format!(
                "eye position {eye} is too far from the terrain for the clipmap lattice"
            )));
        }
        let h = self.height_above_terrain(eye);
        let lv = self.levels as usize;

        let mut frame = std::mem::take(&mut self.frame);
        frame.levels.clear();
        frame.uploads.clear();
        frame.index = self.next_index;
        frame.budget = self.budget;
        let mut zsum = Hash64::new();
        let mut samples = [0u32; MAX_LEVELS];
        let mut complete = [false; MAX_LEVELS];
        let mut desired = [Rect::EMPTY; MAX_LEVELS];

        // GC section 5: walk coarse to fine; stop at the first level the budget cannot finish, so a coarse
        // level is never stale while a finer one is updated.
        let mut left = self.budget;
        let mut stopped = false;
        self.source.begin_frame();
        self.decoded = 0;
        for l in (0..self.levels).rev() {
            let li = l as usize;
            desired[li] = self.desired_active(l, p);
            if !self.height_enabled(l, h) {
                continue;
            }
            let d = self.desired_clip(&desired[li]);
            if stopped {
                complete[li] = self.valid[li] == d;
                continue;
            }
            let mut plan = plan_level(l, &self.valid[li], &d, self.size, left);
            // Streamed: first decode what the bands read, charged to the same budget; a level not resident
            // yet is stale like an overrun (GC sections 5 and 7). The fill is then planned in what is left.
            let mut spare = u64::from(left);
            let k = l.saturating_sub(self.synth);
            let mut ready = self.source.ensure_bands(k, &plan.bands, &mut spare)?;
            let spent = left - u32::try_from(spare).expect("at most the budget left");
            if spent > 0 && ready {
                plan = plan_level(l, &self.valid[li], &d, self.size, left - spent);
                // The smaller plan's bands lie inside the first one's: all hits, nothing charged.
                ready = self.source.ensure_bands(k, &plan.bands, &mut spare)?;
            }
            self.decoded += spent;
            left -= spent;
            if !ready {
                complete[li] = self.valid[li] == d;
                stopped = true;
                continue;
            }
            for band in &plan.bands {
                self.fill(l, band, &mut zsum);
            }
            for u in &plan.uploads {
                frame.uploads.push(*u).map_err(|_| Error::Capacity {
                    what: "frame uploads",
                    capacity: frame.uploads.capacity(),
                })?;
            }
            self.valid[li] = plan.valid;
            samples[li] = plan.samples;
            left -= plan.samples;
            complete[li] = plan.complete;
            stopped = !plan.complete;
        }

        // The detail pool's requests once every ring is finished (coarse-to-fine first), same budget.
        if !stopped {
            self.decoded += self.source.prefetch(&self.requests, left)?;
        }
        // Active regions, coarse to fine: desired, cropped to the clip region and to the coarser active
        // region eroded by one coarse sample, corners snapped inward to even coordinates.
        let mut actives = [Rect::EMPTY; MAX_LEVELS];
        let mut disabled_below = false;
        for l in (0..lv).rev() {
            let l32 = u32::try_from(l).expect("level < MAX_LEVELS");
            if disabled_below || !self.height_enabled(l32, h) {
                disabled_below = true;
                continue;
            }
            let mut a = desired[l].intersect(&self.valid[l]);
            if l + 1 < lv {
                a = a.intersect(&nest_limit(&actives[l + 1]));
            }
            let a = snap_even(&a);
            if a.w < MIN_ACTIVE || a.h < MIN_ACTIVE {
                disabled_below = true;
                continue;
            }
            actives[l] = a;
        }

        let (mut total_samples, mut updated, mut stale, mut disabled, mut tris) = (0, 0, 0, 0, 0);
        for l in 0..lv {
            let a = actives[l];
            let state = if a.is_empty() {
                disabled += 1;
                LevelState::Disabled
            } else if !complete[l] {
                stale += 1;
                LevelState::Stale
            } else if samples[l] > 0 {
                LevelState::Updated
            } else {
                LevelState::Current
            };
            if samples[l] > 0 {
                updated += 1;
            }
            total_samples += samples[l];
            let t = if a.is_empty() {
                0
            } else {
                let quads = |w: u32, h: u32| (w - 1) * (h - 1);
                let inner = if l > 0 && !actives[l - 1].is_empty() {
                    quads(actives[l - 1].w.div_ceil(2), actives[l - 1].h.div_ceil(2))
                } else {
                    0
                };
                2 * (quads(a.w, a.h) - inner)
            };
            tris += t;
            frame
                .levels
                .push(LevelFrame {
                    state,
                    clip: self.valid[l],
                    active: a,
                    samples_updated: samples[l],
                    triangles: t,
                })
                .map_err(|_| Error::Capacity {
                    what: "frame levels",
                    capacity: MAX_LEVELS,
                })?;
        }
        frame.samples_updated = total_samples;
        frame.levels_updated = updated;
        frame.stale_levels = stale;
        frame.disabled_levels = disabled;
        frame.triangles = tris;
        zsum.write_u32(total_samples);
        frame.z_checksum = zsum.finish();
        frame.hash = frame.compute_hash();
        self.stamps.note(frame.index, &frame.uploads);
        self.frame = frame;
        self.next_index += 1;
        Ok(&self.frame)
    }

    /// Fills one band of ring `level` (GC sections 4 and 8), hashing the written bits in order.
    fn fill(&mut self, level: u32, band: &Rect, zsum: &mut Hash64) {
        let li = level as usize;
        // Take the ring out so the coarser ring (synthesis) and the pyramid can be read while writing it.
        let mut ring = std::mem::replace(&mut self.rings[li], Ring::empty());
        {
            let this = &*self;
            let pyramid_coarse = level + 1 >= this.synth;
            let coarser = this.rings.get(li + 1);
            let coarse = |a: i64, b: i64| -> f32 {
                if pyramid_coarse {
                    this.source.at(level + 1 - this.synth, a, b)
                } else {
                    coarser
                        .expect("a synthesised ring has a coarser ring")
                        .get(a, b)[0]
                }
            };
            let size = ring.size() as usize;
            let tx0 = ring.index(band.x0, 0);
            for j in band.y0..band.y1() {
                // A streamed data level reads its row and the two coarse rows of z_c through row readers
                // (one tile lookup per tile, not per sample: the same heights as `texel`).
                let mut rows = level
                    .checked_sub(this.synth)
                    .filter(|_| level + 1 < this.levels)
                    .and_then(|k| {
                        let cj = j >> 1;
                        let src = &this.source;
                        Some((src.row(k, j)?, src.row(k + 1, cj)?, src.row(k + 1, cj + 1)?))
                    });
                // Toroidal addressing, stepped along the row instead of a division per texel.
                let row = ring.index(0, j);
                let mut tx = tx0;
                for i in band.x0..band.x1() {
                    let t = match &mut rows {
                        Some((z, c0, c1)) => {
                            let cj = j >> 1;
                            [
                                z.get(i),
                                coarse_surface(
                                    |a, b| if b == cj { c0.get(a) } else { c1.get(a) },
                                    i,
                                    j,
                                ),
                            ]
                        }
                        None => this.texel(level, i, j, &coarse),
                    };
                    ring.texels_mut()[row + tx] = t;
                    tx += 1;
                    if tx == size {
                        tx = 0;
                    }
                    zsum.write_u64((u64::from(t[0].to_bits()) << 32) | u64::from(t[1].to_bits()));
                }
            }
        }
        self.rings[li] = ring;
    }

    /// GC section 5 constraints (1)-(4) on the last frame; see [`ConstraintViolation`].
    pub fn check_constraints(&self) -> Result<(), ConstraintViolation> {
        let levels = &self.frame.levels;
        for (l, lf) in levels.iter().enumerate() {
            let level = u32::try_from(l).expect("level < MAX_LEVELS");
            let a = lf.active;
            if a.is_empty() {
                continue;
            }
            if !lf.clip.contains(&a) {
                return Err(ConstraintViolation::ActiveOutsideClip {
                    level,
                    active: a,
                    clip: lf.clip,
                });
            }
            if a.x0 & 1 != 0 || a.y0 & 1 != 0 || (a.x1() - 1) & 1 != 0 || (a.y1() - 1) & 1 != 0 {
                return Err(ConstraintViolation::OffCoarseLattice { level, active: a });
            }
            if let Some(c) = levels.get(l + 1) {
                if c.active.is_empty() {
                    return Err(ConstraintViolation::NotContiguous { level });
                }
                if !nest_limit(&c.active).contains(&a) {
                    return Err(ConstraintViolation::NotNested {
                        level,
                        active: a,
                        coarser: c.active,
                    });
                }
            }
        }
        Ok(())
    }
}

/// z_c at fine vertex (i, j): the coarser level's piecewise-linear surface there (GC section 4's z_c).
///
/// Even-even: the coarse sample. Odd on one axis: the mean of the two coarse neighbours along that edge.
/// Odd-odd: the mean of the two coarse samples on the quad's (i, j)-(i+1, j+1) diagonal, the project-wide
/// triangulation (renderer and SAT error maps split every quad the same way).
#[inline]
fn coarse_surface(mut coarse: impl FnMut(i64, i64) -> f32, i: i64, j: i64) -> f32 {
    let (ci, cj) = (i >> 1, j >> 1);
    match (i & 1, j & 1) {
        (0, 0) => coarse(ci, cj),
        (1, 0) => (coarse(ci, cj) + coarse(ci + 1, cj)) * 0.5,
        (0, 1) => (coarse(ci, cj) + coarse(ci, cj + 1)) * 0.5,
        _ => (coarse(ci, cj) + coarse(ci + 1, cj + 1)) * 0.5,
    }
}

/// The region of level l allowed by constraint (2): the coarser active region `c` eroded by one coarse
/// sample, in level-l units (vertices 2 (c.x0 + 1) ..= 2 (c.x1 - 2)).
fn nest_limit(c: &Rect) -> Rect {
    if c.w < 3 || c.h < 3 {
        return Rect::EMPTY;
    }
    Rect::from_bounds(
        2 * (c.x0 + 1),
        2 * (c.y0 + 1),
        2 * (c.x1() - 2) + 1,
        2 * (c.y1() - 2) + 1,
    )
}

/// Shrinks a vertex rectangle so its first and last vertex are even (constraint 3).
fn snap_even(r: &Rect) -> Rect {
    if r.is_empty() {
        return Rect::EMPTY;
    }
    let x0 = r.x0 + (r.x0 & 1);
    let y0 = r.y0 + (r.y0 & 1);
    let xl = (r.x1() - 1) - ((r.x1() - 1) & 1);
    let yl = (r.y1() - 1) - ((r.y1() - 1) & 1);
    Rect::from_bounds(x0, y0, xl + 1, yl + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snapping_and_nesting() {
        let r = snap_even(&Rect::from_bounds(1, 2, 10, 9));
        assert_eq!(r, Rect::from_bounds(2, 2, 9, 9));
        let c = Rect {
            x0: 0,
            y0: 0,
            w: 15,
            h: 15,
        };
        assert_eq!(nest_limit(&c), Rect::from_bounds(2, 2, 27, 27));
    }
}
