//! `clipsat tune-p`: bake stage diagnostics. For each candidate SFAMF exponent p, how far the SAT estimate
//! and the conservative bound stray from the exact block maximum, and the worst SAT rounding error
//! (docs/design.md "SAT LOD" 4).

use std::io::IsTerminal;

use clap::Args;
use clipsat::bake::lod_tables::{error_map, LevelTables};
use clipsat::bake::pyramid::Pyramid;
use clipsat::bake::sat::pow_unit;
use clipsat::Result;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use super::{ProfileArgs, TerrainArgs};

/// The candidate exponents.
const CANDIDATES: [u32; 9] = [2, 4, 8, 12, 16, 24, 32, 48, 64];

/// Every this many blocks, the SAT sum is checked against an f64 brute-force sum.
const BRUTE_EVERY: usize = 7;

#[derive(Args, Debug)]
pub(crate) struct TunePArgs {
    #[command(flatten)]
    terrain: TerrainArgs,
    #[command(flatten)]
    profile: ProfileArgs,
    /// Print the table as JSON on stdout (and no progress bar).
    #[arg(long)]
    json: bool,
}

/// Mean, 99th percentile and max of a list (sorted in place); zeros when empty.
fn stats(v: &mut [f64]) -> (f64, f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0, 0.0);
    }
    v.sort_by(f64::total_cmp);
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "an index into the list"
    )]
    let p99 = v[((v.len() - 1) as f64 * 0.99).round() as usize];
    (mean, p99, v[v.len() - 1])
}

pub(crate) fn run(args: &TunePArgs) -> Result<()> {
    let (name, hm) = args.terrain.load()?;
    let profile = args.profile.load()?;
    let pyramid = Pyramid::build(&hm);
    let (w, h) = (hm.width(), hm.height());
    let levels = profile.clipmap.levels;
    let m = profile.block_m();
    let show = !args.json && std::io::stderr().is_terminal();
    let bar = |len: u64, what: &str| {
        let b = if show {
            ProgressBar::new(len)
        } else {
            ProgressBar::hidden()
        };
        if let Ok(s) =
            ProgressStyle::with_template(&format!("{what} {{bar:30}} {{pos}}/{{len}} {{elapsed}}"))
        {
            b.set_style(s);
        }
        b
    };

    // Error maps once (data level k = clipmap level k, no synthesis); level 0 has none.
    let b = bar(u64::from(levels), "error maps");
    let maps: Vec<Vec<f32>> = (0..levels)
        .map(|k| {
            b.inc(1);
            error_map(&pyramid, k)
        })
        .collect();
    b.finish_and_clear();

    // Blocks: every cell of every ring's fixed grid (m 2^l data samples a side), inclusive footprints.
    let mut blocks = Vec::new();
    for l in 0..levels {
        let side = m << l;
        for cy in 0..(h - 1).div_ceil(side) {
            for cx in 0..(w - 1).div_ceil(side) {
                let (x0, y0) = (cx * side, cy * side);
                blocks.push((
                    x0,
                    y0,
                    (x0 + side).min(w - 1) + 1,
                    (y0 + side).min(h - 1) + 1,
                ));
            }
        }
    }

    let mut rows = Vec::new();
    let b = bar((CANDIDATES.len() as u64) * u64::from(levels), "tuning p");
    for p in CANDIDATES {
        let (mut est, mut cons) = (Vec::new(), Vec::new());
        let (mut worst_quanta, mut worst_rel, mut misses, mut zero_est) =
            (0.0f64, 0.0f64, 0u64, 0u64);
        for (k, map) in maps.iter().enumerate().skip(1) {
            b.inc(1);
            let t = LevelTables::build(w, h, map.clone(), p)?;
            let Some((sat, _)) = t.tables() else {
                continue;
            };
            let e = f64::from(t.e_max());
            for (i, &(x0, y0, x1, y1)) in blocks.iter().enumerate() {
                let be = t.block(p, x0, y0, x1, y1);
                if be.exact > 0.0 {
                    est.push(be.estimate / be.exact);
                    cons.push(be.conservative / be.exact);
                    if be.estimate == 0.0 {
                        zero_est += 1;
                    }
                }
                if !(be.estimate <= be.exact && be.exact <= be.conservative) {
                    misses += 1;
                }
                if i % BRUTE_EVERY == k % BRUTE_EVERY {
                    let mut s = 0.0f64;
                    for y in y0..y1 {
                        let row = &map[(y * w) as usize..];
                        for &v in &row[x0 as usize..x1 as usize] {
                            s += pow_unit(f64::from(v) / e, p);
                        }
                    }
                    let got = sat.box_sum(x0, y0, x1, y1);
                    let n = f64::from(x1 - x0) * f64::from(y1 - y0);
                    worst_quanta = worst_quanta.max((got - s).abs() / (n * sat.quantum()));
                    // Relative error only where the sum is well above the quantisation floor.
                    if s > 1e3 * n * sat.quantum() {
                        worst_rel = worst_rel.max((got - s).abs() / s);
                    }
                }
            }
        }
        let (em, e99, emax) = stats(&mut est);
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "an index into the sorted list"
        )]
        let e01 = est
            .get(((est.len().max(1) - 1) as f64 * 0.01).round() as usize)
            .copied()
            .unwrap_or(0.0);
        let (cm, c99, cmax) = stats(&mut cons);
        rows.push(json!({
            "p": p,
            "blocks": est.len(),
            "estimate_over_exact": {"mean": em, "p99": e99, "max": emax, "p01": e01},
            "estimate_zero": zero_est,
            "conservative_over_exact": {"mean": cm, "p99": c99, "max": cmax},
            "order_violations": misses,
            "sat_worst_error_quanta_per_sample": worst_quanta,
            "sat_worst_relative_error": worst_rel,
        }));
    }
    b.finish_and_clear();

    if args.json {
        super::print_json(&json!({
            "terrain": name,
            "profile": profile.name,
            "block_m": m,
            "levels": levels,
            "rows": rows,
        }));
        return Ok(());
    }
    outln!(
        "terrain {name}, profile {} (blocks of m = {m} quads per ring, {levels} levels)",
        profile.name
    );
    outln!(
        "   p  blocks   est/exact mean    p99    max    p01  est=0   cons/exact mean    p99     max  order  SAT err (quanta/sample, rel)"
    );
    for r in &rows {
        let f = |a: &str, b: &str| r[a][b].as_f64().unwrap_or(f64::NAN);
        outln!(
            "{:>4} {:>7}        {:>6.3} {:>6.3} {:>6.3} {:>6.3} {:>6}        {:>8.3} {:>6.3} {:>7.3} {:>6}  {:.3} {:.2e}",
            r["p"].as_u64().unwrap_or(0),
            r["blocks"].as_u64().unwrap_or(0),
            f("estimate_over_exact", "mean"),
            f("estimate_over_exact", "p99"),
            f("estimate_over_exact", "max"),
            f("estimate_over_exact", "p01"),
            r["estimate_zero"],
            f("conservative_over_exact", "mean"),
            f("conservative_over_exact", "p99"),
            f("conservative_over_exact", "max"),
            r["order_violations"],
            r["sat_worst_error_quanta_per_sample"].as_f64().unwrap_or(f64::NAN),
            r["sat_worst_relative_error"].as_f64().unwrap_or(f64::NAN),
        );
    }
    Ok(())
}
