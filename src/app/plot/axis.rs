//! Application (the binary's plots): axis ranges, ticks and labels in 1-2-5 steps and decades, as the
//! plotters coordinate [`Axis`] whose key points are exactly our ticks.

use plotters::coord::ranged1d::{KeyPointHint, NoDefaultFormatting, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::to_i32;

/// One axis for plotters: a linear coordinate in plot units (log10 units on a log axis) whose key points
/// are exactly our ticks, labelled with our labels, and on a log axis 2..9 x 10^k as light grid lines.
#[derive(Clone)]
pub(super) struct Axis {
    pub(super) range: std::ops::Range<f64>,
    /// (plot units, label).
    pub(super) ticks: Vec<(f64, String)>,
    /// Light grid lines, plot units.
    pub(super) light: Vec<f64>,
}

impl Axis {
    pub(super) fn new(range: &Range, ticks: &[(f64, String)], log: bool) -> Self {
        let at = |v: f64| if log { v.log10() } else { v };
        Self {
            range: range.lo..range.hi,
            ticks: ticks.iter().map(|(v, l)| (at(*v), l.clone())).collect(),
            light: if log {
                range
                    .minor_log_ticks()
                    .into_iter()
                    .map(f64::log10)
                    .collect()
            } else {
                Vec::new()
            },
        }
    }
}

impl Ranged for Axis {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        RangedCoordf64::from(self.range.clone()).map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.ticks.iter().map(|t| t.0).collect()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.range.clone()
    }
}

impl ValueFormatter<f64> for Axis {
    /// The label of the tick nearest `value` (plotters asks with the key point's own value).
    fn format_ext(&self, value: &f64) -> String {
        self.ticks
            .iter()
            .min_by(|a, b| (a.0 - value).abs().total_cmp(&(b.0 - value).abs()))
            .map(|(_, l)| l.clone())
            .unwrap_or_default()
    }
}

pub(super) fn usable(x: f64, y: f64, x_log: bool) -> bool {
    x.is_finite() && y.is_finite() && (!x_log || x > 0.0)
}

/// An axis range in data units (log10 units for a log axis).
pub(super) struct Range {
    pub(super) lo: f64,
    pub(super) hi: f64,
}

impl Range {
    pub(super) fn of(values: impl Iterator<Item = f64>, log: bool) -> Self {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values {
            let v = if log { v.log10() } else { v };
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if !lo.is_finite() {
            return Self { lo: 0.0, hi: 1.0 };
        }
        if hi - lo <= f64::EPSILON * hi.abs().max(1.0) {
            let pad = if log { 0.5 } else { (lo.abs() * 0.1).max(1.0) };
            return Self {
                lo: lo - pad,
                hi: hi + pad,
            };
        }
        let pad = (hi - lo) * 0.04;
        Self {
            lo: lo - pad,
            hi: hi + pad,
        }
    }

    /// Tick values (in data units) and their labels: steps of 1, 2 or 5 x 10^k, about 5 to 10 ticks;
    /// decades on a log axis that spans at least 2.5; on a shorter log axis 1, 2, 5 x 10^k (or 1..8 x 10^k)
    /// when that gives four or more.
    pub(super) fn ticks(&self, log: bool) -> Vec<(f64, String)> {
        if log && self.hi - self.lo >= 2.5 {
            let step = ((self.hi - self.lo) / 8.0).ceil().max(1.0);
            let mut k = (self.lo / step).ceil() * step;
            let mut out = Vec::new();
            while k <= self.hi + 1e-9 {
                let v = 10f64.powf(k);
                out.push((v, format_number(v, v)));
                k += step;
            }
            return out;
        }
        let (lo, hi) = if log {
            (10f64.powf(self.lo), 10f64.powf(self.hi))
        } else {
            (self.lo, self.hi)
        };
        if log {
            for mantissas in [&[1.0, 2.0, 5.0][..], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0]] {
                let mut out = Vec::new();
                let mut k = self.lo.floor();
                while k <= self.hi.ceil() && out.len() < 64 {
                    for m in mantissas {
                        let v = m * 10f64.powf(k);
                        if (lo..=hi).contains(&v) {
                            out.push((v, format_number(v, v)));
                        }
                    }
                    k += 1.0;
                }
                if out.len() >= 4 {
                    return out;
                }
            }
        }
        let raw = (hi - lo) / 6.0;
        let mag = 10f64.powf(raw.log10().floor());
        let step = [1.0, 2.0, 5.0, 10.0]
            .iter()
            .map(|m| m * mag)
            .find(|st| *st >= raw)
            .unwrap_or(10.0 * mag);
        let mut out = Vec::new();
        let mut i = (lo / step).ceil();
        while i * step <= hi + step * 1e-9 && out.len() < 64 {
            // Snap tiny values to zero so "0" is printed, not "-1.1e-17".
            let v = if (i * step).abs() < step * 1e-9 {
                0.0
            } else {
                i * step
            };
            out.push((v, format_number(v, step)));
            i += 1.0;
        }
        out
    }

    /// 2..9 x 10^k inside a log range.
    pub(super) fn minor_log_ticks(&self) -> Vec<f64> {
        let mut out = Vec::new();
        let mut k = self.lo.floor();
        while k <= self.hi && out.len() < 512 {
            for m in 2..10 {
                let v = f64::from(m) * 10f64.powf(k);
                let l = v.log10();
                if l >= self.lo && l <= self.hi {
                    out.push(v);
                }
            }
            k += 1.0;
        }
        out
    }
}

/// A tick label: as many decimals as `step` needs; scientific (`2.5e6`) for very large or small values.
pub(super) fn format_number(v: f64, step: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        let s = format!("{v:e}");
        // Trim long mantissas: 1.2345678e7 -> 1.23e7.
        return match s.split_once('e') {
            Some((m, e)) if m.len() > 5 => format!("{}e{e}", &m[..5].trim_end_matches('0')),
            _ => s,
        };
    }
    let decimals = usize::try_from(to_i32(-step.abs().log10().floor()).clamp(0, 6)).unwrap_or(0);
    format!("{v:.decimals$}")
}
