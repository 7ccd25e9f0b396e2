//! Stage 1b, the package: the residual symbols' entropy coder, static rANS with context-selected tables
//! (`docs/package-codec.md`, "Entropy coding").
//!
//! A residual symbol s is zigzagged to v and split into a token and raw bits, as JPEG XL's hybrid
//! integers do: v < 16 is its own token; above, the token names the position e of v's top bit and the
//! bit below it, and the e - 1 bits under those two follow raw. The tokens go through one rANS state
//! (Duda 2013, "Asymmetric numeral systems", the range variant rANS; 32-bit state, 16-bit words, as in
//! Giesen's interleaved-rANS notes) with probabilities from one of [`CONTEXTS`] tables: the sample's
//! parity and the activity of its decoded neighbours' symbols, bucketed as JPEG-LS buckets its local
//! gradients (Weinberger, Seroussi and Sapiro 2000, context modelling). The raw bits follow the rANS words in a plain
//! little-endian bit stream.
//!
//! The tables are static, one set per package, stored in the header: every tile decodes with them alone.
//! Adaptive per-tile models cost more than the tables' bytes (`docs/package-codec.md`).

/// Probabilities are integers over 2^PROB_BITS.
pub const PROB_BITS: u32 = 12;
const M: u32 = 1 << PROB_BITS;
/// The state's lower bound: the state lies in [L, 2^16 L) between symbols.
const L: u32 = 1 << 16;

/// Tokens: 16 literal values, then two per top-bit position 4 ..= 31.
pub const TOKENS: usize = 16 + 2 * 28;

/// Activity buckets ([`activity`]): at most 0, 2, 4, 7, 11, 17, 25, or more.
const ACTIVITY: [u32; 7] = [0, 2, 4, 7, 11, 17, 25];

/// [`ACTIVITY`]'s bucket of each a up to its last threshold + 1.
const BUCKET: [u8; 27] = {
    let mut t = [0u8; 27];
    let mut a = 0;
    while a < 27 {
        let mut b = 0;
        while b < ACTIVITY.len() && a > ACTIVITY[b] {
            b += 1;
        }
        #[expect(clippy::cast_possible_truncation, reason = "b <= 7")]
        {
            t[a as usize] = b as u8;
        }
        a += 1;
    }
    t
};

/// Context tables: 4 parities x 8 activity buckets.
pub const CONTEXTS: usize = 4 * (ACTIVITY.len() + 1);

/// The part of a sample's activity from the row above: the magnitudes of the symbols above it (n, nw,
/// ne) and U's curvature `curv` in steps (the local gradients of JPEG-LS and CALIC's error energy, Wu and
/// Memon 1997, put together: the neighbours' errors and the coarse level's shape). The whole activity
/// adds the magnitude of the symbol two to the left: a = 2 |s_N| + |s_NW| + |s_NE| + |s_WW| + curv / 2,
/// each term clamped to 64. Not the left neighbour's, so that no context waits for the token just
/// decoded (two rANS states take the tokens in turn): with |s_W| in its place (and doubled) the
/// pyramid was 0.4 % smaller on Big Tujunga, 0.3 % on n07_w006, 1.5 % on N57E011 and the same on Puget
/// Sound, and every token's decoding waited on the one before.
#[inline]
pub fn activity(n: u32, nw: u32, ne: u32, curv: u32) -> u32 {
    2 * n.min(64) + nw.min(64) + ne.min(64) + (curv.min(64) >> 1)
}

/// The first context of parity `par`.
#[inline]
pub fn context_base(par: usize) -> usize {
    (par & 3) * (ACTIVITY.len() + 1)
}

/// The activity bucket of a sample's whole activity ([`activity`] plus |s_WW|). A sample's context is
/// [`context_base`] of its parity plus this.
#[inline]
pub fn bucket(act: u32) -> usize {
    usize::from(BUCKET[act.min(26) as usize])
}

/// Zigzag of a symbol (0, -1, 1, -2 -> 0, 1, 2, 3).
#[inline]
#[expect(
    clippy::cast_sign_loss,
    reason = "zigzag reinterprets the two's complement bits"
)]
pub fn zigzag(s: i32) -> u32 {
    ((s << 1) ^ (s >> 31)) as u32
}

/// Inverse of [`zigzag`].
#[inline]
#[expect(
    clippy::cast_possible_wrap,
    reason = "zigzag reinterprets the two's complement bits"
)]
pub fn unzigzag(v: u32) -> i32 {
    ((v >> 1) as i32) ^ -((v & 1) as i32)
}

