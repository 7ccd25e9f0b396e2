//! Budgets: the profile that sizes every buffer at start-up and bounds every frame's work.
//!
//! A profile is a TOML file (`profiles/*.toml`); the three shipped ones are compiled in, so `--profile
//! gles3-low` works from any directory. Loading validates every field and names the one at fault.

use std::path::Path;

use serde::{Deserialize, Serialize};

pub use crate::profile_imagery::{ImageryBudget, MAX_COLOR_LEVELS};
use crate::profile_imagery::with_gl_spare_layer;
use crate::{Error, Result};

/// The profiles shipped in `profiles/`, by name, with their TOML text.
pub const SHIPPED: [(&str, &str); 3] = [
    ("gles3-low", include_str!("../profiles/gles3-low.toml")),
    ("gles3-mid", include_str!("../profiles/gles3-mid.toml")),
    ("desktop", include_str!("../profiles/desktop.toml")),
];

/// The profile used when none is named.
pub const DEFAULT_PROFILE: &str = "gles3-mid";

/// A budget profile: what one device class can afford. Units are in the field names.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// Short name, printed in reports.
    pub name: String,
    /// Clipmap geometry.
    pub clipmap: ClipmapBudget,
    /// Per-frame work and memory limits.
    pub budget: FrameBudget,
    /// Viewport and accuracy target.
    pub view: View,
    /// The shading features the device may use.
    pub shading: Shading,
    /// The colour clipmap of draped imagery (used only where the terrain has imagery and the profile
    /// allows `imagery`); a profile without the section gets [`ImageryBudget::default`].
    #[serde(default)]
    pub imagery: ImageryBudget,
}

/// Clipmap geometry (GC section 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipmapBudget {
    /// Vertices per ring side, n = 2^k - 1 (GC section 3).
    pub n: u32,
    /// Number of rings L; level 0 is the finest.
    pub levels: u32,
    /// Samples held beyond the active region on each side, so SAT LOD may refine a distant block.
    pub clip_margin: u32,
}

/// Per-frame work and memory limits. Work is counted in samples and primitives, never in time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameBudget {
    /// Height samples written into the rings per frame, at most.
    pub update_samples_per_frame: u32,
    /// Draw calls per frame, at most.
    pub max_draws: u32,
    /// Triangles per frame, at most.
    pub max_triangles: u32,
    /// Bytes of GPU memory everything created at start-up may take.
    pub gpu_memory_bytes: u64,
    /// Bytes of CPU memory the terrain may take at runtime, whatever its size: the CPU copy of the rings,
    /// the SAT LOD tables' resident pages, and the package tile cache, which gets the rest
    /// ([`Profile::cpu_split`]).
    pub cpu_memory_bytes: u64,
    /// Height tiles in the detail pool: finer data for the SAT LOD blocks whose wanted level
    /// the rings do not hold there; 0: no pool. At most [`MAX_DETAIL_TILES`].
    #[serde(default)]
    pub detail_tiles: u32,
    /// Quads per detail tile side: a power of two (0, or more than the block side m, means m). A tile holds
    /// quads + 1 samples per side plus a one-sample border (for normals): [`Profile::detail_side`].
    #[serde(default)]
    pub detail_tile_quads: u32,
    /// Bound evaluations the detail pool's refinement may spend per frame, at most: a count, never a
    /// clock, so frames stay deterministic. The refinement carries over between frames and spends it
    /// where the error is largest (docs/plan-time.md). Positive where the pool is on; default
    /// [`DEFAULT_REFINE_BOUNDS_PER_FRAME`].
    #[serde(default = "default_refine_bounds")]
    pub refine_bounds_per_frame: u32,
}

/// `budget.refine_bounds_per_frame` where a profile does not set it.
pub const DEFAULT_REFINE_BOUNDS_PER_FRAME: u32 = 1000;

fn default_refine_bounds() -> u32 {
    DEFAULT_REFINE_BOUNDS_PER_FRAME
}

