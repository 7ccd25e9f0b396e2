//! CPU twin of `data_surface` in `shaders_gles/clipmap.wgsl` (stage 3's fragment shader, on the CPU):
//! the height and normal under a pixel from the finest ring that holds it (GC section 6's normal maps
//! from the clipmap's data), in the shader's f32 arithmetic, so tests can check what any drawn level is
//! shaded with, and [`fragment_data`]: where and how much `fs_ring_data` (and `fs_skirt`) shade from the
//! rings rather than from the drawn vertices; and [`sg_taps`] / [`sg_inputs`] / [`sg_light`], the twin of
//! the SG shader's per-level table reads (`shaders_gles/sg_clipmap.wgsl`).

use crate::plan::clipmap::Clipmap;
use crate::plan::uniforms::{Globals, ShadeLevel};
use crate::profile::MAX_LEVELS;

/// The data under an eye-relative point: the level read, its height (m) and geometric normal (not unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DataSurface {
    /// The finest ring whose clip region holds the point with a one-sample margin.
    pub level: u32,
    /// Height (m) on the level's drawn triangles (each cell split along its (i, j)-(i+1, j+1) diagonal).
    pub height: f32,
    /// (-dz/dx, -dz/dy, 1): central differences at the cell's corners, bilinearly blended.
    pub normal: [f32; 3],
    /// The finest ring's share (1 away from its edge; below 1 the next coarser ring is blended in).
    pub weight: f32,
}

/// Cells over which the shading blends from a level to the next coarser one; mirrors `DATA_BLEND`.
pub const DATA_BLEND: f32 = 8.0;

/// The CPU twin of `data_surface`: `globals` as the renderer wrote them for the clipmap's last frame,
/// `rel` a position relative to the eye (m). `None` where no ring holds it (the shader then uses the
/// drawn vertex's values). Within [`DATA_BLEND`] cells of the finest ring's edge the next coarser ring
/// is blended in; `level` is the finest.
pub fn data_surface(globals: &Globals, clipmap: &Clipmap, rel: [f32; 2]) -> Option<DataSurface> {
    let count = globals.level_info[0].clamp(0, MAX_LEVELS as i32);
    for l in 0..count {
        let Some((mut out, weight)) = level_surface(globals, clipmap, l, rel) else {
            continue;
        };
        out.weight = weight;
        if weight < 1.0 {
            if let Some((coarse, _)) =
                (l + 1..count).find_map(|c| level_surface(globals, clipmap, c, rel))
            {
                let mix = |a: f32, b: f32| a * (1.0 - weight) + b * weight;
                out.height = mix(coarse.height, out.height);
                for k in 0..3 {
                    out.normal[k] = mix(coarse.normal[k], out.normal[k]);
                }
            }
        }
        return Some(out);
    }
    None
}

/// `CELL_LIMIT` of `clipmap.wgsl`: lattice cells are clamped to it before their conversion to int.
pub const CELL_LIMIT: f32 = 65_536.0;

/// A float-to-int conversion as the shaders write it, `i32(x)` of an `x` they clamped first. GLSL ES 3.00
/// leaves the conversion of a float outside the int range (an infinity, a NaN) undefined, and drivers
/// differ (x86 llvmpipe gives `i32::MIN`, NVIDIA saturates); Rust's `as` saturates, so the twin would
/// silently agree with one of them. Panics instead: a twin reaching this with such a value found
/// undefined behaviour in the shader it mirrors (docs/real-drivers.md).
#[expect(
    clippy::cast_possible_truncation,
    reason = "checked to be within the i32 range first"
)]
pub fn glsl_int(x: f32) -> i32 {
    assert!(
        (-2_147_483_648.0..2_147_483_648.0).contains(&x),
        "float-to-int conversion of {x}: undefined in GLSL ES 3.00 (clamp it first)"
    );
    x as i32
}

/// The twin of `level_cell` in `clipmap.wgsl`: level `lv`'s lattice cell under `rel`, clamped to
/// [`CELL_LIMIT`] before the conversion; `[-1, -1]` (held by nothing) for a level without data, whose
/// spacing (0) is not divided by.
pub fn level_cell(lv: &ShadeLevel, rel: [f32; 2]) -> [i32; 2] {
    if lv.tex[2] <= 0 || lv.tex[3] <= 0 {
        return [-1, -1];
    }
    let u = level_uv(lv, rel);
    u.map(|x| glsl_int(x.floor().clamp(-CELL_LIMIT, CELL_LIMIT)))
}

/// `level_uv`: level `lv`'s lattice coordinates of `rel` (x east, y south).
fn level_uv(lv: &ShadeLevel, rel: [f32; 2]) -> [f32; 2] {
    let g = lv.rel[3];
    [(rel[0] - lv.rel[0]) / g, (lv.rel[1] - rel[1]) / g]
}