/// A zigzagged value's (token, raw bit count, raw bits).
#[inline]
pub fn split(v: u32) -> (usize, u32, u32) {
    if v < 16 {
        return (v as usize, 0, 0);
    }
    let e = 31 - v.leading_zeros();
    let tok = 16 + 2 * (e as usize - 4) + ((v >> (e - 1)) & 1) as usize;
    (tok, e - 1, v & ((1 << (e - 1)) - 1))
}

/// Raw bits following a token (0 for the literal tokens).
#[inline]
pub fn raw_bits(tok: usize) -> u32 {
    if tok < 16 {
        0
    } else {
        // Tokens past the table are refused by the decoder before this is reached.
        #[expect(clippy::cast_possible_truncation, reason = "tok < TOKENS")]
        let e = ((tok - 16) / 2 + 4) as u32;
        e - 1
    }
}

/// A token and its raw bits back to the zigzagged value; `None` when it does not fit 32 bits.
#[inline]
pub fn join(tok: usize, raw: u32) -> Option<u32> {
    if tok < 16 {
        #[expect(clippy::cast_possible_truncation, reason = "tok < 16")]
        return Some(tok as u32);
    }
    #[expect(clippy::cast_possible_truncation, reason = "tok < TOKENS")]
    let (e, half) = (((tok - 16) / 2 + 4) as u32, ((tok - 16) & 1) as u32);
    let top = (2 | half).checked_shl(e - 1)?;
    Some(top | raw)
}

/// The package's tables: per context, a frequency per token summing to 2^PROB_BITS.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tables {
    freq: Vec<[u16; TOKENS]>,
}

/// Per-context token counts, to build [`Tables`] from (the bake's histogram pass).
#[derive(Clone, Debug)]
pub struct Counts(pub Vec<[u64; TOKENS]>);

impl Default for Counts {
    fn default() -> Self {
        Self(vec![[0; TOKENS]; CONTEXTS])
    }
}

impl Tables {
    /// Normalised tables from counts: every seen token keeps a frequency of at least 1, the rounding
    /// difference goes to the most frequent tokens; a context never seen codes token 0 only.
    pub fn from_counts(c: &Counts) -> Self {
        let freq = c.0.iter().map(normalise).collect();
        Self { freq }
    }

    /// Bytes of [`Tables::to_bytes`].
    pub fn byte_len(&self) -> usize {
        self.to_bytes().len()
    }

    /// Per context: the count n of tokens listed (the last nonzero one + 1), then n LEB128 frequencies.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::new();
        for f in &self.freq {
            let n = f.iter().rposition(|&x| x > 0).map_or(0, |i| i + 1);
            #[expect(clippy::cast_possible_truncation, reason = "n <= TOKENS < 256")]
            b.push(n as u8);
            for &x in &f[..n] {
                let mut v = x;
                while v >= 0x80 {
                    #[expect(clippy::cast_possible_truncation, reason = "the low 7 bits")]
                    b.push((v as u8 & 0x7f) | 0x80);
                    v >>= 7;
                }
                #[expect(clippy::cast_possible_truncation, reason = "v < 0x80")]
                b.push(v as u8);
            }
        }
        b
    }

    /// Parses [`Tables::to_bytes`] from the front of `b`: the tables and the bytes read, or the reason.
    pub fn parse(b: &[u8]) -> Result<(Self, usize), String> {
        let mut at = 0usize;
        let mut next = || -> Result<u8, String> {
            let v = *b.get(at).ok_or("rANS tables truncated")?;
            at += 1;
            Ok(v)
        };
        let mut freq = Vec::with_capacity(CONTEXTS);
        for ctx in 0..CONTEXTS {
            let n = usize::from(next()?);
            if n > TOKENS {
                return Err(format!(
                    "rANS context {ctx} lists {n} tokens (at most {TOKENS})"
                ));
            }
            let mut f = [0u16; TOKENS];
            for x in &mut f[..n] {
                let mut v = 0u32;
                for shift in [0, 7, 14] {
                    let byte = next()?;
                    v |= u32::from(byte & 0x7f) << shift;
                    if byte & 0x80 == 0 {
                        break;
                    }
                    if shift == 14 {
                        return Err("rANS frequency longer than 3 bytes".into());
                    }
                }
                *x = u16::try_from(v).map_err(|_| "rANS frequency over 16 bits")?;
            }
            let sum: u32 = f.iter().map(|&x| u32::from(x)).sum();
            if sum != M {
                return Err(format!(
                    "rANS context {ctx}: frequencies sum to {sum}, not {M}"
                ));
            }
            freq.push(f);
        }
        Ok((Self { freq }, at))
    }

    /// Frequency of token `tok` in context `ctx`.
    #[inline]
    pub fn freq(&self, ctx: usize, tok: usize) -> u32 {
        u32::from(self.freq[ctx][tok])
    }
}

