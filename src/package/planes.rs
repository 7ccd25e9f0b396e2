//! Stage 1b, the package: zigzag byte planes under zstd or lz4, the entropy stage of the SAT LOD record
//! tiles and, with `--codec zstd` or `lz4`, of the height tiles' residual symbols.
//!
//! Byte planes (all low bytes, then all second bytes, ...) put the nearly constant high bytes of small
//! values together, where the codec's matcher and entropy coder make them almost free.

use super::kind::CodecKind;

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
        let codec = codec.planes();
        let zstd = match codec {
            CodecKind::Zstd => Some(zstd::bulk::Compressor::new(zstd_level)?),
            CodecKind::Lz4 | CodecKind::Rans => None,
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
        let codec = codec.planes();
        let zstd = match codec {
            CodecKind::Zstd => Some(zstd::bulk::Decompressor::new()?),
            CodecKind::Lz4 | CodecKind::Rans => None,
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
