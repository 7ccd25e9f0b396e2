//! Embedding API: a measurement aid for what `Terrain::open` costs on the render thread.
//! `cargo run --release --example open_time -- TERRAIN...`: each terrain file opened three times
//! through a cache folder of its own in the temp folder, emptied first. The first open bakes its package
//! there (`Terrain::bake` is the explicit step to run on a worker thread instead); the next two find the
//! package and only check it against the source and decode the coarse stand-in, which is what an engine's
//! render thread pays once a terrain has been baked. Prints each open's milliseconds.

use std::time::Instant;

fn main() -> clipsat::Result<()> {
    let cache = std::env::temp_dir().join(format!("clipsat-open-time-{}", std::process::id()));
    let files: Vec<String> = std::env::args().skip(1).collect();
    if files.is_empty() {
        eprintln!("usage: cargo run --release --example open_time -- TERRAIN...");
        std::process::exit(2);
    }
    for file in &files {
        let _ = std::fs::remove_dir_all(&cache);
        for run in ["bake + open", "open", "open"] {
            let t = Instant::now();
            let terrain = clipsat::Terrain::open(file, Some(&cache))?;
            let (w, h) = terrain.size();
            println!(
                "{file} ({w} x {h}, streamed {}): {run} {:.1} ms",
                terrain.is_streamed(),
                t.elapsed().as_secs_f64() * 1e3
            );
        }
    }
    let _ = std::fs::remove_dir_all(&cache);
    Ok(())
}
