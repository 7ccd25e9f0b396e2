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
use super::predict::{LevelModel, MAX_UNITS, TAPS, U_TAPS, WEIGHT_BITS};
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

/// What the passes over one tile share, from [`TileScratch::begin`].
struct Rows {
    tw: usize,
    th: usize,
    st: i64,
    weights: [[i64; TAPS]; 4],
    /// Every U sum of the tile fits i32: U is in `TileScratch::u` and the U taps' weights per column in
    /// `TileScratch::wu`.
    narrow: bool,
}

impl Rows {
    /// The weights of row `j`'s even and odd samples.
    #[inline(always)]
    fn weights(&self, j: usize) -> (&[i64; TAPS], &[i64; TAPS]) {
        (
            &self.weights[(j & 1) << 1],
            &self.weights[1 | ((j & 1) << 1)],
        )
    }
}

impl TileScratch {
    /// Starts a tile: zeroes the borders of the residual and magnitude fields (the neighbours outside
    /// the tile) and decides whether U's sums fit i32; if they do, U in i32 and the U taps' weights
    /// per column are written for [`u_part_narrow`].
    fn begin(&mut self, model: &LevelModel, u: &[i64], (tw, th): (usize, usize)) -> Rows {
        // Only the borders: every interior value is written before it is read. The top rows whole, then
        // the side columns of every row (a narrower tile before this one left values there).
        let (rw, aw) = (tw + 3, tw + 2);
        self.r[..2 * rw].fill(0);
        for row in self.r[2 * rw..(th + 2) * rw].chunks_exact_mut(rw) {
            (row[0], row[1], row[rw - 1]) = (0, 0, 0);
        }
        self.a[..aw].fill(0);
        for row in self.a[aw..(th + 1) * aw].chunks_exact_mut(aw) {
            (row[0], row[aw - 1]) = (0, 0);
        }
        let u = &u[..(tw + 4) * (th + 4)];
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
            for (d, &s) in self.u[..u.len()].iter_mut().zip(u) {
                *d = i32::try_from(s).expect("checked inside i32");
            }
            for rp in 0..2 {
                for k in 0..U_TAPS.len() {
                    let row =
                        &mut self.wu[(rp * U_TAPS.len() + k) * tw..(rp * U_TAPS.len() + k + 1) * tw];
                    for (i, w) in row.iter_mut().enumerate() {
                        *w = i32::from(model.weights[(i & 1) | (rp << 1)][6 + k]);
                    }
                }
            }
        }
        Rows {
            tw,
            th,
            st: i64::from(model.step.max(1)),
            weights,
            narrow,
        }
    }

    /// The part of row `j`'s contexts from the row above, into `act`: [`rans::activity`] of the
    /// magnitudes above each sample and U's curvature in steps.
    #[inline(always)]
    fn row_activity(&mut self, rows: &Rows, u: &[i64], j: usize) {
        let (tw, uw, aw) = (rows.tw, rows.tw + 4, rows.tw + 2);
        let (a, act, curv) = (&self.a, &mut self.act[..tw], &mut self.curv[..tw]);
        let uc0 = (j + 2) * uw + 2;
        if rows.narrow {
            // U_TAPS 0, 4 are E, W; 1, 5 are S, N: U's second differences across and along.
            let row = |dx: isize, dy: isize| {
                let at = (j + 2).wrapping_add_signed(dy) * uw + 2usize.wrapping_add_signed(dx);
                &self.u[at..at + tw]
            };
            let (e, ww, s, n, c0) = (row(1, 0), row(-1, 0), row(0, 1), row(0, -1), row(0, 0));
            for (i, cv) in curv.iter_mut().enumerate() {
                *cv = (e[i] + ww[i] - 2 * c0[i]).abs() + (s[i] + n[i] - 2 * c0[i]).abs();
            }
        } else {
            for (i, cv) in curv.iter_mut().enumerate() {
                let c = uc0 + i;
                let cu = (u[c + 1] + u[c - 1] - 2 * u[c]).abs()
                    + (u[c + uw] + u[c - uw] - 2 * u[c]).abs();
                *cv = i32::try_from(cu.min(i64::from(i32::MAX))).expect("clamped");
            }
        }
        let an0 = j * aw + 1;
        // Steps are at most 2^20 (the header's check), curvatures at least 0.
        let st = u32::try_from(rows.st).expect("a step fits u32");
        for (i, (ac, &cv)) in act.iter_mut().zip(curv.iter()).enumerate() {
            let cv = cv.unsigned_abs();
            let cv = if st == 1 { cv } else { cv / st };
            let an = an0 + i;
            *ac = rans::activity(a[an], a[an - 1], a[an + 1], cv);
        }
    }

    /// The part of row `j`'s prediction sums that does not depend on the row itself, into `pre`: the U
    /// taps, the residual taps on the rows above, and the rounding term. Each sample's sum is exact (in
    /// i32 when `narrow`, else in i64), so it is the same either way.
    #[inline(always)]
    fn row_pre(&mut self, rows: &Rows, u: &[i64], j: usize) {
        let (tw, uw, rw) = (rows.tw, rows.tw + 4, rows.tw + 3);
        let (we, wo) = rows.weights(j);
        let (rc0, uc0) = ((j + 2) * rw + 2, (j + 2) * uw + 2);
        let pre = &mut self.pre[..tw];
        if rows.narrow {
            let nt = U_TAPS.len();
            let wu = &self.wu[(j & 1) * nt * tw..((j & 1) + 1) * nt * tw];
            let acc = &mut self.acc[..tw];
            u_part_narrow(&self.u, uw, tw, j, wu, acc);
            for (p, &s) in pre.iter_mut().zip(acc.iter()) {
                *p = i64::from(s);
            }
        } else {
            for (i, p) in pre.iter_mut().enumerate() {
                let w = if i & 1 == 0 { we } else { wo };
                let c = uc0 + i;
                let mut sum = 0i64;
                for (k, &(dx, dy)) in U_TAPS.iter().enumerate() {
                    let at = c.wrapping_add_signed(dy as isize * uw as isize + dx as isize);
                    sum += w[6 + k] * (u[at] - u[c]);
                }
                *p = sum;
            }
        }
        // n[i], n[i + 1], n[i + 2] are sample i's NW, N and NE; nn[i] its NN. By pairs, so that each
        // sample's weights are known without a test of its parity.
        let (n, nn) = (
            &self.r[rc0 - rw - 1..rc0 - rw + tw + 1],
            &self.r[rc0 - 2 * rw..rc0 - 2 * rw + tw],
        );
        let tap = |w: &[i64; TAPS], i: usize| {
            (1 << (WEIGHT_BITS - 1))
                + w[1] * n[i + 1]
                + w[2] * n[i]
                + w[3] * n[i + 2]
                + w[5] * nn[i]
        };
        let mut pairs = pre.chunks_exact_mut(2);
        for (k, p) in pairs.by_ref().enumerate() {
            p[0] += tap(we, 2 * k);
            p[1] += tap(wo, 2 * k + 1);
        }
        if let [p] = pairs.into_remainder() {
            *p += tap(we, tw - 1);
        }
    }
}

