//! SG numerics at the extremes (docs/design.md "Numerics"): sharpness from 1e-6 to 1e4, products whose raw
//! exponents overflow, the vMF clamp and the kappa approximation.

use clipsat::shading::sg::{self, Sg, Vmf};
use glam::{DVec3, Vec3};

const LAMBDAS: [f32; 9] = [1e-6, 1e-4, 1e-2, 0.5, 2.133, 10.0, 100.0, 1e3, 1e4];

/// A3(kappa) = coth(kappa) - 1/kappa, the mean resultant length of a 3D vMF; series below 1e-2.
fn a3(kappa: f64) -> f64 {
    if kappa < 1e-2 {
        kappa / 3.0 - kappa.powi(3) / 45.0
    } else {
        1.0 / kappa.tanh() - 1.0 / kappa
    }
}

/// The exact inverse of A3 by bisection on a log scale.
fn a3_inverse(r: f64) -> f64 {
    let (mut lo, mut hi) = (1e-9f64, 1e9f64);
    for _ in 0..200 {
        let mid = (lo * hi).sqrt();
        if a3(mid) < r {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (lo * hi).sqrt()
}

#[test]
fn banerjee_kappa_inverts_a3_better_than_the_seed_variant() {
    let banerjee = |r: f64| (3.0 * r - r.powi(3)) / (1.0 - r * r);
    let seed = |r: f64| (3.0 * r - r.powi(3)) / (1.0 - r.powi(3));
    let (mut worst_b, mut worst_s) = ((0.0f64, 0.0), (0.0f64, 0.0));
    let (mut worst_kb, mut worst_ks) = (0.0f64, 0.0f64);
    for i in 0..=980 {
        let r = 0.01 + 0.001 * f64::from(i);
        let exact = a3_inverse(r);
        let eb = (a3(banerjee(r)) - r).abs() / r;
        let es = (a3(seed(r)) - r).abs() / r;
        if eb > worst_b.0 {
            worst_b = (eb, r);
        }
        if es > worst_s.0 {
            worst_s = (es, r);
        }
        worst_kb = worst_kb.max((banerjee(r) - exact).abs() / exact);
        worst_ks = worst_ks.max((seed(r) - exact).abs() / exact);
        // The f32 shipped function is the Banerjee form.
        #[expect(clippy::cast_possible_truncation, reason = "r in [0.01, 0.99]")]
        let shipped = f64::from(sg::kappa_from_mean_length(r as f32));
        assert!(
            (shipped - banerjee(r)).abs() <= 1e-5 * banerjee(r) + 1e-6,
            "r = {r}"
        );
    }
    println!(
        "|r| in [0.01, 0.99]: max relative error of A3(kappa) vs |r|: Banerjee {:.3e} (at {:.3}), \
         seed (1 - r^3) {:.3e} (at {:.3})",
        worst_b.0, worst_b.1, worst_s.0, worst_s.1
    );
    println!("max relative error of kappa vs the exact inverse: Banerjee {worst_kb:.3e}, seed {worst_ks:.3e}");
    assert!(worst_b.0 < 0.03, "Banerjee's kappa is within 3 % in A3");
    assert!(
        worst_s.0 > 3.0 * worst_b.0,
        "the seed variant is clearly worse"
    );
}

#[test]
fn vmf_clamps_mean_length_at_both_ends() {
    for r in [
        Vec3::ZERO,
        Vec3::new(1e-9, 0.0, 1e-9),
        Vec3::new(0.0, 0.0, 1e-4),
    ] {
        let v = Vmf::from_mean_normal(r);
        assert!(
            v.axis.is_finite() && (v.axis.length() - 1.0).abs() < 1e-6,
            "{r}"
        );
        assert!(
            v.kappa.is_finite() && v.kappa > 0.0 && v.kappa < 5e-3,
            "|r| -> 0: {}",
            v.kappa
        );
    }
    for r in [
        Vec3::Z,
        Vec3::new(0.0, 0.6, 0.8),
        Vec3::Z * 1.0001,
        Vec3::new(1.0, 1.0, 1.0),
    ] {
        let v = Vmf::from_mean_normal(r);
        assert!(
            v.kappa.is_finite() && v.kappa > 9e3 && v.kappa < 1.1e4,
            "|r| -> 1: {}",
            v.kappa
        );
    }
}

#[test]
fn eval_and_integral_at_extreme_sharpness() {
    for &l in &LAMBDAS {
        let g = Sg::new(Vec3::Z, l, Vec3::ONE);
        for v in [Vec3::Z, -Vec3::Z, Vec3::X] {
            let x = g.eval(v);
            assert!(
                x.is_finite() && x.min_element() >= 0.0 && x.max_element() <= 1.0,
                "lambda {l}"
            );
        }
        let exact = 2.0 * std::f64::consts::PI * -(-2.0 * f64::from(l)).exp_m1() / f64::from(l);
        let got = f64::from(g.integral().x);
        assert!(
            (got - exact).abs() <= 2e-6 * exact,
            "lambda {l}: {got} vs {exact}"
        );
    }
    let flat = Sg::new(Vec3::Z, 0.0, Vec3::splat(2.0));
    assert!(
        (flat.integral().x - 8.0 * std::f32::consts::PI).abs() < 1e-5,
        "lambda = 0 is 4 pi mu"
    );
}

#[test]
fn expm1_and_ln_1p_are_accurate_everywhere() {
    let mut worst = 0.0f64;
    for i in -400i32..=400 {
        let x = if i == 0 {
            0.0
        } else {
            f64::from(i.signum()) * 10f64.powf(f64::from(i.abs()) / 40.0 - 9.0)
        };
        if x.abs() > 20.0 {
            continue;
        }
        #[expect(clippy::cast_possible_truncation, reason = "test points")]
        let xf = x as f32;
        let x = f64::from(xf);
        let e = (f64::from(sg::expm1(xf)) - x.exp_m1()).abs() / x.exp_m1().abs().max(1e-300);
        worst = worst.max(if x == 0.0 { 0.0 } else { e });
        if x > -0.9 {
            let l = (f64::from(sg::ln_1p(xf)) - x.ln_1p()).abs() / x.ln_1p().abs().max(1e-300);
            worst = worst.max(if x == 0.0 { 0.0 } else { l });
        }
    }
    println!("expm1 / ln_1p worst relative error {worst:.2e}");
    assert!(worst < 2e-5, "worst relative error {worst}");
}

#[test]
fn products_whose_raw_exponents_overflow_stay_finite_and_exact() {
    let dirs = [
        (Vec3::Z, Vec3::Z),
        (Vec3::Z, Vec3::new(0.0, 0.01, 1.0).normalize()),
        (Vec3::Z, Vec3::new(0.0, 1.0, 1.0).normalize()),
        (Vec3::Z, Vec3::X),
        (Vec3::Z, -Vec3::Z),
    ];
    for &l1 in &LAMBDAS {
        for &l2 in &[1e-6f32, 2.133, 500.0, 1e4] {
            for &(a1, a2) in &dirs {
                let g1 = Sg::new(a1, l1, Vec3::new(1.0, 2.0, 0.5));
                let g2 = Sg::new(a2, l2, Vec3::splat(3.0));
                let p = g1.product(&g2);
                assert!(
                    p.mu.is_finite() && p.lambda.is_finite() && p.axis.is_finite(),
                    "{l1} {l2} {a2}"
                );
                assert!(p.mu.min_element() >= 0.0);
                // Pointwise: p(v) = g1(v) g2(v), compared in f64 on exponents (values may underflow).
                for v in [a1, a2, (a1 + a2).normalize_or(a1), Vec3::Y] {
                    let log_exact = f64::from(l1) * (f64::from(v.dot(a1)) - 1.0)
                        + f64::from(l2) * (f64::from(v.dot(a2)) - 1.0)
                        + 3f64.ln();
                    let got = f64::from(p.eval(v).x);
                    let exact = log_exact.exp();
                    // Absolute error relative to the peak: f32 axis/lambda rounding moves the exponent by
                    // about lambda * 1e-7.
                    let tol = 1e-4 * 3.0 + exact * 2e-7 * f64::from(l1 + l2) * 10.0;
                    assert!(
                        (got - exact).abs() <= tol,
                        "l1 {l1} l2 {l2} a2 {a2} v {v}: {got} vs {exact}"
                    );
                }
            }
        }
    }
}

#[test]
fn vmf_convolution_limits() {
    let g = Sg::new(Vec3::Z, sg::COSINE_LAMBDA, Vec3::splat(sg::COSINE_MU));
    let sharp = g.convolve_vmf(1e9);
    assert!((sharp.lambda - g.lambda).abs() < 1e-5 && (sharp.mu - g.mu).length() < 1e-4);
    let flat = g.convolve_vmf(1e-7);
    assert!(flat.lambda < 1e-6);
    let mean = g.integral().x / (4.0 * std::f32::consts::PI);
    assert!(
        (flat.mu.x - mean).abs() < 1e-4 * mean,
        "kappa -> 0 is the mean: {} vs {mean}",
        flat.mu.x
    );
    for kappa in [1e-3f32, 0.1, 1.0, 10.0, 1e4] {
        let c = g.convolve_vmf(kappa);
        assert!(
            (c.integral().x - g.integral().x).abs() < 1e-4 * g.integral().x,
            "kappa {kappa}"
        );
    }
    let _ = DVec3::ZERO;
}
