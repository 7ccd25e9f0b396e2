//! Scenes: shipped scenes load, every bad field is named, features are checked against the profile, and
//! `needs()` asks for exactly what the scene declares.

use clipsat::profile::Profile;
use clipsat::shading::scene::{self, Scene};
use clipsat::shading::{self, Inputs, Patches};
use clipsat::Error;
use glam::Vec3;

const NOON: &str = include_str!("../../profiles/scenes/noon.toml");

fn field_of(err: Error) -> String {
    match err {
        Error::Config { field, .. } => field,
        other => panic!("expected a config error, got {other}"),
    }
}

#[test]
fn shipped_scenes_load_and_shade() {
    for (name, _) in scene::SHIPPED {
        let s = Scene::load(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(s.name, name);
        let c = shading::shade(
            &Inputs {
                r: Vec3::Z,
                horizon: &[0.0; 8],
                view: Vec3::new(0.0, -0.6, 0.8),
            },
            &s,
            &shading::SkyTable::new(&s, Patches::default()),
        );
        assert!(c.is_finite() && c.min_element() > 0.0, "{name}: {c}");
    }
}

#[test]
fn needs_follow_the_declared_effects() {
    let noon = Scene::load("noon").unwrap_or_else(|e| panic!("{e}"));
    let n = noon.needs();
    assert!(!n.bake_horizons && !n.bind_visibility && !n.specular_code && !n.fog && !n.synthesis);
    let evening = Scene::load("evening").unwrap_or_else(|e| panic!("{e}"));
    let e = evening.needs();
    assert!(e.bake_horizons && e.bind_visibility && e.specular_code && e.fog && !e.synthesis);
    // Without visibility in the scene, horizons passed in change nothing.
    let inputs = |h: &'static [f32]| Inputs {
        r: Vec3::Z,
        horizon: h,
        view: Vec3::Z,
    };
    let sky = shading::SkyTable::new(&noon, Patches::P4x8);
    let open = shading::shade(&inputs(&[0.0; 8]), &noon, &sky);
    let walled = shading::shade(&inputs(&[1.5; 8]), &noon, &sky);
    assert_eq!(open, walled);
}

#[test]
fn bad_fields_are_named() {
    let cases: [(&str, &str, &str); 9] = [
        (
            "sharpness = 2000.0",
            "sharpness = 2e5",
            "lights[0].sharpness",
        ),
        (
            "elevation_deg = 65.0",
            "elevation_deg = 95.0",
            "lights[0].elevation_deg",
        ),
        (
            "rgb = [3.0, 2.9, 2.7]",
            "rgb = [3.0, -1.0, 2.7]",
            "lights[0].rgb",
        ),
        (
            "kd = [0.32, 0.29, 0.24]",
            "kd = [1.5, 0.29, 0.24]",
            "material.kd",
        ),
        ("ks = 0.0", "ks = 2.0", "material.ks"),
        ("roughness = 0.8", "roughness = 0.0", "material.roughness"),
        ("fog = false", "fog = true", "fog"),
        (
            "synthesis = false",
            "synthesis = false\nshadows = true",
            "shadows",
        ),
        ("kind = \"sun\"", "kind = \"moon\"", "?"),
    ];
    for (from, to, field) in cases {
        assert!(NOON.contains(from), "{from}");
        let text = NOON.replacen(from, to, 1);
        let err = Scene::parse("noon-edit", &text)
            .err()
            .unwrap_or_else(|| panic!("{to} accepted"));
        let msg = err.to_string();
        let got = field_of(err);
        if field == "?" {
            assert!(msg.contains("moon") || msg.contains("variant"), "{msg}");
        } else {
            assert_eq!(got, field, "{to}: {msg}");
        }
    }
    let no_lights = NOON
        .split("[material]")
        .nth(1)
        .map(|rest| format!("name = \"x\"\nlights = []\n[material]{rest}"))
        .unwrap_or_default();
    assert_eq!(
        field_of(
            Scene::parse("x", &no_lights)
                .err()
                .unwrap_or_else(|| panic!("accepted"))
        ),
        "lights"
    );
}

#[test]
fn scenes_ask_only_for_allowed_features() {
    let low = Profile::load("gles3-low").unwrap_or_else(|e| panic!("{e}"));
    let evening = Scene::load("evening").unwrap_or_else(|e| panic!("{e}"));
    let err = evening
        .check_profile("evening", &low)
        .err()
        .unwrap_or_else(|| panic!("accepted"));
    let msg = err.to_string();
    assert!(msg.contains("sg") && msg.contains("gles3-low"), "{msg}");
    let mut profile = low.clone();
    profile.shading.features = vec![
        clipsat::profile::Feature::Basic,
        clipsat::profile::Feature::Sg,
    ];
    let err = evening
        .check_profile("evening", &profile)
        .err()
        .unwrap_or_else(|| panic!("accepted"));
    assert_eq!(field_of(err), "effects.visibility");
    profile.shading.features.extend([
        clipsat::profile::Feature::Visibility,
        clipsat::profile::Feature::Specular,
        clipsat::profile::Feature::Fog,
    ]);
    assert!(evening.check_profile("evening", &profile).is_ok());
    profile.shading.max_sg_lights = 1;
    assert_eq!(
        field_of(
            evening
                .check_profile("evening", &profile)
                .err()
                .unwrap_or_else(|| panic!("accepted"))
        ),
        "lights"
    );
    let noon = Scene::load("noon").unwrap_or_else(|e| panic!("{e}"));
    for (name, _) in clipsat::profile::SHIPPED {
        let p = Profile::load(name).unwrap_or_else(|e| panic!("{e}"));
        println!(
            "{name}: noon {:?}, evening {:?}",
            noon.check_profile("noon", &p).is_ok(),
            evening.check_profile("evening", &p).is_ok()
        );
    }
}

