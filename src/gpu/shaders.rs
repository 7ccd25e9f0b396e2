//! Stage 3, the GPU: shader text. Each program in `shaders_gles/` is assembled here by concatenation
//! (naga has no `#include`), and the same text feeds the renderer and the GLSL ES 3.00 test.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::shading::debug_view::DebugView;
use crate::shading::scene::Scene;
use crate::shading::Patches;
use crate::{Error, Result};

/// The basic shading library: height ramp, Lambert sun, sky, fog. No entry points.
pub const BASIC_SHADING_WGSL: &str = include_str!("../../shaders_gles/basic_shading.wgsl");
const BRUTE_WGSL: &str = include_str!("../../shaders_gles/brute.wgsl");
const CLIPMAP_WGSL: &str = include_str!("../../shaders_gles/clipmap.wgsl");
const SG_SHADING_WGSL: &str = include_str!("../../shaders_gles/sg_shading.wgsl");
const SG_SPECULAR_WGSL: &str = include_str!("../../shaders_gles/sg_specular.wgsl");
const SG_NO_SPECULAR_WGSL: &str = include_str!("../../shaders_gles/sg_no_specular.wgsl");
const SG_VISIBILITY_WGSL: &str = include_str!("../../shaders_gles/sg_visibility.wgsl");
const SG_NO_VISIBILITY_WGSL: &str = include_str!("../../shaders_gles/sg_no_visibility.wgsl");
const SG_FOG_WGSL: &str = include_str!("../../shaders_gles/sg_fog.wgsl");
const SG_NO_FOG_WGSL: &str = include_str!("../../shaders_gles/sg_no_fog.wgsl");
const SG_CLIPMAP_WGSL: &str = include_str!("../../shaders_gles/sg_clipmap.wgsl");
const SG_PROBE_WGSL: &str = include_str!("../../shaders_gles/sg_probe.wgsl");
const DEBUG_VIEW_WGSL: &str = include_str!("../../shaders_gles/debug_view.wgsl");
const IMAGERY_WGSL: &str = include_str!("../../shaders_gles/imagery.wgsl");

/// The imagery variant's edits of `clipmap.wgsl`: both shading calls take the imagery's albedo, and the
/// pixel's footprint is taken where each fragment program starts, before its discard (GLSL ES 3.00
/// leaves derivatives after a discard undefined).
const IMAGERY_EDITS: [(&str, &str); 4] = [
    (
        "basic_shade(v.height, v.normal, length(v.rel), globals.shading)",
        "imagery_shade(v, v.height, v.normal, globals.shading)",
    ),
    (
        "basic_shade(d.x, d.yzw, length(v.rel), globals.shading)",
        "imagery_shade(v, d.x, d.yzw, globals.shading)",
    ),
    (
        "    let rate = debug_rate(v.rel);\n",
        "    let rate = debug_rate(v.rel);\n    imagery_fp = imagery_footprint(v.rel);\n",
    ),
    (
        "    return plain_colour(v, debug_rate(v.rel));\n",
        "    imagery_fp = imagery_footprint(v.rel);\n    return plain_colour(v, debug_rate(v.rel));\n",
    ),
];

/// The brute-force reference program: basic shading + `brute.wgsl`.
pub fn brute() -> String {
    [BASIC_SHADING_WGSL, BRUTE_WGSL].concat()
}

/// The clipmap renderer's program: basic shading + `debug_view.wgsl` + `clipmap.wgsl`, normal view.
pub fn clipmap() -> String {
    clipmap_view(DebugView::Normal)
}

/// The clipmap renderer's program for a debug view: the `DEBUG_VIEW` constant goes last, so line numbers
/// in shader errors match the files.
pub fn clipmap_view(view: DebugView) -> String {
    let constant = format!("\nconst DEBUG_VIEW: u32 = {}u;\n", view.code());
    [BASIC_SHADING_WGSL, DEBUG_VIEW_WGSL, CLIPMAP_WGSL, &constant].concat()
}

