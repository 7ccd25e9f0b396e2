//! Stage 1b, the package: the integer prediction U of GC section 7 and the tile codec (zigzag byte planes
//! under lz4 or zstd).
//!
//! Heights are integers k in units of the package's one quantum q. Level l is stored as the residual
//! r_l = k_l - U(k~_{l+1}), where k~_{l+1} is the coarser level as the decoder reconstructs it (GC section 7:
//! closed-loop prediction, so quantisation errors do not accumulate down the pyramid). U is the same 4-point
//! subdivision as [`crate::bake::pyramid::predict`], evaluated in exact integer arithmetic with one rounding, so
//! the encoder and every decoder agree bit for bit on every platform.
//!
//! # The compression floor (issue 13)
//!
//! Measured with `cargo run --release --example codec_floor -- FILE 0.5` (the residual pyramid alone, 64^2
//! tiles, bytes per level-0 sample; "order-0" is the Shannon entropy of each level's quantised residuals,
//! the floor of any coder that codes them one at a time; "context" conditions each residual on its left
//! and upper neighbours' |r| (0, 1, 2, 3+) and the sample's parity):
//!
//! ```text
//!                         order-0  context  zstd-19   zstd-22  zstd-3   lz4     zstd-19  zstd-19  zstd-19, whole
//!                         floor    floor    planes*   planes   planes   planes  raw i16  varint   levels, untiled
//! n07_w006 (SRTM 3", 1 m) 0.543    0.529    0.553     0.553    0.615    1.117   0.751    0.553    0.543
//! N57E011 (SRTM 3", sea)  0.171    0.094    0.108     0.108    0.116    0.197   0.131    0.108    0.099
//! Big Tujunga (30 m, 1 m) 0.688    0.652    0.704     0.704    0.724    1.213   0.879    0.705    0.673
//! ```
//!
//! (* shipped.) Both sidecars say these are 3-arc-second tiles, not 1-arc-second. On n07_w006 the level-0
//! residuals alone carry 3.15 bits (order 0) and 3.09 bits (context) per sample at q = 1 m: the integer-metre
//! SRTM noise, which no predictor removes losslessly, so 0.25 B/sample (2 bits) is out of reach for any
//! coder of these residuals at --max-error 0.5; the shipped coding is within 2 % of the order-0 floor.
//! N57E011 is 86 % sea (runs of zero residuals), where zstd's matches beat the order-0 floor. Nothing
//! measured helps: zigzag varints equal the byte planes (the residuals fit a byte), zstd-22 equals 19,
//! zstd-3 costs 8-11 %, lz4 doubles the size, raw i16 costs 22-36 %, and tiling itself costs 2-10 %.
//! Big Tujunga, the one ~1-arc-second terrain, has 3.76 bits a sample at level 0 (order 0): its pyramid
//! cannot reach 0.25 B/sample either. A raw-content zstd dictionary stored once per package
//! (`cargo run --release --example package_floor -- P.clipsat`) costs more than it saves at these sizes
//! (Big Tujunga, 16 KiB: 0.693 + 0.021 B/sample; 64 KiB: 0.659 + 0.089).

use super::format::CodecKind;

/// U: the fine sample (i, j) predicted from the coarse grid, in quantum units (GC sections 4 and 7).
///
/// Weights (-1, 9, 9, -1) / 16 separably: even positions copy, odd ones interpolate; the sum is kept in
/// units of 1/256 and rounded half up once ((v + 128) div 256, a floor division).
#[inline]
pub fn predict_int(coarse: impl Fn(i64, i64) -> i64, i: i64, j: i64) -> i64 {
    let (ci, cj) = (i >> 1, j >> 1);
    let row = |jj: i64| -> i64 {
        if i & 1 == 0 {
            16 * coarse(ci, jj)
        } else {
            9 * (coarse(ci, jj) + coarse(ci + 1, jj)) - coarse(ci - 1, jj) - coarse(ci + 2, jj)
        }
    };
    let v = if j & 1 == 0 {
        16 * row(cj)
    } else {
        9 * (row(cj) + row(cj + 1)) - row(cj - 1) - row(cj + 2)
    };
    (v + 128).div_euclid(256)
}

/// The fast form of [`predict_int`] over a whole tile: U of the fine rectangle (x0, y0, tw, th), with the
/// coarse samples gathered once through `coarse` (which clamps), then two separable passes.
///
/// Holds its scratch, sized once for tiles of side `tile`; bit-identical to [`predict_int`] (tested).
pub struct Predictor {
    gathered: Vec<i64>,
    rows: Vec<i64>,
    tile: usize,
}

impl Predictor {
    /// Scratch for tiles of up to `tile` x `tile` samples.
    pub fn new(tile: u32) -> Self {
        let t = tile as usize;
        let p = t / 2 + 4;
        Self {
            gathered: vec![0; p * p],
            rows: vec![0; p * t],
            tile: t,
        }
    }

