//! Stage 1b, the package: ETC2 RGB8's planar mode for the block encoder (`etc2.rs`): a block as a
//! gradient through three colours, O at texel (0, 0), H at (4, 0) and V at (0, 4), each RGB676. Each
//! channel is fitted alone (the mode's channels share no bits of choice): the least-squares plane through
//! the block's texels, its three values quantised, then every combination within one step of them, the
//! one leaving the least squared error (ties to the first tried). Integer arithmetic throughout.

/// A block's texels, `[y * 4 + x]`, RGB (the encoder's modules share it, and `clamp`, from here).
pub(super) type Texels = [[i32; 3]; 16];

/// `v` clamped to `lo..=hi` (`Ord::clamp` stays a call in the test profile: see `etc2.rs`).
pub(super) fn clamp(v: i32, lo: i32, hi: i32) -> i32 {
    if v < lo {
        lo
    } else if v > hi {
        hi
    } else {
        v
    }
}

/// Bits of each channel's three values: R 6, G 7, B 6.
const BITS: [u32; 3] = [6, 7, 6];

/// A planar block: the quantised O, H, V values per channel and the squared error they leave.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Planar {
    /// `q[channel]` = [O, H, V], in the channel's bits.
    pub(super) q: [[i32; 3]; 3],
    /// Squared RGB error against the texels the block was fitted to.
    pub(super) err: u32,
}

/// A quantised value expanded to 8 bits (its high bits repeated below it).
fn expand(q: i32, bits: u32) -> i32 {
    (q << (8 - bits)) | (q >> (2 * bits - 8))
}

/// The decoded value at texel (x, y) of O, H, V (8-bit), as the spec computes it (OpenGL ES 3.0,
/// section C.1.3, planar mode): (x (H - O) + y (V - O) + 4 O + 2) >> 2, clamped to 0..=255.
fn value([o, h, v]: [i32; 3], x: i32, y: i32) -> i32 {
    clamp((x * (h - o) + y * (v - o) + 4 * o + 2) >> 2, 0, 255)
}

/// The squared error of one channel's quantised O, H, V against `texels` (`[y * 4 + x]`), stopped once
/// past `limit`. (A `while` loop: see `etc2.rs` on the test profile.)
fn channel_err(texels: &[i32; 16], q: [i32; 3], bits: u32, limit: u32) -> u32 {
    let e = [expand(q[0], bits), expand(q[1], bits), expand(q[2], bits)];
    let mut err = 0;
    let mut i = 0;
    while i < 16 && err < limit {
        let d = value(e, i % 4, i / 4) - texels[i as usize];
        err += d.unsigned_abs() * d.unsigned_abs();
        i += 1;
    }
    err
}

