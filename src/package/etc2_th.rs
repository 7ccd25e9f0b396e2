//! Stage 1b, the package: ETC2 RGB8's T and H modes for the block encoder (`etc2.rs`): a block of two
//! colours, RGB444 each, for edges that ETC1's halves and the planar mode smear. The texels are split
//! in two by a two-means clustering (seeded by the texels at the ends of the channel with the widest
//! range, two rounds), each group's rounded mean quantised; T mode paints one colour as it is and the
//! other with a distance added and taken away (both ways round), H mode both with the distance added and
//! taken away; every distance of the eight is tried, each texel taking its nearest paint. The best's
//! colours are then moved to the least-squares ones under its paints (each colour's texels' mean less
//! their paints' offsets) and every distance tried again. Integer arithmetic throughout.

use super::etc2_planar::{clamp, Texels};

/// The distances of T and H modes (OpenGL ES 3.0, table C.8).
const DISTANCES: [i32; 8] = [3, 6, 11, 16, 23, 32, 41, 64];

/// A T or H block: its two colours (RGB444), distance index, each texel's paint and its error.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct TwoColours {
    /// H mode, else T mode.
    pub(super) h: bool,
    /// The colours, in 4 bits a channel.
    pub(super) colours: [[i32; 3]; 2],
    /// The distance index (0..8).
    pub(super) distance: usize,
    /// Each texel's paint (0..4), `[y * 4 + x]`.
    pub(super) paints: [usize; 16],
    /// Squared RGB error against the texels the block was fitted to.
    pub(super) err: u32,
}

/// The four paints of a T or H block (8-bit colours): T: A, B + d, B, B - d; H: A + d, A - d, B + d,
/// B - d (OpenGL ES 3.0, section C.1.3).
fn paints(h: bool, colours: [[i32; 3]; 2], distance: usize) -> [[i32; 3]; 4] {
    let d = DISTANCES[distance];
    let [a, b] = colours;
    let a = [a[0] * 17, a[1] * 17, a[2] * 17];
    let b = [b[0] * 17, b[1] * 17, b[2] * 17];
    let add = |c: [i32; 3], d: i32| {
        [
            clamp(c[0] + d, 0, 255),
            clamp(c[1] + d, 0, 255),
            clamp(c[2] + d, 0, 255),
        ]
    };
    if h {
        [add(a, d), add(a, -d), add(b, d), add(b, -d)]
    } else {
        [a, add(b, d), b, add(b, -d)]
    }
}

/// Each texel's nearest paint (ties to the first) and the error, stopped once past `limit`. (`while`
/// loops: see `etc2.rs` on the test profile.)
fn nearest(texels: &Texels, paints: &[[i32; 3]; 4], limit: u32) -> (u32, [usize; 16]) {
    let mut out = [0; 16];
    let mut err = 0u32;
    let mut i = 0;
    while i < 16 && err < limit {
        let t = texels[i];
        let mut pick = (u32::MAX, 0);
        let mut m = 0;
        while m < 4 {
            let c = paints[m];
            let (r, g, b) = (c[0] - t[0], c[1] - t[1], c[2] - t[2]);
            let e = (r * r + g * g + b * b).unsigned_abs();
            if e < pick.0 {
                pick = (e, m);
            }
            m += 1;
        }
        out[i] = pick.1;
        err += pick.0;
        i += 1;
    }
    (err, out)
}

