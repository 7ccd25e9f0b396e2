//! Stage 1b, the package: the colour rings' texel formats on the GPU, and a decoded imagery tile encoded
//! into them. RGBA8 (4 bytes a texel) everywhere; BC1 or ETC2 RGB8 (8 bytes a 4 x 4 block, 0.5 byte a
//! texel) where the device has them. A tile is encoded once, when the tile cache decodes it
//! (`imagery_cache.rs`): BC1 by Intel's ISPC texture compressor (`intel_tex_2`), ETC2 RGB8 by `etc2.rs`
//! (all its modes: ETC1's individual and differential, planar, T and H); the CPU twin reads the blocks
//! back through `texture2ddecoder`, so it sees the colours the GPU samples. A tile whose side is not a
//! multiple of 4 (the image's last column or row of tiles) is encoded with its last column and row
//! repeated to whole blocks: those texels are written into the ring but never sampled. BC1 encodes every
//! tile as a whole `tile x tile` surface (a smaller one repeats its edges), so the ISPC kernel's SIMD
//! gangs never run past the texels given.

use crate::{Error, Result};

// intel_tex_2's archive also holds the C++ wrapper of its ASTC kernel, whose unwind tables name the C++
// runtime's personality routine: nothing of it is called, but the linker keeps the object, so the C++
// runtime is linked (without it every binary fails to link with `__gxx_personality_v0` undefined).
#[cfg(all(target_os = "linux", not(target_env = "musl")))]
#[link(name = "stdc++")]
unsafe extern "C" {}

/// The colour rings' texel format.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
pub enum ColorFormat {
    /// RGBA8, 4 bytes a texel: every device.
    #[default]
    Rgba8,
    /// BC1 (DXT1) without alpha, 8 bytes a 4 x 4 block: devices with BC texture compression.
    Bc1,
    /// ETC2 RGB8, 8 bytes a 4 x 4 block: devices with ETC2 (core in GLES 3.0).
    Etc2Rgb8,
}

impl ColorFormat {
    /// Texels on a side of a block (1 for RGBA8).
    pub fn block(self) -> u32 {
        match self {
            Self::Rgba8 => 1,
            Self::Bc1 | Self::Etc2Rgb8 => 4,
        }
    }

    /// Bytes of a block.
    pub fn block_bytes(self) -> u32 {
        match self {
            Self::Rgba8 => 4,
            Self::Bc1 | Self::Etc2Rgb8 => 8,
        }
    }

    /// Bytes of `w x h` texels, each side padded to whole blocks.
    pub fn bytes(self, w: u32, h: u32) -> u64 {
        let b = self.block();
        u64::from(w.div_ceil(b)) * u64::from(h.div_ceil(b)) * u64::from(self.block_bytes())
    }

    /// Bytes of a row of blocks `w` texels wide.
    pub fn row_bytes(self, w: u32) -> u32 {
        w.div_ceil(self.block()) * self.block_bytes()
    }

    /// Bytes a texel takes on the GPU, times 16 (64 for RGBA8, 8 for the block formats).
    pub fn bytes_per_16_texels(self) -> u64 {
        self.bytes(4, 4)
    }

    /// Its name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Rgba8 => "rgba8",
            Self::Bc1 => "bc1",
            Self::Etc2Rgb8 => "etc2-rgb8",
        }
    }

    /// Whether a cached tile holds blocks (else RGB8 texels, expanded to RGBA8 when staged).
    pub fn is_block(self) -> bool {
        self.block() > 1
    }
}

/// Bytes a cached tile of `w x h` texels holds: RGB8 for RGBA8 rings, else its blocks.
pub fn tile_bytes(format: ColorFormat, w: u32, h: u32) -> u64 {
    match format {
        ColorFormat::Rgba8 => 3 * u64::from(w) * u64::from(h),
        _ => format.bytes(w, h),
    }
}

/// Encodes decoded tiles into a block format, with the RGBA8 scratch of one tile allocated once.
#[derive(Debug)]
pub struct BlockEncoder {
    format: ColorFormat,
    side: u32,
    rgba: Vec<u8>,
    blocks: Vec<u8>,
}