fn normalise(c: &[u64; TOKENS]) -> [u16; TOKENS] {
    let total: u64 = c.iter().sum();
    let mut f = [0u32; TOKENS];
    if total == 0 {
        f[0] = M;
    } else {
        for (fi, &ci) in f.iter_mut().zip(c) {
            if ci > 0 {
                #[expect(clippy::cast_possible_truncation, reason = "at most M")]
                let v = ((u128::from(ci) * u128::from(M)) / u128::from(total)) as u32;
                *fi = v.max(1);
            }
        }
        // The rounding difference, to or from the largest frequencies (lowest token on ties).
        let mut order: Vec<usize> = (0..TOKENS).filter(|&i| f[i] > 0).collect();
        order.sort_by(|&a, &b| f[b].cmp(&f[a]).then(a.cmp(&b)));
        let sum: u32 = f.iter().sum();
        if sum < M {
            f[order[0]] += M - sum;
        } else {
            let mut over = sum - M;
            for &i in &order {
                let take = over.min(f[i] - 1);
                f[i] -= take;
                over -= take;
            }
        }
    }
    let mut out = [0u16; TOKENS];
    for (o, &v) in out.iter_mut().zip(&f) {
        *o = u16::try_from(v).expect("a frequency is at most M");
    }
    out
}

/// The decoder's view of [`Tables`]: a token per probability slot and each token's cumulative frequency.
#[derive(Clone, Debug)]
pub struct DecodeTables {
    slot: Box<[[u8; M as usize]; CONTEXTS]>,
    /// Per context and token byte: the frequency in the high half, the cumulative frequency in the low
    /// half (256 entries, so any byte indexes it).
    fc: Box<[[u32; 256]; CONTEXTS]>,
}

impl DecodeTables {
    /// Bytes these tables take (for memory budgets).
    pub const BYTES: u64 = (CONTEXTS * (M as usize + 4 * 256)) as u64;

    /// The lookup tables of `t`.
    pub fn new(t: &Tables) -> Self {
        // Fixed sizes: a context masked to CONTEXTS - 1 and a slot masked to M - 1 index them with no
        // bounds check in the decoder's loop.
        let slot: Box<[[u8; M as usize]; CONTEXTS]> = vec![[0u8; M as usize]; CONTEXTS]
            .into_boxed_slice()
            .try_into()
            .expect("CONTEXTS rows");
        let fc: Box<[[u32; 256]; CONTEXTS]> = vec![[0u32; 256]; CONTEXTS]
            .into_boxed_slice()
            .try_into()
            .expect("CONTEXTS rows");
        let mut d = Self { slot, fc };
        d.fill(t);
        d
    }

    /// These tables made `t`'s, in place (allocates nothing: a package set's parts share a few).
    pub fn fill(&mut self, t: &Tables) {
        let (slot, fc) = (&mut self.slot, &mut self.fc);
        for row in fc.iter_mut() {
            row.fill(0);
        }
        for (ctx, f) in t.freq.iter().enumerate() {
            let mut c = 0usize;
            for (tok, &fr) in f.iter().enumerate() {
                fc[ctx][tok] = (u32::from(fr) << 16) | u32::try_from(c).expect("below M");
                let s = &mut slot[ctx][c..c + usize::from(fr)];
                #[expect(clippy::cast_possible_truncation, reason = "tok < TOKENS < 256")]
                s.fill(tok as u8);
                c += usize::from(fr);
            }
        }
    }
}

/// Encodes tokens in reverse (rANS is last in, first out) into 16-bit words, with two states taking the
/// tokens in turn (token n goes through state n % 2): the decoder's two states are independent chains of
/// arithmetic, which a processor runs side by side (Giesen, "Interleaved entropy coders", 2014).
pub struct Encoder {
    x: [u32; 2],
    words: Vec<u16>,
}

impl Default for Encoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Encoder {
    /// An empty stream.
    pub fn new() -> Self {
        Self {
            x: [L; 2],
            words: Vec::new(),
        }
    }

