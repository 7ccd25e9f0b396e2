//! Stage 1b, the package: one height tile's coding, prediction ([`super::predict`]) with near-lossless
//! quantisation and error feedback, then the residual symbols' entropy stage (`docs/package-codec.md`).
//!
//! A tile is walked in raster order. Each sample's prediction p comes from U (the coarser level,
//! reconstructed) and the tile's own reconstructed causal neighbours; the encoder quantises the
//! prediction error e = t - p (t the height over the quantum) to the symbol s = round(e / step) and
//! reconstructs k~ = p + s step, which is what the decoder will compute, and what the later samples are
//! predicted from (the near-lossless mode of JPEG-LS, Weinberger, Seroussi and Sapiro 2000: quantised residuals and
//! the encoder's own reconstruction in the loop, so |t - k~| <= step / 2 for every sample; with an odd
//! step 2N + 1 over integer data, |t - k~| <= N exactly).
//!
//! The symbols then go through rANS ([`super::rans`]) or, for the `lz4` and `zstd` codecs, zigzag byte
//! planes ([`super::planes`]). A rANS payload is the rANS part's length (u32, little-endian), the rANS
//! part, then the raw bits.

pub use super::planes::{unzigzag, zigzag, Decoder, Encoder};
pub use super::predict::{predict_int, Predictor};
use super::predict::{LevelModel, MAX_UNITS, U_TAPS, WEIGHT_BITS};
use super::rans::{self, Counts, DecodeTables, Tables};

/// Border of U around a tile: U is evaluated over (tw + 4) x (th + 4) samples from (x0 - 2, y0 - 2).
pub const U_BORDER: usize = 2;

/// [`U_BORDER`] as a u32, for tile sides.
pub const U_BORDER_U32: u32 = 2;

/// Per-tile scratch: the padded residual field and symbol magnitudes, U in i32, a row's partial sums,
/// sized once for a tile side.
pub struct TileScratch {
    r: Vec<i64>,
    a: Vec<u32>,
    u: Vec<i32>,
    wu: Vec<i32>,
    acc: Vec<i32>,
    curv: Vec<i32>,
    pre: Vec<i64>,
    act: Vec<u32>,
    syms: Vec<i32>,
}

impl TileScratch {
    /// Scratch for tiles of up to `tile` x `tile` samples.
    pub fn new(tile: u32) -> Self {
        let t = tile as usize;
        Self {
            r: vec![0; (t + 3) * (t + 2)],
            a: vec![0; (t + 2) * (t + 1)],
            u: vec![0; (t + 4) * (t + 4)],
            wu: vec![0; 2 * U_TAPS.len() * t],
            acc: vec![0; t],
            curv: vec![0; t],
            pre: vec![0; t],
            act: vec![0; t],
            syms: vec![0; t * t],
        }
    }

    /// Bytes of this scratch for tiles of side `tile`.
    pub fn bytes(tile: u32) -> u64 {
        let t = u64::from(tile);
        8 * (t + 3) * (t + 2)
            + 4 * (t + 2) * (t + 1)
            + 4 * (t + 4) * (t + 4)
            + 64 * t
            + 24 * t
            + 4 * t * t
    }
}

/// The U taps' part of each sample's sum in row `j` (U_TAPS order), into `acc`, in i32: the caller has
/// checked that no sum can leave i32 (`narrow`). Written as one pass per tap over the row, which
/// vectorises.
#[inline(always)]
fn u_part_narrow(u: &[i32], uw: usize, tw: usize, j: usize, wu: &[i32], acc: &mut [i32]) {
    let u0 = &u[(j + 2) * uw + 2..(j + 2) * uw + 2 + tw];
    acc.fill(0);
    for (k, &(dx, dy)) in U_TAPS.iter().enumerate() {
        let at =
            (j + 2).wrapping_add_signed(dy as isize) * uw + 2usize.wrapping_add_signed(dx as isize);
        let un = &u[at..at + tw];
        let w = &wu[k * tw..(k + 1) * tw];
        for (((s, &n), &c), &wk) in acc.iter_mut().zip(un).zip(u0).zip(w) {
            *s += wk * (n - c);
        }
    }
}

