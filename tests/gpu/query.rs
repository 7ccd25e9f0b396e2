//! The embedding API's queries on a renderer: `height_at` bit for bit against the bilinear
//! interpolation of the package's decoded level 0 (streamed) or of the heights given (held whole),
//! `raycast` against the stage's own walk over that grid, and `drawn_height_at` against the surface
//! drawn under the eye (`surface_height`) and, with distance LOD's morph, free of steps along lines out
//! from the eye.

use clipsat::package::query::{self, GridRanges, Level0, ResidentGrid};
use clipsat::package::ray::{self, GridRay};
use clipsat::{Profile, RenderOptions, Terrain, TerrainRenderer};

use crate::render_support::strict;

/// A grid held whole, its world frame, and its samples' bilinear heights (`package::query`).
fn world_height(
    grid: &mut impl Level0,
    hm: &clipsat::source::Heightmap,
    x: f64,
    y: f64,
) -> Option<f64> {
    let (u, v) = hm.world_to_grid(x, y);
    query::height(grid, u, v).expect("height")
}

fn check(name: &str, r: &mut TerrainRenderer, hm: &clipsat::source::Heightmap) {
    let ranges = GridRanges::new(hm);
    let mut grid = ResidentGrid {
        grid: hm,
        ranges: &ranges,
    };
    let (ox, oy) = hm.origin();
    let (ex, ey) = hm.extent_m();
    let s = f64::from(hm.spacing());
    for k in 0..500u32 {
        let (fx, fy) = (
            f64::from(k * 37 % 500) / 499.0,
            f64::from(k * 91 % 500) / 499.0,
        );
        let (x, y) = (
            ox - 0.05 * ex + 1.1 * ex * fx,
            oy - 0.05 * ey + 1.1 * ey * fy,
        );
        let got = r.height_at(x, y).expect("height_at");
        let want = world_height(&mut grid, hm, x, y);
        assert_eq!(
            got.map(f64::to_bits),
            want.map(f64::to_bits),
            "{name}: ({x}, {y})"
        );
        // A ray straight down from above, and one slanting, against the stage's walk over the grid.
        let (_, zhi) = hm.range();
        let o = [x, y, f64::from(zhi) + 50.0];
        for d in [[0.0, 0.0, -1.0], [0.3, -0.2, -0.5]] {
            let hit = r.raycast(o, d, f64::INFINITY).expect("raycast");
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let (u, v) = hm.world_to_grid(o[0], o[1]);
            let gr = GridRay {
                o: [u, v, o[2]],
                d: [d[0] / len / s, -d[1] / len / s, d[2] / len],
                t: (0.0, f64::INFINITY),
            };
            let want = ray::raycast(&mut grid, &gr).expect("grid ray");
            assert_eq!(
                hit.is_some(),
                want.is_some(),
                "{name}: ray from {o:?} along {d:?}"
            );
            if let (Some(h), Some(w)) = (hit, want) {
                assert!(
                    (h.distance - w.t).abs() <= 1e-9 * w.t.max(1.0),
                    "{name}: {h:?} vs {w:?}"
                );
                let surface = world_height(&mut grid, hm, h.point[0], h.point[1]).expect("inside");
                assert!(
                    (h.point[2] - surface).abs() < 1e-6 * surface.abs().max(1.0),
                    "{name}: {h:?}"
                );
                let n = h.normal;
                assert!(
                    ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-12
                        && n[2] > 0.0
                );
            }
            if d[0] == 0.0 {
                assert_eq!(hit.is_some(), want.is_some());
                if let (Some(h), Some(g)) = (hit, got) {
                    assert!(
                        (h.point[2] - g).abs() < 1e-6 * g.abs().max(1.0),
                        "{name}: straight down {h:?} vs {g}"
                    );
                }
            }
        }
        assert!(
            r.raycast(o, [0.0, 0.0, 1.0], f64::INFINITY)
                .expect("up")
                .is_none(),
            "{name}: up"
        );
    }
    assert!(
        r.raycast([ox, oy, 0.0], [0.0, 0.0, 0.0], 1.0).is_err(),
        "a zero direction"
    );
    assert!(
        r.raycast([ox, oy, f64::NAN], [0.0, 0.0, -1.0], 1.0)
            .is_err(),
        "a NaN origin"
    );
    assert!(
        r.raycast([ox, oy, 0.0], [0.0, 0.0, -1.0], -1.0).is_err(),
        "a negative distance"
    );
}

