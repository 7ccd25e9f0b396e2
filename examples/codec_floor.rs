//! Measurement aid: bytes per sample of the residual pyramid under several tile codings,
//! and the order-0 / context-conditioned entropy of the quantised residuals per level.
//! `cargo run --release --example codec_floor -- FILE [MAX_ERROR]`. Since format 4 the residuals are the
//! symbols of the prediction from the coarser level and the decoded neighbours (`docs/package-codec.md`).
#![expect(
    clippy::cast_possible_truncation,
    reason = "a measurement aid: residuals are narrowed to the byte and i16 codings it compares"
)]
use std::collections::HashMap;
use std::path::Path;

use clipsat::package::codec::{zigzag, Encoder};
use clipsat::package::format::Header;
use clipsat::package::write::residual_tiles;
use clipsat::package::CodecKind;

fn entropy(counts: &HashMap<i32, u64>) -> (f64, u64) {
    let n: u64 = counts.values().sum();
    let h = counts
        .values()
        .map(|&c| {
            let p = c as f64 / n as f64;
            -p * p.log2()
        })
        .sum::<f64>();
    (h, n)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = Path::new(&args[1]);
    let max_error: f64 = args.get(2).map_or(0.5, |s| s.parse().unwrap());
    let hm = clipsat::source::load(path, &clipsat::source::LoadOptions::default()).unwrap();
    let n0 = u64::from(hm.width()) * u64::from(hm.height());
    let tile = 64;
    let header = Header::new(
        hm.width(),
        hm.height(),
        hm.spacing(),
        hm.origin(),
        2.0 * max_error,
        CodecKind::Zstd,
        tile,
    );
    // Per level: value counts, context counts (context = left neighbour's |r| bucket in the tile).
    let mut per_level: Vec<HashMap<i32, u64>> = vec![HashMap::new(); header.levels.len()];
    let mut ctx_level: Vec<HashMap<(u8, i32), u64>> = vec![HashMap::new(); header.levels.len()];
    let mut tiles: Vec<(usize, Vec<i32>, u32)> = Vec::new();
    residual_tiles(&hm, &header, |lk, (tx, ty), r| {
        let (_, _, tw, _) = header.tile_rect(lk, tx, ty);
        for (i, &v) in r.iter().enumerate() {
            *per_level[lk].entry(v).or_default() += 1;
            let x = i as u32 % tw;
            let left = if x > 0 { r[i - 1].unsigned_abs() } else { 0 };
            let up = if i >= tw as usize {
                r[i - tw as usize].unsigned_abs()
            } else {
                0
            };
            let b = |a: u32| -> u8 { a.min(3) as u8 };
            let parity = ((i as u32 / tw) & 1) * 2 + (x & 1);
            let c = b(left) * 16 + b(up) * 4 + parity as u8;
            *ctx_level[lk].entry((c, v)).or_default() += 1;
        }
        tiles.push((lk, r.to_vec(), tw));
        Ok(())
    })
    .unwrap();
    println!(
        "{}: {} x {}, {} levels, max_error {max_error} (q {})",
        path.display(),
        hm.width(),
        hm.height(),
        header.levels.len(),
        2.0 * max_error
    );
    let mut h0_bits = 0.0;
    let mut hc_bits = 0.0;
    for (k, counts) in per_level.iter().enumerate().rev() {
        let (h, n) = entropy(counts);
        // Conditional entropy H(V|C) = H(C,V) - H(C).
        let mut joint = HashMap::new();
        let mut cm: HashMap<u8, u64> = HashMap::new();
        for (&(c, v), &n) in &ctx_level[k] {
            joint.insert((c as i32) << 20 ^ v, n);
            *cm.entry(c).or_default() += n;
        }
        let (hj, _) = entropy(&joint);
        let cmi: HashMap<i32, u64> = cm.iter().map(|(&c, &n)| (c as i32, n)).collect();
        let (hcx, _) = entropy(&cmi);
        let hc = hj - hcx;
        let zeros = counts.get(&0).copied().unwrap_or(0) as f64 / n as f64;
        println!("  level {k:2}: {n:9} samples, H0 {h:.3} bits, H(r|ctx) {hc:.3} bits, zeros {:.1}%, distinct {}", 100.0 * zeros, counts.len());
        h0_bits += h * n as f64;
        hc_bits += hc * n as f64;
    }
    println!(
        "  floor order-0: {:.4} B/sample (of level 0); context: {:.4}",
        h0_bits / 8.0 / n0 as f64,
        hc_bits / 8.0 / n0 as f64
    );
    // Codings.
    let total = |f: &mut dyn FnMut(&[i32], u32) -> usize| -> f64 {
        let s: usize = tiles.iter().map(|(_, r, tw)| f(r, *tw)).sum();
        s as f64 / n0 as f64
    };
    for (name, codec, lvl) in [
        ("zstd-19 planes (shipped)", CodecKind::Zstd, 19),
        ("zstd-3 planes", CodecKind::Zstd, 3),
        ("zstd-22 planes", CodecKind::Zstd, 22),
        ("lz4 planes", CodecKind::Lz4, 0),
    ] {
        let mut e = Encoder::new(codec, lvl).unwrap();
        let t0 = std::time::Instant::now();
        let b = total(&mut |r, _| e.encode(r).unwrap().len());
        println!(
            "  {name:28} {b:.4} B/sample ({:.2} s)",
            t0.elapsed().as_secs_f64()
        );
    }
    let mut z = zstd::bulk::Compressor::new(19).unwrap();
    let b = total(&mut |r, _| {
        let bytes: Vec<u8> = r.iter().flat_map(|&v| (v as i16).to_le_bytes()).collect();
        z.compress(&bytes).unwrap().len() + 1
    });
    println!("  {:28} {b:.4} B/sample", "zstd-19 raw i16");
    let b = total(&mut |r, _| {
        let mut bytes = Vec::new();
        for &v in r {
            let mut u = zigzag(v);
            loop {
                if u < 128 {
                    bytes.push(u as u8);
                    break;
                }
                bytes.push((u as u8 & 127) | 128);
                u >>= 7;
            }
        }
        z.compress(&bytes).unwrap().len() + 1
    });
    println!("  {:28} {b:.4} B/sample", "zstd-19 zigzag varint");
    // Whole-level streams (no tiling): what tiling costs.
    let mut by_level: Vec<Vec<u8>> = vec![Vec::new(); header.levels.len()];
    for (lk, r, _) in &tiles {
        by_level[*lk].extend(r.iter().map(|&v| zigzag(v).min(255) as u8));
    }
    let b: usize = by_level.iter().map(|v| z.compress(v).unwrap().len()).sum();
    println!(
        "  {:28} {:.4} B/sample",
        "zstd-19 whole levels, 1 plane",
        b as f64 / n0 as f64
    );
}