/// Walks a tw x th tile in raster order: `sample(i, j, p, ctx)` gets the prediction p of sample (i, j)
/// ([`LevelModel::predict`], computed here a row at a time) and its entropy context
/// ([`rans::context_base`] + [`rans::bucket`]), and returns its reconstruction k~ and its symbol's
/// magnitude (an error stops the walk). `u` is U with its border ([`U_BORDER`]). The encoder's walk;
/// the decoder splits the same computation in two passes ([`decode`]).
///
/// Each row first sums what does not depend on the row itself ([`TileScratch::row_pre`],
/// [`TileScratch::row_activity`]), with no dependency from one sample to the next; the serial part adds
/// the two taps and the context term of the samples to the left.
fn walk<E>(
    model: &LevelModel,
    u: &[i64],
    (tw, th): (usize, usize),
    sc: &mut TileScratch,
    mut sample: impl FnMut(usize, usize, i64, usize) -> Result<(i64, u32), E>,
) -> Result<(), E> {
    let rows = sc.begin(model, u, (tw, th));
    let (rw, uw, aw) = (tw + 3, tw + 4, tw + 2);
    for j in 0..th {
        sc.row_pre(&rows, u, j);
        sc.row_activity(&rows, u, j);
        let (we, wo) = rows.weights(j);
        let (rc0, ac0, uc0) = ((j + 2) * rw + 2, (j + 1) * aw + 1, (j + 2) * uw + 2);
        let (mut r1, mut r2, mut m1, mut m2) = (0i64, 0i64, 0u32, 0u32);
        let base = [
            rans::context_base((j & 1) << 1),
            rans::context_base(1 | ((j & 1) << 1)),
        ];
        let row = sc.pre[..tw].iter().zip(&sc.act[..tw]).zip(&u[uc0..uc0 + tw]);
        for (i, ((&pr, &ac), &u0)) in row.enumerate() {
            let w = if i & 1 == 0 { we } else { wo };
            let s = pr + w[0] * r1 + w[4] * r2;
            let p = (u0 + (s >> WEIGHT_BITS)).clamp(-MAX_UNITS, MAX_UNITS);
            // The context's term from the row itself: the symbol two to the left ([`rans::activity`]).
            let ctx = base[i & 1] + rans::bucket(ac + m2.min(64));
            let (k, mag) = sample(i, j, p, ctx)?;
            let rv = k - u0;
            sc.r[rc0 + i] = rv;
            sc.a[ac0 + i] = mag;
            (r2, r1) = (r1, rv);
            (m2, m1) = (m1, mag);
        }
    }
    Ok(())
}