/// How a profile's `budget.cpu_memory_bytes` is split.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CpuSplit {
    /// The CPU copy of the rings: `clip_size^2 x levels` (z, z_c) f32 pairs.
    pub rings: u64,
    /// What is left for the package tile cache (header, tile map, decoder scratch and tile slots).
    pub tile_cache: u64,
    /// The exact queries' own tile cache and tile ranges ([`QUERY_SHARE`] of what the rings leave, at
    /// most [`QUERY_MAX_BYTES`];
    /// `package::query`): a streamed terrain's full-resolution heights and rays, read apart from the rings'
    /// cache so a query changes no frame.
    pub queries: u64,
    /// The most of the SAT LOD tables' mapped pages held resident ([`LOD_TABLES_SHARE`] of what the
    /// rings leave; `bake::mapped`): the tables' queries trim their map once their pages would pass it.
    pub lod_tables: u64,
    /// The SG shading inputs ([`SHADING_SHARE`] of what the rings leave, on a profile that allows SG;
    /// `package/shading_sats.rs`): their grid is the finest pyramid level whose tables fit it.
    pub shading: u64,
}

impl CpuSplit {
    /// The SAT LOD tables' resident pages: their share, and the SG shading inputs' share too when no SG
    /// shading is drawn (`sg` false): memory a scene does not use goes to the tables, whose pages a rough
    /// terrain needs (docs/plan-time.md).
    pub fn lod_tables_with(&self, sg: bool) -> u64 {
        if sg {
            self.lod_tables
        } else {
            self.lod_tables.saturating_add(self.shading)
        }
    }
}

/// The part of `budget.cpu_memory_bytes` left after the rings that holds the SG shading inputs, on a
/// profile that allows SG: 1/2 (31.0 MiB on gles3-mid, 123.7 MiB on desktop; less where that would leave
/// the tile cache under [`MIN_TILE_CACHE_BYTES`]). Half, because that is the least that keeps the shared
/// terrains (at most 1201^2) shaded at their full resolution: gles3-mid's normal SAT of 1201^2 takes
/// 28.9 MiB, desktop's normal and 16 horizon SATs 117.1 MiB (`shading_sats::grid_bytes`). Larger terrains
/// are shaded on a coarser level of a fixed size (1025^2 from 4097^2 on, on both).
pub const SHADING_SHARE: u64 = 2;

/// The part of `budget.cpu_memory_bytes` left after the rings that the SAT LOD tables' pages may hold
/// (1/8: 7.8 MiB on gles3-mid; less where that would leave the tile cache under
/// [`MIN_TILE_CACHE_BYTES`]); the tile cache gets the rest. Frames that draw no SG shading give the tables
/// the SG inputs' share too ([`CpuSplit::lod_tables_with`]: 38.8 MiB on gles3-mid).
pub const LOD_TABLES_SHARE: u64 = 8;

/// The part of `budget.cpu_memory_bytes` left after the rings that the exact queries' tile cache holds
/// (1/16, at most [`QUERY_MAX_BYTES`]: 3.9 MiB on gles3-mid, about 230 tiles of 64^2 samples; less where
/// that would leave the tile cache under [`MIN_TILE_CACHE_BYTES`]), taken from the tile cache's part.
pub const QUERY_SHARE: u64 = 16;

/// The most the exact queries' tile cache holds: 8 MiB (about 500 tiles of 64^2 samples).
pub const QUERY_MAX_BYTES: u64 = 8 << 20;

/// The smallest tile cache a profile may leave: 1 MiB (about 60 tiles of 64^2 samples).
pub const MIN_TILE_CACHE_BYTES: u64 = 1 << 20;

/// Viewport and accuracy target.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct View {
    /// Screen-space geometric error bound for SAT LOD, pixels.
    pub epsilon_px: f32,
    /// Viewport width, pixels.
    pub width: u32,
    /// Viewport height, pixels.
    pub height: u32,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f32,
}

/// Shading features a device class may use; a scene may ask for less, never more.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shading {
    /// Allowed features.
    pub features: Vec<Feature>,
    /// Spherical-Gaussian light lobes, at most.
    pub max_sg_lights: u32,
}

/// One shading feature.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Feature {
    /// Height ramp, Lambert and nothing else.
    Basic,
    /// Reduced spherical-Gaussian diffuse shading.
    Sg,
    /// SAT-filtered horizon visibility (soft shadows).
    Visibility,
    /// SG specular.
    Specular,
    /// Distance fog.
    Fog,
    /// Fractal detail synthesised below the data's resolution (GC section 8).
    Synthesis,
    /// Draped imagery: the colour clipmap and its albedo (`[imagery]`'s budget).
    Imagery,
}

