//! Stage 1b, the package: an ETC2 RGB8 block encoder, for the colour rings on devices with ETC2 and not
//! BC (`color_blocks.rs`). Written here, in integer arithmetic, because the one maintained encoder on
//! crates.io (`intel_tex_2`'s ISPC ETC1 kernel) reads uninitialised values (valgrind: 111 contexts in
//! `compress_etc1_half`) and gave a tile different blocks from one run to another, which the frame
//! hashes cannot have. Per block it fits ETC1's modes (ETC2's individual and differential modes), then
//! ETC2's planar mode (`etc2_planar.rs`), then its T and H modes (`etc2_th.rs`), each only where it
//! leaves less squared RGB error than the best before it (OpenGL ES 3.0, Annex C.1; Khronos Data Format
//! 1.3, section 21.1). A block's bytes are a function of its texels alone.
//!
//! ETC1 modes: both flips; each of the four half-blocks (left, right, top, bottom) is searched alone,
//! in RGB444 (individual mode) and RGB555 (differential mode). A half's search fits its rounded mean
//! colour: every table, each texel taking its best modifier, the table leaving the least error; then
//! the least-squares colour under the modifiers chosen (the mean less the modifiers' mean), again under
//! every table; then one step up and one step down in all three channels from the best colour, under its
//! table. Differential mode pairs the halves' RGB555 colours kept (each better than the one before it)
//! whose difference fits its 3-bit delta, the pair leaving the least error. On the two shared images,
//! added in this order: the search past the mean colours 0.17-0.25 dB, the planar mode 0.03-0.20 dB,
//! the T and H modes 1.30-2.05 dB (`docs/guide.md` has the totals).

use super::etc2_planar::{self, clamp, Texels};
use super::etc2_th;

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

/// The fits a half's search makes before its neighbours: its mean colour's, then least-squares steps.
const LS_TRIES: usize = 2;
/// The steps around the best base colour a half's search tries last, in the mode's bits.
const NEIGHBOURS: [[i32; 3]; 2] = [[1, 1, 1], [-1, -1, -1]];
/// Base colours a half's search fits, at most.
const TRIES: usize = LS_TRIES + NEIGHBOURS.len();

// The hot loops below are `while` loops over indices, with `min`, `max` and `clamp` written out: the test
// profile (opt-level 1, incremental) leaves range iterators and `Ord`'s methods as calls, which made
// the encoder three times slower there (210 ms a tile, not 70).

/// A half-block's base colour (quantised) with its best table and each texel's modifier.
#[derive(Clone, Copy, Default)]
struct Fit {
    /// The base colour in the mode's bits (4 or 5 a channel).
    q: [i32; 3],
    table: usize,
    /// Modifier index (0..4: +a, +b, -a, -b) per texel of the half, in the half's order.
    idx: [usize; 8],
    err: u32,
}

/// A quantised channel expanded to 8 bits (its high bits repeated below it).
fn expand(q: i32, bits: u32) -> i32 {
    (q << (8 - bits)) | (q >> (2 * bits - 8))
}

/// The nearest `bits`-bit value to an eighth of `sum8` (clamped to 0..=255).
fn quantise(sum8: i32, bits: u32) -> i32 {
    let max = (1 << bits) - 1;
    (clamp(sum8, 0, 8 * 255) * max + 4 * 255) / (8 * 255)
}

/// The modifiers of table `t`: +a, +b, -a, -b.
fn modifiers(t: usize) -> [i32; 4] {
    let [a, b] = TABLES[t];
    [a, b, -a, -b]
}

