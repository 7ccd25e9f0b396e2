//! Stage 1b, the package: one height tile's coding, prediction ([`super::predict`]) with near-lossless
//! quantisation and error feedback, then the residual symbols' entropy stage (`docs/package-codec.md`).
//!
//! A tile is walked in raster order. Each sample's prediction p comes from U (the coarser level,
//! reconstructed) and the tile's own reconstructed causal neighbours; the encoder quantises the
//! prediction error e = t - p (t the height over the quantum) to the symbol s = round(e / step) and
//! reconstructs k~ = p + s step, which is what the decoder will compute, and what the later samples are
//! predicted from (JPEG-LS near-lossless mode, Weinberger et al. 2000, section 4: quantised residuals and
//! the encoder's own reconstruction in the loop, so |t - k~| <= step / 2 for every sample; with an odd
//! step 2N + 1 over integer data, |t - k~| <= N exactly).
//!
//! The symbols then go through rANS ([`super::rans`]) or, for the `lz4` and `zstd` codecs, zigzag byte
//! planes ([`super::planes`]). A rANS payload is the rANS part's length (u32, little-endian), the rANS
//! part, then the raw bits.

pub use super::planes::{unzigzag, zigzag, Decoder, Encoder};
pub use super::predict::{predict_int, Predictor};
use super::predict::{LevelModel, MAX_UNITS, R_TAPS, TAPS, U_TAPS};
use super::rans::{self, Counts, DecodeTables, Tables};

/// Border of U around a tile: U is evaluated over (tw + 4) x (th + 4) samples from (x0 - 2, y0 - 2).
pub const U_BORDER: usize = 2;

/// Per-tile scratch: the padded residual field and symbol magnitudes, sized once for a tile side.
pub struct TileScratch {
    r: Vec<i64>,
    a: Vec<u32>,
    syms: Vec<i32>,
}

impl TileScratch {
    /// Scratch for tiles of up to `tile` x `tile` samples.
    pub fn new(tile: u32) -> Self {
        let t = tile as usize;
        Self {
            r: vec![0; (t + 3) * (t + 2)],
            a: vec![0; (t + 2) * (t + 1)],
            syms: vec![0; t * t],
        }
    }

    /// Bytes of this scratch for tiles of side `tile`.
    pub fn bytes(tile: u32) -> u64 {
        let t = u64::from(tile);
        8 * (t + 3) * (t + 2) + 4 * (t + 2) * (t + 1) + 4 * t * t
    }
}

/// Walks a tw x th tile in raster order: `sample(i, j, p, curv)` gets the prediction p of sample (i, j)
/// and U's curvature there (|second difference| across plus along, in quanta), and returns its
/// reconstruction k~ (an error stops the walk). `u` is U with its border ([`U_BORDER`]).
#[inline(always)]
fn walk<E>(
    model: &LevelModel,
    u: &[i64],
    (tw, th): (usize, usize),
    r: &mut [i64],
    mut sample: impl FnMut(usize, usize, i64, i64) -> Result<i64, E>,
) -> Result<(), E> {
    let (rw, uw) = (tw + 3, tw + 4);
    r[..rw * (th + 2)].fill(0);
    // Offsets of the taps in the padded residual field and in U.
    #[expect(
        clippy::cast_possible_wrap,
        clippy::cast_sign_loss,
        reason = "tap offsets are small and the padded index stays in the buffer"
    )]
    let ro: [isize; 6] = R_TAPS.map(|(dx, dy)| dy as isize * rw as isize + dx as isize);
    #[expect(
        clippy::cast_possible_wrap,
        reason = "tap offsets are small and the padded index stays in the buffer"
    )]
    let uo: [isize; 8] = U_TAPS.map(|(dx, dy)| dy as isize * uw as isize + dx as isize);
    let mut f = [0i64; TAPS];
    for j in 0..th {
        for i in 0..tw {
            let rc = (j + 2) * rw + i + 2;
            let uc = (j + U_BORDER) * uw + i + U_BORDER;
            let u0 = u[uc];
            for (fk, &o) in f[..6].iter_mut().zip(&ro) {
                *fk = r[rc.wrapping_add_signed(o)];
            }
            for (fk, &o) in f[6..].iter_mut().zip(&uo) {
                *fk = u[uc.wrapping_add_signed(o)] - u0;
            }
            let par = (i & 1) | ((j & 1) << 1);
            let p = model.predict(par, u0, &f);
            // U_TAPS: E, S, ..., W, N: f[6] + f[10] and f[7] + f[11] are U's second differences.
            let curv = (f[6] + f[10]).abs() + (f[7] + f[11]).abs();
            let k = sample(i, j, p, curv)?;
            r[rc] = k - u0;
        }
    }
    Ok(())
}

