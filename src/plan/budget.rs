//! Stage 2, the per-frame plan: which samples of one ring to (re)fill this frame under the update budget
//! (GC section 5). Pure and allocation-free: rectangles in, rectangles out.
//!
//! A ring holds `size x size` samples addressed toroidally. Its valid region V (the clip region) is always a
//! rectangle. Moving it to the desired region D (also `size x size`) keeps K = V intersect D and fills the
//! rest as column bands (all of D's rows) and then row bands (all of D's columns): each band is one
//! toroidal texture interval on one axis and the whole texture on the other, so a level never needs more
//! than 4 upload rectangles per frame.

use crate::plan::frame::{Rect, Upload};

/// The plan for one level this frame.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LevelPlan {
    /// Lattice rectangles to fill, in order (at most two column bands, then two row bands).
    pub bands: heapless::Vec<Rect, 4>,
    /// The clip region once the bands are filled.
    pub valid: Rect,
    /// Samples the bands write (a corner written by a column and a row band counts twice).
    pub samples: u32,
    /// Whether `valid` reaches the desired region.
    pub complete: bool,
    /// Texture sub-rectangles covering every written texel, at most 4.
    pub uploads: heapless::Vec<Upload, 4>,
}

/// The part of V worth keeping: V intersect D, or nothing when refilling D from scratch is cheaper
/// (the incremental bands would write more than `size^2` samples) or they do not overlap (a teleport).
fn kept(valid: &Rect, desired: &Rect, size: u32) -> Rect {
    let k = valid.intersect(desired);
    let s = u64::from(size);
    if k.is_empty() || (s - u64::from(k.w)) * s + (s - u64::from(k.h)) * s > s * s {
        // Zero rows of full width at D's top: the row bands then refill all of D, top to bottom.
        Rect {
            x0: desired.x0,
            y0: desired.y0,
            w: desired.w,
            h: 0,
        }
    } else {
        k
    }
}

/// Samples [`plan_level`] would write to bring `valid` to `desired` with an unlimited budget.
pub fn needed_samples(valid: &Rect, desired: &Rect, size: u32) -> u64 {
    let k = kept(valid, desired, size);
    if k == *desired {
        return 0;
    }
    let s = u64::from(size);
    (s - u64::from(k.w)) * s + (s - u64::from(k.h)) * s
}

/// Plans one level: bands that move `valid` toward `desired` (both in lattice units, `desired` is
/// `size x size`), writing at most `budget_left` samples. Bands are shrunk to whole columns or rows that fit;
/// when one is shrunk the plan is incomplete and the caller stops its coarse-to-fine walk (GC section 5).
pub fn plan_level(
    level: u32,
    valid: &Rect,
    desired: &Rect,
    size: u32,
    budget_left: u32,
) -> LevelPlan {
    assert!(
        desired.w == size && desired.h == size,
        "desired clip region {desired:?} is not {size} x {size}"
    );
    let mut plan = LevelPlan::default();
    let mut v = kept(valid, desired, size);
    let mut left = budget_left;
    let mut complete = true;
    // Columns: side A grows V east from v.x1 to D's east edge, side B grows it west from v.x0.
    'cols: for east in [true, false] {
        let need = if east {
            desired.x1() - v.x1()
        } else {
            v.x0 - desired.x0
        };
        if need <= 0 {
            continue;
        }
        let need = u32::try_from(need).expect("band within one ring");
        let c = need.min(left / size);
        if c > 0 {
            let x0 = if east { v.x1() } else { v.x0 - i64::from(c) };
            push_band(
                &mut plan,
                Rect {
                    x0,
                    y0: desired.y0,
                    w: c,
                    h: size,
                },
            );
            left -= c * size;
            if !east {
                v.x0 -= i64::from(c);
            }
            v.w += c;
        }
        if c < need {
            complete = false;
            break 'cols;
        }
    }
    if complete {
        // Rows: all of D's columns (V spans them now), south first then north.
        for south in [true, false] {
            let need = if south {
                desired.y1() - v.y1()
            } else {
                v.y0 - desired.y0
            };
            if need <= 0 {
                continue;
            }
            let need = u32::try_from(need).expect("band within one ring");
            let r = need.min(left / size);
            if r > 0 {
                let y0 = if south { v.y1() } else { v.y0 - i64::from(r) };
                push_band(
                    &mut plan,
                    Rect {
                        x0: desired.x0,
                        y0,
                        w: size,
                        h: r,
                    },
                );
                left -= r * size;
                if !south {
                    v.y0 -= i64::from(r);
                }
                v.h += r;
            }
            if r < need {
                complete = false;
                break;
            }
        }
    }
    plan.samples = budget_left - left;
    plan.complete = complete && v == *desired;
    plan.valid = if v.is_empty() { Rect::EMPTY } else { v };
    plan.uploads = uploads(level, &plan.bands, desired, size);
    plan
}

fn push_band(plan: &mut LevelPlan, band: Rect) {
    plan.bands
        .push(band)
        .expect("at most two column and two row bands");
}