/// The best of tables `tables.0..tables.1` and its modifiers for the texels `px` around the base colour
/// `q` (`bits` a channel), or none where none leaves less error than `limit`.
fn fit(px: &[[i32; 3]; 8], q: [i32; 3], bits: u32, tables: (usize, usize), limit: u32) -> Option<Fit> {
    let base = [expand(q[0], bits), expand(q[1], bits), expand(q[2], bits)];
    // Without clamping a texel's error under modifier d is e0 + d (2 s + 3 d), e0 its squared distance
    // from the base and s the sum of its channels' differences: least for the d of s's opposite sign,
    // min(a (3 a - 2 |s|), b (3 b - 2 |s|)) over e0 (an exact integer).
    let mut e0p = [0i32; 8];
    let mut s = [0i32; 8];
    let mut w = [0i32; 8];
    let mut e0 = 0;
    let mut p = 0;
    while p < 8 {
        let d = [base[0] - px[p][0], base[1] - px[p][1], base[2] - px[p][2]];
        e0p[p] = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        s[p] = d[0] + d[1] + d[2];
        w[p] = 2 * s[p].abs();
        e0 += e0p[p];
        p += 1;
    }
    let lo = if base[0] < base[1] { base[0] } else { base[1] };
    let lo = if lo < base[2] { lo } else { base[2] };
    let hi = if base[0] > base[1] { base[0] } else { base[1] };
    let hi = if hi > base[2] { hi } else { base[2] };
    let clamps = |t: usize| lo - TABLES[t][1] < 0 || hi + TABLES[t][1] > 255;
    // The tables that clamp no modifier first (their error is cheap), then those that do, each stopped
    // once past the best so far.
    let mut best = (limit, usize::MAX);
    let mut t = tables.0;
    while t < tables.1 {
        if !clamps(t) {
            let [a, b] = TABLES[t];
            let (a3, b3) = (3 * a, 3 * b);
            let mut e = e0;
            let mut p = 0;
            while p < 8 {
                let (ea, eb) = (a * (a3 - w[p]), b * (b3 - w[p]));
                e += if eb < ea { eb } else { ea };
                p += 1;
            }
            if e.unsigned_abs() < best.0 {
                best = (e.unsigned_abs(), t);
            }
        }
        t += 1;
    }
    let mut clamped_idx = None;
    let mut t = tables.0;
    while t < tables.1 {
        if clamps(t) {
            let (err, idx) = clamped(px, base, (&e0p, &s), t, best.0);
            if err < best.0 {
                best = (err, t);
                clamped_idx = Some(idx);
            }
        }
        t += 1;
    }
    let t = best.1;
    let [a, b] = *TABLES.get(t)?;
    let idx = if let Some(idx) = clamped_idx.filter(|_| clamps(t)) {
        idx
    } else {
        // +a, +b for s <= 0, -a, -b above; the larger magnitude only where it leaves less.
        let mut idx = [0; 8];
        let mut p = 0;
        while p < 8 {
            let larger = usize::from(b * (3 * b - w[p]) < a * (3 * a - w[p]));
            idx[p] = 2 * usize::from(s[p] > 0) + larger;
            p += 1;
        }
        idx
    };
    Some(Fit {
        q,
        table: t,
        idx,
        err: best.0,
    })
}

/// The error and each texel's modifier of table `t` around `base` where a modifier clamps: each texel's
/// four errors (ties to the first of +a, +b, -a, -b), in full for a modifier that clamps and by
/// `e0 + d (2 s + 3 d)` for one that does not; stopped once past `limit`.
fn clamped(
    px: &[[i32; 3]; 8],
    base: [i32; 3],
    (e0, s): (&[i32; 8], &[i32; 8]),
    t: usize,
    limit: u32,
) -> (u32, [usize; 8]) {
    let mods = modifiers(t);
    let mut colours = [[0; 3]; 4];
    let mut clamps = [false; 4];
    let mut m = 0;
    while m < 4 {
        let mut k = 0;
        while k < 3 {
            colours[m][k] = clamp(base[k] + mods[m], 0, 255);
            clamps[m] |= colours[m][k] != base[k] + mods[m];
            k += 1;
        }
        m += 1;
    }
    let mut idx = [0; 8];
    let mut err = 0u32;
    let mut p = 0;
    while p < 8 {
        let mut pick = (u32::MAX, 0);
        let mut m = 0;
        while m < 4 {
            let e = if clamps[m] {
                let c = colours[m];
                let (r, g, b) = (c[0] - px[p][0], c[1] - px[p][1], c[2] - px[p][2]);
                r * r + g * g + b * b
            } else {
                e0[p] + mods[m] * (2 * s[p] + 3 * mods[m])
            };
            if e.unsigned_abs() < pick.0 {
                pick = (e.unsigned_abs(), m);
            }
            m += 1;
        }
        idx[p] = pick.1;
        err += pick.0;
        // A table already past the best cannot win (ties go to the first).
        if err >= limit {
            break;
        }
        p += 1;
    }
    (err, idx)
}

/// The nearest base colour (`bits` a channel) to the least-squares one under `f`'s modifiers: each
/// channel's mean less the modifiers' mean.
fn refined(px: &[[i32; 3]; 8], f: &Fit, bits: u32) -> [i32; 3] {
    let mods = modifiers(f.table);
    let mut sum8 = [0; 3];
    let mut p = 0;
    while p < 8 {
        let mut k = 0;
        while k < 3 {
            sum8[k] += px[p][k] - mods[f.idx[p]];
            k += 1;
        }
        p += 1;
    }
    [quantise(sum8[0], bits), quantise(sum8[1], bits), quantise(sum8[2], bits)]
}