    /// Pushes token `tok` of context `ctx`, the stream's token number `n`; tokens must be pushed last
    /// first. Panics on a token the tables give no frequency (an encoder bug: the tables are built from
    /// these very tokens).
    #[inline]
    pub fn put(&mut self, t: &Tables, n: usize, ctx: usize, tok: usize) {
        let f = t.freq(ctx, tok);
        assert!(f > 0, "token {tok} has no frequency in context {ctx}");
        let cum: u32 = t.freq[ctx][..tok].iter().map(|&v| u32::from(v)).sum();
        let max = (u64::from(L >> PROB_BITS) << 16) * u64::from(f);
        let x = &mut self.x[n & 1];
        if u64::from(*x) >= max {
            #[expect(clippy::cast_possible_truncation, reason = "the low 16 bits")]
            self.words.push(*x as u16);
            *x >>= 16;
        }
        *x = ((*x / f) << PROB_BITS) + (*x % f) + cum;
    }

    /// The stream as the decoder reads it: the two final states, then the words in reverse order.
    pub fn finish(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.x[0].to_le_bytes());
        out.extend_from_slice(&self.x[1].to_le_bytes());
        for w in self.words.iter().rev() {
            out.extend_from_slice(&w.to_le_bytes());
        }
    }
}

/// Decodes tokens from a stream written by [`Encoder`]. `Copy`, so that a loop can hold it in registers
/// (a copy, written back after the loop) rather than store its state through a reference every token.
#[derive(Clone, Copy)]
pub struct Decoder<'a> {
    x: [u32; 2],
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Decoder<'a> {
    /// Starts on `bytes` (the whole rANS part of a payload).
    pub fn new(bytes: &'a [u8]) -> Result<Self, &'static str> {
        let first = bytes
            .first_chunk::<8>()
            .ok_or("rANS stream shorter than its states")?;
        let x = [
            u32::from_le_bytes([first[0], first[1], first[2], first[3]]),
            u32::from_le_bytes([first[4], first[5], first[6], first[7]]),
        ];
        if x[0] < L || x[1] < L {
            return Err("rANS state out of range");
        }
        Ok(Self { x, bytes, at: 8 })
    }

    /// The stream's next token, in context `ctx` (tokens are read in order, one state after the other:
    /// the states swap places after each token, so the one in use is always the first).
    ///
    /// Never fails: a stream that ends early reads zero words and walks `at` past its end, which
    /// [`Self::finish`] refuses. So the renormalisation is a select, not a branch, and the tile's loop
    /// carries no error path per token (a renormalisation follows about one token in five, too seldom to
    /// predict and too often to mispredict).
    #[inline(always)]
    pub fn get(&mut self, t: &DecodeTables, ctx: usize) -> usize {
        let x = self.x[0];
        let s = x & (M - 1);
        // Contexts are below CONTEXTS (a power of two) by construction; the mask says so to the compiler.
        debug_assert!(ctx < CONTEXTS, "context {ctx} out of range");
        let ctx = ctx & (CONTEXTS - 1);
        let tok = t.slot[ctx][s as usize];
        let fc = t.fc[ctx][usize::from(tok)];
        let (f, c) = (fc >> 16, fc & 0xffff);
        // x >= L and f >= 1 keep this in u32: f (x >> 12) + (s - c) < f 2^20 + f <= 2^32; after it
        // x >= 16 f >= 16, so x << 16 | w >= L again.
        let x = f * (x >> PROB_BITS) + s - c;
        let need = x < L;
        let w = self
            .bytes
            .get(self.at..self.at + 2)
            .map_or(0, |w| u32::from(u16::from_le_bytes([w[0], w[1]])));
        self.at += 2 * usize::from(need);
        self.x = [self.x[1], if need { (x << 16) | w } else { x }];
        usize::from(tok)
    }

    /// Checks that the stream ended where the encoder began: every word read, both initial states back.
    pub fn finish(&self) -> Result<(), &'static str> {
        if self.at > self.bytes.len() {
            Err("rANS stream ends early")
        } else if self.at == self.bytes.len() && self.x == [L; 2] {
            Ok(())
        } else {
            Err("rANS stream does not end where it should")
        }
    }
}

/// Raw bits, least significant first, into bytes.
#[derive(Default)]
pub struct BitWriter {
    acc: u64,
    n: u32,
    /// The bytes written so far.
    pub bytes: Vec<u8>,
}

impl BitWriter {
    /// Appends the low `n` (<= 32) bits of `v`.
    #[inline]
    pub fn put(&mut self, n: u32, v: u32) {
        self.acc |= u64::from(v) << self.n;
        self.n += n;
        while self.n >= 8 {
            #[expect(clippy::cast_possible_truncation, reason = "the low byte")]
            self.bytes.push(self.acc as u8);
            self.acc >>= 8;
            self.n -= 8;
        }
    }

    /// Flushes the last partial byte.
    pub fn finish(mut self) -> Vec<u8> {
        if self.n > 0 {
            #[expect(clippy::cast_possible_truncation, reason = "the low byte")]
            self.bytes.push(self.acc as u8);
        }
        self.bytes
    }
}