/// Walks a tw x th tile in raster order: `sample(i, j, p, ctx)` gets the prediction p of sample (i, j)
/// ([`LevelModel::predict`], computed here a row at a time) and its entropy context
/// ([`rans::context_base`] + [`rans::bucket`]), and returns its reconstruction k~ and its symbol's
/// magnitude (an error stops the walk). `u` is U with its border ([`U_BORDER`]).
///
/// Each row first sums what does not depend on the row itself (the U taps, the taps on the rows above,
/// the context's part from them), with no dependency from one sample to the next; the serial part adds
/// the two taps and the context term of the samples to the left. Every sum is exact, in i32 where the
/// tile's range of U bounds it there and in i64 otherwise, so the prediction is the same either way.
#[inline(always)]
fn walk<E>(
    model: &LevelModel,
    u: &[i64],
    (tw, th): (usize, usize),
    sc: &mut TileScratch,
    mut sample: impl FnMut(usize, usize, i64, usize) -> Result<(i64, u32), E>,
) -> Result<(), E> {
    let (rw, uw, aw) = (tw + 3, tw + 4, tw + 2);
    let u = &u[..uw * (th + 4)];
    let (r, a) = (&mut sc.r[..rw * (th + 2)], &mut sc.a[..aw * (th + 1)]);
    let (pre, act) = (&mut sc.pre[..tw], &mut sc.act[..tw]);
    let (acc, curv) = (&mut sc.acc[..tw], &mut sc.curv[..tw]);
    r.fill(0);
    a.fill(0);
    let st = i64::from(model.step.max(1));
    let weights = model.weights.map(|w| w.map(i64::from));
    // |a U tap's difference| <= max U - min U; the U part of a sum is at most that times the largest
    // sum of |weights| over the U taps.
    let (lo, hi) = u
        .iter()
        .fold((i64::MAX, i64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    let wsum = weights
        .iter()
        .map(|w| w[6..].iter().map(|x| x.abs()).sum::<i64>())
        .max()
        .unwrap_or(0);
    // At least 4 times the range: the curvature's two second differences (each at most twice it) add
    // up inside i32 too.
    let narrow =
        (hi - lo).saturating_mul(wsum.max(4)) < 1 << 30 && hi.abs().max(lo.abs()) < 1 << 30;
    if narrow {
        for (d, &s) in sc.u[..u.len()].iter_mut().zip(u) {
            *d = i32::try_from(s).expect("checked inside i32");
        }
        for rp in 0..2 {
            for k in 0..U_TAPS.len() {
                let row =
                    &mut sc.wu[(rp * U_TAPS.len() + k) * tw..(rp * U_TAPS.len() + k + 1) * tw];
                for (i, w) in row.iter_mut().enumerate() {
                    *w = i32::from(model.weights[(i & 1) | (rp << 1)][6 + k]);
                }
            }
        }
    }
    for j in 0..th {
        let (we, wo) = (&weights[(j & 1) << 1], &weights[1 | ((j & 1) << 1)]);
        let (rc0, ac0, uc0) = ((j + 2) * rw + 2, (j + 1) * aw + 1, (j + 2) * uw + 2);
        let u0row = &u[uc0..uc0 + tw];
        if narrow {
            let nt = U_TAPS.len();
            let wu = &sc.wu[(j & 1) * nt * tw..((j & 1) + 1) * nt * tw];
            u_part_narrow(&sc.u, uw, tw, j, wu, acc);
            // U_TAPS 0, 4 are E, W; 1, 5 are S, N: U's second differences across and along.
            let row = |dx: isize, dy: isize| {
                let at = (j + 2).wrapping_add_signed(dy) * uw + 2usize.wrapping_add_signed(dx);
                &sc.u[at..at + tw]
            };
            let (e, ww, s, n, c0) = (row(1, 0), row(-1, 0), row(0, 1), row(0, -1), row(0, 0));
            for (i, cv) in curv.iter_mut().enumerate() {
                *cv = (e[i] + ww[i] - 2 * c0[i]).abs() + (s[i] + n[i] - 2 * c0[i]).abs();
            }
        } else {
            for (i, (s, cv)) in acc.iter_mut().zip(curv.iter_mut()).enumerate() {
                let w = if i & 1 == 0 { we } else { wo };
                let c = uc0 + i;
                let d = |dx: i32, dy: i32| {
                    u[c.wrapping_add_signed(dy as isize * uw as isize + dx as isize)] - u[c]
                };
                let mut sum = 0i64;
                for (k, &(dx, dy)) in U_TAPS.iter().enumerate() {
                    sum += w[6 + k] * d(dx, dy);
                }
                // Out of i32 only in the wide case: kept in `pre` below through the i64 path.
                *s = 0;
                pre[i] = sum;
                let cu = (d(1, 0) + d(-1, 0)).abs() + (d(0, 1) + d(0, -1)).abs();
                *cv = i32::try_from(cu.min(i64::from(i32::MAX))).expect("clamped");
            }
        }
        for (i, ((pr, ac), (&s, &cv))) in pre
            .iter_mut()
            .zip(act.iter_mut())
            .zip(acc.iter().zip(curv.iter()))
            .enumerate()
        {
            let w = if i & 1 == 0 { we } else { wo };
            let (rc, an) = (rc0 + i, ac0 + i - aw);
            let upart = if narrow { i64::from(s) } else { *pr };
            *pr = upart
                + (1 << (WEIGHT_BITS - 1))
                + w[1] * r[rc - rw]
                + w[2] * r[rc - rw - 1]
                + w[3] * r[rc - rw + 1]
                + w[5] * r[rc - 2 * rw];
            let cv = if st == 1 {
                i64::from(cv)
            } else {
                i64::from(cv) / st
            };
            *ac = rans::activity(a[an], a[an - 1], a[an + 1], cv);
        }
        let (mut r1, mut r2, mut m1, mut m2) = (0i64, 0i64, 0u32, 0u32);
        let base = [
            rans::context_base((j & 1) << 1),
            rans::context_base(1 | ((j & 1) << 1)),
        ];
        for (i, ((&pr, &ac), &u0)) in pre.iter().zip(act.iter()).zip(u0row).enumerate() {
            let w = if i & 1 == 0 { we } else { wo };
            let s = pr + w[0] * r1 + w[4] * r2;
            let p = (u0 + (s >> WEIGHT_BITS)).clamp(-MAX_UNITS, MAX_UNITS);
            // The context's term from the row itself: the symbol two to the left ([`rans::activity`]).
            let ctx = base[i & 1] + rans::bucket(ac + m2.min(64));
            let (k, mag) = sample(i, j, p, ctx)?;
            let rv = k - u0;
            r[rc0 + i] = rv;
            a[ac0 + i] = mag;
            (r2, r1) = (r1, rv);
            (m2, m1) = (m1, mag);
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
    walk(model, u, (tw, th), scratch, |i, j, p, ctx| {
        let at = j * tw + i;
        #[expect(clippy::cast_precision_loss, reason = "|p| <= 2^30 is exact in f64")]
        let e = (t[at] - p as f64) / step;
        let s = e.round();
        if s.is_nan() || s.abs() >= f64::from(i32::MAX) {
            return Err(format!("a residual of {e} steps does not fit a symbol"));
        }
        #[expect(clippy::cast_possible_truncation, reason = "checked to fit i32")]
        let s = s as i32;
        let k = p + i64::from(s) * st;
        if k.abs() > MAX_UNITS {
            return Err(format!("a height of {k} quanta is out of range"));
        }
        syms[at] = s;
        ctxs[at] = u8::try_from(ctx).expect("fewer than 256 contexts");
        #[expect(clippy::cast_possible_truncation, reason = "|k| <= 2^30")]
        let k32 = k as i32;
        recon[at] = k32;
        Ok((k, s.unsigned_abs()))
    })
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
    for (n, (&s, &c)) in syms.iter().zip(ctxs).enumerate().rev() {
        enc.put(tables, n, usize::from(c), rans::split(zigzag(s)).0);
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
            let syms = std::mem::take(&mut scratch.syms);
            let done = walk(model, u, (tw, th), scratch, |i, j, p, _| {
                let at = j * tw + i;
                let s = syms[at];
                Ok::<_, &'static str>((store(out, at, p, s)?, s.unsigned_abs()))
            });
            scratch.syms = syms;
            done
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
            walk(model, u, (tw, th), scratch, |i, j, p, ctx| {
                let tok = dec.get(tables, ctx)?;
                let raw = bits.get(rans::raw_bits(tok))?;
                let v = rans::join(tok, raw).ok_or("a symbol beyond 32 bits")?;
                let s = unzigzag(v);
                Ok::<_, &'static str>((store(out, j * tw + i, p, s)?, s.unsigned_abs()))
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
#[expect(
    clippy::cast_possible_truncation,
    reason = "test indices and values are small"
)]
mod tests {
    use super::*;
    use crate::package::kind::CodecKind;
    use crate::package::predict::{R_TAPS, TAPS};

    /// The prediction as [`LevelModel::predict`] defines it, sample by sample, for lattice targets and
    /// step 1: the reconstruction is the target, so the symbols are target - prediction.
    fn reference_symbols(
        model: &LevelModel,
        u: &[i64],
        (tw, th): (usize, usize),
        t: &[i64],
    ) -> Vec<i32> {
        let uw = tw + 4;
        let uat = |i: i64, j: i64| u[((j + 2) as usize) * uw + (i + 2) as usize];
        let r = |i: i64, j: i64| -> i64 {
            if i < 0 || j < 0 || i >= tw as i64 || j >= th as i64 {
                0
            } else {
                t[j as usize * tw + i as usize] - uat(i, j)
            }
        };
        let mut out = Vec::new();
        for j in 0..th as i64 {
            for i in 0..tw as i64 {
                let mut f = [0i64; TAPS];
                for (fk, &(dx, dy)) in f.iter_mut().zip(&R_TAPS) {
                    *fk = r(i + i64::from(dx), j + i64::from(dy));
                }
                for (fk, &(dx, dy)) in f[6..].iter_mut().zip(&U_TAPS) {
                    *fk = uat(i + i64::from(dx), j + i64::from(dy)) - uat(i, j);
                }
                let par = ((i & 1) | ((j & 1) << 1)) as usize;
                let p = model.predict(par, uat(i, j), &f);
                out.push(i32::try_from(t[j as usize * tw + i as usize] - p).unwrap());
            }
        }
        out
    }

    #[test]
    fn the_row_walk_predicts_as_the_reference_narrow_and_wide() {
        let (tw, th) = (11, 7);
        let mut w = [[0i16; TAPS]; 4];
        for (k, x) in w.iter_mut().flatten().enumerate() {
            *x = ((k as i16 * 37) % 300) - 150;
        }
        let model = LevelModel {
            step: 1,
            weights: w,
        };
        for scale in [1i64, 1 << 22] {
            let u: Vec<i64> = (0..(tw + 4) * (th + 4))
                .map(|k| ((k as i64 * 7919) % 1001 - 500) * scale)
                .collect();
            let t: Vec<i64> = (0..tw * th)
                .map(|k| ((k as i64 * 104_729) % 301 - 150) * scale)
                .collect();
            let tf: Vec<f64> = t.iter().map(|&v| v as f64).collect();
            let mut sc = TileScratch::new(16);
            let (mut syms, mut recon, mut ctxs) =
                (vec![0; tw * th], vec![0; tw * th], vec![0; tw * th]);
            quantise(
                &model,
                &u,
                (tw, th),
                &tf,
                &mut sc,
                (&mut syms, &mut ctxs),
                &mut recon,
            )
            .unwrap();
            assert_eq!(
                syms,
                reference_symbols(&model, &u, (tw, th), &t),
                "scale {scale}"
            );
        }
    }

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
            let (mut syms, mut recon, mut ctxs) =
                (vec![0; tw * th], vec![0; tw * th], vec![0; tw * th]);
            quantise(
                &model,
                &u,
                (tw, th),
                &t,
                &mut sc,
                (&mut syms, &mut ctxs),
                &mut recon,
            )
            .unwrap();
            for (k, (&a, &b)) in recon.iter().zip(&t).enumerate() {
                let bound =
                    f64::from(step) / 2.0 - if lattice && step % 2 == 1 { 0.5 } else { 0.0 };
                assert!(
                    (f64::from(a) - b).abs() <= bound + 1e-9,
                    "{step} sample {k}"
                );
            }
            let mut counts = Counts::default();
            count(&mut counts, &syms, &ctxs);
            let tables = tables(&counts);
            let dt = DecodeTables::new(&tables);
            let payload = encode_rans(&tables, &syms, &ctxs);
            let mut out = vec![0; tw * th];
            decode(
                &model,
                Entropy::Rans(&dt),
                &payload,
                &u,
                (tw, th),
                &mut sc,
                &mut out,
            )
            .unwrap();
            assert_eq!(out, recon, "rans, step {step}");
            for codec in [CodecKind::Zstd, CodecKind::Lz4] {
                let mut e = Encoder::new(codec, 3).unwrap();
                let p = encode_planes(&mut e, &syms).unwrap();
                let mut d = Decoder::new(codec, 256).unwrap();
                let mut out = vec![0; tw * th];
                decode(
                    &model,
                    Entropy::Planes(&mut d),
                    &p,
                    &u,
                    (tw, th),
                    &mut sc,
                    &mut out,
                )
                .unwrap();
                assert_eq!(out, recon, "{codec:?}, step {step}");
            }
            // Damaged payloads: an error or other heights, never a panic.
            for at in 0..payload.len() {
                let mut bad = payload.clone();
                bad[at] ^= 0x5a;
                let _ = decode(
                    &model,
                    Entropy::Rans(&dt),
                    &bad,
                    &u,
                    (tw, th),
                    &mut sc,
                    &mut out,
                );
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
