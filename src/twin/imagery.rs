//! CPU twin of `shaders_gles/imagery.wgsl`: a pixel's albedo from the colour rings at its position and
//! footprint, in the shader's f32 arithmetic, reading each ring's texels from the imagery package's own
//! decode of the pyramid (what the rings hold, `tests/cpu/imagery_rings.rs`), filtered as the GPU's
//! bilinear sampler with repeat is defined to (a driver's own weight precision is within the tolerance).
//! Rings in a block format (BC1, ETC2 RGB8) are read as the GPU samples them: each tile encoded as the
//! tile cache encodes it and its blocks decoded (`package::color_blocks`).
//! The float-to-int conversions panic where GLSL ES 3.00 leaves them undefined (out of range), as the
//! other twins do.

use glam::{Vec3, Vec4};

use crate::package::color_blocks::{self, BlockEncoder};
use crate::plan::color_rings::{ColorRings, ImageryUniform, TexRect};
use crate::Result;

/// [`IMAGERY_BORDER`](../../../shaders_gles/imagery.wgsl) of the shader: texels over which a ring's
/// held region fades into the next coarser ring.
pub const BORDER: f32 = 4.0;

/// [`IMAGERY_BLEND`](../../../shaders_gles/imagery.wgsl) of the shader: the upper part of a level's
/// footprint range (log2) over which a pixel blends it with the next coarser level.
pub const BLEND: f32 = 0.5;

/// `IMAGERY_TAP_IN` of the shader: how far inside a ring's held region its taps are kept, texels (half a
/// texel and a 256th).
pub const TAP_IN: f32 = 0.503_906_25;

/// `imagery_decode`: x^2.2 on [0, 1] as the shader computes it, x^2 (a + b sqrt(x) + (1 - a - b) x),
/// within 0.2 of an 8-bit code of x once encoded again.
pub fn decode(x: f32) -> f32 {
    x * x * (0.3783 + 0.8759 * x.sqrt() - 0.2542 * x)
}

/// What the imagery program reads: its uniform, each ring's held region (absolute texels) and each
/// level's decoded texels (RGB8, row-major).
#[derive(Clone, Debug)]
pub struct ImageryTwin {
    uniform: ImageryUniform,
    held: Vec<TexRect>,
    widths: Vec<u32>,
    levels: Vec<Vec<u8>>,
    ring: i32,
}

impl ImageryTwin {
    /// The twin of what `rings` uploaded for the eye at world (x, y): its uniform, held regions and the
    /// package's levels decoded whole (for test-sized images).
    pub fn new(rings: &ColorRings, x: f64, y: f64) -> Result<Self> {
        let p = rings.package();
        let h = p.header();
        let mut levels = Vec::new();
        let mut widths = Vec::new();
        let side = h.tile as usize;
        let mut tile = vec![0u8; side * side * 3];
        let mut parent = vec![0u8; side * side * 3];
        let format = rings.format();
        let mut encoder = BlockEncoder::new(format, h.tile);
        let mut blocks = vec![0u8; usize::try_from(format.bytes(h.tile, h.tile)).unwrap_or(0)];
        for (level, l) in h
            .levels
            .iter()
            .enumerate()
            .take(rings.level_count() as usize)
        {
            let mut texels = vec![0u8; l.width as usize * l.height as usize * 3];
            for ty in 0..l.tiles_y {
                for tx in 0..l.tiles_x {
                    let (tw, th) = p.decode_texels(level, tx, ty, &mut tile, &mut parent)?;
                    if format.is_block() {
                        let n = usize::try_from(format.bytes(tw, th)).unwrap_or(0);
                        encoder.encode(&tile, tw, th, &mut blocks[..n])?;
                        color_blocks::decode(format, &blocks[..n], tw, th, &mut tile)?;
                    }
                    for row in 0..th as usize {
                        let dst = ((ty as usize * side + row) * l.width as usize
                            + tx as usize * side)
                            * 3;
                        let n = tw as usize * 3;
                        texels[dst..dst + n].copy_from_slice(&tile[row * n..(row + 1) * n]);
                    }
                }
            }
            levels.push(texels);
            widths.push(l.width);
        }
        Ok(Self {
            uniform: rings.uniform(x, y),
            held: (0..levels.len()).map(|l| rings.held(l)).collect(),
            widths,
            levels,
            ring: i32::try_from(rings.ring()).unwrap_or(i32::MAX),
        })
    }

    /// Ring `l`'s texel at ring address (ax, ay): the level's texel whose column and row are those
    /// addresses modulo the ring within the held region (`imagery_texel`'s `textureLoad`).
    fn texel(&self, l: usize, ax: i32, ay: i32) -> Vec4 {
        let held = self.held[l];
        let ring = i64::from(self.ring);
        let i = held.x0 + (i64::from(ax) - held.x0).rem_euclid(ring);
        let j = held.y0 + (i64::from(ay) - held.y0).rem_euclid(ring);
        assert!(
            held.x0 <= i && i < held.x0 + held.w && held.y0 <= j && j < held.y0 + held.h,
            "ring {l}: texel ({i}, {j}) read outside the held region {held:?}"
        );
        let at = usize::try_from((j * i64::from(self.widths[l]) + i) * 3).unwrap_or(0);
        let c = &self.levels[l][at..at + 3];
        Vec4::new(
            f32::from(c[0]) / 255.0,
            f32::from(c[1]) / 255.0,
            f32::from(c[2]) / 255.0,
            1.0,
        )
    }

