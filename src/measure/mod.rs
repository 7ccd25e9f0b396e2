//! Measurements of drawn frames (not the frame path): the projected screen-space error against the data,
//! cracks in the silhouette (and which are holes), the RMSE between two images. CPU only.

mod holes;
mod image;
mod oracle;
mod screen_error;
mod stitch;

pub use holes::{drawn_height, hole_pixels, ray_below_drawn_surface, Drawn, Holes, MAX_TRACED};
pub use image::{crack_pixels, image_rmse, CRACK_CLEAR, CRACK_CLEAR_RGBA8};
pub use oracle::{bound_oracle, oracle, FanGrain, Oracle};
pub use screen_error::{screen_error, MaxAt, ScreenError, SCREEN_ERROR_SAMPLES};
