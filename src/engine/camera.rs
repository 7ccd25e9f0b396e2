//! The embedding API: the camera of one frame, in the terrain's world metres.

use glam::{DMat4, DVec3};

use crate::plan::camera;
use crate::Result;

/// Where a frame is seen from, in the terrain's frame: metres, x east, y north, z up, the grid placed by
/// its file (or at the origin). Checked when built: finite, an up direction that is not along the look
/// direction, a vertical field of view in (1, 179) degrees, and clip planes 0 < near < far (far may be
/// infinite).
///
/// An engine gives its own matrices ([`Camera::from_matrices`]), in a world where the terrain is placed
/// by a rigid transform, any axis up ([`Camera::in_terrain_frame`]), and reads back the matrices the
/// terrain is drawn with ([`Camera::view_matrix`], [`Camera::projection_matrix`]) to draw its own
/// geometry in the same pass. Matrices are column-major `[[f64; 4]; 4]` (glam's `DMat4::to_cols_array_2d`),
/// into wgpu's 0..1 depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera(pub(crate) camera::Camera);

impl Camera {
    /// A camera at `eye` looking at `target`, with a vertical field of view of `fov_y_deg` degrees and
    /// clip planes at 1 m and 1000 km. The screen's up is world +z, or north (+y) for a look straight
    /// down or up ([`Camera::with_up`] sets another).
    pub fn look_at(eye: [f64; 3], target: [f64; 3], fov_y_deg: f64) -> Result<Self> {
        camera::Camera::new(DVec3::from(eye), DVec3::from(target), fov_y_deg).map(Self)
    }

    /// The same camera with clip planes at `near` and `far` metres (0 < near < far; `f64::INFINITY` for an
    /// infinite far plane).
    pub fn with_clip(self, near: f64, far: f64) -> Result<Self> {
        self.0.with_clip(near, far).map(Self)
    }

    /// The same camera with `up` as the screen's up direction: a roll, or a look straight down with, for
    /// example, north up. Refused along the look direction.
    pub fn with_up(self, up: [f64; 3]) -> Result<Self> {
        self.0.with_up(DVec3::from(up)).map(Self)
    }

    /// The same camera with reverse-Z depth (1 at the near plane, 0 at the far one or at infinity;
    /// compared with `Greater`, cleared to 0), which [`crate::RenderOptions::reverse_z`] must match.
    pub fn with_reverse_z(self, reverse_z: bool) -> Self {
        Self(self.0.with_reverse_z(reverse_z))
    }

    /// The engine's camera: a view matrix (world to view, right-handed, looking down -z; a rotation and a
    /// translation) and a symmetric perspective projection into 0..1 depth, conventional or reverse-Z,
    /// with a finite or infinite far plane (as glam's `perspective_rh`, `perspective_infinite_rh` and
    /// `perspective_infinite_reverse_rh` build them). The projection's aspect must then match each
    /// frame's viewport. Anything else is refused with what differs.
    pub fn from_matrices(view: [[f64; 4]; 4], projection: [[f64; 4]; 4]) -> Result<Self> {
        camera::Camera::from_matrices(
            DMat4::from_cols_array_2d(&view),
            DMat4::from_cols_array_2d(&projection),
        )
        .map(Self)
    }

    /// A camera given in the engine's world, where the terrain's frame is placed by `terrain_to_world` (a
    /// rotation and a translation: for a y-up world, the rotation taking z to y), moved into the
    /// terrain's frame. Draw the terrain's frames with the result; the engine's own geometry keeps the
    /// engine's matrices.
    pub fn in_terrain_frame(self, terrain_to_world: [[f64; 4]; 4]) -> Result<Self> {
        self.0
            .in_terrain_frame(DMat4::from_cols_array_2d(&terrain_to_world))
            .map(Self)
    }

    /// The view matrix the terrain is drawn with (terrain frame to view), column-major.
    pub fn view_matrix(&self) -> [[f64; 4]; 4] {
        self.0.view().to_cols_array_2d()
    }

    /// The projection the terrain is drawn with in a `viewport` of (width, height) pixels, column-major.
    pub fn projection_matrix(&self, viewport: (u32, u32)) -> [[f64; 4]; 4] {
        let aspect = f64::from(viewport.0) / f64::from(viewport.1.max(1));
        self.0.projection(aspect).to_cols_array_2d()
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

    /// The public camera of a stages' camera (already checked when it was built).
    pub fn from_stage(camera: camera::Camera) -> Self {
        Self(camera)
    }
}