/// The clipmap renderer's program with draped imagery (`imagery.wgsl`, group 2): `clipmap.wgsl` with
/// `IMAGERY_EDITS`, normal view. Built only for a terrain with imagery.
pub fn clipmap_imagery() -> String {
    let mut body = CLIPMAP_WGSL.to_string();
    for (from, to) in IMAGERY_EDITS {
        debug_assert!(body.contains(from), "clipmap.wgsl no longer has `{from}`");
        body = body.replace(from, to);
    }
    let constant = format!("\nconst DEBUG_VIEW: u32 = {}u;\n", DebugView::Normal.code());
    [BASIC_SHADING_WGSL, DEBUG_VIEW_WGSL, &body, IMAGERY_WGSL, &constant].concat()
}

/// The SG variant's edits for draped imagery: the diffuse term scaled by the imagery's albedo over the
/// scene's k_d (specular unchanged), the footprint taken before each program's discard.
const SG_IMAGERY_EDITS: [(&str, &str); 3] = [
    (
        "    return diffuse + sg_specular(vmf, view, cut, suns, count, s);",
        "    return diffuse * sg_albedo_scale + sg_specular(vmf, view, cut, suns, count, s);",
    ),
    (
        "    let w = sg_footprint(v);\n",
        "    let w = sg_footprint(v);\n    imagery_fp = imagery_footprint(v.rel);\n",
    ),
    (
        "    let colour = sg_fog(sg_shade(",
        "    let kd = sg_scene.kd_count.rgb;\n    \
         sg_albedo_scale = imagery_albedo(v.rel.xy, kd) / max(kd, vec3<f32>(1.0e-6));\n    \
         let colour = sg_fog(sg_shade(",
    ),
];

/// SG variant `v` with draped imagery (`SG_IMAGERY_EDITS`; `imagery.wgsl` bound at group 3, after the
/// SG tables' group 2). Built only for a terrain with imagery under SG shading.
pub fn sg_clipmap_imagery(v: SgVariant) -> String {
    let mut text = sg_clipmap(v);
    for (from, to) in SG_IMAGERY_EDITS {
        debug_assert!(text.contains(from), "the SG program no longer has `{from}`");
        text = text.replace(from, to);
    }
    let imagery = IMAGERY_WGSL.replace("@group(2)", "@group(3)");
    [
        text.as_str(),
        "\n// Draped imagery: the diffuse term's scale, the imagery's albedo over k_d.\n\
         var<private> sg_albedo_scale: vec3<f32>;\n",
        &imagery,
    ]
    .concat()
}

/// Every file in `shaders_gles/`, by file name, as the renderer assembles it. A library file (no entry
/// points) appears on its own, so it is validated even before any program uses it.
pub fn sources() -> Vec<(&'static str, String)> {
    vec![
        ("basic_shading.wgsl", BASIC_SHADING_WGSL.to_string()),
        ("brute.wgsl", brute()),
        ("clipmap.wgsl", clipmap()),
        (
            "sg_shading.wgsl",
            sg_library(SgVariant::default(), SG_NO_SPECULAR_WGSL, SKY_TABLE_CLIPMAP),
        ),
        (
            "sg_specular.wgsl",
            sg_library(SgVariant::default(), SG_SPECULAR_WGSL, SKY_TABLE_CLIPMAP),
        ),
        (
            "sg_no_specular.wgsl",
            sg_library(SgVariant::default(), SG_NO_SPECULAR_WGSL, SKY_TABLE_CLIPMAP),
        ),
        ("sg_visibility.wgsl", sg_clipmap(SgVariant::ALL_ON)),
        ("sg_fog.wgsl", sg_clipmap(SgVariant::ALL_ON)),
        (
            "sg_no_fog.wgsl",
            sg_clipmap(SgVariant {
                fog: false,
                ..SgVariant::ALL_ON
            }),
        ),
        ("sg_no_visibility.wgsl", sg_clipmap(SgVariant::default())),
        ("sg_clipmap.wgsl", sg_clipmap(SgVariant::ALL_ON)),
        ("sg_probe.wgsl", sg_probe(SgVariant::ALL_ON)),
        ("debug_view.wgsl", clipmap_view(DebugView::Wireframe)),
        ("imagery.wgsl", clipmap_imagery()),
    ]
}