impl Feature {
    /// The feature's name in profile and scene files (`sg`, `visibility`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::Basic => "basic",
            Self::Sg => "sg",
            Self::Visibility => "visibility",
            Self::Specular => "specular",
            Self::Fog => "fog",
            Self::Synthesis => "synthesis",
            Self::Imagery => "imagery",
        }
    }
}

/// GPU memory one profile needs, by part, in bytes. `Renderer::new` allocates exactly this (its ledger
/// is checked against it by a test).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Footprint {
    /// Ring heights: one RG32F (z, z_c) 2D array texture, `clip_size^2 x` [`Profile::height_layers`].
    /// Normals are derived from the geometry in the vertex shader (GC section 6.3): no normal texture.
    pub heights: u64,
    /// The static block mesh ((m + 1)^2 vertices), ring skirt mesh (around n + 1 quads), SAT LOD tile
    /// skirt loops (around 1, 2, 4, ..., m quads) and the detail pool's cell mesh (a cell of k quads and
    /// its loop per k, [`Profile::pool_mesh_quads`]), 8-byte vertices and u16 indices; one set serves every
    /// level (see `mesh`).
    pub meshes: u64,
    /// Colour (RGBA8) and depth (32-bit) targets at the viewport size, plus one padded readback buffer.
    pub targets: u64,
    /// Uniform buffers: the globals plus one 256-byte slot per draw (`budget.max_draws`).
    pub uniforms: u64,
    /// The detail pool: one RG32F (z, z_c) 2D array texture of [`Profile::detail_atlas`]'s layers, each
    /// `layer_side`^2 texels.
    pub detail: u64,
    /// The detail pool's cell buffer: one [`POOL_CELL_BYTES`] per-instance record per cell the pool's
    /// instanced draws may draw ([`Profile::pool_cell_capacity`]).
    pub pool_cells: u64,
}

impl Footprint {
    /// Sum of the parts (saturating: a footprint of an unvalidated profile may be absurd, never wrapped).
    pub fn total(&self) -> u64 {
        self.heights
            .saturating_add(self.meshes)
            .saturating_add(self.targets)
            .saturating_add(self.uniforms)
            .saturating_add(self.detail)
            .saturating_add(self.pool_cells)
    }
}

/// Bytes of the clipmap renderer's global uniform block (view-projection, shading, parameters).
pub const GLOBALS_BYTES: u64 = 144 + 48 * MAX_LEVELS as u64 + 16;
/// Bytes of one per-draw uniform slot: the GLES 3.0 floor's uniform offset alignment.
pub const DRAW_SLOT_BYTES: u64 = 256;
/// Most detail pool cells one plan draws: a cell is drawn whole (one instance) or stitched
/// (one instance per unit and border side, [`MAX_POOL_INSTANCES`]).
pub const MAX_POOL_CELLS: usize = 1024;
/// Most per-instance records the pool's instanced draws may draw in one plan: whole cells and stitched
/// cells' units. Each takes at least 2 triangles, so a profile's cell buffer holds the fewer of this and
/// half its triangle budget ([`Profile::pool_cell_capacity`]).
pub const MAX_POOL_INSTANCES: usize = 1 << 17;
/// Bytes of one pool cell's per-instance record (`PoolCell` in the plan's uniforms).
pub const POOL_CELL_BYTES: u64 = 64;

/// Largest 2D texture side on the GLES 3.0 floor (`Limits::downlevel_webgl2_defaults`).
pub const MAX_TEXTURE_SIDE: u32 = 2048;
/// Most array layers on the GLES 3.0 floor.
pub const MAX_TEXTURE_LAYERS: u32 = 256;
/// Most array layers the detail pool takes (the GLES 3.0 floor less the GL backend's spare layer).
pub const MAX_DETAIL_LAYERS: u32 = MAX_TEXTURE_LAYERS - 1;
/// Most detail pool tiles a profile may ask for: an atlas of several tiles per array layer
/// ([`DetailAtlas`]), so more tiles than layers. It sizes the plan's fixed pool collections.
pub const MAX_DETAIL_TILES: u32 = 1024;