/// Toroidal texture intervals of the bands along each axis, merged to at most two per axis.
fn uploads(level: u32, bands: &[Rect], desired: &Rect, size: u32) -> heapless::Vec<Upload, 4> {
    let mut cols: heapless::Vec<(u32, u32), 4> = heapless::Vec::new();
    let mut rows: heapless::Vec<(u32, u32), 4> = heapless::Vec::new();
    for b in bands {
        // A band spans D fully along one axis: all `size` texels of that axis.
        let (start, len, out) = if b.h == size && b.y0 == desired.y0 && b.w < size {
            (b.x0, b.w, &mut cols)
        } else {
            (b.y0, b.h, &mut rows)
        };
        let t0 = u32::try_from(start.rem_euclid(i64::from(size))).expect("texel in ring");
        let first = len.min(size - t0);
        out.push((t0, first)).expect("two intervals per band");
        if first < len {
            out.push((0, len - first)).expect("two intervals per band");
        }
    }
    let mut ups = heapless::Vec::new();
    for (x, w) in merge(&mut cols) {
        ups.push(Upload {
            level,
            tex_x: x,
            tex_y: 0,
            w,
            h: size,
        })
        .expect("two column uploads");
    }
    for (y, h) in merge(&mut rows) {
        ups.push(Upload {
            level,
            tex_x: 0,
            tex_y: y,
            w: size,
            h,
        })
        .expect("two row uploads");
    }
    ups
}

/// Sorts intervals, joins touching or overlapping ones, then joins across the smallest gaps until at most two
/// remain. Joining across a gap re-uploads texels that did not change, which is harmless: the GPU copy of
/// every texel still equals the CPU ring.
fn merge(iv: &mut heapless::Vec<(u32, u32), 4>) -> heapless::Vec<(u32, u32), 2> {
    iv.sort_unstable();
    let mut out: heapless::Vec<(u32, u32), 4> = heapless::Vec::new();
    for &(s, l) in iv.iter() {
        match out.last_mut() {
            Some(last) if s <= last.0 + last.1 => {
                last.1 = last.1.max(s + l - last.0);
            }
            _ => out.push((s, l)).expect("at most four intervals"),
        }
    }
    while out.len() > 2 {
        let k = (0..out.len() - 1)
            .min_by_key(|&k| out[k + 1].0 - (out[k].0 + out[k].1))
            .expect("two or more intervals");
        let end = out[k + 1].0 + out[k + 1].1;
        out[k].1 = end - out[k].0;
        out.remove(k + 1);
    }
    out.iter().copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u32 = 20;

    fn d(x0: i64, y0: i64) -> Rect {
        Rect { x0, y0, w: S, h: S }
    }

    fn covered(plan: &LevelPlan) -> u64 {
        plan.uploads
            .iter()
            .map(|u| u64::from(u.w) * u64::from(u.h))
            .sum()
    }

    #[test]
    fn first_fill_is_rows_and_progressive() {
        let p = plan_level(0, &Rect::EMPTY, &d(5, 7), S, 5 * S + 3);
        assert_eq!(p.samples, 5 * S);
        assert!(!p.complete);
        assert_eq!(
            p.valid,
            Rect {
                x0: 5,
                y0: 7,
                w: S,
                h: 5
            }
        );
        let q = plan_level(0, &p.valid, &d(5, 7), S, 1000);
        assert!(q.complete);
        assert_eq!(q.samples, 15 * S);
        assert_eq!(q.valid, d(5, 7));
    }

    #[test]
    fn small_move_is_l_shaped_and_bounded() {
        let p = plan_level(3, &d(0, 0), &d(2, -3), S, u32::MAX);
        assert!(p.complete);
        assert_eq!(p.samples, 2 * S + 3 * S);
        assert!(p.uploads.len() <= 4);
        assert!(covered(&p) >= u64::from(p.samples) - 2 * 3);
        assert_eq!(needed_samples(&d(0, 0), &d(2, -3), S), 5 * u64::from(S));
        assert_eq!(plan_level(3, &d(0, 0), &d(0, 0), S, 0).samples, 0);
    }

    #[test]
    fn two_sided_bands_merge_to_four_uploads() {
        // V narrower than D on both sides in x and in y.
        let v = Rect {
            x0: 4,
            y0: 4,
            w: 12,
            h: 12,
        };
        let p = plan_level(1, &v, &d(0, 0), S, u32::MAX);
        assert!(p.complete);
        assert!(p.uploads.len() <= 4, "{:?}", p.uploads);
        // Every written texel is in an upload.
        for b in &p.bands {
            for j in b.y0..b.y1() {
                for i in b.x0..b.x1() {
                    let tx = u32::try_from(i.rem_euclid(20)).unwrap();
                    let ty = u32::try_from(j.rem_euclid(20)).unwrap();
                    assert!(p.uploads.iter().any(|u| tx >= u.tex_x
                        && tx < u.tex_x + u.w
                        && ty >= u.tex_y
                        && ty < u.tex_y + u.h));
                }
            }
        }
    }
}
