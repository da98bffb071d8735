//! Sensors rendered on the CPU with no display: the front camera the agent drives from and a
//! bird's-eye debug view. Both are deterministic: the same scene gives the same bytes.

mod birdseye;
mod frame_stack;
mod front;
mod image;
mod palette;
pub(crate) mod scene;

pub use birdseye::{BirdsEye, BirdsEyeConfig};
pub use frame_stack::{FrameStack, interleave_frames};
pub use front::{Camera, CameraConfig, MAX_STACK};
pub use image::Image;
pub use scene::{CAR_HEIGHT, SceneBox, car_box, prop_box, walker_box};