/// Where the detail pool's slots lie in its RG32F array texture: each layer is a grid of
/// `cols x cols` tiles, `side` texels each, filled row by row, then the next layer. A single tile per
/// layer while the tiles fit [`MAX_DETAIL_LAYERS`], else the fewest columns that fit them. Pure: the plan
/// puts each cell's place into its per-instance record (so into its hash), and the renderer uploads there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DetailAtlas {
    /// Texels per tile side ([`Profile::detail_side`]).
    pub side: u32,
    /// Tiles per layer row (and column).
    pub cols: u32,
    /// Array layers, the GL backend's spare layer included.
    pub layers: u32,
}

impl DetailAtlas {
    /// Tiles per layer.
    pub fn per_layer(&self) -> u32 {
        self.cols.saturating_mul(self.cols)
    }

    /// Texels per layer side.
    pub fn layer_side(&self) -> u32 {
        self.cols.saturating_mul(self.side)
    }

    /// Slot `slot`'s (layer, x, y): its layer and the texel of its first sample there.
    pub fn place(&self, slot: u32) -> (u32, u32, u32) {
        let per = self.per_layer().max(1);
        let w = slot % per;
        (
            slot / per,
            (w % self.cols) * self.side,
            (w / self.cols) * self.side,
        )
    }
}
/// Most rings a profile may ask for (g_L = g_0 2^L must stay exact in f32).
pub const MAX_LEVELS: u32 = 16;
/// Most draws any profile may ask for (`budget.max_draws` is checked against it at start-up; the plan's
/// draw list and the renderer's uniform slots are this long at most).
pub const MAX_DRAWS: usize = 2048;
/// Most SG light lobes a shader variant holds: the largest `shading.max_sg_lights` of the shipped
/// profiles (desktop); mirrors `SG_MAX_LIGHTS` in `shaders_gles/sg_shading.wgsl`.
pub const MAX_SG_LIGHTS: usize = 8;

/// The SG sky table's side: mean-normal directions, hemi-octahedral (`shading/sky_table.rs`).
pub const SG_SKY_SIDE: u32 = 32;
/// The SG sky table's layers: vMF spreads, uniform in sqrt(1 - |r|).
pub const SG_SKY_LAYERS: u32 = 16;
/// GPU bytes of the SG sky table: RGBA32F, `SG_SKY_SIDE^2 x SG_SKY_LAYERS`, fixed whatever the profile.
pub const SG_SKY_TABLE_BYTES: u64 =
    16 * (SG_SKY_SIDE as u64) * (SG_SKY_SIDE as u64) * (SG_SKY_LAYERS as u64);
/// Largest `clipmap.n`: the block mesh ((n + 1) / 4 + 1)^2 vertices must fit u16 indices (`mesh::block`);
/// the next 2^k - 1, 1023, needs 257^2 = 66049.
pub const MAX_N: u32 = 511;
const _: () = assert!(((MAX_N + 1) / 4 + 1) * ((MAX_N + 1) / 4 + 1) <= 1 << 16);
const _: () = assert!(((2 * MAX_N + 2) / 4 + 1) * ((2 * MAX_N + 2) / 4 + 1) > 1 << 16);

/// The TOML text of a shipped `what` (profile, scene) by name, or of a file by path; the error names
/// `what` when it is neither.
pub(crate) fn shipped_or_file(
    shipped: &[(&str, &'static str)],
    what: &str,
    name_or_path: &str,
) -> Result<std::borrow::Cow<'static, str>> {
    if let Some((_, text)) = shipped.iter().find(|(n, _)| *n == name_or_path) {
        return Ok(std::borrow::Cow::Borrowed(text));
    }
    let path = Path::new(name_or_path);
    if !path.exists() {
        let names: Vec<&str> = shipped.iter().map(|(n, _)| *n).collect();
        return Err(Error::Invalid {
            what: what.into(),
            reason: format!(
                "`{name_or_path}` is neither a shipped {what} ({}) nor a file",
                names.join(", ")
            ),
        });
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, "cannot read", e))?;
    Ok(std::borrow::Cow::Owned(text))
}

impl Profile {
    /// A shipped profile by name, or a profile file by path.
    pub fn load(name_or_path: &str) -> Result<Self> {
        let text = shipped_or_file(&SHIPPED, "profile", name_or_path)?;
        Self::parse(name_or_path, &text)
    }

