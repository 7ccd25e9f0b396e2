//! Shading maths: spherical Gaussians (SG) and the vMF normal distribution, shared by the CPU twin of the
//! fragment shader ([`crate::shading`]) and, line for line, by its WGSL port.
//!
//! An SG is G(v) = mu exp(lambda (v . axis - 1)) (Wang et al. 2009, "All-frequency rendering of dynamic,
//! spatially-varying reflectance", section 3). Written with the `- 1` inside the exponent it never
//! overflows: the exponent is always in [-2 lambda, 0].
//!
//! Everything here is f32 and avoids functions WGSL lacks: [`expm1`] and [`ln_1p`] are spelled out with a
//! short series near zero so the GPU port computes the same values.

use glam::Vec3;

/// The clamped cosine max(v . n, 0) as one SG about n: lambda = 2.133, mu = 1.170 (Wang et al. 2009,
/// the fit they use for the cosine factor). Its peak is 17 % high and it has a tail below the
/// tangent plane (0.138 at 90 degrees); [`crate::shading`] cuts the tail at the mean normal's plane.
pub const COSINE_LAMBDA: f32 = 2.133;
/// Amplitude of the clamped-cosine SG; see [`COSINE_LAMBDA`].
pub const COSINE_MU: f32 = 1.170;

/// Smallest mean-normal length |r| used for the vMF: below it the mean direction is noise and kappa
/// (about 1.5e-3) already makes the distribution uniform to 0.1 %, so nothing is lost by clamping; it also
/// keeps r / |r| away from a division by zero.
pub const R_MIN: f32 = 1e-3;
/// Largest mean-normal length |r|: kappa = (3 |r| - |r|^3) / (1 - |r|^2) reaches 1e4 here, the sharpest
/// lobe the shading supports, and 1 - |r|^2 = 2e-4 is still 3000 f32 ulps above zero, so the rounding of a
/// SAT-averaged r (about 1e-7 relative) moves kappa by under 0.1 %. Unclamped, |r| = 1 divides by zero.
pub const R_MAX: f32 = 1.0 - 1e-4;

/// e^x - 1 without cancellation near 0, in a form WGSL can copy (it has no expm1): a 4-term Taylor series
/// for |x| < 1e-2 (truncation under 1e-10 relative), `exp(x) - 1` elsewhere (cancellation then costs at
/// most 100 ulps of 1, i.e. 1e-5 relative to x = 1e-2).
pub fn expm1(x: f32) -> f32 {
    if x.abs() < 1e-2 {
        x * (1.0 + x * (0.5 + x * (1.0 / 6.0 + x * (1.0 / 24.0))))
    } else {
        x.exp() - 1.0
    }
}

/// ln(1 + x) without cancellation near 0, WGSL-portable like [`expm1`]: series for |x| < 1e-2.
pub fn ln_1p(x: f32) -> f32 {
    if x.abs() < 1e-2 {
        x * (1.0 - x * (0.5 - x * (1.0 / 3.0 - x * 0.25)))
    } else {
        (1.0 + x).ln()
    }
}

/// (1 - e^(-x)) / x for x >= 0, exact as x -> 0 (-> 1): the normalisation of every SG integral.
pub fn one_minus_exp_over(x: f32) -> f32 {
    if x < 1e-6 {
        1.0 - 0.5 * x
    } else {
        -expm1(-x) / x
    }
}

/// A spherical Gaussian: G(v) = mu exp(lambda (v . axis - 1)), RGB amplitude.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sg {
    /// Lobe direction, unit length.
    pub axis: Vec3,
    /// Sharpness, >= 0 (0 is a constant over the sphere).
    pub lambda: f32,
    /// Amplitude per colour channel (the value at the axis).
    pub mu: Vec3,
}

impl Sg {
    /// An SG; `axis` is normalised (a zero axis is a caller bug).
    pub fn new(axis: Vec3, lambda: f32, mu: Vec3) -> Self {
        let axis = axis.normalize();
        assert!(axis.is_finite(), "SG axis must be non-zero and finite");
        assert!(lambda >= 0.0, "SG sharpness {lambda} must be >= 0");
        Self { axis, lambda, mu }
    }

    /// An SG whose integral over the sphere is `total` per channel.
    pub fn with_integral(axis: Vec3, lambda: f32, total: Vec3) -> Self {
        Self::new(axis, lambda, total / unit_integral(lambda))
    }

    /// G(v); v must be unit length. The exponent is in [-2 lambda, 0]: no overflow.
    pub fn eval(&self, v: Vec3) -> Vec3 {
        self.mu * (self.lambda * (v.dot(self.axis) - 1.0)).exp()
    }

