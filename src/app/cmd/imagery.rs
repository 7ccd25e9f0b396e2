//! Application (CLI): what an imagery package holds, in words and as JSON, for `info`, `bake`, `render`
//! and `fly`.

use clipsat::package::imagery::{whole_quality, ImageryPackage};
use clipsat::plan::color_rings::ColorRings;
use clipsat::profile::Profile;
use clipsat::Result;
use glam::DVec3;
use serde_json::json;

/// The profile with draped imagery (`engine::setup::imagery_profile`): the feature allowed, the colour
/// rings within the GPU budget, the imagery's CPU share taken out of the budget the heights split.
pub(crate) fn check_profile(profile: &mut Profile) -> Result<()> {
    *profile = clipsat::engine::setup::imagery_profile(profile)?;
    Ok(())
}

/// The colour rings as JSON: the package, the rings and the last update.
pub(crate) fn rings_json(rings: &ColorRings) -> serde_json::Value {
    let mut v = imagery_json(rings.package());
    v["rings"] = json!(rings.level_count());
    v["ring_side"] = json!(rings.ring());
    v["gpu_format"] = json!(rings.format().name());
    v["cpu_bytes"] = json!(rings.cpu_bytes());
    v["last_update"] = json!(rings.stats());
    v["hash"] = json!(clipsat::hash::hex(rings.stats().hash));
    v
}

/// The imagery package's header as JSON: file, size, extent, texel spacing per level, tiles, bytes.
pub(crate) fn imagery_json(p: &ImageryPackage) -> serde_json::Value {
    let h = p.header();
    let levels: Vec<_> = h
        .levels
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let (sx, sy) = h.texel_spacing(i);
            json!({
                "width": l.width,
                "height": l.height,
                "tiles": l.tiles_x * l.tiles_y,
                "texel_spacing_m": [sx, sy],
                "stored": if l.residual { "residual of the level above" } else { "whole" },
            })
        })
        .collect();
    #[expect(clippy::cast_precision_loss, reason = "a ratio for a report")]
    let per_texel = p.len() as f64 / h.texels() as f64;
    json!({
        "file": p.path().display().to_string(),
        "format": format!("clipsat imagery package v{}", clipsat::package::imagery::VERSION),
        "codec": format!(
            "JPEG 4:4:4 quality {} (whole levels {}), even levels as residuals of the level above",
            h.quality,
            whole_quality(q8(h.quality))
        ),
        "width": h.width,
        "height": h.height,
        "extent_m": h.extent.to_array(),
        "tile": h.tile,
        "levels": levels,
        "tiles": h.tiles.len(),
        "bytes": p.len(),
        "bytes_per_texel": per_texel,
    })
}

/// A header's quality as the encoder's (it is at most 100 in a package this build baked).
fn q8(q: u32) -> u8 {
    u8::try_from(q).unwrap_or(u8::MAX)
}

/// The imagery package in a few lines, as `clipsat info` prints it.
pub(crate) fn print_imagery(p: &ImageryPackage) {
    let h = p.header();
    let (sx, sy) = h.texel_spacing(0);
    outln!("imagery   {}", p.path().display());
    outln!(
        "texels    {} x {} at {sx:.3} x {sy:.3} m, extent {}",
        h.width,
        h.height,
        h.extent
    );
    #[expect(clippy::cast_precision_loss, reason = "a ratio for a report")]
    let per_texel = p.len() as f64 / h.texels() as f64;
    outln!(
        "stored    {} levels, {} tiles of {}^2, JPEG 4:4:4 quality {} (whole levels {}), {} bytes ({per_texel:.3} B/texel)",
        h.levels.len(),
        h.tiles.len(),
        h.tile,
        h.quality,
        whole_quality(q8(h.quality)),
        p.len()
    );
    let residual: Vec<String> = (0..h.levels.len())
        .filter(|&i| h.levels[i].residual)
        .map(|i| i.to_string())
        .collect();
    if !residual.is_empty() {
        outln!(
            "residual  levels {} stored as residuals of the level above (alternating pyramid)",
            residual.join(", ")
        );
    }
}

/// `fly --imagery`: the colour rings flown with the heights, on the CPU: each frame updates them at the
/// eye under the profile's `[imagery]` budget and folds their hash (regions, writes, texel bits) into the
/// frame's hash; a flight without imagery keeps its hashes.
pub(crate) struct FlyColour {
    rings: Option<ColorRings>,
    texels_max: u64,
    tiles_max: u32,
    stale_frames: u64,
}

impl FlyColour {
    /// The rings of `package`, if any, with `profile` checked and its CPU budget shared ([`check_profile`]).
    pub(crate) fn new(package: Option<ImageryPackage>, profile: &mut Profile) -> Result<Self> {
        let rings = match package {
            Some(p) => {
                check_profile(profile)?;
                Some(ColorRings::new(p, &profile.imagery)?)
            }
            None => None,
        };
        Ok(Self {
            rings,
            texels_max: 0,
            tiles_max: 0,
            stale_frames: 0,
        })
    }

    /// Updates the rings at `eye`; the frame's hash with theirs folded in (unchanged without imagery).
    pub(crate) fn frame(&mut self, eye: DVec3, hash: u64) -> Result<u64> {
        let Some(rings) = self.rings.as_mut() else {
            return Ok(hash);
        };
        let s = rings.update(eye.x, eye.y)?;
        self.texels_max = self.texels_max.max(s.texels);
        self.tiles_max = self.tiles_max.max(s.tiles_decoded);
        self.stale_frames += u64::from(s.stale_levels > 0);
        let mut h = clipsat::hash::Hash64::new();
        h.write_u64(hash);
        h.write_u64(s.hash);
        Ok(h.finish())
    }

    fn summary(&self) -> Option<serde_json::Value> {
        let rings = self.rings.as_ref()?;
        let mut v = imagery_json(rings.package());
        v["rings"] = json!(rings.level_count());
        v["texels_per_frame_max"] = json!(self.texels_max);
        v["tiles_per_frame_max"] = json!(self.tiles_max);
        v["frames_with_stale_rings"] = json!(self.stale_frames);
        v["cpu_bytes"] = json!(rings.cpu_bytes());
        v["cache"] = json!(rings.cache().stats());
        Some(v)
    }

    /// Adds `imagery` to fly's JSON summary.
    pub(crate) fn annotate(&self, out: &mut serde_json::Value) {
        if let Some(v) = self.summary() {
            out["imagery"] = v;
        }
    }

    /// fly's text line for the imagery, with its newline ("" without imagery).
    pub(crate) fn line(&self) -> String {
        self.rings.as_ref().map_or_else(String::new, |rings| {
            format!(
                "imagery      {} rings; texels per frame max {}, tiles decoded per frame max {}, {} \
                 frames with stale rings\n",
                rings.level_count(),
                self.texels_max,
                self.tiles_max,
                self.stale_frames
            )
        })
    }
}
