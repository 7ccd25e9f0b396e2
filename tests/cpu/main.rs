//! The CPU test binary: every stage that needs no GPU adapter (source, bake, plan, shading maths, shader
//! translation). One binary instead of one per file, so `cargo test` links wgpu once for all of them (the
//! layout of wgpu's own test suite). Run one module with `cargo test --test cpu clipmap::`.

mod bake_step;
mod clipmap;
mod drawn;
mod flight;
mod fly_paths;
mod fragment;
mod fuzz_parsers;
mod imagery;
mod imagery_bake;
mod imagery_rings;
mod imagery_small;
mod layering;
mod lod;
mod mosaic;
mod package;
mod plan_time;
mod profiles;
mod query;
mod sat;
mod scene;
mod sg_numerics;
mod shaders_glsl;
mod shaders_glslang;
mod shading;
mod sources;
mod tiff_inputs;

/// The path of a shared data file, or `None` (with a printed reason) when it is missing outside CI;
/// under `CI=true` a missing file fails the test.
pub(crate) fn shared_file(name: &str) -> Option<std::path::PathBuf> {
    let path = clipsat::data_dir().join(name);
    if path.is_file() {
        return Some(path);
    }
    let msg = format!("shared data file {} is missing", path.display());
    assert!(
        std::env::var("CI").as_deref() != Ok("true"),
        "{msg} (CI=true requires it; set CLIPSAT_DATA)"
    );
    eprintln!("skipping: {msg}");
    None
}

/// A shared terrain, or `None` (with a printed reason) when the data is missing outside CI.
pub(crate) fn shared(name: &str, spacing: Option<f32>) -> Option<clipsat::source::Heightmap> {
    let path = shared_file(name)?;
    let opts = clipsat::source::LoadOptions {
        spacing,
        ..clipsat::source::LoadOptions::default()
    };
    Some(clipsat::source::load(&path, &opts).unwrap_or_else(|e| panic!("{name}: {e}")))
}

/// A fresh folder under the system temp dir, unique to its module, test and process; removed on drop.
pub(crate) struct TempDir(std::path::PathBuf);

impl TempDir {
    /// `clipsat-{module}-{pid}-{test}`, emptied and created.
    pub(crate) fn new(module: &str, test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("clipsat-{module}-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create temp dir");
        Self(dir)
    }
}

impl std::ops::Deref for TempDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
