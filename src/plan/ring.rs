//! Stage 2, the per-frame plan: one clipmap ring's toroidal storage (GC section 3), on the CPU and as
//! the bytes the GPU uploads.

/// One ring's storage: `size x size` (z, z_c) pairs, texel (i mod size, j mod size) for lattice sample (i, j).
///
/// The layout is RG32F, row-major: the GPU uploads these bytes as they are.
#[derive(Clone, Debug, PartialEq)]
pub struct Ring {
    size: u32,
    texels: Vec<[f32; 2]>,
}

impl Ring {
    /// A ring of side `size` holding `texels` zeroed (z, z_c) pairs.
    pub(crate) fn new(size: u32, texels: usize) -> Self {
        Self {
            size,
            texels: vec![[0.0; 2]; texels],
        }
    }

    /// A placeholder holding nothing (a ring taken out while it is filled).
    pub(crate) fn empty() -> Self {
        Self {
            size: 0,
            texels: Vec::new(),
        }
    }

    /// The texels, for the fill.
    pub(crate) fn texels_mut(&mut self) -> &mut [[f32; 2]] {
        &mut self.texels
    }

    /// Side of the toroidal storage, `profile.clip_size()`.
    pub fn size(&self) -> u32 {
        self.size
    }

    /// All texels, row-major, (z, z_c) each.
    pub fn texels(&self) -> &[[f32; 2]] {
        &self.texels
    }

    /// The texels as bytes (RG32F), for `write_texture`.
    pub fn bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.texels)
    }

    /// Texel index of lattice sample (i, j).
    #[inline]
    #[expect(
        clippy::cast_possible_truncation,
        reason = "rem_euclid by the ring size is in 0..size"
    )]
    pub fn index(&self, i: i64, j: i64) -> usize {
        let s = i64::from(self.size);
        (j.rem_euclid(s) * s + i.rem_euclid(s)) as usize
    }

    /// The stored (z, z_c) of lattice sample (i, j) (meaningful inside the level's clip region).
    #[inline]
    pub fn get(&self, i: i64, j: i64) -> [f32; 2] {
        self.texels[self.index(i, j)]
    }
}