/// `level_holds`: cell `i` lies in level `lv`'s clip region with a one-sample margin.
fn level_holds(lv: &ShadeLevel, i: [i32; 2]) -> bool {
    i[0] >= 1 && i[1] >= 1 && i[0] <= lv.tex[2] - 3 && i[1] <= lv.tex[3] - 3
}

/// The CPU twin of `finest_level`: the finest ring whose clip region holds `rel` with the one-sample margin
/// of `level_surface`, or `None`. No ring data is read, as the shader fetches none.
pub fn finest_level(globals: &Globals, rel: [f32; 2]) -> Option<u32> {
    let count = globals.level_info[0].clamp(0, MAX_LEVELS as i32);
    (0..count).find_map(|l| {
        let lv = &globals.levels[l as usize];
        level_holds(lv, level_cell(lv, rel)).then_some(l.unsigned_abs())
    })
}

/// The CPU twin of `shade_morph_alpha`: GC 6.2's alpha of level `l`'s active region at `rel` (0 inside, 1
/// from its outer edge on, 1 everywhere for a level that draws nothing).
#[expect(
    clippy::cast_precision_loss,
    reason = "n <= 511, exact in f32, as the shader's f32"
)]
pub fn shade_morph_alpha(globals: &Globals, l: u32, rel: [f32; 2]) -> f32 {
    let lv = &globals.levels[l as usize];
    let g = lv.rel[3];
    let u = [(rel[0] - lv.rel[0]) / g, (lv.rel[1] - rel[1]) / g];
    let w = globals.level_info[2] as f32 / 10.0;
    let m = lv.morph;
    let ax = (((u[0] - m[0]).abs() - (m[2] - w - 1.0)) / w).clamp(0.0, 1.0);
    let ay = (((u[1] - m[1]).abs() - (m[3] - w - 1.0)) / w).clamp(0.0, 1.0);
    ax.max(ay)
}

/// What `fs_ring_data` shades a pixel of a block drawn at `draw_level` with: `None` where it keeps the drawn
/// vertex's values (the block is drawn at the finest ring holding the pixel, as under distance LOD), else
/// the finest ring's data at `rel` and its share `w` ([`FragmentData`]), with `w` the
/// ring's edge blend times (1 - morph x its GC 6.2 alpha), `morph` = `globals.params[0]` (1 under distance
/// LOD, 0 under SAT LOD), so with morphing the finer detail fades out where that ring's drawn geometry does.
pub fn fragment_data(
    globals: &Globals,
    clipmap: &Clipmap,
    rel: [f32; 2],
    draw_level: u32,
) -> Option<FragmentData> {
    let fine = finest_level(globals, rel)?;
    if fine >= draw_level {
        return None;
    }
    #[expect(
        clippy::cast_possible_wrap,
        reason = "levels are below MAX_LEVELS = 16"
    )]
    let (d, weight) = level_surface(globals, clipmap, fine as i32, rel)?;
    let morph = globals.params[0];
    let share = weight * (1.0 - morph * shade_morph_alpha(globals, fine, rel));
    #[expect(
        clippy::cast_possible_wrap,
        reason = "levels are below MAX_LEVELS = 16"
    )]
    let base = if share < 1.0 {
        (fine as i32 + 1..draw_level as i32)
            .find_map(|c| level_surface(globals, clipmap, c, rel))
            .map(|(c, _)| c)
    } else {
        None
    };
    Some(FragmentData {
        data: d,
        share,
        base,
    })
}

/// [`fragment_data`]'s answer: the shader shades with `mix(base, data, share)`, `base` the vertex values
/// when `None`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FragmentData {
    /// The finest ring's data at the pixel.
    pub data: DataSurface,
    /// Its share: the ring's edge blend times (1 - morph x its GC 6.2 alpha).
    pub share: f32,
    /// The next coarser ring's data, when the share is below 1 and that ring is finer than the block.
    pub base: Option<DataSurface>,
}