/// Whether `q` is one of `tries`.
fn tried(tries: &[Fit], q: [i32; 3]) -> bool {
    let mut i = 0;
    while i < tries.len() {
        if tries[i].q == q {
            return true;
        }
        i += 1;
    }
    false
}

/// Searches a half's base colours in `bits` a channel: the rounded mean, then the least-squares colour
/// of the best fit while it is new (`LS_TRIES` times at most), then the steps `NEIGHBOURS` from the best
/// colour under its table alone. A colour is kept only where it leaves less error than the best before
/// it. Returns how many were kept; the first holds the least error (ties to the first tried).
fn search(px: &[[i32; 3]; 8], bits: u32, tries: &mut [Fit; TRIES]) -> usize {
    let mut sum = [0; 3];
    let mut p = 0;
    while p < 8 {
        sum = [sum[0] + px[p][0], sum[1] + px[p][1], sum[2] + px[p][2]];
        p += 1;
    }
    let mut q = [quantise(sum[0], bits), quantise(sum[1], bits), quantise(sum[2], bits)];
    let mut n = 0;
    let mut limit = u32::MAX;
    while n < LS_TRIES && limit > 0 && !tried(&tries[..n], q) {
        let Some(f) = fit(px, q, bits, (0, TABLES.len()), limit) else {
            break;
        };
        tries[n] = f;
        n += 1;
        limit = f.err;
        q = refined(px, &f, bits);
    }
    if n == 0 {
        // Not reached: the first fit has no limit.
        tries[0] = Fit {
            q,
            err: u32::MAX / 4,
            ..Fit::default()
        };
        n = 1;
    }
    let (centre, t) = (tries[n - 1].q, tries[n - 1].table);
    let max = (1 << bits) - 1;
    let mut i = 0;
    while i < NEIGHBOURS.len() && limit > 0 {
        let m = NEIGHBOURS[i];
        let q = [centre[0] + m[0], centre[1] + m[1], centre[2] + m[2]];
        let inside = q[0] >= 0 && q[0] <= max && q[1] >= 0 && q[1] <= max && q[2] >= 0 && q[2] <= max;
        if inside && !tried(&tries[..n], q) {
            if let Some(f) = fit(px, q, bits, (t, t + 1), limit) {
                tries[n] = f;
                n += 1;
                limit = f.err;
            }
        }
        i += 1;
    }
    // Each fit kept leaves less error than those before it: the last is the best.
    tries.swap(0, n - 1);
    n
}

/// The texels (x, y) of half `half` of a block under `flip`: 2 x 4 columns side by side (flip 0) or 4 x 2
/// rows (flip 1).
fn half_pixels(flip: bool, half: u32) -> [(u32, u32); 8] {
    let mut out = [(0, 0); 8];
    for (i, o) in (0u32..).zip(out.iter_mut()) {
        *o = if flip {
            (i % 4, half * 2 + i / 4)
        } else {
            (half * 2 + i / 4, i % 4)
        };
    }
    out
}

/// An ETC1 block (individual or differential mode): its flip, mode and two halves.
#[derive(Clone, Copy, Default)]
struct Etc1 {
    flip: bool,
    diff: bool,
    halves: [Fit; 2],
}

impl Etc1 {
    fn err(&self) -> u32 {
        self.halves[0].err + self.halves[1].err
    }

    #[cfg(test)]
    fn bits(&self) -> u32 {
        if self.diff { 5 } else { 4 }
    }

