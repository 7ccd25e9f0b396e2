//! Stage 2, the per-frame plan: what a [`Clipmap`] says of the data it is filled from (the resident
//! pyramid or a streamed package's tile cache, [`HeightSource`]): sizes, range, slope, readable samples
//! and the requests the next update decodes.

use crate::bake::pyramid::Pyramid;
use crate::package::TileCache;
use crate::plan::clipmap::Clipmap;
use crate::plan::frame::Rect;
use crate::plan::stream::HeightSource;

impl Clipmap {
    /// The pyramid the rings are filled from. Panics for a streamed clipmap, which holds no pyramid (a
    /// caller bug: check [`Clipmap::tile_cache`]).
    pub fn pyramid(&self) -> &Pyramid {
        match &self.source {
            HeightSource::Resident(p) => p,
            HeightSource::Streamed(_) => panic!("a streamed clipmap holds no resident pyramid"),
        }
    }

    /// The data pyramid's level `k` at sample (i, j), as [`Pyramid::at`] reads it (clamped to the data),
    /// where it can be read without decoding: always for a resident pyramid; streamed, while its tile is
    /// in the cache. For measurements of a drawn frame, whose tiles the fill just read.
    pub fn data_height(&self, k: u32, i: i64, j: i64) -> Option<f32> {
        self.source.try_at(k, i, j)
    }

    /// Level-0 samples of the data, (columns, rows).
    pub fn data_size(&self) -> (u32, u32) {
        match &self.source {
            HeightSource::Resident(p) => (p.level(0).width(), p.level(0).height()),
            HeightSource::Streamed(c) => (c.package().header().width, c.package().header().height),
        }
    }

    /// Lowest and highest data height, metres (a streamed package's header has them).
    pub fn data_range(&self) -> (f32, f32) {
        match &self.source {
            HeightSource::Resident(p) => p
                .level(0)
                .heights()
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &z| {
                    (a.min(z), b.max(z))
                }),
            HeightSource::Streamed(c) => c.package().header().range,
        }
    }

    /// Mean slope (rise over run) of the data, as [`crate::shading::basic::mean_slope`] of level 0; a
    /// streamed package's is that of its finest level of at most 1 Mi samples.
    pub fn data_mean_slope(&self) -> f64 {
        match &self.source {
            HeightSource::Resident(p) => {
                let l0 = p.level(0);
                crate::shading::basic::mean_slope(
                    l0.heights(),
                    l0.width() as usize,
                    self.data_spacing,
                )
            }
            HeightSource::Streamed(_) => self.streamed_slope,
        }
    }

    /// The package tile cache of a streamed clipmap.
    pub fn tile_cache(&self) -> Option<&TileCache> {
        match &self.source {
            HeightSource::Streamed(c) => Some(c),
            HeightSource::Resident(_) => None,
        }
    }

    /// The next [`Clipmap::update`] makes `requests` (level, samples: the pool's `DetailFrame::wanted`)
    /// readable in order with what the rings leave of its budget; replaces the last (keeps 255).
    pub fn request_samples(&mut self, requests: &[(u32, Rect)]) {
        let n = requests.len().min(self.requests.capacity());
        self.requests.clear();
        let _ = self.requests.extend_from_slice(&requests[..n]);
    }

    /// Makes samples `rect` of data level `k` readable now with the next coarser level's under them (what
    /// a detail pool tile reads), decoding whatever the tile cache lacks past any budget, after a new
    /// cache frame (the tiles pinned so far are let go): a detail pool tile sent again after a lost
    /// device, whose package tiles were evicted since it was filled. `Ok(false)`: the cache cannot hold
    /// them.
    pub fn decode_now(&mut self, k: u32, rect: &Rect) -> crate::Result<bool> {
        self.source.begin_frame();
        let mut budget = u64::MAX;
        self.source
            .ensure_bands(k, std::slice::from_ref(rect), &mut budget)
    }

    /// Whether samples `rect` of pyramid level `k` are readable now (streamed: their tiles resident).
    pub fn source_ready(&self, k: u32, rect: &Rect) -> bool {
        self.source.rect_ready(k, rect)
    }

    /// Samples decoded from the package in the last frame, inside its update budget (0 if resident).
    pub fn decoded_samples(&self) -> u32 {
        self.decoded
    }
}
