//! Stage 2, the per-frame plan: the GC section 5 constraints a clipmap frame must keep, as typed errors.

use crate::plan::frame::Rect;

/// A broken GC section 5 constraint, naming the constraint and the level.
///
/// The constraints, on the regions of GC section 3 (clip = data held, active = rendered), with A ⊘ 2 the
/// region coarsened to the next level's lattice and A ⊖ 1 the region eroded by one sample:
///
/// 1. active_region(l) ⊆ clip_region(l): every rendered vertex has data.
/// 2. active_region(l) ⊘ 2 ⊆ active_region(l+1) ⊖ 1: each level nests inside the next coarser one with at
///    least one coarse sample of border, so the coarser ring's render region is a true ring and the
///    transition region has room.
/// 3. The corners of active_region(l) lie on level l+1's lattice (even coordinates), so the boundary vertices
///    of the finer level coincide with coarser vertices (no T-junctions; z_c = z there).
/// 4. The enabled levels are a contiguous range ending at the coarsest: disabled levels are the finest ones.
///
/// The GC paper text itself was not at hand while writing this; these are the constraints as docs/design.md and
/// the paper's section 5 describe them, in the form the renderer relies on.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ConstraintViolation {
    /// (1) active_region(l) is not inside clip_region(l): rendered vertices without data.
    #[error(
        "constraint 1, level {level}: active region {active:?} is not inside clip region {clip:?}"
    )]
    ActiveOutsideClip {
        /// Level.
        level: u32,
        /// Its active region.
        active: Rect,
        /// Its clip region.
        clip: Rect,
    },
    /// (2) active_region(l) coarsened is not inside active_region(l+1) eroded by one coarse sample.
    #[error(
        "constraint 2, level {level}: active region {active:?} is not nested in level {}'s {coarser:?} \
         with a one-sample border",
        level + 1
    )]
    NotNested {
        /// The finer level.
        level: u32,
        /// Its active region.
        active: Rect,
        /// The coarser level's active region.
        coarser: Rect,
    },
    /// (3) a corner of active_region(l) is not on the coarser level's lattice (an odd coordinate).
    #[error("constraint 3, level {level}: active region {active:?} has a corner off the coarser lattice")]
    OffCoarseLattice {
        /// Level.
        level: u32,
        /// Its active region.
        active: Rect,
    },
    /// (4) an enabled level has a disabled coarser level: enabled levels must be a contiguous coarse range.
    #[error("constraint 4, level {level}: enabled while coarser level {} is disabled", level + 1)]
    NotContiguous {
        /// The enabled level.
        level: u32,
    },
}