/// The decoder's first pass over a rANS tile: every symbol, in raster order, into `sc.syms`. A context
/// needs only symbols (the magnitudes above and two to the left) and U, never a height, so the tokens
/// decode before any prediction is made, in a loop whose only chain from token to token is the rANS
/// state and the context ([`walk`] computes the same contexts).
fn rans_symbols(
    tables: &DecodeTables,
    dec: &mut rans::Decoder<'_>,
    bits: &mut rans::BitReader<'_>,
    u: &[i64],
    rows: &Rows,
    sc: &mut TileScratch,
) -> Result<(), &'static str> {
    let (tw, aw) = (rows.tw, rows.tw + 2);
    for j in 0..rows.th {
        sc.row_activity(rows, u, j);
        let ac0 = (j + 1) * aw + 1;
        let base = [
            rans::context_base((j & 1) << 1),
            rans::context_base(1 | ((j & 1) << 1)),
        ];
        let (mut m1, mut m2) = (0u32, 0u32);
        let mut d = *dec;
        let srow = &mut sc.syms[j * tw..(j + 1) * tw];
        let arow = &mut sc.a[ac0..ac0 + tw];
        for (i, ((sy, am), &ac)) in srow.iter_mut().zip(arow).zip(&sc.act[..tw]).enumerate() {
            let tok = d.get(tables, base[i & 1] + rans::bucket(ac + m2));
            let v = if tok < 16 {
                #[expect(clippy::cast_possible_truncation, reason = "tok < 16")]
                let v = tok as u32;
                v
            } else {
                let raw = bits.get(rans::raw_bits(tok))?;
                rans::join(tok, raw).ok_or("a symbol beyond 32 bits")?
            };
            let s = unzigzag(v);
            // Clamped as [`rans::activity`] clamps it.
            let mag = s.unsigned_abs().min(64);
            (*sy, *am) = (s, mag);
            (m2, m1) = (m1, mag);
        }
        *dec = d;
    }
    Ok(())
}

