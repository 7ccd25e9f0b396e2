//! Scenes: what a render shows - SG lights, one material and the effects it asks for (docs/design.md "Only the
//! effects a scene calls for").
//!
//! A scene is a TOML file (`profiles/scenes/*.toml`; the shipped ones are compiled in). Loading validates
//! every field and names the one at fault; [`Scene::check_profile`] refuses features the profile does not
//! allow; [`Scene::needs`] tells the renderer what to bake, bind and compile, and nothing more.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::profile::{Feature, Profile};
use crate::shading::sg::Sg;
use crate::{Error, Result};

/// The scenes shipped in `profiles/scenes/`, by name, with their TOML text.
pub const SHIPPED: [(&str, &str); 3] = [
    ("noon", include_str!("../../profiles/scenes/noon.toml")),
    (
        "evening",
        include_str!("../../profiles/scenes/evening.toml"),
    ),
    (
        "overcast",
        include_str!("../../profiles/scenes/overcast.toml"),
    ),
];

/// Sharpest light lobe a scene may declare: the numerics are tested up to here (`tests/cpu/sg_numerics.rs`).
pub const MAX_SHARPNESS: f32 = 1e4;

/// A scene file as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Short name, printed in reports.
    pub name: String,
    /// The light lobes.
    pub lights: Vec<LightFile>,
    /// The terrain's material.
    pub material: MaterialFile,
    /// Which effects to render.
    pub effects: Effects,
    /// Fog parameters; required when `effects.fog` is on.
    #[serde(default)]
    pub fog: Option<FogFile>,
}

/// What a light lobe's `rgb` means.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LightKind {
    /// A sun: `rgb` is the irradiance at normal incidence (the lobe's integral over the sphere).
    Sun,
    /// A sky lobe: `rgb` is the radiance at the lobe's axis (its SG amplitude).
    Sky,
}

/// One SG light lobe as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightFile {
    /// Sun or sky; see [`LightKind`].
    pub kind: LightKind,
    /// Elevation of the lobe axis above the horizontal, degrees in [-90, 90].
    pub elevation_deg: f32,
    /// Compass azimuth of the lobe axis, degrees: 0 north, 90 east.
    pub azimuth_deg: f32,
    /// SG sharpness lambda, in [0, 1e4].
    pub sharpness: f32,
    /// Linear RGB, non-negative; see [`LightKind`].
    pub rgb: [f32; 3],
}

/// The terrain's material as written.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialFile {
    /// Diffuse albedo, linear RGB in [0, 1].
    pub kd: [f32; 3],
    /// Specular amplitude in [0, 1] (Fresnel folded in).
    pub ks: f32,
    /// Perceptual roughness in [0.05, 1]; alpha = roughness^2.
    pub roughness: f32,
}

/// The terrain's material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Diffuse albedo, linear RGB in [0, 1].
    pub kd: Vec3,
    /// Specular amplitude in [0, 1] (Fresnel folded in).
    pub ks: f32,
    /// Perceptual roughness in [0.05, 1]; alpha = roughness^2.
    pub roughness: f32,
}

/// Effects a scene asks for. Each one that is off is neither baked, bound nor compiled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    /// Horizon visibility (soft terrain shadows).
    pub visibility: bool,
    /// SG specular.
    pub specular: bool,
    /// Distance fog.
    pub fog: bool,
    /// Fractal detail below the data's resolution.
    pub synthesis: bool,
}

/// Distance fog as written.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FogFile {
    /// Extinction per kilometre, > 0.
    pub density_per_km: f32,
    /// Fog colour, linear RGB.
    pub rgb: [f32; 3],
}

/// Distance fog: colour = mix(rgb, colour, exp(-density distance)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fog {
    /// Extinction per kilometre, > 0.
    pub density_per_km: f32,
    /// Fog colour, linear RGB.
    pub rgb: Vec3,
}

/// A validated scene: lights as SGs (world, z up), material and effects.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Short name.
    pub name: String,
    /// Light lobes.
    pub lights: Vec<Sg>,
    /// Material.
    pub material: Material,
    /// Effects.
    pub effects: Effects,
    /// Fog, present iff `effects.fog`.
    pub fog: Option<Fog>,
}