    /// Writes U(coarse) at fine samples x0..x0+tw, y0..y0+th (x0, y0 even) into `out`, row-major.
    ///
    /// Panics if the rectangle is larger than the tile size or `out` is not tw * th (caller bugs).
    pub fn predict(
        &mut self,
        coarse: impl Fn(i64, i64) -> i64,
        (x0, y0): (i64, i64),
        (tw, th): (usize, usize),
        out: &mut [i64],
    ) {
        assert!(
            tw <= self.tile
                && th <= self.tile
                && out.len() == tw * th
                && x0 & 1 == 0
                && y0 & 1 == 0,
            "predict: a {tw} x {th} tile at ({x0}, {y0}) does not fit {} or out",
            self.tile
        );
        // Coarse columns cx0 .. cx0 + pw cover every 4-point stencil of the fine columns.
        let (pw, ph) = (tw / 2 + 4, th / 2 + 4);
        let (cx0, cy0) = ((x0 >> 1) - 1, (y0 >> 1) - 1);
        let g = &mut self.gathered[..pw * ph];
        for (r, row) in g.chunks_exact_mut(pw).enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = coarse(cx0 + c as i64, cy0 + r as i64);
            }
        }
        // Horizontal pass: each coarse row to fine columns, in units of 1/16.
        let h = &mut self.rows[..ph * tw];
        for (grow, hrow) in g.chunks_exact(pw).zip(h.chunks_exact_mut(tw)) {
            for (i, v) in hrow.iter_mut().enumerate() {
                let c = i / 2 + 1;
                *v = if i & 1 == 0 {
                    16 * grow[c]
                } else {
                    9 * (grow[c] + grow[c + 1]) - grow[c - 1] - grow[c + 2]
                };
            }
        }
        // Vertical pass, in units of 1/256, rounded half up (floor of v + 128 over 256).
        for (j, orow) in out.chunks_exact_mut(tw).enumerate() {
            let c = j / 2 + 1;
            let row = |k: usize| &h[k * tw..(k + 1) * tw];
            if j & 1 == 0 {
                for (o, &a) in orow.iter_mut().zip(row(c)) {
                    *o = (16 * a + 128) >> 8;
                }
            } else {
                let (a, b, cc, d) = (row(c - 1), row(c), row(c + 1), row(c + 2));
                for (i, o) in orow.iter_mut().enumerate() {
                    *o = (9 * (b[i] + cc[i]) - a[i] - d[i] + 128) >> 8;
                }
            }
        }
    }
}

/// Zigzag: small signed residuals become small unsigned ones (0, -1, 1, -2 -> 0, 1, 2, 3).
#[inline]
#[expect(
    clippy::cast_sign_loss,
    reason = "zigzag reinterprets the two's complement bits"
)]
pub fn zigzag(v: i32) -> u32 {
    ((v << 1) ^ (v >> 31)) as u32
}

/// Inverse of [`zigzag`].
#[inline]
#[expect(
    clippy::cast_possible_wrap,
    reason = "zigzag reinterprets the two's complement bits"
)]
pub fn unzigzag(u: u32) -> i32 {
    ((u >> 1) as i32) ^ -((u & 1) as i32)
}

/// Compresses tiles (bake time; allocates).
pub struct Encoder {
    codec: CodecKind,
    zstd: Option<zstd::bulk::Compressor<'static>>,
    planes: Vec<u8>,
}

impl Encoder {
    /// An encoder for `codec`; `zstd_level` applies to zstd only.
    pub fn new(codec: CodecKind, zstd_level: i32) -> std::io::Result<Self> {
        let zstd = match codec {
            CodecKind::Zstd => Some(zstd::bulk::Compressor::new(zstd_level)?),
            CodecKind::Lz4 => None,
        };
        Ok(Self {
            codec,
            zstd,
            planes: Vec::new(),
        })
    }

    /// One tile's payload: the plane count, then the compressed byte planes of the zigzagged residuals.
    ///
    /// Byte planes (all low bytes, then all second bytes, ...) put the nearly constant high bytes of small
    /// residuals together, where the codec's matcher and entropy coder make them almost free.
    pub fn encode(&mut self, residuals: &[i32]) -> std::io::Result<Vec<u8>> {
        let max = residuals.iter().map(|&r| zigzag(r)).max().unwrap_or(0);
        let planes = (4 - (max.leading_zeros() / 8)).max(1) as usize;
        self.planes.clear();
        for p in 0..planes {
            self.planes.extend(residuals.iter().map(|&r| {
                #[expect(clippy::cast_possible_truncation, reason = "one byte of the value")]
                let b = (zigzag(r) >> (8 * p)) as u8;
                b
            }));
        }
        #[expect(clippy::cast_possible_truncation, reason = "planes is 1..=4")]
        let mut out = vec![planes as u8];
        match (&mut self.zstd, self.codec) {
            (Some(z), CodecKind::Zstd) => out.extend_from_slice(&z.compress(&self.planes)?),
            _ => out.extend_from_slice(&lz4_flex::block::compress(&self.planes)),
        }
        Ok(out)
    }
}