/// The decoder's second pass: the heights from the symbols in `sc.syms`, into `out`. The chain from
/// sample to sample is one multiply, the shift and the clamp; the clamp's bounds are U's, known before.
fn reconstruct(
    u: &[i64],
    rows: &Rows,
    sc: &mut TileScratch,
    out: &mut [i32],
) -> Result<(), &'static str> {
    let (tw, rw, uw) = (rows.tw, rows.tw + 3, rows.tw + 4);
    let st = rows.st;
    for j in 0..rows.th {
        sc.row_pre(rows, u, j);
        let (we, wo) = rows.weights(j);
        // The two taps on the row itself, W and WW, for even and odd samples.
        let (w0, w4) = ([we[0], wo[0]], [we[4], wo[4]]);
        let (rc0, uc0) = ((j + 2) * rw + 2, (j + 2) * uw + 2);
        let (mut r1, mut r2) = (0i64, 0i64);
        let row = sc.pre[..tw]
            .iter()
            .zip(&u[uc0..uc0 + tw])
            .zip(&sc.syms[j * tw..(j + 1) * tw])
            .zip(sc.r[rc0..rc0 + tw].iter_mut().zip(&mut out[j * tw..(j + 1) * tw]));
        for (i, (((&pr, &u0), &sy), (rv, o))) in row.enumerate() {
            // k~ = clamp(U + q) + s step, and r = k~ - U: the clamp moves to q, by bounds off the chain.
            let q = (pr + w4[i & 1] * r2 + w0[i & 1] * r1) >> WEIGHT_BITS;
            let r = q.max(-MAX_UNITS - u0).min(MAX_UNITS - u0) + i64::from(sy) * st;
            let k = u0 + r;
            if k.abs() > MAX_UNITS {
                return Err("reconstructed height out of range");
            }
            #[expect(clippy::cast_possible_truncation, reason = "|k| <= 2^30")]
            let k32 = k as i32;
            (*rv, *o) = (r, k32);
            (r2, r1) = (r1, r);
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
        // f64::round is a libm call on the x86-64 baseline; the sign of a zero does not matter here.
        let s = super::spill::round_half_away(e);
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
///
/// Two passes, the symbols (`rans_symbols`, or the byte planes) and then the heights
/// (`reconstruct`), compute what `walk` computes for the encoder. Each serial loop is short, with no
/// error path per token (one lean loop doing both measured the same; two are simpler to read).
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
    if n > scratch.syms.len() || u.len() < (tw + 4) * (th + 4) {
        return Err("tile larger than the package's tile size");
    }
    let rows = scratch.begin(model, u, (tw, th));
    match entropy {
        Entropy::Planes(dec) => dec.decode(payload, &mut scratch.syms[..n])?,
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
            rans_symbols(tables, &mut dec, &mut bits, u, &rows, scratch)?;
            dec.finish()?;
            bits.finish()?;
        }
    }
    reconstruct(u, &rows, scratch, out)
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
    use crate::package::predict::R_TAPS;

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
            let (syms, _, _) = quantised(&model, &u, (tw, th), &tf);
            assert_eq!(
                syms,
                reference_symbols(&model, &u, (tw, th), &t),
                "scale {scale}"
            );
        }
    }

    /// The encoder's walk over one tile with a scratch of its own: (symbols, contexts, reconstruction).
    fn quantised(
        model: &LevelModel,
        u: &[i64],
        (tw, th): (usize, usize),
        t: &[f64],
    ) -> (Vec<i32>, Vec<u8>, Vec<i32>) {
        let mut sc = TileScratch::new(16);
        let (mut syms, mut ctxs, mut recon) = (vec![0; tw * th], vec![0; tw * th], vec![0; tw * th]);
        quantise(
            model,
            u,
            (tw, th),
            t,
            &mut sc,
            (&mut syms, &mut ctxs),
            &mut recon,
        )
        .unwrap();
        (syms, ctxs, recon)
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
            let (syms, ctxs, recon) = quantised(&model, &u, (tw, th), &t);
            let mut sc = TileScratch::new(16);
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

    #[test]
    fn a_scratch_decodes_a_narrower_tile_after_a_wider_one() {
        // The passes zero only the fields' borders: what a wider tile left inside them must not leak into
        // a narrower tile's neighbours. The wide tile is rough; the narrow one is U exactly (every symbol
        // 0 under U alone), so its contexts come from U's curvature and the borders alone; with weights,
        // its predictions read the residual field's borders.
        let mut w = [[0i16; TAPS]; 4];
        for (k, x) in w.iter_mut().flatten().enumerate() {
            *x = ((k as i16 * 53) % 200) - 100;
        }
        for model in [LevelModel::plain(1), LevelModel { step: 1, weights: w }] {
            let tile = |tw: usize, th: usize, rough: bool| {
                let u = u_field(tw, th);
                let t: Vec<f64> = (0..tw * th)
                    .map(|k| {
                        let at = (k / tw + 2) * (tw + 4) + k % tw + 2;
                        let noise = if rough { (k as i64 * 7919) % 23 * 37 } else { 0 };
                        (u[at] + noise) as f64
                    })
                    .collect();
                let (syms, ctxs, recon) = quantised(&model, &u, (tw, th), &t);
                (u, syms, ctxs, recon)
            };
            let (wide, narrow) = (tile(16, 16, true), tile(5, 9, false));
            let mut counts = Counts::default();
            count(&mut counts, &wide.1, &wide.2);
            count(&mut counts, &narrow.1, &narrow.2);
            let t = tables(&counts);
            let dt = DecodeTables::new(&t);
            let mut sc = TileScratch::new(16);
            for (tw, th, (u, syms, ctxs, recon)) in [(16, 16, &wide), (5, 9, &narrow)] {
                let payload = encode_rans(&t, syms, ctxs);
                let mut out = vec![0; tw * th];
                let dec = Entropy::Rans(&dt);
                decode(&model, dec, &payload, u, (tw, th), &mut sc, &mut out).unwrap();
                assert_eq!(&out, recon, "{tw} x {th}, {model:?}");
            }
        }
    }
}