/// The best planar block for `texels`, or none where it cannot leave less error than `limit`: the
/// least-squares planes' own error, before quantisation, is already that much, or their quantised
/// values' is.
pub(super) fn fit(texels: &Texels, limit: u32) -> Option<Planar> {
    // The least-squares plane a + b x + c y over x, y in 0..4 of each channel: with S the sum, Sx the
    // sum of (2x - 3) t and Sy of (2y - 3) t, b = Sx / 40 and c = Sy / 40, a = S / 16 - 1.5 (b + c);
    // then O = a, H = a + 4 b, V = a + 4 c, each 1/80 of an integer. Its error, times 80, is
    // 80 sum(t^2) - 5 S^2 - Sx^2 - Sy^2 (the three terms orthogonal over the block).
    let mut channels = [[0i32; 16]; 3];
    let mut sums = [[0i32; 3]; 3];
    let mut residual80 = 0i64;
    let mut k = 0;
    while k < 3 {
        let (mut s, mut sx, mut sy, mut s2) = (0, 0, 0, 0);
        let mut i = 0;
        while i < 16 {
            let t = texels[i as usize][k];
            channels[k][i as usize] = t;
            s += t;
            sx += (2 * (i % 4) - 3) * t;
            sy += (2 * (i / 4) - 3) * t;
            s2 += t * t;
            i += 1;
        }
        residual80 += i64::from(80 * s2) - i64::from(5 * s * s) - i64::from(sx * sx + sy * sy);
        sums[k] = [s, sx, sy];
        k += 1;
    }
    if residual80 >= 80 * i64::from(limit) {
        return None;
    }
    let mut out = Planar::default();
    let mut k = 0;
    while k < 3 {
        let (bits, [s, sx, sy]) = (BITS[k], sums[k]);
        let max = (1 << bits) - 1;
        let quant = |n80: i32| (clamp(n80, 0, 80 * 255) * max + 40 * 255) / (80 * 255);
        let start = [
            quant(5 * s - 6 * sx - 6 * sy),
            quant(5 * s + 2 * sx - 6 * sy),
            quant(5 * s - 6 * sx + 2 * sy),
        ];
        // Every combination within one step of the three, the least error kept (ties to the first).
        let mut best = (u32::MAX, start);
        let mut d = 0;
        while d < 27 {
            let step = |j: usize| [0, -1, 1][(d / [1, 3, 9][j]) % 3];
            let q = [start[0] + step(0), start[1] + step(1), start[2] + step(2)];
            let inside = q[0] >= 0 && q[0] <= max && q[1] >= 0 && q[1] <= max && q[2] >= 0 && q[2] <= max;
            if inside {
                let e = channel_err(&channels[k], q, bits, best.0);
                if e < best.0 {
                    best = (e, q);
                }
            }
            d += 1;
        }
        out.q[k] = best.1;
        out.err += best.0;
        if out.err >= limit {
            return None;
        }
        k += 1;
    }
    Some(out)
}

impl Planar {
    /// The colours a decoder gives the block's texels, `[y * 4 + x]`.
    #[cfg(test)]
    pub(super) fn texels(&self) -> Texels {
        std::array::from_fn(|i| {
            let n = i32::try_from(i).unwrap_or(0);
            [0, 1, 2].map(|k| value(self.q[k].map(|v| expand(v, BITS[k])), n % 4, n / 4))
        })
    }

    /// The block's 64 bits (OpenGL ES 3.0, table C.2 d; Khronos Data Format 1.3, section 21.1.4: RO
    /// 62..57, GO 56 and 54..49, BO 48, 44..43 and 41..39, RH 38..34 and 32, GH 31..25, BH 24..19, RV
    /// 18..13, GV 12..6, BV 5..0, the differential bit 33 set). The free bits 63, 55, 47..45 and 42 are
    /// set so that the red and green base-plus-delta stay within 0..=31 and the blue one leaves it,
    /// which is what tells a decoder the block is planar.
    pub(super) fn word(&self) -> u64 {
        let [[ro, rh, rv], [go, gh, gv], [bo, bh, bv]] =
            self.q.map(|c| c.map(|v| u64::try_from(v).unwrap_or(0)));
        let mut w = (ro << 57) | ((go >> 6) << 56) | ((go & 63) << 49);
        w |= ((bo >> 5) << 48) | (((bo >> 3) & 3) << 43) | ((bo & 7) << 39);
        w |= ((rh >> 1) << 34) | ((rh & 1) << 32) | (gh << 25) | (bh << 19);
        w |= (rv << 13) | (gv << 6) | bv | (1 << 33);
        // A 3-bit delta field as the decoder reads it: two's complement, -4..=3.
        let signed = |d: u64| i64::try_from(d).unwrap_or(0) - if d >= 4 { 8 } else { 0 };
        let r = i64::try_from(ro >> 2).unwrap_or(0) + signed(((ro & 3) << 1) | (go >> 6));
        if r < 0 {
            w |= 1 << 63;
        }
        let g = i64::try_from((go & 63) >> 2).unwrap_or(0) + signed(((go & 3) << 1) | (bo >> 5));
        if g < 0 {
            w |= 1 << 55;
        }
        // Blue: 28 + BO[4..3] + BO[2..1] past 31, or BO[4..3] + BO[2..1] - 4 below 0.
        if ((bo >> 3) & 3) + ((bo >> 1) & 3) >= 4 {
            w |= 7 << 45;
        } else {
            w |= 1 << 42;
        }
        w
    }
}