impl Scene {
    /// Fits the scene's fog to a terrain whose horizontal diagonal is `diagonal_m` metres: the density is
    /// clamped so that fog never hides more than the far third, i.e. at two thirds of the diagonal at
    /// most half the colour is fog ([`MAX_FOG_AT_TWO_THIRDS`]). A scene's `density_per_km` is authored for
    /// some terrain size; without the clamp 0.08/km turns a 111 km tile into one beige polygon.
    pub fn fit_fog(&mut self, diagonal_m: f64) {
        if let Some(f) = &mut self.fog {
            let max = -(1.0 - MAX_FOG_AT_TWO_THIRDS).ln() / (2.0 / 3.0 * diagonal_m.max(1.0)) * 1e3;
            #[expect(
                clippy::cast_possible_truncation,
                reason = "a small positive density, f32 as the shader holds it"
            )]
            let max = max as f32;
            f.density_per_km = f.density_per_km.min(max);
        }
    }
}

/// Most of the colour that fog may take at two thirds of the terrain's diagonal ([`Scene::fit_fog`]).
pub const MAX_FOG_AT_TWO_THIRDS: f64 = 0.5;

/// What the renderer must prepare for a scene: it bakes, binds and compiles exactly these.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Needs {
    /// Bake the horizon angles (and their SATs).
    pub bake_horizons: bool,
    /// Bind the visibility textures.
    pub bind_visibility: bool,
    /// Compile the specular code into the shader variant.
    pub specular_code: bool,
    /// Compile fog.
    pub fog: bool,
    /// Synthesise detail below the data.
    pub synthesis: bool,
}

/// A world direction from compass azimuth (0 north, 90 east) and elevation, degrees: x east, y north, z up.
pub fn direction(azimuth_deg: f32, elevation_deg: f32) -> Vec3 {
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    let (se, ce) = elevation_deg.to_radians().sin_cos();
    Vec3::new(sa * ce, ca * ce, se)
}

impl Scene {
    /// A shipped scene by name, or a scene file by path.
    pub fn load(name_or_path: &str) -> Result<Self> {
        let text = crate::profile::shipped_or_file(&SHIPPED, "scene", name_or_path)?;
        Self::parse(name_or_path, &text)
    }

    /// Parses and validates a scene's TOML text; `source_name` names it in errors.
    pub fn parse(source_name: &str, text: &str) -> Result<Self> {
        let file: SceneFile =
            toml::from_str(text).map_err(|e| crate::profile::toml_error(source_name, text, &e))?;
        Self::from_file(source_name, &file)
    }