/// One SG shader variant: what the text of a program contains (docs/design.md "Only the effects a scene
/// calls for"). Each effect set is its own text and its own pipeline.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SgVariant {
    /// Theta bands x phi sectors of the patch integration (a WGSL constant).
    pub patches: Patches,
    /// Horizon tables are declared and fetched (`sg_visibility.wgsl`), else `sg_no_visibility.wgsl`.
    pub visibility: bool,
    /// The specular term is compiled (`sg_specular.wgsl`), else the zero stub `sg_no_specular.wgsl`.
    pub specular: bool,
    /// Scene fog is compiled (`sg_fog.wgsl`), else the pass-through `sg_no_fog.wgsl`.
    pub fog: bool,
    /// A term left out, for `clipsat bench shading`'s per-term breakdown only ([`SgOmit::None`] in every
    /// rendering variant).
    pub omit: SgOmit,
}

/// One term of the SG fragment shading that a benchmark variant leaves out (the WGSL constant `SG_OMIT`),
/// so that its cost is the time it saves. Visibility and specular are measured by their own variants.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SgOmit {
    /// Everything is computed.
    #[default]
    None,
    /// No footprint fetch of the normals (the level tables): r is the drawn mesh's normal.
    Footprint,
    /// No vMF: a single normal (kappa 1e4, no convolution, no lowered plane).
    Vmf,
    /// No light table (with visibility) and no sky table: every lobe is one direction, as a sun,
    /// unshadowed.
    Sky,
}

impl SgOmit {
    /// Every term, in the order of the breakdown.
    pub const TERMS: [Self; 3] = [Self::Footprint, Self::Vmf, Self::Sky];

    /// The `SG_OMIT` code.
    pub fn code(self) -> u32 {
        match self {
            Self::None => 0,
            Self::Footprint => 1,
            Self::Vmf => 2,
            Self::Sky => 3,
        }
    }

    /// The term's name in the breakdown.
    pub fn label(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Footprint => "footprint fetch",
            Self::Vmf => "vMF",
            Self::Sky => "light + sky tables",
        }
    }
}

impl SgVariant {
    /// Everything on, 4x8.
    pub const ALL_ON: Self = Self {
        patches: Patches::P4x8,
        visibility: true,
        specular: true,
        fog: true,
        omit: SgOmit::None,
    };

    /// Every variant: 3 patch counts x visibility x specular x fog.
    pub fn all() -> Vec<Self> {
        let mut out = Vec::new();
        for patches in Patches::ALL {
            for visibility in [false, true] {
                for specular in [false, true] {
                    for fog in [false, true] {
                        out.push(Self {
                            patches,
                            visibility,
                            specular,
                            fog,
                            omit: SgOmit::None,
                        });
                    }
                }
            }
        }
        out
    }

    /// "4x8+vis+spec" style label.
    pub fn label(&self) -> String {
        let mut s = self.patches.label().to_string();
        if self.visibility {
            s.push_str("+vis");
        }
        if self.specular {
            s.push_str("+spec");
        }
        if self.fog {
            s.push_str("+fog");
        }
        if self.omit != SgOmit::None {
            s.push_str(&format!("-omit{}", self.omit.code()));
        }
        s
    }
}

/// Where the renderer's SG programs bind the sky table (group 2 of `sg_clipmap.wgsl`).
pub const SKY_TABLE_CLIPMAP: (u32, u32) = (2, 3);
/// Where the probe binds it (group 0 of `sg_probe.wgsl`).
pub const SKY_TABLE_PROBE: (u32, u32) = (0, 2);

