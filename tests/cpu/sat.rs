//! The fixed-point SAT against brute-force sums: exactness, one-sided rounding, and the numerical hard
//! cases of docs/design.md "SAT LOD" 4 (16385^2 extent, a one-sample needle, values from 1e-300 to 1, sums at
//! the representation's limit, p = 2 and 64).

#![expect(
    clippy::cast_possible_truncation,
    reason = "test arithmetic on values known to be in range"
)]

use clipsat::bake::sat::{pow_unit, Sat};

/// A deterministic pseudo-random value in [0, 1) per sample.
fn noise(x: u32, y: u32) -> f64 {
    let mut z = (u64::from(x) << 32 | u64::from(y)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Brute-force f64 sum and exact integer sum of the quantised values over a box.
fn brute(f: &impl Fn(u32, u32) -> f64, q: u32, b: (u32, u32, u32, u32)) -> (f64, u128) {
    let scale = 2f64.powi(q as i32);
    // Neumaier-compensated, so the reference is good to a few ulps of the total.
    let (mut s, mut comp, mut qs) = (0.0f64, 0.0f64, 0u128);
    for y in b.1..b.3 {
        for x in b.0..b.2 {
            let v = f(x, y);
            let t = s + v;
            comp += if s.abs() >= v.abs() {
                (s - t) + v
            } else {
                (v - t) + s
            };
            s = t;
            qs += (v * scale).ceil() as u128;
        }
    }
    (s + comp, qs)
}

const BOXES: [(u32, u32, u32, u32); 7] = [
    (0, 0, 300, 200),
    (0, 0, 1, 1),
    (299, 199, 300, 200),
    (17, 33, 18, 190),
    (100, 50, 250, 51),
    (3, 4, 290, 197),
    (120, 80, 120, 90),
];

/// Exact integer equality with a brute-force sum of quantised values, and the stated f64 error bound
/// 0 <= box_sum - sum(v) < n 2^-Q, for p = 2 and p = 64 powers of a random field.
#[test]
fn box_sums_match_brute_force_p2_p64() {
    let (w, h) = (300, 200);
    for p in [1u32, 2, 64] {
        let f = move |x: u32, y: u32| pow_unit(noise(x, y), p);
        let q = Sat::max_frac_bits(u64::from(w * h));
        let sat = Sat::build(w, h, 1, q, f).expect("sat");
        let mut worst = 0.0f64;
        for b in BOXES {
            let (s, qs) = brute(&f, q, b);
            assert_eq!(
                u128::from(sat.box_sum_raw(b.0, b.1, b.2, b.3)),
                qs,
                "p {p} box {b:?}"
            );
            let n = f64::from((b.2 - b.0) * (b.3 - b.1));
            let got = sat.box_sum(b.0, b.1, b.2, b.3);
            let err = got - s;
            // The compensated reference and the final conversion: a few ulps of the total.
            let fl = s * 4.0 * f64::EPSILON;
            let tol = n * sat.quantum() + fl;
            assert!(err >= -fl && err <= tol, "p {p} box {b:?}: {got} vs {s}");
            let (lo, hi) = sat.box_bounds(b.0, b.1, b.2, b.3);
            assert!(lo <= s + fl && s <= hi + fl, "p {p} {b:?}");
            if n > 0.0 {
                worst = worst.max(err / (n * sat.quantum()));
            }
        }
        eprintln!("p {p}: Q = {q}, worst rounding error {worst:.3} quanta per sample");
    }
}

/// A one-sample needle on zero: the box holding it sums to at least one quantum even when its value
/// underflows, and boxes without it sum to exactly zero.
#[test]
fn needle_never_vanishes() {
    for v in [1.0, 0.5, 1e-12, 1e-300, pow_unit(1e-6, 64)] {
        let f = move |x: u32, y: u32| if (x, y) == (40, 9) { v } else { 0.0 };
        let sat = Sat::build(64, 64, 1, Sat::max_frac_bits(4096), f).expect("sat");
        assert!(sat.box_sum_raw(40, 9, 41, 10) >= 1, "value {v} vanished");
        assert!(sat.box_sum_raw(0, 0, 64, 64) >= 1);
        assert_eq!(sat.box_sum_raw(0, 0, 40, 64), 0);
        assert_eq!(sat.box_sum_raw(41, 0, 64, 64), 0);
        assert_eq!(sat.box_sum_raw(0, 10, 64, 64), 0);
        let (lo, hi) = sat.box_bounds(30, 0, 50, 20);
        assert!(lo <= v && v <= hi, "{v} not in [{lo}, {hi}]");
    }
}

/// Values spanning 1e-300 to 1 in one grid: every box sum within its bound of the f64 sum.
#[test]
fn values_spanning_many_decades() {
    let f = |x: u32, y: u32| 10f64.powi(-(((x * 7 + y * 13) % 301) as i32));
    let (w, h) = (150, 90);
    let q = Sat::max_frac_bits(u64::from(w * h));
    let sat = Sat::build(w, h, 1, q, f).expect("sat");
    for b in [
        (0, 0, 150, 90),
        (5, 5, 6, 6),
        (10, 20, 70, 21),
        (149, 0, 150, 90),
    ] {
        let (s, qs) = brute(&f, q, b);
        assert_eq!(u128::from(sat.box_sum_raw(b.0, b.1, b.2, b.3)), qs);
        let (lo, hi) = sat.box_bounds(b.0, b.1, b.2, b.3);
        assert!(
            lo <= s && s <= hi * (1.0 + 1e-15),
            "{b:?}: {s} not in [{lo}, {hi}]"
        );
    }
}

/// Sums at the representation's limit: every value 1 at the finest quantum, so the full-grid sum
/// N 2^Q lies in [2^63, 2^64); every box is still exact.
#[test]
fn sums_at_the_limit() {
    for (w, h) in [(1024u32, 1024u32), (1025, 1025), (3, 5)] {
        let n = u64::from(w) * u64::from(h);
        let q = Sat::max_frac_bits(n);
        let sat = Sat::build(w, h, 1, q, |_, _| 1.0).expect("sat");
        let full = sat.box_sum_raw(0, 0, w, h);
        assert_eq!(u128::from(full), u128::from(n) << q);
        assert!(
            full >= 1 << 62,
            "{w}x{h}: the limit case should be near 2^64, got {full}"
        );
        assert_eq!(
            sat.box_sum_raw(1, 1, w, h),
            (u64::from(w - 1) * u64::from(h - 1)) << q
        );
        // One bit finer would let the sum reach 2^64: refused.
        assert!(Sat::build(w, h, 1, q + 1, |_, _| 1.0).is_err() || q == 62);
    }
}

/// A 16385 x 16385 extent (the largest procedural terrain): constant 1 - 2^-35 with a needle of 1, in
/// 16 x 16 cells (8.4 MB instead of 2.1 GB). Box sums are checked against the closed form.
#[test]
fn extent_16385_constant_plus_needle() {
    let side = 16385u32;
    let n = u64::from(side) * u64::from(side);
    let q = Sat::max_frac_bits(n);
    assert_eq!(q, 35);
    let c = 1.0 - 2f64.powi(-35);
    let needle = (12_345u32, 6_789u32);
    let f = move |x: u32, y: u32| if (x, y) == needle { 1.0 } else { c };
    let sat = Sat::build(side, side, 16, q, f).expect("sat");
    assert_eq!(sat.memory_bytes(), 1025 * 1025 * 8);
    let cq = (c * 2f64.powi(35)).ceil() as u128;
    let full = 1u128 << 35;
    for b in [
        (0, 0, side, side),
        (12_336, 6_784, 12_352, 6_800),
        (0, 0, 16, 16),
        (16_368, 16_368, side, side),
        (16, 6_784, 16_384, 6_800),
        (0, 0, 12_336, side),
    ] {
        let cells = u128::from(b.2 - b.0) * u128::from(b.3 - b.1);
        let inside = needle.0 >= b.0 && needle.0 < b.2 && needle.1 >= b.1 && needle.1 < b.3;
        let expect = cells * cq + if inside { full - cq } else { 0 };
        assert_eq!(
            u128::from(sat.box_sum_raw(b.0, b.1, b.2, b.3)),
            expect,
            "{b:?}"
        );
    }
}

/// Misuse is refused: an empty grid, a quantum too fine for the grid.
#[test]
fn refuses_bad_parameters() {
    assert!(Sat::build(0, 5, 1, 10, |_, _| 0.0).is_err());
    assert!(Sat::build(5, 5, 0, 10, |_, _| 0.0).is_err());
    assert!(Sat::build(1 << 16, 1 << 16, 64, 32, |_, _| 0.0).is_err());
    assert!(Sat::from_parts(4, 4, 1, 10, vec![0; 15]).is_err());
}

#[test]
#[should_panic(expected = "outside [0, 1]")]
fn out_of_range_value_panics() {
    let _ = Sat::build(4, 4, 1, 10, |_, _| 1.5);
}
