//! The viewer: a validated pinhole camera in world metres (x east, y north, z up).
//!
//! Positions are f64 so that a terrain placed 1e6 m from the origin loses nothing; every GPU-bound matrix is
//! built camera-relative ([`Camera::view_proj_relative`]) so vertex positions never carry large offsets.

use glam::{DMat4, DVec3, Mat4};

use crate::{Error, Result};

/// The default camera's distance to its target, in units of the terrain's larger extent.
pub const DEFAULT_VIEW_DISTANCE: f64 = 0.45;

/// How many times the typical relief ([`crate::source::Heightmap::typical_range`]) the height range must span
/// before the default camera aims at the typical relief instead.
pub const OUTLIER_STRETCH: f64 = 4.0;

/// A perspective camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position, metres.
    pub eye: DVec3,
    /// The point looked at, metres.
    pub target: DVec3,
    /// Which way is up on the screen: the camera's up is this direction made perpendicular to the look
    /// direction (world +z for a look-at camera, north (+y) for one looking straight down or up; any
    /// other for roll).
    pub up: DVec3,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f64,
    /// Near plane, metres.
    pub near: f64,
    /// Far plane, metres; infinite for an infinite far plane.
    pub far: f64,
    /// Reverse-Z: depth 1 at the near plane and 0 at the far one (or at infinity), compared with
    /// `Greater` and cleared to 0. Otherwise depth 0 at the near plane and 1 at the far one.
    pub reverse_z: bool,
    /// The width-to-height ratio of a projection given by the caller ([`Camera::from_matrices`]), which a
    /// viewport must match; None: the viewport's own.
    pub aspect: Option<f64>,
}

impl Camera {
    /// A camera at `eye` looking at `target`, checked: finite, distinct points, and a sane field of view.
    pub fn new(eye: DVec3, target: DVec3, fov_y_deg: f64) -> Result<Self> {
        if !eye.is_finite() {
            return Err(Error::camera(format!("eye position {eye} is not finite")));
        }
        if !target.is_finite() {
            return Err(Error::camera(format!(
                "look-at point {target} is not finite"
            )));
        }
        let dir = target - eye;
        if dir.length() < 1e-6 {
            return Err(Error::camera(
                "look direction has zero length (eye and look-at coincide)",
            ));
        }
        // World +z is the screen's up, except looking straight down or up, where it has no direction on
        // the screen: north (+y) is up there, as on a map (`with_up` sets another).
        let up = if dir.normalize().cross(DVec3::Z).length() < 1e-9 {
            DVec3::Y
        } else {
            DVec3::Z
        };
        check_fov(fov_y_deg)?;
        Ok(Self {
            eye,
            target,
            up,
            fov_y_deg,
            near: 1.0,
            far: 1.0e6,
            reverse_z: false,
            aspect: None,
        })
    }

    /// The same camera with `up` as the screen's up direction (rolled, or looking straight down with
    /// north or any other horizontal direction up): finite, and not along the look direction.
    pub fn with_up(mut self, up: DVec3) -> Result<Self> {
        if !(up.is_finite() && up.length() > 1e-12) {
            return Err(Error::camera(format!("up direction {up} is not a direction")));
        }
        if self.forward().cross(up.normalize()).length() < 1e-9 {
            return Err(Error::camera(format!(
                "up direction {up} lies along the look direction: the view has no defined up"
            )));
        }
        self.up = up.normalize();
        Ok(self)
    }

    /// The same camera with reverse-Z depth ([`Camera::reverse_z`]) on or off.
    pub fn with_reverse_z(mut self, reverse_z: bool) -> Self {
        self.reverse_z = reverse_z;
        self
    }