impl BlockEncoder {
    /// An encoder for tiles of at most `tile^2` texels.
    pub fn new(format: ColorFormat, tile: u32) -> Self {
        let side = tile.next_multiple_of(4);
        let (rgba, blocks) = if format.is_block() {
            let n = side as usize * side as usize;
            (vec![0; n * 4], vec![0; n / 2])
        } else {
            (Vec::new(), Vec::new())
        };
        Self {
            format,
            side,
            rgba,
            blocks,
        }
    }

    /// Bytes it holds.
    pub fn bytes(&self) -> u64 {
        (self.rgba.len() + self.blocks.len()) as u64
    }

    /// Encodes `w x h` RGB8 texels (rows of `w`) into `out`, [`ColorFormat::bytes`] of them (blocks
    /// row-major), the last column and row repeated to whole blocks. Refused for RGBA8, a tile past the
    /// scratch or buffers of the wrong size.
    pub fn encode(&mut self, rgb: &[u8], w: u32, h: u32, out: &mut [u8]) -> Result<()> {
        let side = self.side;
        if !self.format.is_block()
            || w == 0
            || h == 0
            || w > side
            || h > side
            || rgb.len() < w as usize * h as usize * 3
            || out.len() as u64 != self.format.bytes(w, h)
        {
            return Err(Error::Invalid {
                what: "colour block encoder".into(),
                reason: format!(
                    "{w} x {h} texels ({} bytes) into {} bytes of {}",
                    rgb.len(),
                    out.len(),
                    self.format.name()
                ),
            });
        }
        let row = self.format.row_bytes(w) as usize;
        let full_row = self.format.row_bytes(side) as usize;
        let (w, h, s) = (w as usize, h as usize, side as usize);
        for y in 0..s {
            let sy = y.min(h - 1);
            for x in 0..s {
                let from = (sy * w + x.min(w - 1)) * 3;
                let d = (y * s + x) * 4;
                self.rgba[d..d + 3].copy_from_slice(&rgb[from..from + 3]);
                self.rgba[d + 3] = 255;
            }
        }
        if self.format == ColorFormat::Etc2Rgb8 {
            for by in 0..h.div_ceil(4) {
                for bx in 0..w.div_ceil(4) {
                    let mut px = [[[0u8; 3]; 4]; 4];
                    for (y, row) in px.iter_mut().enumerate() {
                        for (x, p) in row.iter_mut().enumerate() {
                            let at = ((by * 4 + y) * s + bx * 4 + x) * 4;
                            p.copy_from_slice(&self.rgba[at..at + 3]);
                        }
                    }
                    let at = (by * w.div_ceil(4) + bx) * 8;
                    out[at..at + 8].copy_from_slice(&super::etc2::encode_block(&px));
                }
            }
            return Ok(());
        }
        let surface = intel_tex_2::RgbaSurface {
            data: &self.rgba,
            width: side,
            height: side,
            stride: side * 4,
        };
        intel_tex_2::bc1::compress_blocks_into(&surface, &mut self.blocks);
        for by in 0..h.div_ceil(4) {
            out[by * row..(by + 1) * row]
                .copy_from_slice(&self.blocks[by * full_row..by * full_row + row]);
        }
        Ok(())
    }
}

/// Decodes `blocks` of a `w x h` texel region (blocks row-major, sides padded to whole blocks) into RGB8
/// texels, rows of `w`: the colours a GPU samples from them (the twin's read).
pub fn decode(format: ColorFormat, blocks: &[u8], w: u32, h: u32, rgb: &mut [u8]) -> Result<()> {
    let need = format.bytes(w, h);
    let (w, h) = (w as usize, h as usize);
    if !format.is_block() || (blocks.len() as u64) < need || rgb.len() < w * h * 3 {
        return Err(Error::Invalid {
            what: "colour block decoder".into(),
            reason: format!("{w} x {h} texels of {}", format.name()),
        });
    }
    let bx = w.div_ceil(4);
    let mut px = [0u32; 16];
    for by in 0..h.div_ceil(4) {
        for bxi in 0..bx {
            let at = (by * bx + bxi) * 8;
            let block = &blocks[at..at + 8];
            match format {
                ColorFormat::Bc1 => texture2ddecoder::decode_bc1_block(block, &mut px),
                _ => texture2ddecoder::decode_etc2_rgb_block(block, &mut px),
            }
            for (i, p) in px.iter().enumerate() {
                let (x, y) = (bxi * 4 + i % 4, by * 4 + i / 4);
                if x < w && y < h {
                    // texture2ddecoder's colour: bytes B, G, R, A.
                    let [b, g, r, _] = p.to_le_bytes();
                    rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&[r, g, b]);
                }
            }
        }
    }
    Ok(())
}