/// `level_surface`: level `l`'s data at `rel` and its blend weight, or `None` outside its clip region's
/// one-sample margin.
#[expect(
    clippy::cast_sign_loss,
    clippy::cast_precision_loss,
    reason = "lattice coordinates inside a ring, as the shader's i32/f32"
)]
fn level_surface(
    globals: &Globals,
    clipmap: &Clipmap,
    l: i32,
    rel: [f32; 2],
) -> Option<(DataSurface, f32)> {
    let s = globals.level_info[1];
    let lv = &globals.levels[l as usize];
    let g = lv.rel[3];
    let i = level_cell(lv, rel);
    if !level_holds(lv, i) {
        return None;
    }
    let u = level_uv(lv, rel);
    let f = [u[0] - i[0] as f32, u[1] - i[1] as f32];
    let ring = clipmap.ring(l as u32).texels();
    let z = |dx: i32, dy: i32| {
        let tx = (lv.tex[0] + i[0] + dx) % s;
        let ty = (lv.tex[1] + i[1] + dy) % s;
        ring[(ty * s + tx) as usize][0]
    };
    let mix = |a: f32, b: f32, t: f32| a * (1.0 - t) + b * t;
    let (z00, z10, z01, z11) = (z(0, 0), z(1, 0), z(0, 1), z(1, 1));
    let gx = mix(
        mix(z10 - z(-1, 0), z(2, 0) - z00, f[0]),
        mix(z11 - z(-1, 1), z(2, 1) - z01, f[0]),
        f[1],
    );
    let gy = mix(
        mix(z(0, -1) - z01, z(1, -1) - z11, f[0]),
        mix(z00 - z(0, 2), z10 - z(1, 2), f[0]),
        f[1],
    );
    // The drawn triangles' height (shaders_gles/clipmap.wgsl `level_surface` says why).
    let (dzx, dzy) = if f[0] >= f[1] {
        (z10 - z00, z11 - z10)
    } else {
        (z11 - z01, z01 - z00)
    };
    let room_x = (u[0] - 1.0).min(lv.tex[2] as f32 - 2.0 - u[0]);
    let room_y = (u[1] - 1.0).min(lv.tex[3] as f32 - 2.0 - u[1]);
    let weight = (room_x.min(room_y) / DATA_BLEND).clamp(0.0, 1.0);
    Some((
        DataSurface {
            level: l as u32,
            height: z00 + f[0] * dzx + f[1] * dzy,
            normal: [-gx / (2.0 * g), -gy / (2.0 * g), 1.0],
            weight,
        },
        weight,
    ))
}

/// The CPU twin of `sg_taps` in `shaders_gles/sg_clipmap.wgsl`: the ring SG shading reads at `rel` for a
/// pixel footprint of `w` data samples, on a terrain of `data_spacing` metres, and the bilinear weights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SgTaps {
    /// The ring read.
    pub level: u32,
    /// Clip-relative lattice point of the first tap (the other three are +x, +y, +xy).
    pub cell: [i32; 2],
    /// Bilinear weights.
    pub f: [f32; 2],
}

/// The CPU twin of `sg_taps`: the first ring from data level round(log2 w) on that holds `rel` with
/// `finest_level`'s margin (so at least the finest ring holding it); where none does, the
/// coarsest ring of 4 x 4 samples or more (`globals.level_info[3]`) with the cell clamped into its held
/// ones. The data level comes from that ring's spacing (a level without data has spacing 0). `None` only
/// without such a ring. Every float-to-int conversion goes through [`glsl_int`].
#[expect(
    clippy::cast_sign_loss,
    clippy::cast_precision_loss,
    reason = "level indices checked to be in range, and ring sizes exact in f32, as the shader's"
)]
pub fn sg_taps(globals: &Globals, data_spacing: f32, rel: [f32; 2], w: f32) -> Option<SgTaps> {
    let count = globals.level_info[0].clamp(0, MAX_LEVELS as i32);
    let fallback = globals.level_info[3];
    if !(0..count).contains(&fallback) {
        return None;
    }
    let g = globals.levels[fallback as usize].rel[3];
    // WGSL's round is round-half-to-even, as f32::round_ties_even.
    let synth = (fallback
        + glsl_int(
            (data_spacing / g)
                .log2()
                .round_ties_even()
                .clamp(-32.0, 32.0),
        ))
    .max(0);
    // A NaN footprint compares false: one sample.
    let side = if w > 1.0 { w.min(1.0e9) } else { 1.0 };
    let k = glsl_int(side.log2().round_ties_even().clamp(0.0, 32.0));
    let pick = (synth + k..count)
        .find(|&l| {
            let lv = &globals.levels[l as usize];
            level_holds(lv, level_cell(lv, rel))
        })
        .unwrap_or(fallback);
    let lv = &globals.levels[pick as usize];
    let u = level_uv(lv, rel);
    let hi = [(lv.tex[2] - 3) as f32, (lv.tex[3] - 3) as f32];
    let i = [
        glsl_int(u[0].floor().clamp(1.0, hi[0])),
        glsl_int(u[1].floor().clamp(1.0, hi[1])),
    ];
    Some(SgTaps {
        level: pick as u32,
        cell: i,
        f: [
            (u[0] - i[0] as f32).clamp(0.0, 1.0),
            (u[1] - i[1] as f32).clamp(0.0, 1.0),
        ],
    })
}