    /// The camera of a view matrix (world to view, right-handed, looking down -z, rigid: a rotation and a
    /// translation) and a perspective projection into wgpu's 0..1 depth, symmetric, with a finite or
    /// infinite far plane, conventional or reverse-Z: what glam's `perspective_rh`,
    /// `perspective_infinite_rh` and `perspective_infinite_reverse_rh` (and `perspective_rh` with the
    /// planes swapped) build. Anything else is refused with what differs.
    pub fn from_matrices(view: DMat4, proj: DMat4) -> Result<Self> {
        if !(view.is_finite() && proj.is_finite()) {
            return Err(Error::camera("a view or projection matrix is not finite"));
        }
        if !rigid(view) {
            return Err(Error::camera(
                "the view matrix is not a rotation and a translation (scale, shear or projection)",
            ));
        }
        let inv = view.inverse();
        let eye = inv.w_axis.truncate();
        let fwd = -inv.z_axis.truncate().normalize();
        let up = inv.y_axis.truncate().normalize();
        let (f, fx) = (proj.y_axis.y, proj.x_axis.x);
        let (a, b) = (proj.z_axis.z, proj.w_axis.z);
        let zero = [
            proj.x_axis.y, proj.x_axis.z, proj.x_axis.w, proj.y_axis.x, proj.y_axis.z, proj.y_axis.w,
            proj.z_axis.x, proj.z_axis.y, proj.w_axis.x, proj.w_axis.y, proj.w_axis.w,
        ];
        let perspective = f > 0.0
            && fx > 0.0
            && (proj.z_axis.w + 1.0).abs() < 1e-12
            && zero.iter().all(|e| e.abs() < 1e-12 * f.max(1.0));
        if !perspective {
            return Err(Error::camera(
                "the projection is not a symmetric right-handed perspective into 0..1 depth",
            ));
        }
        // Depth at distance d in front of the eye: z = -a + b / d (docs/engine.md "Depth").
        let (near, far, reverse_z) = if b > 0.0 {
            // 1 at the near plane, 0 at the far one (a = 0: infinitely far).
            (b / (1.0 + a), if a.abs() < 1e-12 { f64::INFINITY } else { b / a }, true)
        } else if b < 0.0 && a < 0.0 {
            // 0 at the near plane, 1 at the far one (a = -1: infinitely far).
            (b / a, if (a + 1.0).abs() < 1e-12 { f64::INFINITY } else { b / (1.0 + a) }, false)
        } else {
            return Err(Error::camera("the projection's depth terms give no near plane"));
        };
        let fov = 2.0 * (1.0 / f).atan().to_degrees();
        check_fov(fov)?;
        let mut cam = Self {
            eye,
            target: eye + fwd,
            up,
            fov_y_deg: fov,
            near: 1.0,
            far: 2.0,
            reverse_z,
            aspect: Some(f / fx),
        };
        cam = cam.with_clip(near, far)?;
        Ok(cam)
    }

    /// The same camera in the terrain's frame, for a camera given in the caller's world where the terrain
    /// is placed by `terrain_to_world` (rigid: a rotation, such as z up to y up, and a translation).
    pub fn in_terrain_frame(self, terrain_to_world: DMat4) -> Result<Self> {
        if !(terrain_to_world.is_finite() && rigid(terrain_to_world)) {
            return Err(Error::camera(
                "the terrain's placement is not a rotation and a translation",
            ));
        }
        let inv = terrain_to_world.inverse();
        Ok(Self {
            eye: inv.transform_point3(self.eye),
            target: inv.transform_point3(self.target),
            up: inv.transform_vector3(self.up).normalize(),
            ..self
        })
    }

