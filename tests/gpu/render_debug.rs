//! The renderer's debug views (`render --debug`): the level-colour view shows each drawn level in its own
//! colour, in distance and SAT LOD modes alike, the wireframe view draws lattice lines, and the normal view
//! is the default rendering. Headless strict GLES 3.0 on llvmpipe.

use std::collections::BTreeMap;

use crate::render_support::{clipmap, lod, profile, relief, renderer_in, strict};
use clipsat::gpu::headless::{render_frame, FrameOptions};
use clipsat::gpu::readback::Image;
use clipsat::plan::camera::Camera;
use clipsat::plan::lod::LodMode;
use clipsat::shading::debug_view::{level_of_pixel, DebugView};

/// Pixels per level colour found in `image`.
fn level_pixels(image: &Image) -> BTreeMap<u32, u64> {
    let mut found = BTreeMap::new();
    for px in image.rgba.chunks_exact(4) {
        if let Some(l) = level_of_pixel([px[0], px[1], px[2], px[3]]) {
            *found.entry(l).or_insert(0) += 1;
        }
    }
    found
}

#[test]
fn level_colours_show_the_drawn_levels() {
    let gpu = strict();
    let hm = relief();
    let p = profile("gles3-low", 192, 108, None);
    let cam = Camera::default_for(&hm).expect("camera");
    let mut cm = clipmap(&hm, &p);
    cm.fill_at(cam.eye, 10_000).expect("fill");
    let tables = lod(&hm, &p, &cm);
    let mut r = renderer_in(&gpu, &p, &cm, LodMode::Distance, None, DebugView::Normal);
    let normal = render_frame(&mut r, &cm, &cam, &FrameOptions::default()).expect("frame");
    let again = render_frame(&mut r, &cm, &cam, &FrameOptions::default()).expect("frame");
    assert_eq!(normal.image_hash, again.image_hash);
    for mode in [LodMode::Distance, LodMode::Sat] {
        let mut r = renderer_in(&gpu, &p, &cm, mode, Some(&tables), DebugView::Levels);
        let out = render_frame(&mut r, &cm, &cam, &FrameOptions::default()).expect("levels frame");
        let drawn: Vec<u32> = r.draws().iter().map(|d| d.level).collect();
        let found = level_pixels(&out.image);
        let shown: Vec<u32> = found
            .iter()
            .filter(|(_, &n)| n >= 20)
            .map(|(&l, _)| l)
            .collect();
        // SAT LOD draws this view at levels 5-7, level 7 only past the data's border (cut away).
        assert!(
            shown.len() >= 2,
            "{mode}: level colours {found:?}, drawn levels {drawn:?}"
        );
        for l in &shown {
            assert!(
                drawn.contains(l),
                "{mode}: level {l} coloured but not drawn ({drawn:?})"
            );
        }
        // The normal view shows no level colours in quantity.
        let stray: u64 = level_pixels(&normal.image).values().sum();
        let shaded: u64 = found.values().sum();
        assert!(
            stray * 4 < shaded,
            "normal view: {stray} level-coloured pixels, levels view {shaded}"
        );
    }
    let mut r = renderer_in(&gpu, &p, &cm, LodMode::Distance, None, DebugView::Wireframe);
    let wire = render_frame(&mut r, &cm, &cam, &FrameOptions::default()).expect("wireframe frame");
    let lines: u64 = level_pixels(&wire.image).values().sum();
    assert!(lines > 200, "wireframe: {lines} line pixels");
    assert_ne!(wire.image_hash, normal.image_hash);
}
