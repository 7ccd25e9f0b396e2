//! `Terrain::bake`, the explicit bake an engine runs on a worker thread: it bakes once, with progress,
//! and after it `Terrain::open_with` finds the package and opens it without baking.

use std::cell::Cell;
use std::path::Path;

use clipsat::{Progress, ProgressReport, Terrain, TerrainOptions};

#[test]
fn a_bake_on_a_worker_thread_is_found_by_the_next_open() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bake_step");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let png = dir.join("heights.png");
    let (w, h) = (257u32, 193u32);
    let grey: Vec<u16> = (0..w * h)
        .map(|i| u16::try_from((i % w) * 40 + (i / w) * 25).unwrap_or(u16::MAX))
        .collect();
    image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, grey)
        .expect("image")
        .save(&png)
        .expect("write the PNG");
    let cache = dir.join("cache");
    // The bake, with its progress, on a thread of its own (what an engine's loader does).
    let (path, reports) = std::thread::scope(|s| {
        s.spawn(|| {
            let reports = Cell::new(0u32);
            let report = |_: ProgressReport<'_>| reports.set(reports.get() + 1);
            let options = TerrainOptions::default()
                .cache_dir(&cache)
                .spacing_m(30.0)
                .progress(Progress::new(&report));
            let path = Terrain::bake(&png, &options).expect("bake");
            (path, reports.get())
        })
        .join()
        .expect("bake thread")
    });
    assert!(
        path.starts_with(&cache) && path.exists(),
        "{}",
        path.display()
    );
    assert!(reports > 0, "the bake reported no progress");
    // Baked once: the same options find it, report nothing and bake nothing.
    let again = Cell::new(0u32);
    let report = |_: ProgressReport<'_>| again.set(again.get() + 1);
    let options = TerrainOptions::default()
        .cache_dir(&cache)
        .spacing_m(30.0)
        .progress(Progress::new(&report));
    let modified = std::fs::metadata(&path)
        .and_then(|m| m.modified())
        .expect("package");
    assert_eq!(Terrain::bake(&png, &options).expect("bake"), path);
    let terrain = Terrain::open_with(&png, &options).expect("open");
    assert!(terrain.is_streamed());
    assert_eq!(terrain.size(), (w, h));
    assert_eq!(again.get(), 0, "baked again");
    assert_eq!(
        std::fs::metadata(&path).and_then(|m| m.modified()).ok(),
        Some(modified)
    );
    // A package is its own bake; no cache folder, or a resident terrain, is refused.
    assert_eq!(
        Terrain::bake(&path, &TerrainOptions::default().cache_dir(&cache)).expect("package"),
        path
    );
    assert!(Terrain::bake(&png, &TerrainOptions::default()).is_err());
    assert!(Terrain::bake(
        &png,
        &TerrainOptions::default().cache_dir(&cache).resident(true)
    )
    .is_err());
}

/// A file over the limit is refused before anything is allocated, and the error names the public option
/// that raises the limit (`TerrainOptions::max_samples`), which then opens it.
#[test]
fn a_terrain_over_the_limit_names_the_option_that_raises_it() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bake_step_limit");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let png = dir.join("heights.png");
    image::GrayImage::from_fn(64, 64, |x, y| {
        image::Luma([u8::try_from(x + y).unwrap_or(0)])
    })
    .save(&png)
    .expect("write the PNG");
    let e = Terrain::open_with(&png, &TerrainOptions::default().max_samples(1000))
        .expect_err("4096 samples over a limit of 1000");
    assert!(
        matches!(
            e,
            clipsat::Error::TooLarge {
                limit: 1000,
                samples: 4096,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(
        e.to_string().contains("`TerrainOptions::max_samples`"),
        "{e}"
    );
    let t = Terrain::open_with(&png, &TerrainOptions::default().max_samples(4096)).expect("open");
    assert_eq!(t.size(), (64, 64));
}