/// The encoder's walk: symbols, their contexts and the reconstruction of a tile from its targets `t`
/// (heights over the quantum, row-major; integers where the level is on the quantum's lattice). The
/// reason when a symbol or a reconstruction leaves the stored range.
pub fn quantise(
    model: &LevelModel,
    u: &[i64],
    (tw, th): (usize, usize),
    t: &[f64],
    scratch: &mut TileScratch,
    (syms, ctxs): (&mut [i32], &mut [u8]),
    recon: &mut [i32],
) -> Result<(), String> {
    let step = f64::from(model.step.max(1));
    let st = i64::from(model.step.max(1));
    let aw = tw + 2;
    let a = &mut scratch.a;
    a[..aw * (th + 1)].fill(0);
    walk(model, u, (tw, th), &mut scratch.r, |i, j, p, curv| {
        let at = j * tw + i;
        #[expect(clippy::cast_precision_loss, reason = "|p| <= 2^30 is exact in f64")]
        let e = (t[at] - p as f64) / step;
        let s = e.round();
        if !(s.abs() < f64::from(i32::MAX)) {
            return Err(format!("a residual of {e} steps does not fit a symbol"));
        }
        #[expect(clippy::cast_possible_truncation, reason = "checked to fit i32")]
        let s = s as i32;
        let k = p + i64::from(s) * st;
        if k.abs() > MAX_UNITS {
            return Err(format!("a height of {k} quanta is out of range"));
        }
        syms[at] = s;
        #[expect(clippy::cast_possible_truncation, reason = "fewer than 256 contexts")]
        let c = ctx_at(a, aw, i, j, curv / st) as u8;
        ctxs[at] = c;
        a[(j + 1) * aw + i + 1] = s.unsigned_abs();
        #[expect(clippy::cast_possible_truncation, reason = "|k| <= 2^30")]
        let k32 = k as i32;
        recon[at] = k32;
        Ok(k)
    })
}

/// The context of sample (i, j) from the padded symbol magnitudes `a` (width aw = tw + 2, one row
/// above) and U's curvature in steps.
#[inline(always)]
fn ctx_at(a: &[u32], aw: usize, i: usize, j: usize, curv: i64) -> usize {
    let c = (j + 1) * aw + i + 1;
    rans::context(
        (i & 1) | ((j & 1) << 1),
        (a[c - 1], a[c - aw], a[c - aw - 1], a[c - aw + 1]),
        u32::try_from(curv).unwrap_or(u32::MAX),
    )
}

/// Adds a tile's symbols to the per-context token counts.
pub fn count(counts: &mut Counts, syms: &[i32], ctxs: &[u8]) {
    for (&s, &c) in syms.iter().zip(ctxs) {
        counts.0[usize::from(c)][rans::split(zigzag(s)).0] += 1;
    }
}

/// A tile's rANS payload from its symbols and their contexts.
pub fn encode_rans(tables: &Tables, syms: &[i32], ctxs: &[u8]) -> Vec<u8> {
    let mut bits = rans::BitWriter::default();
    for &s in syms {
        let (_, n, raw) = rans::split(zigzag(s));
        bits.put(n, raw);
    }
    let mut enc = rans::Encoder::new();
    for (&s, &c) in syms.iter().zip(ctxs).rev() {
        enc.put(tables, usize::from(c), rans::split(zigzag(s)).0);
    }
    let mut body = Vec::new();
    enc.finish(&mut body);
    let n = u32::try_from(body.len()).expect("a tile's rANS part is under 4 GiB");
    let mut out = Vec::with_capacity(4 + body.len() + bits.bytes.len() + 1);
    out.extend_from_slice(&n.to_le_bytes());
    out.extend_from_slice(&body);
    out.extend_from_slice(&bits.finish());
    out
}

/// How a tile's symbols are stored.
pub enum Entropy<'a> {
    /// rANS with the package's tables.
    Rans(&'a DecodeTables),
    /// Byte planes under zstd or lz4.
    Planes(&'a mut Decoder),
}

/// Decodes a tile: `u` is U with its border, `out` receives the tw x th reconstructed heights. The reason
/// on failure: a payload that does not decode to exactly the tile's symbols, or a height out of range.
pub fn decode(
    model: &LevelModel,
    entropy: Entropy<'_>,
    payload: &[u8],
    u: &[i64],
    (tw, th): (usize, usize),
    scratch: &mut TileScratch,
    out: &mut [i32],
) -> Result<(), &'static str> {
    let n = tw * th;
    let out = out.get_mut(..n).ok_or("output smaller than the tile")?;
    let st = i64::from(model.step.max(1));
    let store = |out: &mut [i32], at: usize, p: i64, s: i32| -> Result<i64, &'static str> {
        let k = p + i64::from(s) * st;
        if k.abs() > MAX_UNITS {
            return Err("reconstructed height out of range");
        }
        #[expect(clippy::cast_possible_truncation, reason = "|k| <= 2^30")]
        let k32 = k as i32;
        out[at] = k32;
        Ok(k)
    };
    match entropy {
        Entropy::Planes(dec) => {
            let syms = scratch
                .syms
                .get_mut(..n)
                .ok_or("tile larger than the package's tile size")?;
            dec.decode(payload, syms)?;
            let syms = &scratch.syms[..n];
            walk(model, u, (tw, th), &mut scratch.r, |i, j, p, _| {
                let at = j * tw + i;
                store(out, at, p, syms[at])
            })
        }
        Entropy::Rans(tables) => {
            let (len, rest) = payload
                .split_first_chunk::<4>()
                .ok_or("tile shorter than its rANS length")?;
            let len = usize::try_from(u32::from_le_bytes(*len)).map_err(|_| "bad rANS length")?;
            if len > rest.len() {
                return Err("rANS part runs past the tile's end");
            }
            let (body, raw) = rest.split_at(len);
            let mut dec = rans::Decoder::new(body)?;
            let mut bits = rans::BitReader::new(raw);
            let aw = tw + 2;
            let a = &mut scratch.a;
            a[..aw * (th + 1)].fill(0);
            walk(model, u, (tw, th), &mut scratch.r, |i, j, p, curv| {
                let ctx = ctx_at(a, aw, i, j, curv / st);
                let tok = dec.get(tables, ctx)?;
                let raw = bits.get(rans::raw_bits(tok))?;
                let v = rans::join(tok, raw).ok_or("a symbol beyond 32 bits")?;
                let s = unzigzag(v);
                a[(j + 1) * aw + i + 1] = s.unsigned_abs();
                store(out, j * tw + i, p, s)
            })?;
            dec.finish()?;
            bits.finish()
        }
    }
}

