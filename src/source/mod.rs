//! Stage 0, the source: terrain files and the built-in procedural terrain, all turned into a [`Heightmap`].
//!
//! Every loader checks sizes against [`LoadOptions::max_samples`] before it allocates, and names the file
//! and the problem in its error; none panics on any input.

use std::path::{Path, PathBuf};

use crate::{Error, Heightmap, Result};

/// How to read a terrain file. The defaults suit the data in `../shared/data`.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Sample spacing in metres, overriding (or supplying) what the file says.
    pub spacing: Option<f32>,
    /// Metres per stored unit for PNG and raw u16 (default: 0.1 for 16-bit, 1.0 for 8-bit).
    pub height_scale: Option<f32>,
    /// Metres added after scaling.
    pub height_offset: f32,
    /// Layout of a headerless raw file.
    pub raw: Option<RawLayout>,
    /// Most samples a file may declare; checked before allocating.
    pub max_samples: u64,
}

/// Default [`LoadOptions::max_samples`]: 2^30 samples, 4 GiB of f32 heights.
pub const DEFAULT_MAX_SAMPLES: u64 = 1 << 30;

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            spacing: None,
            height_scale: None,
            height_offset: 0.0,
            raw: None,
            max_samples: DEFAULT_MAX_SAMPLES,
        }
    }
}

/// The layout of a headerless raw file: little-endian samples, row-major, north-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawLayout {
    /// Samples per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Sample type.
    pub format: RawFormat,
}

/// Sample type of a raw file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RawFormat {
    /// Little-endian u16, scaled by the height scale.
    U16,
    /// Little-endian f32 metres.
    F32,
}

/// Where a terrain comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum TerrainSpec {
    /// The built-in procedural terrain.
    Procedural(crate::source::procedural::ProceduralParams),
    /// A file, its format told by extension (and magic number).
    File(PathBuf),
}

pub mod procedural;

impl TerrainSpec {
    /// Parses `--terrain`: `procedural[:seed=S,size=N,spacing=M]` (also `builtin`), else a file path.
    pub fn parse(text: &str) -> Result<Self> {
        let (head, params) = text.split_once(':').unwrap_or((text, ""));
        if head != "procedural" && head != "builtin" {
            return Ok(Self::File(PathBuf::from(text)));
        }
        let mut p = procedural::ProceduralParams::default();
        for kv in params.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let bad = |reason: String| Error::Arg {
                arg: "--terrain".into(),
                reason,
            };
            let (k, v) = kv
                .split_once('=')
                .ok_or_else(|| bad(format!("`{kv}` is not key=value")))?;
            let num = |what: &str| bad(format!("{what} `{v}` is not a valid number"));
            match k {
                "seed" => p.seed = v.parse().map_err(|_| num("seed"))?,
                "size" => p.size = v.parse().map_err(|_| num("size"))?,
                "spacing" => p.spacing = v.parse().map_err(|_| num("spacing"))?,
                _ => {
                    return Err(bad(format!(
                        "unknown procedural parameter `{k}` (seed, size, spacing)"
                    )))
                }
            }
        }
        Ok(Self::Procedural(p))
    }
}

/// Loads a terrain file, choosing the format from its extension: `.png`, `.tif`/`.tiff`, `.hgt`,
/// `.raw`/`.r16`/`.f32` (the raw ones need [`LoadOptions::raw`]).
pub fn load(path: &Path, opts: &LoadOptions) -> Result<Heightmap> {
    let _ = opts;
    Err(Error::format(path, "loader not written yet"))
}