    /// The block's 64 bits (OpenGL ES 3.0, table C.2 a and b: individual R1 63..60, R2 59..56, G1
    /// 55..52, ...; differential R 63..59, dR 58..56, G 55..51, ...; tables 39..37 and 36..34, the
    /// differential bit 33, flip 32; each texel's index split, its high bit in 31..16 and its low bit in
    /// 15..0, texel (x, y) at bit x * 4 + y of each).
    fn word(&self) -> u64 {
        let [a, b] = self.halves;
        let mut word = 0u64;
        for k in 0..3 {
            let shift = 59 - 8 * k;
            let (qa, qb) = (a.q[k], b.q[k]);
            word |= if self.diff {
                (u64::try_from(qa).unwrap_or(0) << shift)
                    | (u64::try_from((qb - qa) & 7).unwrap_or(0) << (shift - 3))
            } else {
                (u64::try_from(qa).unwrap_or(0) << (shift + 1))
                    | (u64::try_from(qb).unwrap_or(0) << (shift - 3))
            };
        }
        word |= (u64::try_from(a.table).unwrap_or(0) << 37) | (u64::try_from(b.table).unwrap_or(0) << 34);
        word |= (u64::from(self.diff) << 33) | (u64::from(self.flip) << 32);
        for (h, half) in self.halves.iter().zip(0u32..) {
            for ((x, y), &m) in half_pixels(self.flip, half).iter().zip(&h.idx) {
                let i = x * 4 + y;
                let m = u64::try_from(m).unwrap_or(0);
                word |= ((m >> 1) << (16 + i)) | ((m & 1) << i);
            }
        }
        word
    }

    /// The colours a decoder gives the block's texels.
    #[cfg(test)]
    fn texels(&self) -> Texels {
        let mut out = [[0; 3]; 16];
        for (h, half) in self.halves.iter().zip(0u32..) {
            let mods = modifiers(h.table);
            for ((x, y), &m) in half_pixels(self.flip, half).iter().zip(&h.idx) {
                let d = mods[m];
                out[(y * 4 + x) as usize] = h.q.map(|v| (expand(v, self.bits()) + d).clamp(0, 255));
            }
        }
        out
    }
}

/// The best ETC1 block for `texels`.
fn etc1(texels: &Texels) -> Etc1 {
    let mut best = Etc1 {
        halves: [Fit {
            err: u32::MAX / 2,
            ..Fit::default()
        }; 2],
        ..Etc1::default()
    };
    for flip in [false, true] {
        let mut px = [[[0; 3]; 8]; 2];
        for (half, px) in (0..2).zip(&mut px) {
            for (p, (x, y)) in px.iter_mut().zip(half_pixels(flip, half)) {
                *p = texels[(y * 4 + x) as usize];
            }
        }
        // Individual: each half's best RGB444 colour.
        let mut tries = [[Fit::default(); TRIES]; 2];
        for h in 0..2 {
            search(&px[h], 4, &mut tries[h]);
        }
        let individual = Etc1 {
            flip,
            diff: false,
            halves: [tries[0][0], tries[1][0]],
        };
        if individual.err() < best.err() {
            best = individual;
        }
        // Differential: the best pair of the halves' RGB555 colours tried whose difference fits -4..=3.
        let n = [search(&px[0], 5, &mut tries[0]), search(&px[1], 5, &mut tries[1])];
        let mut i = 0;
        while i < n[0] {
            let mut j = 0;
            while j < n[1] {
                let (a, b) = (&tries[0][i], &tries[1][j]);
                let d = [b.q[0] - a.q[0], b.q[1] - a.q[1], b.q[2] - a.q[2]];
                let fits = d[0] >= -4 && d[0] <= 3 && d[1] >= -4 && d[1] <= 3 && d[2] >= -4 && d[2] <= 3;
                if fits && a.err + b.err < best.err() {
                    best = Etc1 {
                        flip,
                        diff: true,
                        halves: [*a, *b],
                    };
                }
                j += 1;
            }
            i += 1;
        }
    }
    best
}