/// `sg_shading.wgsl` with its constants and the sky table's binding `(group, binding)` prepended and the
/// specular file appended.
fn sg_library(v: SgVariant, specular: &str, (group, binding): (u32, u32)) -> String {
    let head = format!(
        "// Variant {}: M theta bands; the term left out (0: none); whether the diffuse term comes from \
         the light table; the sky table (clipsat::shading::sky_table).\nconst SG_BANDS: u32 = {}u;\n\
         const SG_OMIT: u32 = {}u;\nconst SG_VISIBILITY: bool = {};\n\
         const SG_SKY_SIDE: i32 = {};\nconst SG_SKY_LAYERS: i32 = {};\n\
         @group({group}) @binding({binding}) var sky_table: texture_2d<f32>;\n\n",
        v.label(),
        v.patches.bands(),
        v.omit.code(),
        v.visibility,
        crate::profile::SG_SKY_SIDE,
        crate::profile::SG_SKY_LAYERS,
    );
    [head.as_str(), SG_SHADING_WGSL, specular].concat()
}

fn sg_specular_text(v: SgVariant) -> &'static str {
    if v.specular {
        SG_SPECULAR_WGSL
    } else {
        SG_NO_SPECULAR_WGSL
    }
}

/// The clipmap renderer's SG program for variant `v`: [`clipmap`] + `sg_shading.wgsl`
/// + the variant's specular, visibility and fog files + `sg_clipmap.wgsl` (entry points `vs_main`, `fs_sg`).
pub fn sg_clipmap(v: SgVariant) -> String {
    let visibility = if v.visibility {
        SG_VISIBILITY_WGSL
    } else {
        SG_NO_VISIBILITY_WGSL
    };
    let fog = if v.fog { SG_FOG_WGSL } else { SG_NO_FOG_WGSL };
    [
        clipmap().as_str(),
        &sg_library(v, sg_specular_text(v), SKY_TABLE_CLIPMAP),
        visibility,
        fog,
        SG_CLIPMAP_WGSL,
    ]
    .concat()
}

/// The SG probe program for variant `v` (with visibility the diffuse term is the probe's light-table
/// input): `sg_shading.wgsl` + specular file + `sg_probe.wgsl`.
pub fn sg_probe(v: SgVariant) -> String {
    [
        sg_library(v, sg_specular_text(v), SKY_TABLE_PROBE).as_str(),
        SG_PROBE_WGSL,
    ]
    .concat()
}

/// Every SG program variant, named `file[label]`, for validation; the benchmark's term omissions too.
pub fn sg_variants() -> Vec<(String, String)> {
    let mut out = Vec::new();
    for v in SgVariant::all() {
        out.push((format!("sg_clipmap.wgsl[{}]", v.label()), sg_clipmap(v)));
        out.push((format!("sg_probe.wgsl[{}]", v.label()), sg_probe(v)));
    }
    // With draped imagery: every effect on, and none.
    for v in [SgVariant::ALL_ON, SgVariant::default()] {
        out.push((
            format!("sg_clipmap.wgsl[{}+imagery]", v.label()),
            sg_clipmap_imagery(v),
        ));
    }
    for omit in SgOmit::TERMS {
        let v = SgVariant {
            omit,
            ..SgVariant::ALL_ON
        };
        out.push((format!("sg_clipmap.wgsl[{}]", v.label()), sg_clipmap(v)));
    }
    out
}

// The limit lives with the budget it bounds, so that the profile depends on no stage.
pub use crate::profile::MAX_SG_LIGHTS;

/// One SG light; mirrors `SgLight` in `shaders_gles/sg_shading.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SgLightUniform {
    /// xyz: unit axis, w: sharpness.
    pub axis_lambda: [f32; 4],
    /// rgb: amplitude, w: unused.
    pub mu: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<SgLightUniform>() == 32);

/// The SG scene uniform; mirrors `SgScene` in `shaders_gles/sg_shading.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SgSceneUniform {
    /// The light lobes; the first `kd_count[3]` are used.
    pub lights: [SgLightUniform; MAX_SG_LIGHTS],
    /// rgb: k_d, w: number of lights.
    pub kd_count: [f32; 4],
    /// x: k_s, y: roughness, z: azimuths D of the light table (0: visibility off; informative, the
    /// shader reads the light table whatever D), w: fog extinction (1/m, 0: off).
    pub material: [f32; 4],
    /// rgb: fog colour (linear).
    pub fog: [f32; 4],
    /// x: the data's spacing (m); y: unused; z: the number of sharp lights (suns, `lambda >=
    /// SHARP_LAMBDA`), which come first in `lights`; w: unused.
    pub grid: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<SgSceneUniform>() == 320);

