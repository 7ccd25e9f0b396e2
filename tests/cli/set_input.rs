//! Package sets through the binary: `clipsat bake --parts` refuses a package set given as its tiles (it
//! had said the folder held no tile) and the tiles' own folder as the set's (the set had been baked
//! beside the tiles, and `--terrain` on that folder then read the set, not the tiles).

use super::{clipsat, geotiff_tile, scratch_in};

#[test]
fn bake_parts_refuses_a_set_and_the_tiles_folder() {
    let dir = scratch_in("set_input", "refused");
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).expect("folder");
    geotiff_tile(
        &tiles.join("t.tif"),
        65,
        (11.0, 58.0),
        1.0 / 3600.0,
        |x, y| (x + y) as f32,
    );
    let set = dir.join("set");
    std::fs::create_dir_all(&set).expect("folder");
    std::fs::write(
        set.join("clipsat-set.toml"),
        "# clipsat package set: one terrain baked as parts, each read where the index places it.\n",
    )
    .expect("an index");
    let path = |p: &std::path::Path| p.to_str().expect("utf-8 path").to_string();
    let again = path(&dir.join("again"));
    let out = clipsat(&["bake", "--terrain", &path(&set), "--parts", &again]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("is a package set"),
        "{err}"
    );
    let out = clipsat(&["bake", "--terrain", &path(&tiles), "--parts", &path(&tiles)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("the tiles' own folder"),
        "{err}"
    );
    assert!(!tiles.join("clipsat-set.toml").exists(), "nothing written");
}