/// Encodes one 4 x 4 block (`px[y][x]`, RGB) into ETC2 RGB8's 8 bytes.
pub fn encode_block(px: &[[[u8; 3]; 4]; 4]) -> [u8; 8] {
    let mut texels: Texels = [[0; 3]; 16];
    for (i, t) in texels.iter_mut().enumerate() {
        for k in 0..3 {
            t[k] = i32::from(px[i / 4][i % 4][k]);
        }
    }
    let e = etc1(&texels);
    let (mut err, mut word) = (e.err(), e.word());
    if err > 0 {
        if let Some(p) = etc2_planar::fit(&texels, err) {
            (err, word) = (p.err, p.word());
        }
    }
    if err > 0 {
        if let Some(t) = etc2_th::fit(&texels, err) {
            word = t.word();
        }
    }
    word.to_be_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The colours `texture2ddecoder` (the CPU twin's decoder) gives a block's bytes.
    fn decoded(bytes: [u8; 8]) -> Texels {
        let mut out = [0u32; 16];
        texture2ddecoder::decode_etc2_rgb_block(&bytes, &mut out);
        out.map(|p| {
            let [b, g, r, _] = p.to_le_bytes();
            [r, g, b].map(i32::from)
        })
    }

    /// Test blocks from a fixed generator: noise, gradients, two-colour edges and flat blocks, dark and
    /// bright (where the modifiers clamp).
    fn blocks() -> Vec<Texels> {
        let mut seed = 0x2545_f491_u32;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            i32::try_from(seed >> 24).unwrap_or(0)
        };
        let mut out = Vec::new();
        for n in 0..600 {
            let base = [next(), next(), next()];
            let (gx, gy) = (next() % 32 - 16, next() % 32 - 16);
            let noise = [0, 2, 8, 40][n % 4];
            out.push(std::array::from_fn(|i| {
                let (x, y) = (i32::try_from(i % 4).unwrap_or(0), i32::try_from(i / 4).unwrap_or(0));
                let edge = if n % 5 == 0 && x + y > 3 { 90 } else { 0 };
                base.map(|b| {
                    let v = b + gx * x + gy * y + edge + if noise > 0 { next() % noise } else { 0 };
                    let v = match n % 7 {
                        0 => v / 8,
                        1 => 255 - v / 8,
                        _ => v,
                    };
                    v.clamp(0, 255)
                })
            }));
        }
        out
    }

    fn err(a: &Texels, b: &Texels) -> u32 {
        a.iter()
            .zip(b)
            .flat_map(|(p, q)| (0..3).map(move |k| (p[k] - q[k]).unsigned_abs().pow(2)))
            .sum()
    }

    #[test]
    fn etc1_modes_decode_to_the_colours_the_encoder_fitted() {
        let (mut diff, mut individual) = (0, 0);
        for t in blocks() {
            let e = etc1(&t);
            assert_eq!(decoded(e.word().to_be_bytes()), e.texels(), "{t:?}");
            assert_eq!(err(&e.texels(), &t), e.err());
            if e.diff {
                diff += 1;
            } else {
                individual += 1;
            }
        }
        assert!(diff > 50 && individual > 50, "{diff} {individual}");
    }

    #[test]
    fn planar_mode_decodes_to_the_colours_the_encoder_fitted() {
        for t in blocks() {
            let Some(p) = etc2_planar::fit(&t, u32::MAX) else {
                panic!("no planar block under no limit");
            };
            assert_eq!(decoded(p.word().to_be_bytes()), p.texels(), "{t:?}");
            assert_eq!(err(&p.texels(), &t), p.err);
        }
    }

    #[test]
    fn t_and_h_modes_decode_to_the_colours_the_encoder_fitted() {
        let mut modes = [0; 2];
        for t in blocks() {
            let Some(th) = etc2_th::fit(&t, u32::MAX) else {
                panic!("no T or H block under no limit");
            };
            assert_eq!(decoded(th.word().to_be_bytes()), th.texels(), "{t:?}");
            assert_eq!(err(&th.texels(), &t), th.err);
            modes[usize::from(th.h)] += 1;
            // H mode with every distance, either order of its colours.
            if th.colours[0] != th.colours[1] {
                for distance in 0..8 {
                    let h = etc2_th::TwoColours {
                        h: true,
                        distance,
                        ..th
                    };
                    assert_eq!(decoded(h.word().to_be_bytes()), h.texels(), "{h:?}");
                    let swapped = etc2_th::TwoColours {
                        colours: [h.colours[1], h.colours[0]],
                        ..h
                    };
                    assert_eq!(decoded(swapped.word().to_be_bytes()), swapped.texels());
                }
            }
        }
        assert!(modes[0] > 20 && modes[1] > 20, "{modes:?}");
    }

    #[test]
    fn a_block_is_its_best_mode_and_the_same_each_time() {
        let (mut planar, mut two) = (0, 0);
        for t in blocks() {
            let byte = |v: i32| u8::try_from(v).unwrap_or(0);
            let px: [[[u8; 3]; 4]; 4] =
                std::array::from_fn(|y| std::array::from_fn(|x| t[y * 4 + x].map(byte)));
            let bytes = encode_block(&px);
            assert_eq!(encode_block(&px), bytes);
            let got = err(&decoded(bytes), &t);
            let mut want = etc1(&t).err();
            if let Some(p) = etc2_planar::fit(&t, want) {
                want = p.err;
                planar += 1;
            }
            if let Some(th) = etc2_th::fit(&t, want) {
                want = th.err;
                two += 1;
            }
            assert_eq!(got, want);
        }
        assert!(planar > 20 && two > 20, "{planar} {two}");
    }
}