/// The two groups' mean colours, quantised to 4 bits a channel: two rounds of two-means from the texels
/// at the ends of the channel with the widest range.
fn clusters(texels: &Texels) -> [[i32; 3]; 2] {
    let mut widest = (-1, 0, 0, 0);
    let mut k = 0;
    while k < 3 {
        let (mut lo, mut hi) = (0, 0);
        let mut i = 1;
        while i < 16 {
            if texels[i][k] < texels[lo][k] {
                lo = i;
            }
            if texels[i][k] > texels[hi][k] {
                hi = i;
            }
            i += 1;
        }
        if texels[hi][k] - texels[lo][k] > widest.0 {
            widest = (texels[hi][k] - texels[lo][k], k, lo, hi);
        }
        k += 1;
    }
    let mut centres = [texels[widest.2], texels[widest.3]];
    let mut round = 0;
    while round < 2 {
        let mut sums = [[0; 3]; 2];
        let mut counts = [0; 2];
        let mut i = 0;
        while i < 16 {
            let t = texels[i];
            let dist = |c: [i32; 3]| {
                let (r, g, b) = (c[0] - t[0], c[1] - t[1], c[2] - t[2]);
                r * r + g * g + b * b
            };
            let g = usize::from(dist(centres[1]) < dist(centres[0]));
            sums[g] = [sums[g][0] + t[0], sums[g][1] + t[1], sums[g][2] + t[2]];
            counts[g] += 1;
            i += 1;
        }
        let mut g = 0;
        while g < 2 {
            if counts[g] > 0 {
                let n = counts[g];
                let mean = |s: i32| (2 * s + n) / (2 * n);
                centres[g] = [mean(sums[g][0]), mean(sums[g][1]), mean(sums[g][2])];
            }
            g += 1;
        }
        round += 1;
    }
    centres.map(|c| c.map(|v| (v * 15 + 127) / 255))
}

/// The best T or H block for `texels`, or none where none leaves less error than `limit`.
pub(super) fn fit(texels: &Texels, limit: u32) -> Option<TwoColours> {
    let [a, b] = clusters(texels);
    let mut best: Option<TwoColours> = None;
    // Searched under no limit of its own, so that a block first past `limit` can still be refined below
    // it.
    let mut least = u32::MAX;
    // T mode either way round, then H mode (whose distance's lowest bit is the colours' order, so an
    // even one needs two different colours).
    for (h, colours) in [(false, [a, b]), (false, [b, a]), (true, [a, b])] {
        let mut distance = 0;
        while distance < DISTANCES.len() {
            if !(h && a == b && distance % 2 == 0) {
                let (err, paints) = nearest(texels, &paints(h, colours, distance), least);
                if err < least {
                    least = err;
                    best = Some(TwoColours {
                        h,
                        colours,
                        distance,
                        paints,
                        err,
                    });
                }
            }
            distance += 1;
        }
    }
    // Then the best's colours moved to the least-squares ones under the paints chosen (each colour's
    // texels' mean less their paints' offsets), under every distance.
    if let Some(b) = best {
        let colours = refined(texels, &b);
        let mut distance = 0;
        while colours != b.colours && distance < DISTANCES.len() {
            if !(b.h && colours[0] == colours[1] && distance % 2 == 0) {
                let (err, paints) = nearest(texels, &paints(b.h, colours, distance), least);
                if err < least {
                    least = err;
                    best = Some(TwoColours {
                        h: b.h,
                        colours,
                        distance,
                        paints,
                        err,
                    });
                }
            }
            distance += 1;
        }
    }
    best.filter(|b| b.err < limit)
}

/// The RGB444 colours nearest the least-squares ones under `b`'s paints: each colour the mean of its
/// texels less their paints' offsets from it (a colour with no texel kept).
fn refined(texels: &Texels, b: &TwoColours) -> [[i32; 3]; 2] {
    let d = DISTANCES[b.distance];
    // Each paint's colour and its offset from it: T: A, B + d, B, B - d; H: A + d, A - d, B + d, B - d.
    let (of, offset) = if b.h {
        ([0, 0, 1, 1], [d, -d, d, -d])
    } else {
        ([0, 1, 1, 1], [0, d, 0, -d])
    };
    let mut sums = [[0; 3]; 2];
    let mut counts = [0; 2];
    let mut i = 0;
    while i < 16 {
        let (m, t) = (b.paints[i], texels[i]);
        let c = of[m];
        sums[c] = [
            sums[c][0] + t[0] - offset[m],
            sums[c][1] + t[1] - offset[m],
            sums[c][2] + t[2] - offset[m],
        ];
        counts[c] += 1;
        i += 1;
    }
    let mut out = b.colours;
    let mut c = 0;
    while c < 2 {
        let n = counts[c];
        if n > 0 {
            let q = |s: i32| (30 * clamp(s, 0, 255 * n) + 255 * n) / (2 * 255 * n);
            out[c] = [q(sums[c][0]), q(sums[c][1]), q(sums[c][2])];
        }
        c += 1;
    }
    out
}