    /// Validates a parsed scene; the error names the field.
    pub fn from_file(source_name: &str, f: &SceneFile) -> Result<Self> {
        let bad = |field: String, reason: String| Err(Error::config(source_name, field, reason));
        if f.lights.is_empty() {
            return bad("lights".into(), "declare at least one light lobe".into());
        }
        let mut lights = Vec::with_capacity(f.lights.len());
        for (i, l) in f.lights.iter().enumerate() {
            let at = |name: &str| format!("lights[{i}].{name}");
            if !(l.elevation_deg.is_finite() && (-90.0..=90.0).contains(&l.elevation_deg)) {
                return bad(
                    at("elevation_deg"),
                    format!("{} is not in [-90, 90] degrees", l.elevation_deg),
                );
            }
            if !l.azimuth_deg.is_finite() {
                return bad(
                    at("azimuth_deg"),
                    format!("{} is not finite", l.azimuth_deg),
                );
            }
            if !(l.sharpness.is_finite() && (0.0..=MAX_SHARPNESS).contains(&l.sharpness)) {
                return bad(
                    at("sharpness"),
                    format!("{} is not in [0, {MAX_SHARPNESS}]", l.sharpness),
                );
            }
            if l.rgb.iter().any(|c| !(c.is_finite() && *c >= 0.0)) {
                return bad(
                    at("rgb"),
                    format!("{:?} must be finite and non-negative", l.rgb),
                );
            }
            let axis = direction(l.azimuth_deg, l.elevation_deg);
            let rgb = Vec3::from(l.rgb);
            lights.push(match l.kind {
                LightKind::Sun => Sg::with_integral(axis, l.sharpness, rgb),
                LightKind::Sky => Sg::new(axis, l.sharpness, rgb),
            });
        }
        let m = &Material {
            kd: Vec3::from(f.material.kd),
            ks: f.material.ks,
            roughness: f.material.roughness,
        };
        if !(m.kd.is_finite() && m.kd.min_element() >= 0.0 && m.kd.max_element() <= 1.0) {
            return bad(
                "material.kd".into(),
                format!("{} is not in [0, 1] per channel", m.kd),
            );
        }
        if !(m.ks.is_finite() && (0.0..=1.0).contains(&m.ks)) {
            return bad("material.ks".into(), format!("{} is not in [0, 1]", m.ks));
        }
        if !(m.roughness.is_finite() && (0.05..=1.0).contains(&m.roughness)) {
            return bad(
                "material.roughness".into(),
                format!("{} is not in [0.05, 1]", m.roughness),
            );
        }
        match (f.effects.fog, &f.fog) {
            (true, None) => {
                return bad(
                    "fog".into(),
                    "effects.fog is on: give [fog] density_per_km and rgb".into(),
                )
            }
            (false, Some(_)) => {
                return bad(
                    "fog".into(),
                    "a [fog] table with effects.fog off would be ignored".into(),
                )
            }
            (_, Some(fog)) => {
                let fog = Fog {
                    density_per_km: fog.density_per_km,
                    rgb: Vec3::from(fog.rgb),
                };
                if !(fog.density_per_km.is_finite() && fog.density_per_km > 0.0) {
                    return bad(
                        "fog.density_per_km".into(),
                        format!("{} must be positive", fog.density_per_km),
                    );
                }
                if !(fog.rgb.is_finite() && fog.rgb.min_element() >= 0.0) {
                    return bad(
                        "fog.rgb".into(),
                        format!("{} must be finite and non-negative", fog.rgb),
                    );
                }
            }
            (false, None) => {}
        }
        Ok(Self {
            name: f.name.clone(),
            lights,
            material: *m,
            effects: f.effects,
            fog: f.fog.map(|g| Fog {
                density_per_km: g.density_per_km,
                rgb: Vec3::from(g.rgb),
            }),
        })
    }

    /// The profile features this scene uses: always `sg` (its lights are SG lobes), plus one per effect.
    pub fn features(&self) -> Vec<Feature> {
        let e = &self.effects;
        let mut out = vec![Feature::Sg];
        for (on, f) in [
            (e.visibility, Feature::Visibility),
            (e.specular, Feature::Specular),
            (e.fog, Feature::Fog),
            (e.synthesis, Feature::Synthesis),
        ] {
            if on {
                out.push(f);
            }
        }
        out
    }

    /// Refuses a scene that asks for a feature the profile does not allow, or more lights than it affords.
    pub fn check_profile(&self, source_name: &str, profile: &Profile) -> Result<()> {
        for f in self.features() {
            if !profile.allows(f) {
                let name = format!("\"{}\"", f.name());
                return Err(Error::config(
                    source_name,
                    match f {
                        Feature::Sg | Feature::Basic => "lights".to_string(),
                        other => format!("effects.{}", other.name()),
                    },
                    format!(
                        "needs shading feature {name}, which profile `{}` does not allow (it allows {:?})",
                        profile.name, profile.shading.features
                    ),
                ));
            }
        }
        let max = profile.shading.max_sg_lights as usize;
        if self.lights.len() > max {
            return Err(Error::config(
                source_name,
                "lights",
                format!(
                    "{} light lobes, but profile `{}` affords at most {max}",
                    self.lights.len(),
                    profile.name
                ),
            ));
        }
        Ok(())
    }

    /// What the renderer must bake, bind and compile for this scene.
    pub fn needs(&self) -> Needs {
        let e = &self.effects;
        Needs {
            bake_horizons: e.visibility,
            bind_visibility: e.visibility,
            specular_code: e.specular,
            fog: e.fog,
            synthesis: e.synthesis,
        }
    }
}

/// Applies the scene's fog to a colour seen at `distance_m` metres (no-op without fog).
pub fn apply_fog(colour: Vec3, distance_m: f32, fog: Option<&Fog>) -> Vec3 {
    match fog {
        None => colour,
        Some(f) => {
            let keep = (-f.density_per_km * distance_m.max(0.0) * 1e-3).exp();
            colour * keep + f.rgb * (1.0 - keep)
        }
    }
}