    /// The integral over the sphere, 2 pi mu (1 - e^(-2 lambda)) / lambda, -> 4 pi mu as lambda -> 0.
    pub fn integral(&self) -> Vec3 {
        self.mu * unit_integral(self.lambda)
    }

    /// The product of two SGs is an SG (Wang et al. 2009, section 3):
    /// axis = (l1 a1 + l2 a2) / |l1 a1 + l2 a2|, lambda = |l1 a1 + l2 a2|, mu = mu1 mu2 e^(lambda - l1 - l2).
    ///
    /// The raw exponents, e^(lambda) and e^(-l1 - l2), overflow f32 beyond about 88; the combined exponent
    /// lambda - (l1 + l2) is the largest one subtracted from the rest and is <= 0 (triangle inequality), so
    /// the amplitude stays finite for any sharpness.
    pub fn product(&self, other: &Self) -> Self {
        let s = self.axis * self.lambda + other.axis * other.lambda;
        let lambda = s.length();
        // Opposite lobes of equal sharpness: the product is a constant e^(-2 l), any axis will do.
        let axis = if lambda > 1e-20 {
            s / lambda
        } else {
            self.axis
        };
        let exponent = (lambda - (self.lambda + other.lambda)).min(0.0);
        Self {
            axis,
            lambda,
            mu: self.mu * other.mu * exponent.exp(),
        }
    }

    /// This SG convolved with a vMF of concentration `kappa` (unit mass), approximated by an SG:
    /// lambda' = lambda kappa / (lambda + kappa) (the angular variances 1/lambda add, as for vMF lobes in Han et
    /// al. 2007, "Frequency domain normal map filtering"), mu' chosen so the integral is unchanged
    /// (a unit-mass convolution preserves it). Exact in the limits kappa -> infinity and kappa -> 0 (a
    /// constant equal to the mean).
    pub fn convolve_vmf(&self, kappa: f32) -> Self {
        if kappa == f32::INFINITY {
            return *self;
        }
        let lambda = self.lambda * kappa / (self.lambda + kappa).max(1e-30);
        let mu = self.mu * (unit_integral(self.lambda) / unit_integral(lambda));
        Self {
            axis: self.axis,
            lambda,
            mu,
        }
    }
}

/// The integral of an SG with unit amplitude: 2 pi (1 - e^(-2 lambda)) / lambda = 4 pi (1 - e^(-2l))/(2l).
pub fn unit_integral(lambda: f32) -> f32 {
    4.0 * std::f32::consts::PI * one_minus_exp_over(2.0 * lambda)
}

/// The vMF distribution of normals recovered from an unnormalised mean normal r (SAT paper section 5,
/// algorithm 2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vmf {
    /// Mean direction r / |r| (+z when r is zero).
    pub axis: Vec3,
    /// Concentration kappa.
    pub kappa: f32,
    /// |r| after clamping into [[`R_MIN`], [`R_MAX`]].
    pub r_len: f32,
}

impl Vmf {
    /// mu = r / |r|, kappa from [`kappa_from_mean_length`] with |r| clamped into [R_MIN, R_MAX].
    pub fn from_mean_normal(r: Vec3) -> Self {
        let len = r.length();
        let axis = if len > 1e-30 && r.is_finite() {
            r / len
        } else {
            Vec3::Z
        };
        let r_len = len.clamp(R_MIN, R_MAX);
        Self {
            axis,
            kappa: kappa_from_mean_length(r_len),
            r_len,
        }
    }
}

/// kappa = (3 |r| - |r|^3) / (1 - |r|^2), Banerjee et al. 2005 ("Clustering on the unit hypersphere using
/// von Mises-Fisher distributions", JMLR 6, the approximation for dimension p = 3), the approximate inverse of the mean
/// resultant length A3(kappa) = coth(kappa) - 1/kappa. `tests/cpu/sg_numerics.rs` measures it against the
/// (1 - |r|^3)-denominator variant of the seed text. Callers clamp |r| into [R_MIN, R_MAX].
pub fn kappa_from_mean_length(r_len: f32) -> f32 {
    let r = r_len.clamp(R_MIN, R_MAX);
    r * (3.0 - r * r) / ((1.0 - r) * (1.0 + r))
}

/// An orthonormal basis (t, b) completing unit n, branch-free apart from the sign (Duff et al. 2017,
/// "Building an orthonormal basis, revisited", JCGT 6(1), listing 3).
pub fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_is_orthonormal() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.2).normalize(),
        ] {
            let (t, b) = basis(n);
            assert!((t.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
            assert!(t.dot(b).abs() < 1e-6 && t.dot(n).abs() < 1e-6 && b.dot(n).abs() < 1e-6);
            assert!((t.cross(b) - n).length() < 1e-5, "right-handed for {n}");
        }
    }
}