#[test]
fn fog_blends_toward_its_colour() {
    let evening = Scene::load("evening").unwrap_or_else(|e| panic!("{e}"));
    let fog = evening.fog.as_ref();
    let c = Vec3::new(0.1, 0.2, 0.3);
    assert_eq!(scene::apply_fog(c, 0.0, fog), c);
    let far = scene::apply_fog(c, 1e6, fog);
    assert!((far - Vec3::new(0.55, 0.45, 0.4)).length() < 1e-4);
    assert_eq!(scene::apply_fog(c, 1e6, None), c);
}

/// Scene fog is fitted to the terrain: on a 111 km tile `evening`'s 0.08/km is clamped so that
/// at two thirds of the diagonal at most half the colour is fog; on a 5 km terrain it is left as written.
#[test]
fn fog_never_hides_more_than_the_far_third() {
    let evening = Scene::load("evening").unwrap_or_else(|e| panic!("{e}"));
    let c = Vec3::new(0.1, 0.2, 0.3);
    let diagonal = 111_000f64 * 2f64.sqrt();
    let mut fitted = evening.clone();
    fitted.fit_fog(diagonal);
    #[expect(clippy::cast_possible_truncation, reason = "metres as f32")]
    let two_thirds = (2.0 / 3.0 * diagonal) as f32;
    let seen = scene::apply_fog(c, two_thirds, fitted.fog.as_ref());
    let fog = evening.fog.as_ref().map(|f| f.rgb).unwrap_or_default();
    // The fraction of fog in the colour, per channel.
    let share = (seen - c).x / (fog - c).x;
    assert!(
        share <= 0.5 + 1e-4,
        "{share} of the colour is fog at 2/3 of the diagonal"
    );
    let mut small = evening.clone();
    small.fit_fog(5_000.0);
    assert_eq!(small.fog, evening.fog);
}

#[test]
fn missing_and_mistyped_fields_are_refused() {
    // (edit, what the error must mention); each is refused with a config error, never a panic.
    let cases: [(&str, &str, &str); 8] = [
        ("name = \"noon\"", "", "name"),
        ("ks = 0.0", "", "ks"),
        ("roughness = 0.8", "roughness = \"rough\"", "roughness"),
        ("kd = [0.32, 0.29, 0.24]", "kd = [0.32, 0.29]", "kd"),
        ("sharpness = 1.5", "sharpness = nan", "lights[1].sharpness"),
        ("sharpness = 1.5", "sharpness = inf", "lights[1].sharpness"),
        ("fog = false", "fog = 3", "fog"),
        ("[material]", "material = 7\n[materialx]", "material"),
    ];
    for (from, to, needle) in cases {
        assert!(NOON.contains(from), "{from}");
        let text = NOON.replacen(from, to, 1);
        match Scene::parse("noon-edit", &text) {
            Err(e @ Error::Config { .. }) => {
                let msg = e.to_string();
                assert!(msg.contains(needle), "`{to}`: {msg} does not name {needle}");
            }
            Err(other) => panic!("`{to}`: expected a config error, got {other}"),
            Ok(_) => panic!("`{to}` accepted"),
        }
    }
    for garbage in ["", "\u{0}\u{1}", "name = ", "[[lights]]\nkind = \"sun\""] {
        assert!(
            matches!(Scene::parse("g", garbage), Err(Error::Config { .. })),
            "{garbage:?}"
        );
    }
}

/// Synthesis exists only when asked for: a clipmap without synthesised rings has no noise
/// table (GC section 8), one with them has it; `fly` refuses synthesised rings under a scene that does
/// not declare `effects.synthesis` (tests/cli/fly.rs `bad_inputs_fail_with_a_clear_error`), and no
/// shipped scene declares it.
#[test]
fn synthesis_exists_only_when_asked_for() {
    use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
    use clipsat::source::procedural::{generate, ProceduralParams};
    let hm = generate(&ProceduralParams {
        size: 65,
        ..ProceduralParams::default()
    })
    .expect("terrain");
    let profile = Profile::load("gles3-low").expect("profile");
    for (synth_levels, wanted) in [(0, false), (1, true)] {
        let clipmap =
            Clipmap::new(&hm, &profile, ClipmapOptions { synth_levels }).expect("clipmap");
        assert_eq!(
            clipmap.has_synthesis(),
            wanted,
            "synth_levels {synth_levels}"
        );
    }
    for (name, _) in scene::SHIPPED {
        let s = Scene::load(name).expect("shipped scene");
        assert!(!s.effects.synthesis && !s.needs().synthesis, "{name}");
    }
}
