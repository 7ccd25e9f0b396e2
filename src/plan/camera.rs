//! The viewer: a validated pinhole camera in world metres (x east, y north, z up).
//!
//! Positions are f64 so that a terrain placed 1e6 m from the origin loses nothing; every GPU-bound matrix is
//! built camera-relative ([`Camera::view_proj_relative`]) so vertex positions never carry large offsets.

use glam::{DMat4, DVec3, Mat4};

use crate::{Error, Result};

/// The default camera's distance to its target, in units of the terrain's larger extent.
pub const DEFAULT_VIEW_DISTANCE: f64 = 0.45;

/// A perspective camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position, metres.
    pub eye: DVec3,
    /// The point looked at, metres.
    pub target: DVec3,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f64,
    /// Near plane, metres.
    pub near: f64,
    /// Far plane, metres.
    pub far: f64,
}

impl Camera {
    /// A camera at `eye` looking at `target`, checked: finite, distinct points, and a sane field of view.
    pub fn new(eye: DVec3, target: DVec3, fov_y_deg: f64) -> Result<Self> {
        if !eye.is_finite() {
            return Err(Error::Camera(format!("eye position {eye} is not finite")));
        }
        if !target.is_finite() {
            return Err(Error::Camera(format!(
                "look-at point {target} is not finite"
            )));
        }
        let dir = target - eye;
        if dir.length() < 1e-6 {
            return Err(Error::Camera(
                "look direction has zero length (eye and look-at coincide)".into(),
            ));
        }
        if dir.normalize().cross(DVec3::Z).length() < 1e-9 {
            return Err(Error::Camera(
                "looking straight up or down: the view has no defined 'up'".into(),
            ));
        }
        if !(fov_y_deg.is_finite() && fov_y_deg > 1.0 && fov_y_deg < 179.0) {
            return Err(Error::Camera(format!(
                "field of view {fov_y_deg} deg is not in (1, 179)"
            )));
        }
        Ok(Self {
            eye,
            target,
            fov_y_deg,
            near: 1.0,
            far: 1.0e6,
        })
    }

    /// The default view of `hm`: an oblique look north across the terrain from above its southern part,
    /// close enough that its relief reads, derived from its extent and height range only (so it frames
    /// a flat, a tiny, a huge or a non-square terrain alike).
    ///
    /// The target is the centre, a tenth of the north-south extent ahead, at a third of the relief. The eye
    /// looks down at 28 degrees from [`DEFAULT_VIEW_DISTANCE`] times the larger extent, a little west of
    /// south so that north-south ridges do not line up with the view; it stays above the highest sample
    /// by a twentieth of the extent. A 60 degree vertical field of view then spans the whole width at the
    /// centre on a 16:9 frame; the clip planes are fitted to the terrain.
    pub fn default_for(hm: &crate::Heightmap) -> Result<Self> {
        let (ex, ey) = hm.extent_m();
        let (lo, hi) = hm.range();
        let (lo, hi) = (f64::from(lo), f64::from(hi));
        let size = ex.max(ey).max(1e-3);
        let (ox, oy) = hm.origin();
        let o = DVec3::new(ox, oy, 0.0);
        let target = o + DVec3::new(0.5 * ex, 0.6 * ey, lo + (hi - lo) / 3.0);
        let (dep, az) = (28f64.to_radians(), 12f64.to_radians());
        let dist = DEFAULT_VIEW_DISTANCE * size;
        let back = DVec3::new(-az.sin(), -az.cos(), 0.0) * (dist * dep.cos());
        let mut eye = target + back + DVec3::new(0.0, 0.0, dist * dep.sin());
        eye.z = eye.z.max(hi + 0.05 * size);
        let corners = [(0.0, 0.0), (ex, 0.0), (0.0, ey), (ex, ey)];
        let far = corners
            .iter()
            .map(|&(x, y)| (o + DVec3::new(x, y, lo) - eye).length())
            .fold(0.0, f64::max)
            * 1.5;
        Self::new(eye, target, 60.0)?.with_clip((far * 1e-5).max(1e-3), far)
    }

    /// Sets the clip planes (metres); `near` must be positive and below `far`.
    pub fn with_clip(mut self, near: f64, far: f64) -> Result<Self> {
        if !(near.is_finite() && far.is_finite() && near > 0.0 && far > near) {
            return Err(Error::Camera(format!(
                "clip planes near {near} m, far {far} m: need 0 < near < far"
            )));
        }
        self.near = near;
        self.far = far;
        Ok(self)
    }

    /// Unit look direction.
    pub fn forward(&self) -> DVec3 {
        (self.target - self.eye).normalize()
    }

    /// View-projection for positions given relative to the eye (world - eye), with wgpu's 0..1 depth.
    ///
    /// Translating by the eye in f64 before the f32 cast is what keeps far-from-origin terrain jitter-free.
    pub fn view_proj_relative(&self, aspect: f64) -> Mat4 {
        let view = DMat4::look_to_rh(DVec3::ZERO, self.forward(), DVec3::Z);
        let proj = DMat4::perspective_rh(self.fov_y_deg.to_radians(), aspect, self.near, self.far);
        (proj * view).as_mat4()
    }

    /// Pixels per metre of a vertical segment at distance `dist` on a viewport `height_px` tall.
    pub fn pixels_per_metre(&self, dist: f64, height_px: u32) -> f64 {
        f64::from(height_px)
            / (2.0 * dist.max(self.near) * (self.fov_y_deg.to_radians() * 0.5).tan())
    }
}

/// Parses `X,Y,Z` (metres); errors name the value `what` is.
pub fn parse_vec3(what: &str, text: &str) -> Result<DVec3> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let bad = |reason: String| Error::Invalid {
        what: what.into(),
        reason,
    };
    if parts.len() != 3 {
        return Err(bad(format!("`{text}` is not X,Y,Z")));
    }
    let mut v = [0.0; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        *slot = p
            .parse::<f64>()
            .map_err(|_| bad(format!("`{p}` in `{text}` is not a number")))?;
    }
    Ok(DVec3::from_array(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_bad_cameras() {
        let z = DVec3::ZERO;
        assert!(Camera::new(DVec3::new(f64::NAN, 0.0, 0.0), DVec3::X, 60.0).is_err());
        assert!(Camera::new(z, DVec3::new(0.0, f64::INFINITY, 0.0), 60.0).is_err());
        assert!(Camera::new(z, z, 60.0).is_err());
        assert!(Camera::new(z, DVec3::Z, 60.0).is_err());
        assert!(Camera::new(z, DVec3::X, 0.0).is_err());
        assert!(Camera::new(z, DVec3::X, 60.0).is_ok());
        assert!(parse_vec3("eye", "1,2").is_err());
        assert!(parse_vec3("eye", "1,x,2").is_err());
        assert_eq!(
            parse_vec3("eye", "1, 2,3").ok(),
            Some(DVec3::new(1.0, 2.0, 3.0))
        );
    }
}
