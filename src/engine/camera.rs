//! The embedding API: the camera of one frame, in the terrain's world metres.

use glam::DVec3;

use crate::plan::camera;
use crate::Result;

/// Where a frame is seen from, in world metres: x east, y north, z up, the terrain's grid placed by its
/// file (or at the origin). Checked when built: finite, a look direction that is not straight up or
/// down, a vertical field of view in (1, 179) degrees, and clip planes 0 < near < far.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera(pub(crate) camera::Camera);

impl Camera {
    /// A camera at `eye` looking at `target`, with a vertical field of view of `fov_y_deg` degrees and
    /// clip planes at 1 m and 1000 km.
    pub fn look_at(eye: [f64; 3], target: [f64; 3], fov_y_deg: f64) -> Result<Self> {
        camera::Camera::new(DVec3::from(eye), DVec3::from(target), fov_y_deg).map(Self)
    }

    /// The same camera with clip planes at `near` and `far` metres (0 < near < far).
    pub fn with_clip(self, near: f64, far: f64) -> Result<Self> {
        self.0.with_clip(near, far).map(Self)
    }

    /// The eye, world metres.
    pub fn eye(&self) -> [f64; 3] {
        self.0.eye.to_array()
    }

    /// The point looked at, world metres.
    pub fn target(&self) -> [f64; 3] {
        self.0.target.to_array()
    }
}

#[cfg(feature = "internals")]
impl Camera {
    /// The stages' camera.
    pub fn get(&self) -> &camera::Camera {
        &self.0
    }
}