/// Copies texels `(lx, ly) .. + (w, h)` of a cached tile `tw` texels wide (`data`, as
/// [`tile_bytes`] lays it out) into `out` in `format`'s upload layout: RGBA8 rows packed, or whole
/// blocks row-major (`lx`, `ly` multiples of 4, the sides padded to whole blocks). Returns the bytes
/// written.
pub fn stage(
    format: ColorFormat,
    data: &[u8],
    tw: u32,
    (lx, ly, w, h): (u32, u32, u32, u32),
    out: &mut [u8],
) -> usize {
    let mut n = 0;
    if format.is_block() {
        let row = format.row_bytes(w) as usize;
        let tile_row = format.row_bytes(tw) as usize;
        let skip = (lx / 4) as usize * 8;
        for by in ly / 4..(ly + h).div_ceil(4) {
            let at = by as usize * tile_row + skip;
            out[n..n + row].copy_from_slice(&data[at..at + row]);
            n += row;
        }
    } else {
        for y in ly..ly + h {
            for x in lx..lx + w {
                let i = (y as usize * tw as usize + x as usize) * 3;
                out[n..n + 4].copy_from_slice(&[data[i], data[i + 1], data[i + 2], 255]);
                n += 4;
            }
        }
    }
    n
}

/// A block format's own loss on an image ([`round_trip`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RoundTrip {
    /// Sum of the squared RGB differences between the image and its decoded blocks.
    pub squared_error: u64,
    /// RGB samples compared (3 a texel).
    pub samples: u64,
    /// Tiles encoded.
    pub tiles: u32,
    /// Seconds the encodes took (not the decodes).
    pub encode_secs: f64,
}

impl RoundTrip {
    /// PSNR over RGB, dB.
    pub fn psnr(&self) -> f64 {
        super::imagery::psnr(self.squared_error, self.samples)
    }
}

/// A block format's own loss on `src`: its texels encoded in `tile x tile` tiles, as the tile cache
/// encodes each tile, and decoded again as the GPU samples them. A measurement aid: it allocates its
/// buffers.
pub fn round_trip(
    format: ColorFormat,
    src: &crate::source::imagery::Imagery,
    tile: u32,
) -> Result<RoundTrip> {
    let (w, h) = src.size();
    let side = tile as usize;
    let mut enc = BlockEncoder::new(format, tile);
    let (mut rgb, mut back) = (vec![0u8; side * side * 3], vec![0u8; side * side * 3]);
    let mut blocks = vec![0u8; usize::try_from(format.bytes(tile, tile)).unwrap_or(0)];
    let mut out = RoundTrip {
        samples: u64::from(w) * u64::from(h) * 3,
        ..RoundTrip::default()
    };
    for ty in (0..h).step_by(side) {
        for tx in (0..w).step_by(side) {
            let (tw, th) = ((w - tx).min(tile), (h - ty).min(tile));
            let texels = tw as usize * th as usize;
            for j in 0..th {
                for i in 0..tw {
                    let at = (j as usize * tw as usize + i as usize) * 3;
                    rgb[at..at + 3]
                        .copy_from_slice(&src.texel(i64::from(tx + i), i64::from(ty + j)));
                }
            }
            let n = usize::try_from(format.bytes(tw, th)).unwrap_or(usize::MAX);
            let start = std::time::Instant::now();
            enc.encode(&rgb, tw, th, &mut blocks[..n])?;
            out.encode_secs += start.elapsed().as_secs_f64();
            out.tiles += 1;
            decode(format, &blocks[..n], tw, th, &mut back)?;
            for (a, b) in rgb[..texels * 3].iter().zip(&back) {
                out.squared_error += u64::from(a.abs_diff(*b)).pow(2);
            }
        }
    }
    Ok(out)
}