    /// Parses and validates a profile's TOML text; `source_name` names it in errors.
    pub fn parse(source_name: &str, text: &str) -> Result<Self> {
        let profile: Self = toml::from_str(text).map_err(|e| toml_error(source_name, text, &e))?;
        profile.validate(source_name)?;
        Ok(profile)
    }

    /// Checks every constraint the later stages rely on; the error names the field.
    ///
    /// Every field is range-checked with checked (u64) arithmetic, so a profile that validates can neither
    /// panic nor wrap in any later stage: n up to [`MAX_N`] (u16 mesh indices), the clip texture within
    /// [`MAX_TEXTURE_SIDE`], draws within the renderer's fixed capacity, lights within the shaders'.
    pub fn validate(&self, source_name: &str) -> Result<()> {
        let bad = |field: &str, reason: String| Err(Error::config(source_name, field, reason));
        let c = &self.clipmap;
        if c.n < 15 || c.n > MAX_N || !c.n.wrapping_add(1).is_power_of_two() {
            return bad(
                "clipmap.n",
                format!(
                    "{} is not 2^k - 1 in 15..={MAX_N} (15, 31, 63, 127, 255, 511; larger blocks \
                     overflow the meshes' 16-bit indices)",
                    c.n
                ),
            );
        }
        if c.levels == 0 || c.levels > MAX_LEVELS {
            return bad(
                "clipmap.levels",
                format!("{} is not in 1..={MAX_LEVELS}", c.levels),
            );
        }
        // n + 1 + 2 margin in u64: a margin near 2^31 must not wrap to a small side.
        let side = u64::from(c.n) + 1 + 2 * u64::from(c.clip_margin);
        if side > u64::from(MAX_TEXTURE_SIDE) {
            return bad(
                "clipmap.clip_margin",
                format!(
                    "n + 1 + 2 * margin = {side} exceeds the GLES 3.0 texture side {MAX_TEXTURE_SIDE}"
                ),
            );
        }
        let b = &self.budget;
        if b.update_samples_per_frame == 0 {
            return bad(
                "budget.update_samples_per_frame",
                "must be positive: a zero budget never fills a ring".into(),
            );
        }
        if b.max_draws == 0 || b.max_draws as usize > MAX_DRAWS {
            return bad(
                "budget.max_draws",
                format!(
                    "{} is not in 1..={} (the renderer's fixed draw capacity)",
                    b.max_draws, MAX_DRAWS
                ),
            );
        }
        if b.max_triangles == 0 {
            return bad("budget.max_triangles", "must be positive".into());
        }
        if b.detail_tiles > MAX_DETAIL_TILES {
            return bad(
                "budget.detail_tiles",
                format!(
                    "{} is not in 0..={MAX_DETAIL_TILES} (the plan's fixed pool capacity)",
                    b.detail_tiles
                ),
            );
        }
        if b.detail_tiles > 0 && b.refine_bounds_per_frame == 0 {
            return bad(
                "budget.refine_bounds_per_frame",
                "must be positive where the detail pool is on (budget.detail_tiles > 0): a zero \
                 budget never refines a block"
                    .into(),
            );
        }
        if b.detail_tile_quads != 0 && !b.detail_tile_quads.is_power_of_two() {
            return bad(
                "budget.detail_tile_quads",
                format!(
                    "{} is not 0 or a power of two (a tile is drawn with the block mesh)",
                    b.detail_tile_quads
                ),
            );
        }
        let atlas = self.detail_atlas();
        if atlas.layer_side() > MAX_TEXTURE_SIDE {
            return bad(
                "budget.detail_tiles",
                format!(
                    "{} tiles of {} samples need a {} texel atlas layer, over the GLES 3.0 {MAX_TEXTURE_SIDE}",
                    b.detail_tiles,
                    atlas.side,
                    atlas.layer_side()
                ),
            );
        }
        let v = &self.view;
        if !(v.epsilon_px.is_finite() && v.epsilon_px > 0.0) {
            return bad(
                "view.epsilon_px",
                format!("{} must be a positive number of pixels", v.epsilon_px),
            );
        }
        for (field, side) in [("view.width", v.width), ("view.height", v.height)] {
            if side == 0 || side > MAX_TEXTURE_SIDE {
                return bad(
                    field,
                    format!("{side} is not in 1..={MAX_TEXTURE_SIDE} pixels"),
                );
            }
        }
        if !(v.fov_y_deg.is_finite() && v.fov_y_deg > 1.0 && v.fov_y_deg < 179.0) {
            return bad(
                "view.fov_y_deg",
                format!("{} is not in (1, 179) degrees", v.fov_y_deg),
            );
        }
        if self.shading.features.is_empty() {
            return bad(
                "shading.features",
                "list at least one feature (\"basic\")".into(),
            );
        }
        let max_lights = MAX_SG_LIGHTS;
        if self.shading.max_sg_lights as usize > max_lights {
            return bad(
                "shading.max_sg_lights",
                format!(
                    "{} exceeds the {max_lights} light lobes a shader variant holds",
                    self.shading.max_sg_lights
                ),
            );
        }
        let rings = u64::from(self.clip_size())
            .checked_mul(u64::from(self.clip_size()))
            .and_then(|t| t.checked_mul(u64::from(c.levels)))
            .and_then(|t| t.checked_mul(8));
        // The `[imagery]` section's fields, where the profile allows imagery; its memory is checked
        // where a terrain has imagery (`engine::setup::imagery_profile`).
        if self.allows(Feature::Imagery) {
            self.imagery.validate(source_name)?;
        }
        match rings.and_then(|r| r.checked_add(MIN_TILE_CACHE_BYTES)) {
            Some(need) if need <= b.cpu_memory_bytes => {}
            _ => {
                return bad(
                    "budget.cpu_memory_bytes",
                    format!(
                    "{} bytes do not hold the rings' CPU copy ({} bytes) plus a tile cache of at \
                         least {MIN_TILE_CACHE_BYTES} bytes",
                    b.cpu_memory_bytes,
                    rings.map_or_else(|| "overflowing".to_owned(), |r| r.to_string())
                ),
                )
            }
        }
        // Every part is bounded by the checks above (at most a few GiB), so the u64 sums cannot wrap.
        let need = self.footprint().total();
        if b.gpu_memory_bytes == 0 || need > b.gpu_memory_bytes {
            return bad(
                "budget.gpu_memory_bytes",
                format!(
                    "the profile needs {need} bytes of GPU memory but the budget is {}",
                    b.gpu_memory_bytes
                ),
            );
        }
        Ok(())
    }

