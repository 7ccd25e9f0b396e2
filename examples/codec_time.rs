//! Stage 1b, the package: a measurement aid for the codec's speed goals (`docs/package-codec.md`).
//! `cargo run --release --example codec_time -- PACKAGE.clipsat`: the whole pyramid decoded to level 0
//! (20 times), then the level-0 tiles under a centred 255 x 255 window decoded through a cold cache
//! (its coarser levels resident) and copied into a ring (100 times). Reports this thread's CPU time
//! (Linux's `/proc/thread-self/schedstat`, which a shared machine's other work does not inflate as it
//! does wall time) beside the best wall time.

use clipsat::package::{Package, TileCache};

/// This thread's time on a CPU so far, seconds (0 where the kernel does not say).
fn on_cpu() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(0.0, |ns| ns * 1e-9)
}

fn main() {
    let path = std::path::PathBuf::from(std::env::args().nth(1).expect("a package path"));
    let pkg = Package::open(&path).expect("a package");
    let n0 = pkg.header().samples() as f64;
    // The CPU time over all the runs together: the kernel counts it in ticks of a few ms on some
    // machines, as long as one run.
    let (runs, mut wall) = (20, f64::MAX);
    let c0 = on_cpu();
    for _ in 0..runs {
        let t = std::time::Instant::now();
        std::hint::black_box(pkg.decode_level0().expect("decode"));
        wall = wall.min(t.elapsed().as_secs_f64());
    }
    let cpu = (on_cpu() - c0) / f64::from(runs);
    println!(
        "{}: pyramid to level 0: cpu {:.2} ms = {:.2} ns per level-0 sample (mean of {runs}; best wall {:.2} ms)",
        path.display(),
        cpu * 1e3,
        cpu * 1e9 / n0,
        wall * 1e3
    );
    const N: u32 = 255;
    let h = pkg.header().clone();
    let (x0, y0) = (
        h.width.saturating_sub(N) / 2,
        h.height.saturating_sub(N) / 2,
    );
    let (w, hh) = (N.min(h.width), N.min(h.height));
    let mut ring = vec![0i32; (w * hh) as usize];
    let (mut best, mut decoded, mut sum) = (f64::MAX, 0, 0.0);
    let iters = 100;
    for _ in 0..iters {
        let mut cache = TileCache::new(
            Package::open(&path).expect("a package"),
            64 << 20,
            "codec_time",
        )
        .expect("cache");
        let mut budget = u64::MAX;
        // The coarser levels, resident first (the clipmap fills coarse to fine).
        let (cx, cy) = (i64::from(x0 / 2) - 40, i64::from(y0 / 2) - 40);
        let c1 = i64::from(N / 2 + 80);
        if h.levels.len() > 1 {
            cache
                .ensure_rect(1, (cx, cy, cx + c1, cy + c1), &mut budget)
                .expect("decode");
        }
        let before = cache.stats().decoded_samples;
        let (c, t) = (on_cpu(), std::time::Instant::now());
        let rect = (
            i64::from(x0),
            i64::from(y0),
            i64::from(x0 + w),
            i64::from(y0 + hh),
        );
        cache.ensure_rect(0, rect, &mut budget).expect("decode");
        for y in 0..hh {
            let mut x = 0;
            while x < w {
                let (sx, seg) = cache.row_segment(0, x0 + x, y0 + y).expect("resident");
                let from = (x0 + x - sx) as usize;
                let take = seg.len().saturating_sub(from).min((w - x) as usize);
                let at = (y * w + x) as usize;
                ring[at..at + take].copy_from_slice(&seg[from..from + take]);
                x += u32::try_from(take).expect("at most N");
            }
        }
        std::hint::black_box(&ring);
        sum += on_cpu() - c;
        best = best.min(t.elapsed().as_secs_f64());
        decoded = cache.stats().decoded_samples - before;
    }
    println!(
        "  {w} x {hh} level, decode + fill: cpu {:.3} ms a time (mean of {iters}), best wall {:.3} ms; \
         {decoded} samples decoded ({:.2} ns each)",
        sum * 1e3 / f64::from(iters),
        best * 1e3,
        sum * 1e9 / f64::from(iters) / decoded as f64
    );
}
