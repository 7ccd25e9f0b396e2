//! Budgets: the profile's `[imagery]` section, what the colour clipmap of draped imagery may take (beside
//! `profile.rs`, the bottom of the import graph, which it extends). Used only where a terrain has
//! imagery: a frame without imagery allocates and spends none of it.

use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// Most colour levels (rings) a profile may keep: a 2^(12 + 11) texel-wide image at its coarsest ring.
pub const MAX_COLOR_LEVELS: u32 = 12;

/// The colour clipmap's budget: ring size, levels, per-frame work and memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageryBudget {
    /// Texels on a side of each colour ring (a power of two, 64 ..= 2048): the GPU holds
    /// `ring^2 x levels` texels, RGBA8 (4 bytes) or BC1 / ETC2 RGB8 blocks (0.5 byte) where the device
    /// has them.
    pub ring: u32,
    /// Colour rings, at most (the image's pyramid may have fewer levels); 1 ..= [`MAX_COLOR_LEVELS`].
    pub levels: u32,
    /// Colour texels written into the rings per frame, at most (at least one tile row, 256).
    pub texels_per_frame: u32,
    /// Imagery tiles decoded per frame, at most (at least 1).
    pub tiles_per_frame: u32,
    /// Bytes of CPU memory for the imagery tile cache (decoded RGB8 tiles of 256^2, 192 KiB each, at
    /// least one); the upload staging (`texels_per_frame x 4` bytes) comes on top.
    pub cache_bytes: u64,
}

impl Default for ImageryBudget {
    /// A small colour clipmap for a profile without an `[imagery]` section: rings of 256^2, 8 levels.
    fn default() -> Self {
        Self {
            ring: 256,
            levels: 8,
            texels_per_frame: 65536,
            tiles_per_frame: 2,
            cache_bytes: 4 << 20,
        }
    }
}

impl ImageryBudget {
    /// Bytes of GPU memory of the colour rings at most: `ring^2 x layers` RGBA8 texels, the format every
    /// device has (in BC1 or ETC2 RGB8 they take an eighth of it; the ledger counts what was made), with
    /// one layer a level and the GL backend's spare ([`ImageryBudget::layers`]).
    pub fn gpu_bytes(&self) -> u64 {
        u64::from(self.ring) * u64::from(self.ring) * u64::from(Self::layers(self.levels)) * 4
    }

    /// Layers of the rings' array texture for `levels` colour levels: one a level, and one more where
    /// that makes 1 or a multiple of 6, which wgpu's GL backend would make a plain 2D texture or a cube
    /// map (sampled as an array, it read as one grey: an image of one level, at most 256 texels a side,
    /// or of six, 4097 to 8192, on every GL device), as [`crate::profile::Profile::height_layers`] does.
    pub fn layers(levels: u32) -> u32 {
        with_gl_spare_layer(levels)
    }

    /// Bytes of CPU memory: the tile cache and the upload staging.
    pub fn cpu_bytes(&self) -> u64 {
        self.cache_bytes + u64::from(self.texels_per_frame) * 4
    }

    /// Checks every field, naming the one at fault (`imagery.ring`).
    pub fn validate(&self, source_name: &str) -> Result<()> {
        let bad = |field: &str, reason: String| Err(Error::config(source_name, field, reason));
        if !(64..=2048).contains(&self.ring) || !self.ring.is_power_of_two() {
            return bad(
                "imagery.ring",
                format!(
                    "{} is not a power of two in 64..=2048 (toroidal wrap by the sampler, the GLES \
                     3.0 texture floor)",
                    self.ring
                ),
            );
        }
        if self.levels == 0 || self.levels > MAX_COLOR_LEVELS {
            return bad(
                "imagery.levels",
                format!("{} is not in 1..={MAX_COLOR_LEVELS}", self.levels),
            );
        }
        if self.texels_per_frame < 256 {
            return bad(
                "imagery.texels_per_frame",
                format!("{} is under one tile row (256)", self.texels_per_frame),
            );
        }
        if self.tiles_per_frame == 0 {
            return bad("imagery.tiles_per_frame", "must be at least 1".into());
        }
        if self.cache_bytes < 3 * 256 * 256 + 4096 {
            return bad(
                "imagery.cache_bytes",
                format!(
                    "{} bytes do not hold one decoded tile (196608 bytes and its record)",
                    self.cache_bytes
                ),
            );
        }
        Ok(())
    }
}

/// `layers` array layers, plus the spare one wgpu's GL backend needs where it would take the texture
/// for a plain 2D texture (one layer) or a cube map (a multiple of 6): the height rings', the detail
/// pool's and the colour rings' layers ([`crate::profile::Profile::height_layers`]).
pub(crate) fn with_gl_spare_layer(layers: u32) -> u32 {
    if layers == 1 || layers.is_multiple_of(6) {
        layers.saturating_add(1)
    } else {
        layers
    }
}

#[cfg(test)]
mod tests {
    use super::ImageryBudget;

    /// One layer a level, and a spare where wgpu's GL backend would take 1 layer for a plain 2D texture
    /// or a multiple of 6 for a cube map.
    #[test]
    fn ring_layers_avoid_gl_s_special_counts() {
        let layers: Vec<u32> = (1..=13).map(ImageryBudget::layers).collect();
        assert_eq!(layers, [2, 2, 3, 4, 5, 7, 7, 8, 9, 10, 11, 13, 13]);
    }
}