    /// The default view of `hm`: an oblique look north across the terrain from above its southern part,
    /// close enough that its relief reads, derived from its extent and height range only (so it frames
    /// a flat, a tiny, a huge or a non-square terrain alike).
    ///
    /// The target is the centre, a tenth of the north-south extent ahead, at a third of the relief (the
    /// typical relief where outliers stretch the range past [`OUTLIER_STRETCH`] times it). The eye
    /// looks down at 28 degrees from [`DEFAULT_VIEW_DISTANCE`] times the larger extent, a little west of
    /// south so that north-south ridges do not line up with the view; it stays above the highest sample
    /// by a twentieth of the extent. A 60 degree vertical field of view then spans the whole width at the
    /// centre on a 16:9 frame; the clip planes are fitted to the terrain.
    pub fn default_for(hm: &crate::source::Heightmap) -> Result<Self> {
        let (ex, ey) = hm.extent_m();
        let (lo, hi) = hm.range();
        let (lo, hi) = (f64::from(lo), f64::from(hi));
        let size = ex.max(ey);
        let (ox, oy) = hm.origin();
        let o = DVec3::new(ox, oy, 0.0);
        // Outliers that stretch the range far past the typical relief (an untagged void 30 km down, a
        // spike) would aim the view at empty space: aim at the typical relief then. The hundredth of the
        // extent keeps a nearly flat terrain (typical relief ~0) on its own range.
        let (tlo, thi) = hm.typical_range();
        let (tlo, thi) = (f64::from(tlo), f64::from(thi));
        let (alo, ahi) = if hi - lo > OUTLIER_STRETCH * (thi - tlo) + 0.01 * size {
            (tlo, thi)
        } else {
            (lo, hi)
        };
        let target = o + DVec3::new(0.5 * ex, 0.6 * ey, alo + (ahi - alo) / 3.0);
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
        // The near plane: 1 mm, or a hundredth of the far one on a terrain a few centimetres across,
        // where 1 mm would lie past the far plane or in front of the whole view.
        Self::new(eye, target, 60.0)?.with_clip((far * 1e-5).max(1e-3).min(far * 1e-2), far)
    }