    /// How `budget.cpu_memory_bytes` is split between the rings' CPU copy, the LOD tables' pages, the SG
    /// shading inputs, the exact queries' cache and the tile cache (a validated profile never saturates).
    pub fn cpu_split(&self) -> CpuSplit {
        let s = u64::from(self.clip_size());
        let rings = s
            .saturating_mul(s)
            .saturating_mul(u64::from(self.clipmap.levels))
            .saturating_mul(8);
        let rest = self.budget.cpu_memory_bytes.saturating_sub(rings);
        // Never taking the tile cache under its minimum (validation guarantees rest >= the minimum).
        let lod_tables = (rest / LOD_TABLES_SHARE).min(rest.saturating_sub(MIN_TILE_CACHE_BYTES));
        let shading = if self.allows(Feature::Sg) {
            (rest / SHADING_SHARE).min(
                rest.saturating_sub(lod_tables)
                    .saturating_sub(MIN_TILE_CACHE_BYTES),
            )
        } else {
            0
        };
        let queries = (rest / QUERY_SHARE).min(QUERY_MAX_BYTES).min(
            rest.saturating_sub(lod_tables)
                .saturating_sub(shading)
                .saturating_sub(MIN_TILE_CACHE_BYTES),
        );
        CpuSplit {
            rings,
            tile_cache: rest - lod_tables - shading - queries,
            queries,
            lod_tables,
            shading,
        }
    }

    /// GPU bytes of the colour rings where the profile allows imagery (else 0): counted against
    /// `budget.gpu_memory_bytes` with [`Profile::footprint`] for a terrain with imagery
    /// (`engine::setup::imagery_profile`), and allocated only for one.
    pub fn imagery_gpu_bytes(&self) -> u64 {
        if self.allows(Feature::Imagery) {
            self.imagery.gpu_bytes()
        } else {
            0
        }
    }

    /// Side of the toroidal clip texture: n + 1 (GC's n plus the wrap row) plus the margin on each side.
    /// Saturates at `u32::MAX` for a profile that has not been validated (never wraps).
    pub fn clip_size(&self) -> u32 {
        let side = u64::from(self.clipmap.n) + 1 + 2 * u64::from(self.clipmap.clip_margin);
        u32::try_from(side).unwrap_or(u32::MAX)
    }