/// The tile's symbols as byte planes (the `lz4` and `zstd` codecs).
pub fn encode_planes(enc: &mut Encoder, syms: &[i32]) -> std::io::Result<Vec<u8>> {
    enc.encode(syms)
}

/// The package's rANS tables from the bake's counts.
pub fn tables(counts: &Counts) -> Tables {
    Tables::from_counts(counts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::package::kind::CodecKind;

    fn u_field(tw: usize, th: usize) -> Vec<i64> {
        (0..(tw + 4) * (th + 4))
            .map(|k| {
                let (x, y) = ((k % (tw + 4)) as i64, (k / (tw + 4)) as i64);
                100 + 3 * x - 2 * y + (x * y) % 7
            })
            .collect()
    }

    #[test]
    fn tiles_round_trip_within_the_step() {
        let (tw, th) = (13, 9);
        let u = u_field(tw, th);
        let t: Vec<f64> = (0..tw * th)
            .map(|k| {
                let (x, y) = ((k % tw) as f64, (k / tw) as f64);
                100.0 + 3.0 * x - 2.0 * y + (x * 1.3).sin() * 9.0 + ((k * 7919) % 13) as f64
            })
            .collect();
        let mut w = [[0i16; TAPS]; 4];
        w[1][0] = 100;
        w[3][1] = -40;
        w[2][7] = 300;
        for (step, lattice) in [(1u32, true), (5, true), (4, false), (1, false)] {
            let model = LevelModel { step, weights: w };
            let t: Vec<f64> = if lattice {
                t.iter().map(|v| v.round()).collect()
            } else {
                t.clone()
            };
            let mut sc = TileScratch::new(16);
            let (mut syms, mut recon, mut ctxs) = (vec![0; tw * th], vec![0; tw * th], vec![0; tw * th]);
            quantise(&model, &u, (tw, th), &t, &mut sc, (&mut syms, &mut ctxs), &mut recon).unwrap();
            for (k, (&a, &b)) in recon.iter().zip(&t).enumerate() {
                let bound = f64::from(step) / 2.0 - if lattice && step % 2 == 1 { 0.5 } else { 0.0 };
                assert!((f64::from(a) - b).abs() <= bound + 1e-9, "{step} sample {k}");
            }
            let mut counts = Counts::default();
            count(&mut counts, &syms, &ctxs);
            let tables = tables(&counts);
            let dt = DecodeTables::new(&tables);
            let payload = encode_rans(&tables, &syms, &ctxs);
            let mut out = vec![0; tw * th];
            decode(&model, Entropy::Rans(&dt), &payload, &u, (tw, th), &mut sc, &mut out).unwrap();
            assert_eq!(out, recon, "rans, step {step}");
            for codec in [CodecKind::Zstd, CodecKind::Lz4] {
                let mut e = Encoder::new(codec, 3).unwrap();
                let p = encode_planes(&mut e, &syms).unwrap();
                let mut d = Decoder::new(codec, 256).unwrap();
                let mut out = vec![0; tw * th];
                decode(&model, Entropy::Planes(&mut d), &p, &u, (tw, th), &mut sc, &mut out)
                    .unwrap();
                assert_eq!(out, recon, "{codec:?}, step {step}");
            }
            // Damaged payloads: an error or other heights, never a panic.
            for at in 0..payload.len() {
                let mut bad = payload.clone();
                bad[at] ^= 0x5a;
                let _ = decode(&model, Entropy::Rans(&dt), &bad, &u, (tw, th), &mut sc, &mut out);
                let _ = decode(
                    &model,
                    Entropy::Rans(&dt),
                    &payload[..at],
                    &u,
                    (tw, th),
                    &mut sc,
                    &mut out,
                );
            }
        }
    }
}