/// Reads [`BitWriter`]'s bits.
pub struct BitReader<'a> {
    bytes: &'a [u8],
    at: usize,
    acc: u64,
    n: u32,
}

impl<'a> BitReader<'a> {
    /// Reads `bytes` from the start.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self {
            bytes,
            at: 0,
            acc: 0,
            n: 0,
        }
    }

    /// The next `n` (<= 32) bits.
    #[inline]
    pub fn get(&mut self, n: u32) -> Result<u32, &'static str> {
        while self.n < n {
            let b = *self.bytes.get(self.at).ok_or("raw bits end early")?;
            self.acc |= u64::from(b) << self.n;
            self.at += 1;
            self.n += 8;
        }
        #[expect(clippy::cast_possible_truncation, reason = "masked to n <= 32 bits")]
        let v = (self.acc & ((1u64 << n) - 1)) as u32;
        self.acc >>= n;
        self.n -= n;
        Ok(v)
    }

    /// Checks every byte was read (the last one's spare bits aside).
    pub fn finish(&self) -> Result<(), &'static str> {
        if self.at == self.bytes.len() && self.n < 8 {
            Ok(())
        } else {
            Err("raw bits left over")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_split_and_join() {
        for v in (0..70_000u32).chain([u32::MAX, u32::MAX - 1, 1 << 31, (1 << 31) - 1]) {
            let (tok, n, raw) = split(v);
            assert!(tok < TOKENS);
            assert_eq!(n, raw_bits(tok));
            assert_eq!(join(tok, raw), Some(v), "{v}");
        }
        for s in [0, 1, -1, i32::MAX, i32::MIN] {
            assert_eq!(unzigzag(zigzag(s)), s);
        }
    }

    #[test]
    fn tables_normalise_and_round_trip() {
        let mut c = Counts::default();
        c.0[0][0] = 1_000_000;
        c.0[0][5] = 1;
        c.0[0][TOKENS - 1] = 3;
        c.0[3][1] = 7;
        let t = Tables::from_counts(&c);
        for f in &t.freq {
            assert_eq!(f.iter().map(|&x| u32::from(x)).sum::<u32>(), M);
        }
        assert!(t.freq(0, 5) >= 1 && t.freq(0, TOKENS - 1) >= 1);
        let b = t.to_bytes();
        let (back, n) = Tables::parse(&b).unwrap();
        assert_eq!((back, n), (t, b.len()));
        for cut in 0..b.len() {
            assert!(Tables::parse(&b[..cut]).is_err());
        }
    }

    #[test]
    fn rans_round_trips_and_refuses_damage() {
        let syms: Vec<(usize, usize)> = (0..5000usize)
            .map(|i| {
                (
                    (i * 7) % CONTEXTS,
                    ((i * i) % 97 % 23) * usize::from(i % 3 == 0),
                )
            })
            .collect();
        let mut c = Counts::default();
        for &(ctx, tok) in &syms {
            c.0[ctx][tok] += 1;
        }
        let t = Tables::from_counts(&c);
        let mut e = Encoder::new();
        for (n, &(ctx, tok)) in syms.iter().enumerate().rev() {
            e.put(&t, n, ctx, tok);
        }
        let mut bytes = Vec::new();
        e.finish(&mut bytes);
        let dt = DecodeTables::new(&t);
        let mut d = Decoder::new(&bytes).unwrap();
        for &(ctx, tok) in &syms {
            assert_eq!(d.get(&dt, ctx), tok);
        }
        d.finish().unwrap();
        // Cut or flipped streams: errors or wrong tokens, never a panic.
        for cut in [0, 3, 4, 8, bytes.len() / 2, bytes.len() - 1] {
            let r = Decoder::new(&bytes[..cut]).and_then(|mut d| {
                for &(ctx, _) in &syms {
                    d.get(&dt, ctx);
                }
                d.finish()
            });
            assert!(r.is_err(), "cut at {cut}");
        }
        let mut w = BitWriter::default();
        for i in 0..300u32 {
            w.put(
                i % 31,
                i.wrapping_mul(2_654_435_761) & ((1 << (i % 31)) - 1),
            );
        }
        let b = w.finish();
        let mut r = BitReader::new(&b);
        for i in 0..300u32 {
            assert_eq!(
                r.get(i % 31).unwrap(),
                i.wrapping_mul(2_654_435_761) & ((1 << (i % 31)) - 1)
            );
        }
        r.finish().unwrap();
        assert!(BitReader::new(&b[..b.len() - 1]).get(32).is_ok());
    }
}
