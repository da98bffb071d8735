//! Sensors rendered on the CPU with no display: the front camera the agent drives from and a
//! bird's-eye debug view. Both are deterministic: the same scene gives the same bytes.

mod birdseye;
mod front;
mod image;
mod palette;
pub(crate) mod scene;

pub use birdseye::{BirdsEye, BirdsEyeConfig};
pub use front::{Camera, CameraConfig};
pub use image::Image;
pub use scene::{CAR_HEIGHT, SceneBox, car_box, prop_box, walker_box};