/// The SG inputs at `taps`: r as the shader blends it from the normal table, and the D horizon angles
/// blended the same way (as sines rounded to f16, handed back as the arcsines of the blend), each texel
/// [`crate::package::shading_sats::ShadingBake::level_texel`] of its lattice sample. The shader itself
/// blends the light table's texels instead of the horizons ([`sg_light`]).
pub fn sg_inputs(
    bake: &crate::package::shading_sats::ShadingBake,
    clipmap: &Clipmap,
    taps: &SgTaps,
) -> (glam::Vec3, heapless::Vec<f32, 16>) {
    let clip = clipmap.frame().levels[taps.level as usize].clip;
    let data_level = i32::try_from(taps.level).unwrap_or(i32::MAX)
        - i32::try_from(clipmap.synth_levels()).unwrap_or(0);
    let at = |dx: i32, dy: i32| {
        bake.level_texel(
            data_level,
            clip.x0 + i64::from(taps.cell[0] + dx),
            clip.y0 + i64::from(taps.cell[1] + dy),
        )
    };
    let (a, b, c, d) = (at(0, 0), at(1, 0), at(0, 1), at(1, 1));
    let [fx, fy] = taps.f;
    let mix = |p: f32, q: f32, t: f32| p * (1.0 - t) + q * t;
    let bil = |p: f32, q: f32, r: f32, s: f32| mix(mix(p, q, fx), mix(r, s, fx), fy);
    let v = |p: glam::Vec3, q: glam::Vec3, r: glam::Vec3, s: glam::Vec3| {
        glam::Vec3::new(
            bil(p.x, q.x, r.x, s.x),
            bil(p.y, q.y, r.y, s.y),
            bil(p.z, q.z, r.z, s.z),
        )
    };
    let r = v(a.0, b.0, c.0, d.0);
    let f16 = |x: f32| half::f16::from_f32(x).to_f32();
    let mut hz = heapless::Vec::new();
    // The table holds the angles' sines; the shader blends those. Handed back as angles again.
    let sf = |x: f32| f16(x.sin());
    for k in 0..a.1.len() {
        // At most 16 angles, the capacity.
        let blended = bil(sf(a.1[k]), sf(b.1[k]), sf(c.1[k]), sf(d.1[k]));
        let _ = hz.push(blended.clamp(-1.0, 1.0).asin());
    }
    (r, hz)
}

/// The CPU twin of `sg_colour`'s light-table read (with visibility, `shaders_gles/sg_visibility.wgsl`):
/// the bilinear blend over `taps`' four texels of what the light table holds at each (rgb: the diffuse
/// radiance, a: the horizon's mean sine; [`crate::shading::TexelLighting::texel`] of the texel's
/// [`crate::package::shading_sats::ShadingBake::level_texel`], rounded to f16), and of the normal table's w
/// (the horizon's sine toward the first sun, f32).
pub fn sg_light(
    bake: &crate::package::shading_sats::ShadingBake,
    clipmap: &Clipmap,
    taps: &SgTaps,
    lighting: &crate::shading::TexelLighting,
    sky: &crate::shading::SkyTable,
) -> ([f32; 4], f32) {
    let clip = clipmap.frame().levels[taps.level as usize].clip;
    let data_level = i32::try_from(taps.level).unwrap_or(i32::MAX)
        - i32::try_from(clipmap.synth_levels()).unwrap_or(0);
    let f16 = |x: f32| half::f16::from_f32(x).to_f32();
    let at = |dx: i32, dy: i32| {
        let (r, hz) = bake.level_texel(
            data_level,
            clip.x0 + i64::from(taps.cell[0] + dx),
            clip.y0 + i64::from(taps.cell[1] + dy),
        );
        let sines: heapless::Vec<f32, 16> = hz.iter().map(|a| a.sin()).collect();
        let t = lighting.texel(r, &sines, sky);
        let d = t.diffuse;
        ([f16(d.x), f16(d.y), f16(d.z), f16(t.mean_sin)], t.sun_sin)
    };
    let (a, b, c, d) = (at(0, 0), at(1, 0), at(0, 1), at(1, 1));
    let [fx, fy] = taps.f;
    let mix = |p: f32, q: f32, t: f32| p * (1.0 - t) + q * t;
    let bil = |p: f32, q: f32, r: f32, s: f32| mix(mix(p, q, fx), mix(r, s, fx), fy);
    let light = std::array::from_fn(|k| bil(a.0[k], b.0[k], c.0[k], d.0[k]));
    (light, bil(a.1, b.1, c.1, d.1))
}
