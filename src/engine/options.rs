//! The embedding API: builders for the options structs ([`RenderOptions`], [`TerrainOptions`]), which
//! are `#[non_exhaustive]` so that options can be added without breaking a caller. Each method sets one
//! option and returns the options: `RenderOptions::default().sat_lod_px(1.0).reverse_z(true)`.

use std::path::PathBuf;

use crate::progress::Progress;
use crate::{RenderOptions, TerrainOptions};

impl<'a> RenderOptions<'a> {
    /// The colour attachment's format ([`RenderOptions::color_format`]).
    #[must_use]
    pub fn color_format(mut self, format: wgpu::TextureFormat) -> Self {
        self.color_format = format;
        self
    }

    /// The depth attachment's format ([`RenderOptions::depth_format`]).
    #[must_use]
    pub fn depth_format(mut self, format: wgpu::TextureFormat) -> Self {
        self.depth_format = format;
        self
    }

    /// Reverse-Z depth ([`RenderOptions::reverse_z`]).
    #[must_use]
    pub fn reverse_z(mut self, on: bool) -> Self {
        self.reverse_z = on;
        self
    }

    /// The pass's sample count ([`RenderOptions::sample_count`]).
    #[must_use]
    pub fn sample_count(mut self, count: u32) -> Self {
        self.sample_count = count;
        self
    }

    /// SAT LOD at this screen-space error bound, pixels ([`RenderOptions::sat_lod_px`]).
    #[must_use]
    pub fn sat_lod_px(mut self, px: f32) -> Self {
        self.sat_lod_px = Some(px);
        self
    }

    /// SG shading of a shipped scene or a scene file ([`RenderOptions::sg_scene`]).
    #[must_use]
    pub fn sg_scene(mut self, scene: &'a str) -> Self {
        self.sg_scene = Some(scene);
        self
    }

    /// Where the set-up's bakes report their progress ([`RenderOptions::progress`]).
    #[must_use]
    pub fn progress(mut self, progress: Progress<'a>) -> Self {
        self.progress = progress;
        self
    }

    /// Draped imagery in RGBA8 whatever the device offers ([`RenderOptions::imagery_rgba8`]).
    #[must_use]
    pub fn imagery_rgba8(mut self, on: bool) -> Self {
        self.imagery_rgba8 = on;
        self
    }
}

impl<'a> TerrainOptions<'a> {
    /// The cache folder ([`TerrainOptions::cache_dir`]).
    #[must_use]
    pub fn cache_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.cache_dir = Some(dir.into());
        self
    }

    /// Hold the whole terrain in memory ([`TerrainOptions::resident`]).
    #[must_use]
    pub fn resident(mut self, resident: bool) -> Self {
        self.resident = resident;
        self
    }

    /// The sample spacing, metres ([`TerrainOptions::spacing_m`]).
    #[must_use]
    pub fn spacing_m(mut self, spacing: f32) -> Self {
        self.spacing_m = Some(spacing);
        self
    }

    /// Metres per stored unit ([`TerrainOptions::height_scale`]).
    #[must_use]
    pub fn height_scale(mut self, scale: f32) -> Self {
        self.height_scale = Some(scale);
        self
    }

    /// Metres added to every height ([`TerrainOptions::height_offset`]).
    #[must_use]
    pub fn height_offset(mut self, offset: f32) -> Self {
        self.height_offset = offset;
        self
    }

    /// The stored value that marks voids ([`TerrainOptions::nodata`]).
    #[must_use]
    pub fn nodata(mut self, value: f64) -> Self {
        self.nodata = Some(value);
        self
    }

    /// The height of a mosaic's samples with no data ([`TerrainOptions::fill_height`]).
    #[must_use]
    pub fn fill_height(mut self, metres: f32) -> Self {
        self.fill_height = Some(metres);
        self
    }

    /// Where the first bake reports its progress ([`TerrainOptions::progress`]).
    #[must_use]
    pub fn progress(mut self, progress: Progress<'a>) -> Self {
        self.progress = progress;
        self
    }

    /// The most samples a terrain file may declare ([`TerrainOptions::max_samples`]).
    #[must_use]
    pub fn max_samples(mut self, samples: u64) -> Self {
        self.max_samples = Some(samples);
        self
    }

    /// The most texels an imagery file may declare ([`TerrainOptions::max_imagery_texels`]).
    #[must_use]
    pub fn max_imagery_texels(mut self, texels: u64) -> Self {
        self.max_imagery_texels = Some(texels);
        self
    }

    /// An image to drape on the terrain ([`TerrainOptions::imagery`]).
    #[must_use]
    pub fn imagery(mut self, path: impl Into<PathBuf>) -> Self {
        self.imagery = Some(path.into());
        self
    }

    /// Where the imagery lies, (west, south, east, north) metres ([`TerrainOptions::imagery_extent`]).
    #[must_use]
    pub fn imagery_extent(mut self, extent: [f64; 4]) -> Self {
        self.imagery_extent = Some(extent);
        self
    }

    /// The imagery's sample values drawn black and white ([`TerrainOptions::imagery_range`]).
    #[must_use]
    pub fn imagery_range(mut self, low: f64, high: f64) -> Self {
        self.imagery_range = Some((low, high));
        self
    }
}

// What an engine moves to a worker thread: a terrain opened or baked there, and the renderer itself.
const _: () = {
    const fn send<T: Send>() {}
    send::<crate::Terrain>();
    send::<crate::TerrainRenderer>();
    send::<crate::Profile>();
    send::<crate::Camera>();
};