#[test]
fn renderer_queries_read_the_full_resolution_data_and_the_drawn_surface() {
    let gpu = strict();
    let profile = Profile::load("gles3-low").expect("profile");
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("query_cache");
    // Streamed through a package baked in the cache folder, and the same heights held whole.
    let streamed = Terrain::procedural(4, 257, 30.0, Some(&dir)).expect("terrain");
    assert!(streamed.is_streamed());
    // Over the middle of the terrain, looking north-east and down.
    let (lo, hi) = streamed.height_range();
    let c = 128.0 * 30.0;
    let cam = clipsat::Camera::look_at(
        [c, c, f64::from(hi) + 300.0],
        [c + 1500.0, c + 1500.0, f64::from(lo)],
        60.0,
    )
    .expect("camera");
    let decoded = {
        let t = Terrain::procedural(4, 257, 30.0, Some(&dir)).expect("terrain");
        let (_, _, pkg) = t.parts();
        pkg.expect("streamed").to_heightmap().expect("decode")
    };
    let options = RenderOptions::default();
    let mut r = TerrainRenderer::new(gpu.device(), gpu.queue(), streamed, &profile, &options)
        .expect("renderer");
    let share = profile.get().cpu_split().queries;
    assert!(
        r.query_bytes() > 0 && r.query_bytes() <= share,
        "{} bytes in a {share}-byte share",
        r.query_bytes()
    );
    let eye = cam.eye();
    assert_eq!(r.drawn_height_at(eye[0], eye[1]), None, "nothing drawn yet");
    r.warm_up(gpu.queue(), &cam, (160, 90)).expect("warm up");
    r.prepare(gpu.queue(), &cam, (160, 90)).expect("frame");
    check("streamed", &mut r, &decoded);
    // Under the eye the finest ring is drawn unmorphed: the surface the flight keeps clear of.
    let under = r
        .drawn_height_at(eye[0], eye[1])
        .expect("drawn under the eye");
    let surface = f64::from(r.surface_height(&cam).expect("surface"));
    assert!((under - surface).abs() < 1e-3, "{under} vs {surface}");
    assert_eq!(r.drawn_height_at(-1.0e6, 0.0), None);
    // With distance LOD the rings morph toward the coarser ring over their outer tenth, so the drawn
    // surface has no step where rings meet: along lines out from the eye, every rise over 1/64 of a
    // sample is within what the data's own slope and the morph's ramp allow (a step would not shrink
    // with the distance walked).
    let (mut worst_drawn, mut worst_data, mut some) = (0.0f64, 0.0f64, 0u32);
    for a in 0..8 {
        let (dx, dy) = (
            f64::from(a).mul_add(0.785, 0.3).cos(),
            f64::from(a).mul_add(0.785, 0.3).sin(),
        );
        let mut prev: Option<(f64, f64)> = None;
        for k in 0..6400 {
            let t = f64::from(k) * 30.0 / 64.0;
            let (x, y) = (eye[0] + t * dx, eye[1] + t * dy);
            let cur = r
                .drawn_height_at(x, y)
                .zip(r.height_at(x, y).expect("height"));
            some += u32::from(cur.is_some());
            if let (Some((d0, h0)), Some((d1, h1))) = (prev, cur) {
                worst_drawn = worst_drawn.max((d1 - d0).abs());
                worst_data = worst_data.max((h1 - h0).abs());
            }
            prev = cur;
        }
    }
    eprintln!(
        "drawn surface: largest rise {worst_drawn} m over 1/64 of a sample, data {worst_data} m ({some} points)"
    );
    assert!(
        worst_drawn > 0.0 && worst_drawn <= 2.0 * worst_data,
        "{worst_drawn} vs {worst_data}"
    );

    let hm = decoded;
    let held = Terrain::from_heights(
        hm.width(),
        hm.height(),
        hm.spacing(),
        hm.heights().to_vec(),
        None,
    )
    .expect("terrain");
    let mut r = TerrainRenderer::new(gpu.device(), gpu.queue(), held, &profile, &options)
        .expect("renderer");
    check("held", &mut r, &hm);
}
