//! CPU twin of `data_surface` in `shaders_gles/clipmap.wgsl` (stage 3's fragment shader, on the CPU):
//! the height and normal under a pixel from the finest ring that holds it (GC section 6's normal maps
//! from the clipmap's data), in the shader's f32 arithmetic, so tests can check what any drawn level is
//! shaded with.

use crate::plan::clipmap::Clipmap;
use crate::plan::uniforms::Globals;

/// The data under an eye-relative point: the level read, its height (m) and geometric normal (not unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DataSurface {
    /// The ring read (the finest whose clip region holds the point with a one-sample margin).
    pub level: u32,
    /// Bilinear height (m).
    pub height: f32,
    /// (-dz/dx, -dz/dy, 1): central differences at the cell's corners, bilinearly blended.
    pub normal: [f32; 3],
}

/// The CPU twin of `data_surface`: `globals` as the renderer wrote them for the clipmap's last frame,
/// `rel` a position relative to the eye (m). `None` where no ring holds it (the shader then uses the
/// drawn vertex's values).
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_precision_loss,
    reason = "lattice coordinates inside a ring, as the shader's i32/f32"
)]
pub fn data_surface(globals: &Globals, clipmap: &Clipmap, rel: [f32; 2]) -> Option<DataSurface> {
    let count = globals.level_info[0].clamp(0, globals.levels.len() as i32);
    let s = globals.level_info[1];
    for l in 0..count {
        let lv = &globals.levels[l as usize];
        let g = lv.rel[3];
        let u = [(rel[0] - lv.rel[0]) / g, (lv.rel[1] - rel[1]) / g];
        let i = [u[0].floor() as i32, u[1].floor() as i32];
        if i[0] < 1 || i[1] < 1 || i[0] > lv.tex[2] - 3 || i[1] > lv.tex[3] - 3 {
            continue;
        }
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
        return Some(DataSurface {
            level: l as u32,
            height: mix(mix(z00, z10, f[0]), mix(z01, z11, f[0]), f[1]),
            normal: [-gx / (2.0 * g), -gy / (2.0 * g), 1.0],
        });
    }
    None
}
