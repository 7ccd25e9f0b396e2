//! Stage 2, the per-frame plan: the record of one clipmap frame (regions, update plan, uploads) and its hash.
//!
//! Every field is fixed-capacity, so building a frame never allocates; [`Frame::hash`] is exact and
//! platform-independent (it is built from integers and the exact bits of the written heights).

use crate::hash::Hash64;

/// Most clipmap levels (rings) of any profile.
pub const MAX_LEVELS: usize = crate::profile::MAX_LEVELS as usize;
/// Most texture uploads per frame: at most 4 sub-rectangles per level (GC section 5).
pub const MAX_UPLOADS: usize = 4 * MAX_LEVELS;

/// A half-open rectangle of lattice samples of one level: columns `x0..x0+w`, rows `y0..y0+h`.
///
/// Columns run east, rows south (like the heightmap's rows). A rectangle with `w == 0` or `h == 0` is empty.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Rect {
    /// First column.
    pub x0: i64,
    /// First row.
    pub y0: i64,
    /// Columns.
    pub w: u32,
    /// Rows.
    pub h: u32,
}

impl Rect {
    /// The empty rectangle.
    pub const EMPTY: Self = Self {
        x0: 0,
        y0: 0,
        w: 0,
        h: 0,
    };

    /// A rectangle from its inclusive start and exclusive end; empty if the end is not past the start.
    pub fn from_bounds(x0: i64, y0: i64, x1: i64, y1: i64) -> Self {
        if x1 <= x0 || y1 <= y0 {
            return Self::EMPTY;
        }
        Self {
            x0,
            y0,
            w: u32::try_from(x1 - x0).expect("rectangle wider than u32"),
            h: u32::try_from(y1 - y0).expect("rectangle taller than u32"),
        }
    }

    /// One past the last column.
    pub fn x1(&self) -> i64 {
        self.x0 + i64::from(self.w)
    }

    /// One past the last row.
    pub fn y1(&self) -> i64 {
        self.y0 + i64::from(self.h)
    }

    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.w == 0 || self.h == 0
    }

    /// Samples held.
    pub fn area(&self) -> u64 {
        u64::from(self.w) * u64::from(self.h)
    }

    /// The common part (empty if none).
    pub fn intersect(&self, o: &Rect) -> Rect {
        if self.is_empty() || o.is_empty() {
            return Self::EMPTY;
        }
        Self::from_bounds(
            self.x0.max(o.x0),
            self.y0.max(o.y0),
            self.x1().min(o.x1()),
            self.y1().min(o.y1()),
        )
    }

    /// Whether every sample of `o` is in `self` (an empty `o` is contained in anything).
    pub fn contains(&self, o: &Rect) -> bool {
        o.is_empty()
            || (!self.is_empty()
                && o.x0 >= self.x0
                && o.y0 >= self.y0
                && o.x1() <= self.x1()
                && o.y1() <= self.y1())
    }

    /// Whether sample (i, j) is inside.
    pub fn contains_point(&self, i: i64, j: i64) -> bool {
        i >= self.x0 && i < self.x1() && j >= self.y0 && j < self.y1()
    }

    fn write(&self, h: &mut Hash64) {
        h.write_i64(self.x0);
        h.write_i64(self.y0);
        h.write_u32(self.w);
        h.write_u32(self.h);
    }
}

/// What happened to one level this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LevelState {
    /// Its clip region already equals the desired one; nothing written.
    Current,
    /// Samples were written and its clip region now equals the desired one.
    Updated,
    /// Its clip region lags the desired one (the budget ran out at or before it); its active region is cropped.
    Stale,
    /// Not rendered: too high above the terrain for it, or its cropped active region is too small.
    Disabled,
}

impl LevelState {
    fn code(self) -> u32 {
        match self {
            Self::Current => 0,
            Self::Updated => 1,
            Self::Stale => 2,
            Self::Disabled => 3,
        }
    }
}

/// One level's part of a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LevelFrame {
    /// What happened to it.
    pub state: LevelState,
    /// The clip region: the samples the ring holds valid data for, in the level's lattice units.
    pub clip: Rect,
    /// The active region: vertices rendered (empty when disabled), in the level's lattice units.
    pub active: Rect,
    /// Samples written into this ring this frame (a twice-written band corner counts twice).
    pub samples_updated: u32,
    /// Triangles its render region (active minus the next finer active) draws, 2 per quad.
    pub triangles: u32,
}

/// One texture sub-rectangle to copy from the CPU ring to the GPU array texture (toroidal texel coordinates).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Upload {
    /// Level, the array layer.
    pub level: u32,
    /// First texel column.
    pub tex_x: u32,
    /// First texel row.
    pub tex_y: u32,
    /// Columns.
    pub w: u32,
    /// Rows.
    pub h: u32,
}

/// The record of one clipmap frame: what `clipsat fly` prints and what the frame hash covers.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Frame {
    /// Frame number, from 0.
    pub index: u64,
    /// Samples written into all rings this frame; never above `budget`.
    pub samples_updated: u32,
    /// The profile's update budget, samples per frame.
    pub budget: u32,
    /// Levels that had samples written.
    pub levels_updated: u32,
    /// Levels left [`LevelState::Stale`].
    pub stale_levels: u32,
    /// Levels [`LevelState::Disabled`].
    pub disabled_levels: u32,
    /// Per level, finest first.
    pub levels: heapless::Vec<LevelFrame, MAX_LEVELS>,
    /// The texture sub-rectangles to upload, at most 4 per level.
    pub uploads: heapless::Vec<Upload, MAX_UPLOADS>,
    /// Triangles the render regions would draw.
    pub triangles: u32,
    /// Hash of the exact bits of every (z, z_c) written this frame, in write order.
    pub z_checksum: u64,
    /// Hash of the whole record; see [`Frame::compute_hash`].
    pub hash: u64,
}

impl Frame {
    /// The 64-bit hash of everything above except `hash` itself.
    pub fn compute_hash(&self) -> u64 {
        let mut h = Hash64::new();
        h.write_u64(self.index);
        h.write_u32(self.samples_updated);
        h.write_u32(self.budget);
        h.write_u32(self.levels_updated);
        h.write_u32(self.stale_levels);
        h.write_u32(self.disabled_levels);
        h.write_u64(self.levels.len() as u64);
        for l in &self.levels {
            h.write_u32(l.state.code());
            l.clip.write(&mut h);
            l.active.write(&mut h);
            h.write_u32(l.samples_updated);
            h.write_u32(l.triangles);
        }
        h.write_u64(self.uploads.len() as u64);
        for u in &self.uploads {
            for v in [u.level, u.tex_x, u.tex_y, u.w, u.h] {
                h.write_u32(v);
            }
        }
        h.write_u32(self.triangles);
        h.write_u64(self.z_checksum);
        h.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rect_ops() {
        let a = Rect::from_bounds(0, 0, 10, 10);
        let b = Rect::from_bounds(5, -3, 20, 4);
        assert_eq!(a.intersect(&b), Rect::from_bounds(5, 0, 10, 4));
        assert!(a.intersect(&Rect::from_bounds(10, 0, 12, 5)).is_empty());
        assert!(a.contains(&Rect::from_bounds(1, 1, 10, 10)));
        assert!(!a.contains(&b));
        assert!(a.contains(&Rect::EMPTY));
    }
}
