//! Measurement aid: what a baked package's tiles cost against the entropy of what they hold.
//! `cargo run --release --example package_floor -- PACKAGE.clipsat` (bake it first: `clipsat bake T
//! --out PACKAGE.clipsat --max-error 0.5 --codec zstd`: it reads the byte-plane codings only); the
//! results are recorded in `src/package/lod_tiles.rs`, `docs/package-codec.md` and the README's
//! **Terrain packages**.
//!
//! - The residual pyramid: its tiles' bytes, the order-0 floor (Shannon entropy of each level's
//!   residuals), a context floor (each residual conditioned on the sum of its left, upper and half its
//!   upper diagonal neighbours' |r|, capped at 15), and zstd-19 with a raw-content dictionary of 16 and
//!   64 KiB sampled from the package's own tiles (the dictionary's bytes reported apart).
//! - The SAT LOD records (stored levels): their tiles' bytes; per level the order-0 entropy of the max and
//!   mean codes and conditioned on a neighbour context (max codes: the MED prediction of the left, upper
//!   and upper-left codes; mean codes: the containing closed cell's max code / 8); and zstd-19 over tiles
//!   of 32-256 cells with the max and mean codes in one stream or two.
#![expect(
    clippy::cast_possible_truncation,
    reason = "a measurement aid: zigzagged residuals are cut into their byte planes"
)]
use std::collections::HashMap;

use clipsat::package::codec::{zigzag, Decoder};
use clipsat::package::format::Header;
use clipsat::package::lod_tiles::decode_tile;

/// Entropy in bits of the counted values, times their count.
fn bits(counts: &HashMap<i64, u64>) -> f64 {
    let n: u64 = counts.values().sum();
    counts
        .values()
        .map(|&c| -(c as f64) * (c as f64 / n as f64).log2())
        .sum()
}

/// Total bits of the order-0 entropy of `v`.
fn order0(v: impl Iterator<Item = i64>) -> f64 {
    let mut c = HashMap::new();
    for x in v {
        *c.entry(x).or_default() += 1u64;
    }
    bits(&c)
}

/// Total bits of H(V | C) over (context, value) pairs: H(C, V) - H(C).
fn conditional(pairs: &[(i64, i64)]) -> f64 {
    let (mut joint, mut ctx): (HashMap<i64, u64>, HashMap<i64, u64>) = Default::default();
    for &(c, v) in pairs {
        *joint.entry(c * 1_000_003 + v).or_default() += 1;
        *ctx.entry(c).or_default() += 1;
    }
    bits(&joint) - bits(&ctx)
}

/// The zigzagged byte planes of a tile, as the package codes them.
fn planes(r: &[i32]) -> Vec<u8> {
    let max = r.iter().map(|&v| zigzag(v)).max().unwrap_or(0);
    let n = (4 - max.leading_zeros() / 8).max(1);
    (0..n)
        .flat_map(|p| r.iter().map(move |&v| (zigzag(v) >> (8 * p)) as u8))
        .collect()
}

/// The median edge detector: a code predicted from its left, upper and upper-left neighbours.
fn med(l: i64, u: i64, ul: i64) -> i64 {
    if ul >= l.max(u) {
        l.min(u)
    } else if ul <= l.min(u) {
        l.max(u)
    } else {
        l + u - ul
    }
}

