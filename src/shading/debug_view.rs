//! Stage 3, the GPU: the renderer's debug views (`render --debug`, `clipsat view`), each its own shader
//! variant of `shaders_gles/clipmap.wgsl` (see `shaders_gles/debug_view.wgsl`).
//!
//! `Levels` colours every block by the level it was drawn at, like the SAT paper's figure 3 (Li et al.
//! 2021), in every LOD mode; `Wireframe` draws the lattice lines of each block in its level's colour over
//! the dimmed normal shading (GLES 3.0 has no line polygon mode, so the lines are drawn in the fragment
//! shader).

use std::fmt;
use std::str::FromStr;

use crate::Error;

/// What the terrain's fragment shader shows: the shading, or a debug view of the LOD
/// ([`crate::FrameOptions::debug`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DebugView {
    /// The normal shading (the frame hashes and goldens).
    #[default]
    Normal,
    /// Blocks coloured by their drawn level (twelve hues, the last repeated past level 11), lit by a plain
    /// Lambert factor.
    Levels,
    /// Lattice lines in the level colours over the dimmed normal shading.
    Wireframe,
}

impl DebugView {
    /// Every view, in the order `clipsat view` cycles them.
    #[doc(hidden)]
    pub const ALL: [DebugView; 3] = [DebugView::Normal, DebugView::Levels, DebugView::Wireframe];

    /// The shader's `DEBUG_VIEW` constant.
    #[doc(hidden)]
    pub fn code(self) -> u32 {
        match self {
            DebugView::Normal => 0,
            DebugView::Levels => 1,
            DebugView::Wireframe => 2,
        }
    }

    /// The next view in [`DebugView::ALL`], wrapping.
    pub fn next(self) -> Self {
        Self::ALL[(self.code() as usize + 1) % Self::ALL.len()]
    }
}

impl fmt::Display for DebugView {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DebugView::Normal => "normal",
            DebugView::Levels => "levels",
            DebugView::Wireframe => "wireframe",
        })
    }
}

impl FromStr for DebugView {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self, Error> {
        match s {
            "normal" | "none" => Ok(DebugView::Normal),
            "levels" => Ok(DebugView::Levels),
            "wireframe" => Ok(DebugView::Wireframe),
            other => Err(Error::Invalid {
                what: "debug view".into(),
                reason: format!("`{other}` is not normal, levels or wireframe"),
            }),
        }
    }
}

/// The level colours (display-encoded RGB); mirrors `DEBUG_LEVEL_COLOURS` in
/// `shaders_gles/debug_view.wgsl`. Hues 30 degrees apart (HSV s 0.8, v 0.95), ordered so that neighbouring
/// levels contrast; levels past the last take the last colour.
pub const LEVEL_COLOURS: [[f32; 3]; 12] = [
    [0.95, 0.19, 0.19],
    [0.19, 0.95, 0.19],
    [0.19, 0.19, 0.95],
    [0.95, 0.95, 0.19],
    [0.19, 0.95, 0.95],
    [0.95, 0.19, 0.95],
    [0.95, 0.57, 0.19],
    [0.19, 0.95, 0.57],
    [0.57, 0.19, 0.95],
    [0.57, 0.95, 0.19],
    [0.19, 0.57, 0.95],
    [0.95, 0.19, 0.57],
];

/// The level whose colour an RGBA8 pixel of a [`DebugView::Levels`] image has, if any. The shader scales
/// a level colour by a light factor of at least 0.4, so the pixel is matched by chromaticity (each channel
/// over the largest); pixels too dark to tell (largest channel under 48) match nothing.
pub fn level_of_pixel(px: [u8; 4]) -> Option<u32> {
    let max = px[0].max(px[1]).max(px[2]);
    if max < 48 {
        return None;
    }
    let chroma = |c: [f32; 3]| {
        let m = c[0].max(c[1]).max(c[2]);
        [c[0] / m, c[1] / m, c[2] / m]
    };
    let p = chroma([f32::from(px[0]), f32::from(px[1]), f32::from(px[2])]);
    // Neighbouring hues differ by at least 0.4 in one channel's chromaticity; rounding costs at most 1/48.
    LEVEL_COLOURS.iter().zip(0u32..).find_map(|(c, level)| {
        let c = chroma(*c);
        let close = (0..3).all(|i| (p[i] - c[i]).abs() < 0.12);
        close.then_some(level)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_displays_and_cycles() {
        for v in DebugView::ALL {
            assert_eq!(v.to_string().parse::<DebugView>().ok(), Some(v));
        }
        assert!("levelz".parse::<DebugView>().is_err());
        assert_eq!(DebugView::Wireframe.next(), DebugView::Normal);
        assert_eq!(DebugView::Normal.next(), DebugView::Levels);
    }

    #[test]
    fn level_colours_are_told_apart_at_every_light_level() {
        for (c, level) in LEVEL_COLOURS.iter().zip(0u32..) {
            for light in [0.4f32, 0.7, 1.0] {
                #[expect(
                    clippy::cast_possible_truncation,
                    reason = "a [0, 255] channel value rounds to a u8"
                )]
                let px = c.map(|v| (v * light * 255.0).round() as u8);
                assert_eq!(level_of_pixel([px[0], px[1], px[2], 255]), Some(level));
            }
        }
        // The sky and a mid-grey are no level.
        assert_eq!(level_of_pixel([161, 194, 230, 255]), None);
        assert_eq!(level_of_pixel([128, 128, 128, 255]), None);
    }
}