    /// Block side m = (n + 1) / 4 vertices (GPU Gems 2, ch. 2).
    pub fn block_m(&self) -> u32 {
        u32::try_from((u64::from(self.clipmap.n) + 1) / 4).unwrap_or(u32::MAX)
    }

    /// Whether the profile allows `feature`.
    pub fn allows(&self, feature: Feature) -> bool {
        self.shading.features.contains(&feature)
    }

    /// Layers of the ring height array texture: the level count, except that wgpu's GL backend takes a
    /// one-layer texture for a plain 2D texture and a square one with a multiple of 6 layers for a cube
    /// map, so those counts get one spare layer.
    pub fn height_layers(&self) -> u32 {
        with_gl_spare_layer(self.clipmap.levels)
    }

    /// Layers of the SG normal table (docs/design.md "Memory model"): one per ring, with the same GL spare layer as
    /// [`Profile::height_layers`].
    pub fn sg_normal_layers(&self) -> u32 {
        self.height_layers()
    }

    /// Layers of the SG light table (`visibility`: the scene has horizon visibility; else no table): one
    /// per ring, with the GL spare layer.
    pub fn sg_light_layers(&self, visibility: bool) -> u32 {
        if !visibility {
            return 0;
        }
        let l = self.clipmap.levels;
        if l == 1 || l.is_multiple_of(6) {
            l.saturating_add(1)
        } else {
            l
        }
    }

    /// GPU bytes of the SG shading tables (`gpu/renderer/sg_tables.rs`): the normal table (RGBA32F,
    /// `clip_size^2 x` [`Profile::sg_normal_layers`]) and, for `azimuths > 0` (visibility), the light table
    /// (RGBA16F, `clip_size^2 x` [`Profile::sg_light_layers`], whatever D). Fixed by the profile and the
    /// scene's visibility, whatever the terrain's size, plus the scene's sky table
    /// ([`SG_SKY_TABLE_BYTES`]); [`Profile::footprint`] holds the rest.
    pub fn sg_table_bytes(&self, azimuths: u32) -> u64 {
        let s = u64::from(self.clip_size());
        (s * s)
            .saturating_mul(16 * u64::from(self.sg_normal_layers()))
            .saturating_add(
                (s * s).saturating_mul(8 * u64::from(self.sg_light_layers(azimuths > 0))),
            )
            .saturating_add(SG_SKY_TABLE_BYTES)
    }

    /// Quads per detail tile side ([`FrameBudget::detail_tile_quads`], 0 meaning the block side m, and
    /// never more than m: a tile is drawn with the block mesh).
    pub fn detail_quads(&self) -> u32 {
        match self.budget.detail_tile_quads {
            0 => self.block_m(),
            q => q.min(self.block_m()),
        }
    }

    /// Quads of the pool cell mesh ([`crate::plan::mesh::pool_cells`]): the tile's, or 1 without a pool.
    pub fn pool_mesh_quads(&self) -> u32 {
        if self.budget.detail_tiles == 0 {
            1
        } else {
            self.detail_quads()
        }
    }

    /// Samples per detail tile side: quads + 1 plus a one-sample border on each side.
    pub fn detail_side(&self) -> u32 {
        self.detail_quads().saturating_add(3)
    }

    /// The detail pool texture's layout ([`DetailAtlas`]): at least one tile; one tile per layer up to
    /// [`MAX_DETAIL_LAYERS`] tiles, else the fewest tiles per layer side that fit; the layer count with
    /// the same GL spare layer as [`Profile::height_layers`].
    pub fn detail_atlas(&self) -> DetailAtlas {
        let tiles = self.budget.detail_tiles.max(1);
        let mut cols = 1u32;
        while cols.saturating_mul(cols).saturating_mul(MAX_DETAIL_LAYERS) < tiles {
            cols += 1;
        }
        DetailAtlas {
            side: self.detail_side(),
            cols,
            layers: with_gl_spare_layer(tiles.div_ceil(cols * cols)),
        }
    }

    /// Layers of the detail pool texture ([`Profile::detail_atlas`]).
    pub fn detail_layers(&self) -> u32 {
        self.detail_atlas().layers
    }