fn main() {
    let path = std::path::PathBuf::from(std::env::args().nth(1).expect("a package path"));
    let bytes = std::fs::read(&path).expect("read the package");
    let hd = Header::parse(&path, &bytes, bytes.len() as u64).expect("a package");
    if hd.codec == clipsat::package::CodecKind::Rans {
        eprintln!(
            "{}: rANS height tiles; bake it with `--codec zstd` or `lz4`",
            path.display()
        );
        std::process::exit(2);
    }
    let n0 = hd.samples() as f64;
    let per = |b: f64| b / n0;
    let t = hd.tile as usize;
    let mut dec = Decoder::new(hd.codec, t * t).expect("decoder");
    let payload = |offset: u64, len: u32| &bytes[offset as usize..offset as usize + len as usize];
    println!("{}: {} x {}", path.display(), hd.width, hd.height);

    // The residual pyramid.
    let mut tiles: Vec<(usize, usize, Vec<i32>)> = Vec::new();
    for (l, d) in hd.levels.iter().enumerate() {
        for ty in 0..d.tiles_y {
            for tx in 0..d.tiles_x {
                let e = hd.tile(l, tx, ty).expect("tile");
                let (_, _, tw, th) = hd.tile_rect(l, tx, ty);
                let mut out = vec![0; (tw * th) as usize];
                dec.decode(payload(e.offset, e.len), &mut out)
                    .expect("an intact tile");
                tiles.push((l, tw as usize, out));
            }
        }
    }
    let (mut h0, mut hc) = (0.0, 0.0);
    for l in 0..hd.levels.len() {
        let mut pairs = Vec::new();
        for (_, tw, r) in tiles.iter().filter(|(ll, _, _)| *ll == l) {
            for (i, &x) in r.iter().enumerate() {
                let (xx, yy) = (i % tw, i / tw);
                let at = |ok: bool, j: usize| if ok { r[j].unsigned_abs() } else { 0 };
                let left = at(xx > 0, i.wrapping_sub(1));
                let up = at(yy > 0, i.wrapping_sub(*tw));
                let ul = at(xx > 0 && yy > 0, i.wrapping_sub(tw + 1));
                let ur = at(xx + 1 < *tw && yy > 0, i.wrapping_sub(tw - 1));
                pairs.push((i64::from((left + up + (ul + ur) / 2).min(15)), i64::from(x)));
            }
        }
        h0 += order0(pairs.iter().map(|p| p.1));
        hc += conditional(&pairs);
    }
    println!(
        "  pyramid tiles {:.4} B/sample; order-0 floor {:.4}; context floor {:.4}",
        per(hd.pyramid_bytes() as f64),
        per(h0 / 8.0),
        per(hc / 8.0)
    );
    let all: Vec<Vec<u8>> = tiles.iter().map(|(_, _, r)| planes(r)).collect();
    for kib in [16usize, 64] {
        let mut dict = Vec::new();
        for p in all.iter().step_by((all.len() / 64).max(1)) {
            if dict.len() >= kib << 10 {
                break;
            }
            dict.extend_from_slice(&p[..p.len().min((kib << 10) / 16)]);
        }
        let mut z = zstd::bulk::Compressor::with_dictionary(19, &dict).expect("zstd");
        let s: usize = all
            .iter()
            .map(|p| z.compress(p).expect("zstd").len() + 1)
            .sum();
        println!(
            "  pyramid, zstd-19 with a {kib} KiB raw-content dictionary: {:.4} B/sample + {:.4} the dictionary",
            per(s as f64),
            per(dict.len() as f64)
        );
    }

    // The SAT LOD records' stored levels, gathered into whole-level code grids.
    let Some(lod) = hd.lod.as_ref() else {
        return;
    };
    let mut scratch = Vec::new();
    let mut grids = Vec::new();
    for lv in lod.levels.iter().filter(|l| l.stored) {
        let g = lv.grid;
        let mut mg = vec![0u8; (g.cw * g.ch) as usize];
        let mut ng = vec![0u8; (g.sw * g.sh) as usize];
        for ty in 0..g.tiles_y {
            for tx in 0..g.tiles_x {
                let e = lod.tiles[lv.first_tile + (ty * g.tiles_x + tx) as usize];
                let (mx, my, mw, mh) = g.max_rect(tx, ty);
                let (nx, ny, nw, nh) = g.mean_rect(tx, ty);
                let (mut a, mut b) = (vec![0u8; (mw * mh) as usize], vec![0u8; (nw * nh) as usize]);
                decode_tile(
                    &mut dec,
                    payload(e.offset, e.len),
                    &mut a,
                    &mut b,
                    &mut scratch,
                )
                .expect("an intact record tile");
                for j in 0..mh {
                    for i in 0..mw {
                        mg[((my + j) * g.cw + mx + i) as usize] = a[(j * mw + i) as usize];
                    }
                }
                for j in 0..nh {
                    for i in 0..nw {
                        ng[((ny + j) * g.sw + nx + i) as usize] = b[(j * nw + i) as usize];
                    }
                }
            }
        }
        grids.push((g, mg, ng));
    }
    println!("  record tiles {:.4} B/sample", per(hd.lod_bytes() as f64));
    let (mut r0, mut rc) = (0.0, 0.0);
    for (g, mg, ng) in &grids {
        let (cw, sw) = (g.cw as usize, g.sw as usize);
        let code = |i: usize| i64::from(mg[i]);
        let mut mp = Vec::new();
        for i in 0..mg.len() {
            let (x, y) = (i % cw, i / cw);
            let l = if x > 0 {
                code(i - 1)
            } else if y > 0 {
                code(i - cw)
            } else {
                0
            };
            let u = if y > 0 { code(i - cw) } else { l };
            let ul = if x > 0 && y > 0 { code(i - cw - 1) } else { u };
            mp.push((med(l, u, ul), code(i)));
        }
        let np: Vec<(i64, i64)> = ng
            .iter()
            .enumerate()
            .map(|(i, &c)| {
                let (x, y) = ((i % sw).min(cw - 1), (i / sw).min(g.ch as usize - 1));
                (code(y * cw + x) / 8, i64::from(c))
            })
            .collect();
        let (a, b) = (
            order0(mp.iter().map(|p| p.1)),
            order0(np.iter().map(|p| p.1)),
        );
        let (c, d) = (conditional(&mp), conditional(&np));
        println!(
            "  level {:2}: max code {:.2} bits (order 0), {:.2} (MED context); mean code {:.2}, {:.2} (max/8 context)",
            g.k,
            a / mp.len() as f64,
            c / mp.len() as f64,
            b / np.len() as f64,
            d / np.len() as f64
        );
        r0 += a + b;
        rc += c + d;
    }
    println!(
        "  records order-0 floor {:.4} B/sample; context floor {:.4}",
        per(r0 / 8.0),
        per(rc / 8.0)
    );
    let mut z = zstd::bulk::Compressor::new(19).expect("zstd");
    for tile in [32usize, 64, 128, 256] {
        let (mut one, mut two) = (0usize, 0usize);
        for (g, mg, ng) in &grids {
            let (cw, sw, ch, sh) = (g.cw as usize, g.sw as usize, g.ch as usize, g.sh as usize);
            for ty in (0..sh).step_by(tile) {
                for tx in (0..sw).step_by(tile) {
                    let cut = |grid: &[u8], w: usize, h: usize| -> Vec<u8> {
                        (ty..(ty + tile).min(h))
                            .flat_map(|y| (tx..(tx + tile).min(w)).map(move |x| (x, y)))
                            .map(|(x, y)| grid[y * w + x])
                            .collect()
                    };
                    let (a, b) = (cut(mg, cw, ch), cut(ng, sw, sh));
                    let both: Vec<u8> = a.iter().chain(&b).copied().collect();
                    one += z.compress(&both).expect("zstd").len() + 1;
                    two += z.compress(&a).expect("zstd").len()
                        + z.compress(&b).expect("zstd").len()
                        + 6;
                }
            }
        }
        println!(
            "  records, zstd-19 in tiles of {tile} cells: one stream {:.4} B/sample, two streams {:.4}",
            per(one as f64),
            per(two as f64)
        );
    }
}