/// Decompresses tiles into caller buffers without allocating (after construction).
pub struct Decoder {
    codec: CodecKind,
    zstd: Option<zstd::bulk::Decompressor<'static>>,
    planes: Vec<u8>,
}

impl Decoder {
    /// A decoder for `codec`, with scratch for tiles of up to `max_samples` samples.
    pub fn new(codec: CodecKind, max_samples: usize) -> std::io::Result<Self> {
        let zstd = match codec {
            CodecKind::Zstd => Some(zstd::bulk::Decompressor::new()?),
            CodecKind::Lz4 => None,
        };
        Ok(Self {
            codec,
            zstd,
            planes: vec![0; 4 * max_samples],
        })
    }

    /// Decodes one payload into `out` (zigzag residuals restored to i32); the reason on failure.
    ///
    /// The payload must decompress to exactly `out.len()` samples of its plane count: anything else is a
    /// damaged tile, reported, never guessed at.
    pub fn decode(&mut self, payload: &[u8], out: &mut [i32]) -> Result<(), &'static str> {
        let (&planes, stream) = payload.split_first().ok_or("empty tile payload")?;
        if !(1..=4).contains(&planes) {
            return Err("bad byte-plane count");
        }
        let n = out.len();
        let want = n * usize::from(planes);
        let buf = self
            .planes
            .get_mut(..want)
            .ok_or("tile larger than the package's tile size")?;
        let got = match (&mut self.zstd, self.codec) {
            (Some(z), CodecKind::Zstd) => z
                .decompress_to_buffer(stream, buf)
                .map_err(|_| "zstd stream is damaged")?,
            _ => lz4_flex::block::decompress_into(stream, buf)
                .map_err(|_| "lz4 stream is damaged")?,
        };
        if got != want {
            return Err("tile decompresses to the wrong number of bytes");
        }
        let buf = &self.planes[..want];
        for (o, &b) in out.iter_mut().zip(&buf[..n]) {
            *o = i32::from(b);
        }
        for p in 1..usize::from(planes) {
            let shift = 8 * p;
            for (o, &b) in out.iter_mut().zip(&buf[p * n..(p + 1) * n]) {
                *o |= i32::from(b) << shift;
            }
        }
        for o in out.iter_mut() {
            #[expect(clippy::cast_sign_loss, reason = "the assembled zigzag bits")]
            let u = *o as u32;
            *o = unzigzag(u);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zigzag_round_trips() {
        for v in [0, 1, -1, 2, -2, 1000, -1000, i32::MAX, i32::MIN] {
            assert_eq!(unzigzag(zigzag(v)), v);
        }
        assert_eq!(zigzag(-1), 1);
        assert_eq!(zigzag(1), 2);
    }

    #[test]
    fn prediction_reproduces_linear_and_copies_even() {
        // A linear ramp in coarse units doubles in fine units: U reproduces it exactly.
        let c = |a: i64, b: i64| 10 * a + 3 * b;
        for j in 0..8 {
            for i in 0..8 {
                let p = predict_int(c, i, j);
                // Fine (i, j) sits at coarse (i/2, j/2): 10 i/2 + 3 j/2, rounded half up.
                assert_eq!(p, (10 * i + 3 * j + 1).div_euclid(2), "at ({i}, {j})");
            }
        }
    }

    #[test]
    fn fast_prediction_matches_reference() {
        let c = |a: i64, b: i64| {
            let (a, b) = (a.clamp(0, 40), b.clamp(0, 30));
            (a * 7919 + b * 104_729) % 2001 - 1000
        };
        let mut p = Predictor::new(16);
        for (x0, y0, tw, th) in [
            (0, 0, 16, 16),
            (16, 32, 16, 7),
            (48, 16, 5, 16),
            (80, 60, 3, 2),
        ] {
            let mut out = vec![0; tw * th];
            p.predict(c, (x0, y0), (tw, th), &mut out);
            for j in 0..th {
                for i in 0..tw {
                    let (fi, fj) = (x0 + i as i64, y0 + j as i64);
                    assert_eq!(out[j * tw + i], predict_int(c, fi, fj), "at ({fi}, {fj})");
                }
            }
        }
    }

    #[test]
    fn codecs_round_trip() {
        let r: Vec<i32> = (0..4096).map(|i| (i * 7919 % 601) - 300).collect();
        for codec in CodecKind::ALL {
            let mut e = Encoder::new(codec, 3).unwrap();
            let payload = e.encode(&r).unwrap();
            let mut d = Decoder::new(codec, 4096).unwrap();
            let mut out = vec![0; 4096];
            d.decode(&payload, &mut out).unwrap();
            assert_eq!(out, r, "{codec:?}");
            let mut short = vec![0; 4000];
            assert!(d.decode(&payload, &mut short).is_err());
        }
    }
}