    /// Sets the clip planes (metres); `near` must be positive and below `far`, which may be infinite.
    pub fn with_clip(mut self, near: f64, far: f64) -> Result<Self> {
        if !(near.is_finite() && !far.is_nan() && near > 0.0 && far > near) {
            return Err(Error::camera(format!(
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

    /// The camera's right and up, unit vectors: right is forward x up, up is right x forward.
    pub fn basis(&self) -> (DVec3, DVec3) {
        let fwd = self.forward();
        let right = fwd.cross(self.up).normalize();
        (right, right.cross(fwd))
    }

    /// The view matrix for positions relative to the eye (world - eye).
    pub fn view_relative(&self) -> DMat4 {
        DMat4::look_to_rh(DVec3::ZERO, self.forward(), self.up)
    }

    /// The view matrix, world to view (right-handed, looking down -z).
    pub fn view(&self) -> DMat4 {
        DMat4::look_to_rh(self.eye, self.forward(), self.up)
    }

    /// The projection into wgpu's 0..1 depth: conventional or reverse-Z, with a finite or infinite far
    /// plane, at the caller's aspect when it gave one, else `aspect`.
    pub fn projection(&self, aspect: f64) -> DMat4 {
        let (fov, aspect) = (self.fov_y_deg.to_radians(), self.aspect.unwrap_or(aspect));
        match (self.reverse_z, self.far.is_finite()) {
            (false, true) => DMat4::perspective_rh(fov, aspect, self.near, self.far),
            (false, false) => DMat4::perspective_infinite_rh(fov, aspect, self.near),
            (true, true) => DMat4::perspective_rh(fov, aspect, self.far, self.near),
            (true, false) => DMat4::perspective_infinite_reverse_rh(fov, aspect, self.near),
        }
    }

    /// The conventional-depth projection of the same frustum (for its planes: [`crate::plan::cull`]).
    pub fn projection_conventional(&self, aspect: f64) -> DMat4 {
        Self {
            reverse_z: false,
            ..*self
        }
        .projection(aspect)
    }

    /// View-projection for positions given relative to the eye (world - eye), with wgpu's 0..1 depth.
    ///
    /// Translating by the eye in f64 before the f32 cast is what keeps far-from-origin terrain jitter-free.
    pub fn view_proj_relative(&self, aspect: f64) -> Mat4 {
        (self.projection(aspect) * self.view_relative()).as_mat4()
    }

    /// Pixels per metre of a segment seen face-on at distance `dist` on the screen's axis, viewport
    /// `height_px` tall (the focal length over the distance). Off the axis a vertical segment can project
    /// longer than this (by up to 1 / cos^2 of the angle off the axis): [`VerticalScale`] is the true one.
    pub fn pixels_per_metre(&self, dist: f64, height_px: u32) -> f64 {
        f64::from(height_px)
            / (2.0 * dist.max(self.near) * (self.fov_y_deg.to_radians() * 0.5).tan())
    }

    /// How this camera projects vertical segments on a `view` (width, height) viewport
    /// (docs/design.md "SAT LOD" 5).
    pub fn vertical_scale(&self, view: (u32, u32)) -> VerticalScale {
        let fwd = self.forward();
        let (right, up) = self.basis();
        let ty = (self.fov_y_deg.to_radians() * 0.5).tan();
        let tx = ty * self
            .aspect
            .unwrap_or(f64::from(view.0) / f64::from(view.1.max(1)));
        // |n| / q_z = g(s, t) at image point (s, t) = (q_x, q_y) / q_z is convex: largest at a corner.
        let max_slope = [(-tx, -ty), (tx, -ty), (-tx, ty), (tx, ty)]
            .iter()
            .map(|&(s, t)| slope_at(right.z, up.z, fwd.z, s, t))
            .fold(0.0, f64::max);
        VerticalScale {
            focal_px: f64::from(view.1) / (2.0 * ty),
            right,
            up,
            fwd,
            max_slope,
            min_cos: 1.0 / (1.0 + tx * tx + ty * ty).sqrt(),
            near: self.near,
        }
    }
}

/// The true projection of a vertical segment (docs/design.md "SAT LOD" 5): how many pixels a point moves on
/// the screen when its height is off by e.
///
/// A point q (camera space: x right, y up, z depth) and q + t v, v the world's up (v = (v_x, v_y, v_z);
/// v_x = 0 without roll), project f q_xy / q_z apart by f t (q_z v_xy - q_xy v_z) / (q_z (q_z + t v_z)),
/// f the focal length in pixels. The numerator n has |n| / q_z = g(s, t) = |(v_x - s v_z, v_y - t v_z)| at the
/// point's image-plane position (s, t) = (q_x, q_y) / q_z, a convex function of it. The longer of the two
/// directions (t = +e or -e) is f e |n| / (q_z (q_z - e |v_z|)) = f e g(s, t) / (q_z - e |v_z|). On the
/// screen's axis of a camera pitched by phi this is about f e cos(phi) / q_z; off the axis it exceeds
/// [`Camera::pixels_per_metre`] at the point's distance (by up to 1 / cos^2 of the angle).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VerticalScale {
    focal_px: f64,
    right: DVec3,
    up: DVec3,
    fwd: DVec3,
    /// The largest |n| / q_z over the frustum's rays (at one of its four corner rays).
    max_slope: f64,
    /// The smallest cosine between a frustum ray and the axis (at the corners): q_z >= |q| min_cos there.
    min_cos: f64,
    near: f64,
}

/// One corner of a box for [`VerticalScale::box_of`]: its depth and (|n| / q_z)^2 there (squared: the box
/// takes the largest of its corners' and one square root of that, the same value as the largest root, since
/// a correctly rounded square root never decreases; a split's 50 corners cost 16 roots instead of 50).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Corner {
    qz: f64,
    slope_sq: f64,
}

/// [`VerticalScale::box_max`]: a bound of the projected length of any vertical error in a box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxScale {
    /// f max(|n| / q_z), pixels.
    focal_slope: f64,
    /// The least depth q_z of a visible point, metres.
    depth: f64,
    /// |v_z|: how much a vertical segment changes the depth, per metre.
    vz: f64,
}

impl BoxScale {
    /// Pixels a metre of error moves a visible point of the box at most, to first order (f max(|n| /
    /// q_z) / min q_z): how the box's bounds scale from one view to another.
    pub fn per_metre(&self) -> f64 {
        self.focal_slope / self.depth
    }

    /// The most pixels a vertical error of at most `eta` metres moves a visible point of the box:
    /// f eta max(|n| / q_z) / (min q_z - eta |v_z|) (infinite when the error can reach the eye's depth).
    pub fn px(&self, eta: f64) -> f64 {
        let den = self.depth - eta * self.vz;
        if eta == 0.0 {
            0.0
        } else if den > 0.0 {
            self.focal_slope * eta / den
        } else {
            f64::INFINITY
        }
    }
}

impl VerticalScale {
    /// The pixels the point `rel` (relative to the eye) moves when its height is off by `e` metres, in the
    /// longer of the two directions (the measured error keeps no sign); the depth is taken at least the
    /// near plane (nearer points are clipped). [`VerticalScale::parts`] gives the same as two factors.
    pub fn px(&self, rel: DVec3, e: f64) -> f64 {
        let (s, c) = self.parts(rel);
        px_of_parts(s, c, e)
    }

    /// The point `rel`'s factors (s, c): the projected length of an error e there is e s / (1 - e c)
    /// ([`px_of_parts`]): s = f |n| / q_z^2 pixels per metre to first order, c = |v_z| / q_z per metre.
    pub fn parts(&self, rel: DVec3) -> (f64, f64) {
        let qz = self.fwd.dot(rel).max(self.near);
        let (qx, qy) = (self.right.dot(rel), self.up.dot(rel));
        let (vx, vy, vz) = (self.right.z, self.up.z, self.fwd.z);
        // An unrolled camera has v_x = 0 exactly: its term is written as it always was, so that its
        // plans stay the same bit for bit.
        let nx2 = if vx == 0.0 {
            qx * qx * vz * vz
        } else {
            (qz * vx - qx * vz).powi(2)
        };
        let n = (nx2 + (qz * vy - qy * vz).powi(2)).sqrt();
        (self.focal_px * n / (qz * qz), vz.abs() / qz)
    }

    /// A bound of [`VerticalScale::px`] over the points of the box [lo, hi] (relative to the eye) that
    /// lie in the view frustum, for every error up to some eta ([`BoxScale::px`]).
    ///
    /// - |n| / q_z is a convex function g of the image-plane position; a box wholly in front of the eye
    ///   projects onto the convex hull of its corners' images, so its largest value there is at a
    ///   corner; a visible point's is also at most the screen's largest (at a screen corner).
    /// - q_z is linear: its least value is at a corner; a visible point also has q_z >= near and
    ///   q_z >= |q| min_cos >= min_cos times the box's distance from the eye.
    pub fn box_max(&self, lo: DVec3, hi: DVec3) -> BoxScale {
        let mut corners = [Corner::default(); 8];
        for (i, c) in corners.iter_mut().enumerate() {
            let pick = |bit: usize, l: f64, h: f64| if i & bit == 0 { l } else { h };
            *c = self.corner(DVec3::new(
                pick(1, lo.x, hi.x),
                pick(2, lo.y, hi.y),
                pick(4, lo.z, hi.z),
            ));
        }
        self.box_of(&corners, DVec3::ZERO.clamp(lo, hi).length())
    }

    /// What [`VerticalScale::box_of`] needs of one corner `q` (relative to the eye) of a box.
    pub fn corner(&self, q: DVec3) -> Corner {
        let qz = self.fwd.dot(q);
        let inv = 1.0 / qz;
        Corner {
            qz,
            slope_sq: slope_sq_at(
                self.right.z,
                self.up.z,
                self.fwd.z,
                self.right.dot(q) * inv,
                self.up.dot(q) * inv,
            ),
        }
    }

    /// [`VerticalScale::box_max`] from the box's eight corners ([`VerticalScale::corner`]) and its
    /// distance from the eye `dist` (boxes that share corners compute them once).
    pub fn box_of(&self, corners: &[Corner; 8], dist: f64) -> BoxScale {
        let mut qz_min = f64::INFINITY;
        let mut slope_sq = 0.0f64;
        for c in corners {
            qz_min = qz_min.min(c.qz);
            slope_sq = slope_sq.max(c.slope_sq);
        }
        let slope = slope_sq.sqrt();
        let slope = if qz_min > 0.0 {
            slope.min(self.max_slope)
        } else {
            self.max_slope
        };
        BoxScale {
            focal_slope: self.focal_px * slope,
            depth: qz_min.max(dist * self.min_cos).max(self.near),
            vz: self.fwd.z.abs(),
        }
    }
}

/// |n| / q_z = |(v_x - s v_z, v_y - t v_z)| at image-plane position (s, t) ([`VerticalScale`]).
fn slope_at(vx: f64, vy: f64, vz: f64, s: f64, t: f64) -> f64 {
    slope_sq_at(vx, vy, vz, s, t).sqrt()
}

/// The square of [`slope_at`], whose root it is bit for bit.
fn slope_sq_at(vx: f64, vy: f64, vz: f64, s: f64, t: f64) -> f64 {
    // Not hypot: bounded terms, and libm's hypot was a seventh of a SAT LOD flight's plan time. The
    // square of -s v_z equals that of v_x - s v_z bit for bit when v_x = 0 (an unrolled camera).
    let (a, b) = (vx - s * vz, vy - t * vz);
    a * a + b * b
}

/// e s / (1 - e c) for [`VerticalScale::parts`] (s, c): infinite when the error reaches the eye's depth.
pub fn px_of_parts(s: f64, c: f64, e: f64) -> f64 {
    let den = 1.0 - e * c;
    if e == 0.0 {
        0.0
    } else if den > 0.0 {
        e * s / den
    } else {
        f64::INFINITY
    }
}

/// Whether `m` is a rotation and a translation (no scale, shear, reflection or projection), within
/// rounding.
fn rigid(m: DMat4) -> bool {
    let r = glam::DMat3::from_mat4(m);
    (r * r.transpose() - glam::DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .all(|e| e.abs() < 1e-6)
        && (r.determinant() - 1.0).abs() < 1e-6
        && (m.row(3) - glam::DVec4::W).length() < 1e-12
}

/// Refuses a vertical field of view outside (1, 179) degrees.
fn check_fov(fov_y_deg: f64) -> Result<()> {
    if fov_y_deg.is_finite() && fov_y_deg > 1.0 && fov_y_deg < 179.0 {
        Ok(())
    } else {
        Err(Error::camera(format!(
            "field of view {fov_y_deg} deg is not in (1, 179)"
        )))
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
        // Straight up (or down): north is the screen's up, not refused.
        assert_eq!(Camera::new(z, DVec3::Z, 60.0).map(|c| c.up).ok(), Some(DVec3::Y));
        assert!(Camera::new(z, DVec3::X, 0.0).is_err());
        assert!(Camera::new(z, DVec3::X, 60.0).is_ok());
        assert!(parse_vec3("eye", "1,2").is_err());
        assert!(parse_vec3("eye", "1,x,2").is_err());
        assert_eq!(
            parse_vec3("eye", "1, 2,3").ok(),
            Some(DVec3::new(1.0, 2.0, 3.0))
        );
    }

    /// A terrain a fraction of a millimetre across still gets a default view with its near plane in
    /// front of its far one (the 1 mm near plane lay past it).
    #[test]
    fn default_view_of_a_tiny_terrain() {
        for spacing in [1.0e-6, 1.0e-4, 30.0] {
            let hm = crate::source::Heightmap::new(
                std::path::Path::new("<tiny>"),
                3,
                3,
                spacing,
                vec![0.0, 1.0e-6, 0.0, 2.0e-6, 0.0, 1.0e-6, 0.0, 0.0, 0.0],
            )
            .expect("heights");
            let cam = Camera::default_for(&hm).expect("a default view");
            assert!(cam.near > 0.0 && cam.near < cam.far, "{spacing}: {cam:?}");
        }
    }

    /// The matrices a camera returns give back the same camera, in each depth convention, rolled or
    /// looking straight down.
    #[test]
    fn matrices_round_trip() {
        let eye = DVec3::new(100.0, -50.0, 800.0);
        let cams = [
            Camera::new(eye, DVec3::new(900.0, 400.0, 10.0), 50.0).expect("camera"),
            Camera::new(eye, DVec3::new(900.0, 400.0, 10.0), 50.0)
                .and_then(|c| c.with_up(DVec3::new(0.3, 0.0, 1.0)))
                .expect("rolled"),
            Camera::new(eye, eye + DVec3::X, 70.0)
                .expect("camera")
                .with_clip(0.5, f64::INFINITY)
                .expect("infinite"),
        ];
        let down = Camera::new(eye, eye - 500.0 * DVec3::Z, 60.0).expect("straight down, north up");
        assert_eq!(down.up, DVec3::Y);
        assert!(down.with_up(DVec3::Z).is_err(), "up along the look");
        let down = down.with_up(DVec3::X).expect("straight down, east up");
        for cam in cams.into_iter().chain([down]) {
            for reverse_z in [false, true] {
                let c = cam.with_reverse_z(reverse_z);
                let back = Camera::from_matrices(c.view(), c.projection(1.5)).expect("matrices");
                let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(1.0) || a == b;
                assert!((back.eye - c.eye).length() < 1e-9, "{back:?}");
                assert!((back.forward() - c.forward()).length() < 1e-12);
                assert!((back.basis().1 - c.basis().1).length() < 1e-12);
                assert!(close(back.fov_y_deg, c.fov_y_deg), "{back:?} {c:?}");
                assert!(close(back.near, c.near) && close(back.far, c.far), "{back:?} {c:?}");
                assert_eq!(back.reverse_z, reverse_z);
                assert!(close(back.aspect.unwrap_or(0.0), 1.5));
            }
        }
        let scaled = DMat4::from_scale(DVec3::splat(2.0)) * cams_view(eye);
        assert!(Camera::from_matrices(scaled, DMat4::perspective_rh(1.0, 1.0, 1.0, 10.0)).is_err());
        let ortho = DMat4::orthographic_rh(-1.0, 1.0, -1.0, 1.0, 1.0, 10.0);
        assert!(Camera::from_matrices(cams_view(eye), ortho).is_err());
    }

    fn cams_view(eye: DVec3) -> DMat4 {
        DMat4::look_to_rh(eye, DVec3::X, DVec3::Z)
    }

    /// A rolled camera's vertical scale is the projected length of a vertical segment, measured by
    /// projecting its two ends.
    #[test]
    fn rolled_vertical_scale_is_the_projected_length() {
        let eye = DVec3::new(0.0, 0.0, 500.0);
        let base = Camera::new(eye, DVec3::new(2000.0, 800.0, 0.0), 60.0).expect("camera");
        let view = (640, 360);
        for up in [DVec3::Z, DVec3::new(0.4, -0.2, 1.0), DVec3::new(1.0, 0.0, 0.2)] {
            let c = base.with_up(up).expect("up");
            let s = c.vertical_scale(view);
            let m = c.projection(640.0 / 360.0) * c.view_relative();
            let px = |p: DVec3| {
                let q = m * p.extend(1.0);
                DVec3::new(q.x / q.w * 320.0, q.y / q.w * 180.0, 0.0)
            };
            for p in [DVec3::new(1500.0, 700.0, -400.0), DVec3::new(900.0, -100.0, -480.0)] {
                let e = 0.5;
                let measured = (px(p + DVec3::Z * e) - px(p))
                    .length()
                    .max((px(p - DVec3::Z * e) - px(p)).length());
                let got = s.px(p, e);
                assert!((got / measured - 1.0).abs() < 1e-6, "{up}: {got} against {measured}");
            }
        }
    }

}
