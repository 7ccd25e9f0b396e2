//! Stage 3, the GPU: what clipsat needs of a device, checked against what an adapter offers: the GLES 3.0
//! floor's limits ([`wgpu::Limits::downlevel_webgl2_defaults`], which every device is created with) and
//! the texture formats and usages the renderer, the read-back and the test instruments use. Not the
//! version string: a driver may hand out ES 3.2 for a 3.0 request (NVIDIA does, with no way to pin it),
//! and a Vulkan device has none; what clipsat relies on is these, and the shaders staying on GLSL ES 3.00
//! (docs/real-drivers.md).

use serde::Serialize;

/// One requirement and whether the adapter meets it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct FloorCheck {
    /// What is needed, e.g. "limit max_texture_array_layers" or "Rg32Float: TEXTURE_BINDING | COPY_DST".
    pub what: String,
    /// Whether the adapter offers it.
    pub ok: bool,
    /// What the adapter has, where it falls short (empty when `ok`).
    pub detail: String,
}

/// The texture formats clipsat creates and the usages it gives each: the ring heights and detail pool
/// (RG32F), the SG normal and sky tables (RGBA32F), the SG light table (RGBA16F), the colour target and
/// read-back (RGBA8), the depth target, and the probes' exact-bits targets (RGBA32 uint).
pub const FORMATS: [(wgpu::TextureFormat, wgpu::TextureUsages); 6] = {
    use wgpu::TextureFormat as F;
    use wgpu::TextureUsages as U;
    let table = U::TEXTURE_BINDING.union(U::COPY_DST).union(U::COPY_SRC);
    let target = U::RENDER_ATTACHMENT.union(U::COPY_SRC);
    [
        (F::Rg32Float, table),
        (F::Rgba32Float, table),
        (F::Rgba16Float, table),
        (F::Rgba8Unorm, target),
        (F::Depth32Float, U::RENDER_ATTACHMENT),
        (F::Rgba32Uint, target),
    ]
};

/// Checks `adapter` against the floor: every limit of [`wgpu::Limits::downlevel_webgl2_defaults`] (the
/// device clipsat requests) and every format of [`FORMATS`] with its usages and a non-filtering float
/// or uint sample type (float tables are read with `textureLoad`, never filtered: not filterable on GLES
/// 3.0).
pub fn check(adapter: &wgpu::Adapter) -> Vec<FloorCheck> {
    let mut out = Vec::new();
    let have = adapter.limits();
    let mut short = Vec::new();
    wgpu::Limits::downlevel_webgl2_defaults().check_limits_with_fail_fn(
        &have,
        false,
        |name, want, got| short.push(format!("{name}: {got}, needs {want}")),
    );
    out.push(FloorCheck {
        what: "the GLES 3.0 / WebGL2 limits".into(),
        ok: short.is_empty(),
        detail: short.join("; "),
    });
    for (format, usage) in FORMATS {
        let f = adapter.get_texture_format_features(format);
        let missing = usage - f.allowed_usages;
        out.push(FloorCheck {
            what: format!("{format:?}: {usage:?}"),
            ok: missing.is_empty(),
            detail: if missing.is_empty() {
                String::new()
            } else {
                format!("lacks {missing:?}")
            },
        });
    }
    out
}

/// The checks of [`check`] that fail, as one sentence each.
pub fn shortfalls(checks: &[FloorCheck]) -> Vec<String> {
    checks
        .iter()
        .filter(|c| !c.ok)
        .map(|c| format!("{}: {}", c.what, c.detail))
        .collect()
}
