//! Budget profiles: every shipped profile loads, and every bad profile names the field at fault.

use clipsat::profile::{Feature, Profile, SHIPPED};
use clipsat::Error;

fn base() -> String {
    SHIPPED
        .iter()
        .find(|(n, _)| *n == "gles3-low")
        .map(|(_, t)| t.to_string())
        .unwrap_or_default()
}

/// Replaces the line starting with `key =` in the low profile's text.
fn with(key: &str, value: &str) -> String {
    base()
        .lines()
        .map(|l| {
            if l.trim_start().starts_with(&format!("{key} =")) {
                format!("{key} = {value}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn field_of(text: &str) -> (String, String) {
    match Profile::parse("test.toml", text) {
        Err(Error::Config { field, reason, .. }) => (field, reason),
        Err(other) => panic!("expected a Config error, got {other}"),
        Ok(_) => panic!("profile was accepted:\n{text}"),
    }
}

#[test]
fn shipped_profiles_load_from_names_and_files() {
    for (name, _) in SHIPPED {
        let p = Profile::load(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(p.name, name);
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("profiles")
            .join(format!("{name}.toml"));
        let from_file = Profile::load(path.to_str().unwrap_or_default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            p, from_file,
            "{name}: compiled-in text and profiles/ file differ"
        );
        assert!((p.clipmap.n + 1).is_power_of_two());
        assert!(p.allows(Feature::Basic));
        assert!(p.footprint().total() <= p.budget.gpu_memory_bytes);
    }
}

#[test]
fn design_table_values() {
    // docs/design.md "Budgets": gles3-low n=63 L=8 ~8k; gles3-mid n=127 L=10 ~32k; desktop n=255 L=11 n^2.
    // Low and mid are whole rows of their clip texture (S = 80, 160): updates are spent in rows.
    let expect = [
        ("gles3-low", 63, 8, 8160),
        ("gles3-mid", 127, 10, 32640),
        ("desktop", 255, 11, 255 * 255),
    ];
    for (name, n, l, b) in expect {
        let p = Profile::load(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            (
                p.clipmap.n,
                p.clipmap.levels,
                p.budget.update_samples_per_frame
            ),
            (n, l, b),
            "{name}"
        );
    }
}

#[test]
fn bad_values_name_their_field() {
    let cases = [
        ("n", "64", "clipmap.n"),
        ("n", "7", "clipmap.n"),
        ("levels", "0", "clipmap.levels"),
        ("levels", "40", "clipmap.levels"),
        ("clip_margin", "2000", "clipmap.clip_margin"),
        (
            "update_samples_per_frame",
            "0",
            "budget.update_samples_per_frame",
        ),
        ("max_draws", "0", "budget.max_draws"),
        ("max_triangles", "0", "budget.max_triangles"),
        ("gpu_memory_bytes", "1000", "budget.gpu_memory_bytes"),
        ("cpu_memory_bytes", "1000", "budget.cpu_memory_bytes"),
        ("cpu_memory_bytes", "0", "budget.cpu_memory_bytes"),
        ("epsilon_px", "0.0", "view.epsilon_px"),
        ("epsilon_px", "nan", "view.epsilon_px"),
        ("width", "0", "view.width"),
        ("height", "4096", "view.height"),
        ("fov_y_deg", "180.0", "view.fov_y_deg"),
        ("features", "[]", "shading.features"),
        // These once validated, then panicked (n = 1023 in mesh::block's u16 indices), wrapped
        // (2 * clip_margin in u32: 0 triangles, no error) or overflowed (n + 1).
        ("n", "1023", "clipmap.n"),
        ("n", "4294967295", "clipmap.n"),
        ("clip_margin", "2147483648", "clipmap.clip_margin"),
        ("clip_margin", "4294967295", "clipmap.clip_margin"),
        ("max_draws", "2049", "budget.max_draws"),
        ("max_draws", "4294967295", "budget.max_draws"),
        ("max_sg_lights", "9", "shading.max_sg_lights"),
        ("width", "4294967295", "view.width"),
        // A pool that never refines, and a count past u32.
        (
            "refine_bounds_per_frame",
            "0",
            "budget.refine_bounds_per_frame",
        ),
        (
            "refine_bounds_per_frame",
            "4294967296",
            "budget.refine_bounds_per_frame",
        ),
        (
            "refine_bounds_per_frame",
            "-1",
            "budget.refine_bounds_per_frame",
        ),
    ];
    for (key, value, field) in cases {
        let (got, reason) = field_of(&with(key, value));
        assert_eq!(got, field, "{key} = {value}: {reason}");
        assert!(!reason.is_empty());
    }
    let (_, reason) = field_of(&with("gpu_memory_bytes", "1000"));
    assert!(
        reason.contains("needs") && reason.contains("1000"),
        "memory reason should give both numbers: {reason}"
    );
}

/// The detail pool's refinement budget: every shipped profile sets it, a profile without it takes the
/// default, and a profile without a pool may set 0.
#[test]
fn refinement_budget_is_set_or_defaulted() {
    for (name, _) in SHIPPED {
        let p = Profile::load(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(p.budget.refine_bounds_per_frame > 0, "{name}");
    }
    let without: String = base()
        .lines()
        .filter(|l| !l.trim_start().starts_with("refine_bounds_per_frame"))
        .collect::<Vec<_>>()
        .join("\n");
    let p = Profile::parse("test.toml", &without).expect("a profile without the field");
    assert_eq!(
        p.budget.refine_bounds_per_frame,
        clipsat::profile::DEFAULT_REFINE_BOUNDS_PER_FRAME
    );
    let no_pool = with("detail_tiles", "0")
        .lines()
        .map(|l| {
            if l.trim_start().starts_with("refine_bounds_per_frame") {
                "refine_bounds_per_frame = 0".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    assert!(Profile::parse("test.toml", &no_pool).is_ok());
}

#[test]
fn malformed_profiles_name_their_field() {
    // Wrong type.
    let (field, reason) = field_of(&with("n", "\"sixty-three\""));
    assert!(reason.contains("line"), "{field}: {reason}");
    // Missing field.
    let text: String = base()
        .lines()
        .filter(|l| !l.starts_with("levels"))
        .collect::<Vec<_>>()
        .join("\n");
    let (field, reason) = field_of(&text);
    assert_eq!(field, "levels", "{reason}");
    // Unknown field (a typo must not be silently ignored).
    let (field, reason) = field_of(&format!("{}\n[extra]\nx = 1\n", base()));
    assert_eq!(field, "extra", "{reason}");
    // Unknown feature.
    let (_, reason) = field_of(&with("features", "[\"raytracing\"]"));
    assert!(reason.contains("raytracing"), "{reason}");
    // Not TOML at all.
    assert!(matches!(
        Profile::parse("junk", "\u{0}\u{1}garbage ="),
        Err(Error::Config { .. })
    ));
}

#[test]
fn missing_profile_file_is_a_clear_error() {
    let err = Profile::load("no/such/profile.toml")
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        err.contains("gles3-low") && err.contains("no/such/profile.toml"),
        "{err}"
    );
}

/// The CPU budget's split adds up to the budget, and frames without SG give the SG inputs' share to the
/// SAT LOD tables' pages (memory the scene does not use), never more than that.
#[test]
fn cpu_split_fills_the_budget_and_lends_the_shading_share_to_the_tables() {
    for (name, _) in SHIPPED {
        let p = Profile::load(name).expect("shipped profile");
        let s = p.cpu_split();
        assert_eq!(
            s.rings + s.tile_cache + s.queries + s.lod_tables + s.shading,
            p.budget.cpu_memory_bytes,
            "{name}: {s:?}"
        );
        assert_eq!(s.lod_tables_with(true), s.lod_tables, "{name}");
        assert_eq!(s.lod_tables_with(false), s.lod_tables + s.shading, "{name}");
        assert_eq!(s.shading == 0, !p.allows(Feature::Sg), "{name}: {s:?}");
    }
}