impl TwoColours {
    /// The colours a decoder gives the block's texels, `[y * 4 + x]`.
    #[cfg(test)]
    pub(super) fn texels(&self) -> Texels {
        let p = paints(self.h, self.colours, self.distance);
        self.paints.map(|m| p[m])
    }

    /// The block's 64 bits (OpenGL ES 3.0, table C.2 c and d; Khronos Data Format 1.3, section 21.1.4).
    /// T: R1 60..59 and 57..56, G1 55..52, B1 51..48, R2 47..44, G2 43..40, B2 39..36, distance 35..34
    /// and 32; the free bits 63..61 and 58 set so that red's base plus delta leaves 0..=31, which tells a
    /// decoder the block is T. H: R1 62..59, G1 58..56 and 52, B1 51 and 49..47, R2 46..43, G2 42..39, B2
    /// 38..35, the distance's bits 2 and 1 at 34 and 32 and its bit 0 the colours' order (first >= second
    /// as 12-bit numbers); bit 63 keeps red's base plus delta within 0..=31 and 55..53 and 50 take green's
    /// out of it. The differential bit 33 set; each texel's paint as in ETC1's modes (high bit 31..16, low
    /// bit 15..0, texel (x, y) at bit x * 4 + y).
    pub(super) fn word(&self) -> u64 {
        let u = |v: i32| u64::try_from(v).unwrap_or(0);
        let mut colours = self.colours;
        let mut paints = self.paints;
        let mut w = 1u64 << 33;
        if self.h {
            let key = |c: [i32; 3]| (c[0] << 8) | (c[1] << 4) | c[2];
            if (key(colours[0]) >= key(colours[1])) != (self.distance % 2 == 1) {
                colours.swap(0, 1);
                paints = paints.map(|m| m ^ 2);
            }
            let [[r1, g1, b1], [r2, g2, b2]] = colours.map(|c| c.map(u));
            w |= (r1 << 59) | ((g1 >> 1) << 56) | ((g1 & 1) << 52) | ((b1 >> 3) << 51);
            w |= ((b1 & 7) << 47) | (r2 << 43) | (g2 << 39) | (b2 << 35);
            let d = u64::try_from(self.distance).unwrap_or(0);
            w |= ((d >> 2) << 34) | (((d >> 1) & 1) << 32);
            // Red: R1 + signed(G1's bits 3..1) below 0 takes bit 63 (R5 = 16 + R1).
            let dr = i64::try_from(g1 >> 1).unwrap_or(0) - if g1 >> 3 == 1 { 8 } else { 0 };
            if i64::try_from(r1).unwrap_or(0) + dr < 0 {
                w |= 1 << 63;
            }
            // Green: 28 + hi + lo past 31, or hi + lo - 4 below 0.
            let (hi, lo) = (((g1 & 1) << 1) | (b1 >> 3), (b1 >> 1) & 3);
            if hi + lo >= 4 {
                w |= 7 << 53;
            } else {
                w |= 1 << 50;
            }
        } else {
            let [[r1, g1, b1], [r2, g2, b2]] = colours.map(|c| c.map(u));
            w |= ((r1 >> 2) << 59) | ((r1 & 3) << 56) | (g1 << 52) | (b1 << 48);
            w |= (r2 << 44) | (g2 << 40) | (b2 << 36);
            let d = u64::try_from(self.distance).unwrap_or(0);
            w |= ((d >> 1) << 34) | ((d & 1) << 32);
            // Red: 28 + hi + lo past 31, or hi + lo - 4 below 0.
            if (r1 >> 2) + (r1 & 3) >= 4 {
                w |= 7 << 61;
            } else {
                w |= 1 << 58;
            }
        }
        for (i, &m) in paints.iter().enumerate() {
            let bit = (i % 4) * 4 + i / 4;
            let m = u64::try_from(m).unwrap_or(0);
            w |= ((m >> 1) << (16 + bit)) | ((m & 1) << bit);
        }
        w
    }
}
