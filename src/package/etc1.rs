//! Stage 1b, the package: an ETC1 block encoder (ETC1 blocks are ETC2 RGB8's individual and differential
//! modes, which every ETC2 decoder reads), for the colour rings on devices with ETC2 and not BC
//! (`color_blocks.rs`). Written here, in integer arithmetic, because the one maintained encoder on
//! crates.io (`intel_tex_2`'s ISPC ETC1 kernel) reads uninitialised values (valgrind: 111 contexts in
//! `compress_etc1_half`) and gave a tile different blocks from one run to another, which the frame
//! hashes cannot have. Per block: both flips, both modes (individual RGB444 pairs, differential RGB555
//! with a 3-bit delta where the halves' colours allow it), each half's base colour its rounded mean and
//! each half's table the one of the eight that leaves the least squared error, every pixel taking its
//! best of the table's four modifiers; the least total error wins, ties to the first tried (the
//! Ericsson Texture Compression format, OES_compressed_ETC1_RGB8_texture). A block's bytes are a
//! function of its texels alone.

/// The modifier tables (the smaller and larger magnitude of each; the four values are +a, +b, -a, -b).
const TABLES: [[i32; 2]; 8] = [
    [2, 8],
    [5, 17],
    [9, 29],
    [13, 42],
    [18, 60],
    [24, 80],
    [33, 106],
    [47, 183],
];

/// One half-block's choice: its base colour (expanded to 8 bits), table and each pixel's index.
#[derive(Clone, Copy, Default)]
struct Half {
    table: u32,
    /// Pixel index (0..4: +a, +b, -a, -b) per pixel of the half, in the half's order.
    idx: [u32; 8],
    err: u64,
}

/// The best table and indices for `pixels` around `base`.
fn fit(pixels: &[[i32; 3]; 8], base: [i32; 3]) -> Half {
    let mut best = Half {
        err: u64::MAX,
        ..Half::default()
    };
    for (t, [a, b]) in TABLES.iter().enumerate() {
        let mods = [*a, *b, -a, -b];
        let mut h = Half {
            table: u32::try_from(t).unwrap_or(0),
            ..Half::default()
        };
        for (p, px) in pixels.iter().enumerate() {
            let mut pick = (u64::MAX, 0u32);
            for (m, d) in (0u32..).zip(mods) {
                let r = (base[0] + d).clamp(0, 255) - px[0];
                let g = (base[1] + d).clamp(0, 255) - px[1];
                let b = (base[2] + d).clamp(0, 255) - px[2];
                let e = u64::from((r * r + g * g + b * b).unsigned_abs());
                if e < pick.0 {
                    pick = (e, m);
                }
            }
            h.idx[p] = pick.1;
            h.err += pick.0;
            // A table already past the best cannot win (ties go to the first).
            if h.err >= best.err {
                break;
            }
        }
        if h.err < best.err {
            best = h;
        }
    }
    best
}

/// The pixels (x, y) of half `half` of a block under `flip`: 2 x 4 columns side by side (flip 0) or 4 x 2
/// rows (flip 1).
fn half_pixels(flip: bool, half: u32) -> [(u32, u32); 8] {
    let mut out = [(0, 0); 8];
    for (i, o) in out.iter_mut().enumerate() {
        let i = u32::try_from(i).unwrap_or(0);
        *o = if flip {
            (i % 4, half * 2 + i / 4)
        } else {
            (half * 2 + i / 4, i % 4)
        };
    }
    out
}

/// Encodes one 4 x 4 block (`px[y][x]`, RGB) into ETC1's 8 bytes.
pub fn encode_block(px: &[[[u8; 3]; 4]; 4]) -> [u8; 8] {
    let mut best: Option<(u64, u64)> = None;
    for flip in [false, true] {
        let halves = [half_pixels(flip, 0), half_pixels(flip, 1)];
        let colours = halves.map(|h| {
            h.map(|(x, y)| {
                let c = px[y as usize][x as usize];
                [i32::from(c[0]), i32::from(c[1]), i32::from(c[2])]
            })
        });
        let mean = colours.map(|c| {
            let mut s = [0i32; 3];
            for p in &c {
                for k in 0..3 {
                    s[k] += p[k];
                }
            }
            s.map(|v| (v + 4) / 8)
        });
        // Individual: RGB444 each.
        let q4 = mean.map(|m| m.map(|v| (v * 15 + 127) / 255));
        let e4 = |q: [i32; 3]| q.map(|v| v * 17);
        // Differential: RGB555 and a delta in -4..=3.
        let q5 = mean.map(|m| m.map(|v| (v * 31 + 127) / 255));
        let e5 = |q: [i32; 3]| q.map(|v| (v << 3) | (v >> 2));
        let delta = [0, 1, 2].map(|k| q5[1][k] - q5[0][k]);
        let mut modes = heapless::Vec::<(bool, [[i32; 3]; 2]), 2>::new();
        let _ = modes.push((false, [e4(q4[0]), e4(q4[1])]));
        if delta.iter().all(|d| (-4..=3).contains(d)) {
            let _ = modes.push((true, [e5(q5[0]), e5(q5[1])]));
        }
        for (diff, bases) in modes {
            let h = [fit(&colours[0], bases[0]), fit(&colours[1], bases[1])];
            let err = h[0].err + h[1].err;
            if best.is_some_and(|(e, _)| e <= err) {
                continue;
            }
            let mut word = 0u64;
            for k in 0..3 {
                let shift = 59 - 8 * k;
                word |= if diff {
                    (u64::try_from(q5[0][k]).unwrap_or(0) << shift)
                        | (u64::try_from(delta[k] & 7).unwrap_or(0) << (shift - 3))
                } else {
                    (u64::try_from(q4[0][k]).unwrap_or(0) << (shift + 1))
                        | (u64::try_from(q4[1][k]).unwrap_or(0) << (shift - 3))
                };
            }
            word |= (u64::from(h[0].table) << 37) | (u64::from(h[1].table) << 34);
            word |= (u64::from(diff) << 33) | (u64::from(flip) << 32);
            for (half, pixels) in halves.iter().enumerate() {
                for (p, (x, y)) in pixels.iter().enumerate() {
                    let i = x * 4 + y;
                    let idx = u64::from(h[half].idx[p]);
                    word |= ((idx >> 1) << (16 + i)) | ((idx & 1) << i);
                }
            }
            best = Some((err, word));
        }
    }
    best.map_or([0; 8], |(_, w)| w.to_be_bytes())
}