    /// The GPU memory this profile needs; see [`Footprint`] for what each part holds.
    ///
    /// Exact for a validated profile; saturating (never wrapping) for any other.
    pub fn footprint(&self) -> Footprint {
        let s = u64::from(self.clip_size());
        let meshes = crate::plan::mesh::block_bytes(self.block_m())
            .saturating_add(crate::plan::mesh::skirt_bytes(
                self.clipmap.n.saturating_add(1),
            ))
            .saturating_add(crate::plan::mesh::skirt_loops_bytes(self.block_m()))
            .saturating_add(crate::plan::mesh::pool_cells_bytes(self.pool_mesh_quads()));
        // Each factor is below 2^32, so the products of two cannot wrap.
        let (w, h) = (u64::from(self.view.width), u64::from(self.view.height));
        let padded_row = (w * 4).div_ceil(256) * 256;
        Footprint {
            heights: (s * s)
                .saturating_mul(u64::from(self.height_layers()))
                .saturating_mul(8),
            meshes,
            targets: (w * h)
                .saturating_mul(8)
                .saturating_add(padded_row.saturating_mul(h)),
            uniforms: GLOBALS_BYTES
                .saturating_add(u64::from(self.budget.max_draws) * DRAW_SLOT_BYTES),
            detail: {
                let a = self.detail_atlas();
                u64::from(a.layer_side())
                    .saturating_mul(u64::from(a.layer_side()))
                    .saturating_mul(u64::from(a.layers))
                    .saturating_mul(8)
            },
            pool_cells: self.pool_cell_capacity() as u64 * POOL_CELL_BYTES,
        }
    }

    /// Records the detail pool's cell buffer holds (whole cells and stitched cells' units): the fewer of
    /// [`MAX_POOL_INSTANCES`] and half `budget.max_triangles`, at least [`MAX_POOL_CELLS`]; one when the
    /// pool is off (every terrain draw binds the buffer and reads instance 0).
    pub fn pool_cell_capacity(&self) -> usize {
        if self.budget.detail_tiles == 0 {
            1
        } else {
            (self.budget.max_triangles as usize / 2).clamp(MAX_POOL_CELLS, MAX_POOL_INSTANCES)
        }
    }
}


/// A TOML parse error as [`Error::Config`]: the key written where the error points (mistyped values), or
/// else the field toml's message names (missing, unknown keys), with line and column.
pub(crate) fn toml_error(source_name: &str, text: &str, e: &toml::de::Error) -> Error {
    let msg = e.message().to_string();
    let start = e.span().map(|s| s.start);
    let field = start
        .and_then(|o| key_at(text, o))
        .or_else(|| msg.split('`').nth(1).map(str::to_owned))
        .unwrap_or_else(|| "?".to_owned());
    let at = start.map(|o| line_col(text, o)).unwrap_or_default();
    Error::config(source_name, field, format!("{msg}{at}"))
}

/// The dotted key whose value starts at byte `offset` (`material.kd`, `lights[1].rgb`), read back from the
/// text: the key before `=` on that line, under the nearest table header above it.
fn key_at(text: &str, offset: usize) -> Option<String> {
    let before = text.get(..offset)?;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let key = before[line_start..].split_once('=')?.0.trim();
    if key.is_empty() || key.starts_with(['#', '[']) {
        return None;
    }
    let above = &before[..line_start];
    let table = above.lines().rev().map(str::trim).find_map(|l| {
        if let Some(name) = l.strip_prefix("[[").and_then(|r| r.split_once("]]")) {
            let header = format!("[[{}]]", name.0);
            let index = above.lines().filter(|x| x.trim() == header).count();
            Some(format!("{}[{}]", name.0.trim(), index.saturating_sub(1)))
        } else {
            l.strip_prefix('[')
                .and_then(|r| r.split_once(']'))
                .map(|(n, _)| n.trim().to_owned())
        }
    });
    Some(match table {
        Some(t) => format!("{t}.{key}"),
        None => key.to_owned(),
    })
}

fn line_col(text: &str, offset: usize) -> String {
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    format!(" (line {line}, column {col})")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_profiles_load() {
        for (name, _) in SHIPPED {
            let p = Profile::load(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(p.name, name);
            assert!(p.footprint().total() <= p.budget.gpu_memory_bytes);
        }
    }
}