impl SgSceneUniform {
    /// The uniform for `scene`: lights (suns first), material, fog; `azimuths` is D when visibility is
    /// bound (else 0). `grid` holds only the sun count (the renderer fills x).
    pub fn new(scene: &Scene, azimuths: u32) -> Result<Self> {
        if scene.lights.len() > MAX_SG_LIGHTS {
            return Err(Error::Capacity {
                what: "SG light lobes per scene",
                capacity: MAX_SG_LIGHTS,
            });
        }
        let mut u = Self::default();
        // Suns first, then the lobes integrated over patches: the shader runs one loop over each, so no
        // pixel pays for the other kind's path (llvmpipe runs both sides of a branch under a mask).
        let sharp = |l: &&crate::shading::sg::Sg| l.lambda >= crate::shading::SHARP_LAMBDA;
        let suns = scene.lights.iter().filter(sharp);
        let lobes = scene.lights.iter().filter(|l| !sharp(l));
        for (slot, l) in u.lights.iter_mut().zip(suns.chain(lobes)) {
            *slot = SgLightUniform {
                axis_lambda: [l.axis.x, l.axis.y, l.axis.z, l.lambda],
                mu: [l.mu.x, l.mu.y, l.mu.z, 0.0],
            };
        }
        #[expect(clippy::cast_precision_loss, reason = "at most MAX_SG_LIGHTS")]
        let suns = scene.lights.iter().filter(sharp).count() as f32;
        u.grid[2] = suns;
        let m = &scene.material;
        #[expect(clippy::cast_precision_loss, reason = "at most MAX_SG_LIGHTS")]
        let count = scene.lights.len() as f32;
        u.kd_count = [m.kd.x, m.kd.y, m.kd.z, count];
        let vis = if scene.effects.visibility {
            azimuths
        } else {
            0
        };
        #[expect(clippy::cast_precision_loss, reason = "at most MAX_AZIMUTHS")]
        let vis = vis as f32;
        let ks = if scene.effects.specular { m.ks } else { 0.0 };
        let (fog_density, fog_rgb) = match &scene.fog {
            Some(f) => (f.density_per_km * 1e-3, f.rgb),
            None => (0.0, Vec3::ZERO),
        };
        u.material = [ks, m.roughness, vis, fog_density];
        u.fog = [fog_rgb.x, fog_rgb.y, fog_rgb.z, 0.0];
        Ok(u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every edit of the imagery variant finds its text in `clipmap.wgsl`: the footprint is taken in all
    /// four fragment programs and both shading calls take the imagery's albedo.
    #[test]
    fn imagery_edits_apply() {
        let counts = IMAGERY_EDITS.map(|(from, _)| CLIPMAP_WGSL.matches(from).count());
        assert!(counts.iter().all(|&c| c > 0), "{counts:?}");
        let text = clipmap_imagery();
        assert!(!text.contains("basic_shade(v."), "a shading call kept the basic albedo");
        assert!(!text.contains("basic_shade(d."), "a shading call kept the basic albedo");
        let counts = SG_IMAGERY_EDITS.map(|(from, _)| sg_clipmap(SgVariant::ALL_ON).matches(from).count());
        assert!(counts.iter().all(|&c| c > 0), "{counts:?}");
        for entry in ["fs_interior", "fs_plain", "fs_ring_data", "fs_skirt"] {
            let at = text.find(&format!("fn {entry}(")).expect(entry);
            let body = &text[at..at + text[at..].find("\n}").expect("end")];
            let fp = body.find("imagery_fp = imagery_footprint").expect(entry);
            assert!(body.find("discard").is_none_or(|d| fp < d), "{entry}");
        }
    }
}