    /// The sampler's wrap (repeat): a texel coordinate modulo the ring.
    fn address(&self, i: f32) -> i32 {
        assert!(i.is_finite(), "a NaN texel coordinate");
        #[expect(
            clippy::cast_possible_truncation,
            reason = "a floored texel coordinate near the ring"
        )]
        let i = i as i64;
        i32::try_from(i.rem_euclid(i64::from(self.ring))).unwrap_or(0)
    }

    /// `imagery_sample`: ring `l`'s premultiplied colour at `rel` (m from the eye).
    fn sample(&self, l: usize, rel: [f32; 2]) -> Vec4 {
        let [eye, held, fade, inner] = self.uniform.levels[l];
        let t = [rel[0] * eye[2], -rel[1] * eye[3]];
        let lo = [t[0] - (inner[0] + 0.5), t[1] - (inner[1] + 0.5)];
        let hi = [(inner[2] - 0.5) - t[0], (inner[3] - 0.5) - t[1]];
        let d = lo[0].min(lo[1]).min(hi[0].min(hi[1]));
        let w = (d / BORDER).clamp(0.0, 1.0) * fade[0];
        if w.is_nan() || w <= 0.0 {
            return Vec4::ZERO;
        }
        // The sampler's bilinear filter (GLES 3.0 section 3.8.10): u = uv size - 1/2, taps at floor(u)
        // and the next, weights its fraction, each wrapped.
        // The taps kept on held texels (max then min, as the shader).
        let tc = [
            t[0].max(held[0] + TAP_IN).min(held[2] - TAP_IN),
            t[1].max(held[1] + TAP_IN).min(held[3] - TAP_IN),
        ];
        let ring = self.ring as f32;
        let uv = [(eye[0] + tc[0]) / ring, (eye[1] + tc[1]) / ring];
        let u = [uv[0] * ring - 0.5, uv[1] * ring - 0.5];
        let b = [u[0].floor(), u[1].floor()];
        let f = [u[0] - b[0], u[1] - b[1]];
        let tap =
            |dx: f32, dy: f32| self.texel(l, self.address(b[0] + dx), self.address(b[1] + dy));
        let mix = |a: Vec4, b: Vec4, t: f32| a * (1.0 - t) + b * t;
        let c = mix(
            mix(tap(0.0, 0.0), tap(1.0, 0.0), f[0]),
            mix(tap(0.0, 1.0), tap(1.0, 1.0), f[0]),
            f[1],
        );
        (c.truncate() * w).extend(w)
    }

    /// `imagery_albedo`: the linear-light albedo of a pixel at `rel` (m from the eye) of footprint `fp`
    /// (m) whose terrain albedo is `base`.
    pub fn albedo(&self, rel: [f32; 2], fp: f32, base: Vec3) -> Vec3 {
        let n = self.uniform.levels_in_use();
        let lod = (fp * self.uniform.levels[0][0][2]).max(1.0e-6).log2();
        let lod = lod.clamp(0.0, (n - 1) as f32);
        assert!(lod.is_finite(), "a NaN level (undefined in GLSL ES 3.00)");
        #[expect(
            clippy::cast_possible_truncation,
            reason = "clamped to [0, n - 1] above"
        )]
        let l0 = lod as i32;
        let t = ((lod - l0 as f32 - (1.0 - BLEND)) / BLEND).clamp(0.0, 1.0);
        let mut c = Vec4::ZERO;
        let mut coarse = Vec4::ZERO;
        for l in l0..n {
            let s = self.sample(usize::try_from(l).unwrap_or(0), rel);
            c += (1.0 - c.w) * s;
            if l > l0 {
                coarse += (1.0 - coarse.w) * s;
            }
            if c.w >= 1.0 && (coarse.w >= 1.0 || t <= 0.0) {
                break;
            }
        }
        let m = if l0 + 1 < n {
            c * (1.0 - t) + coarse * t
        } else {
            c
        };
        let rgb = m.truncate() / m.w.max(1.0e-6);
        let img = Vec3::new(decode(rgb.x), decode(rgb.y), decode(rgb.z));
        // The image's edge, smoothed over the footprint.
        let im = self.uniform.image;
        let inside = (rel[0] - im[0])
            .min(rel[1] - im[1])
            .min((im[2] - rel[0]).min(im[3] - rel[1]));
        let cover = (inside / fp.max(1.0e-6) + 0.5).clamp(0.0, 1.0);
        let a = m.w * cover;
        base * (1.0 - a) + img * a
    }
}

impl ImageryUniform {
    /// Rings in use (`info.x`).
    pub fn levels_in_use(&self) -> i32 {
        self.info[0]
    }
}
