//! Sensors rendered on the CPU with no display: the front camera the agent drives from and a
//! bird's-eye debug view. Both are deterministic: the same scene gives the same bytes.

mod birdseye;
pub(crate) mod front;
pub(crate) mod palette;

pub use birdseye::{BirdsEye, BirdsEyeConfig};
pub use front::{Camera, CameraConfig, car_box};

use crate::collision::Obb;

/// An 8-bit image, row-major, `channels` bytes per pixel (1 = gray, 3 = RGB), top row first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub channels: u8,
    pub data: Vec<u8>,
}

impl Image {
    /// An image of zeros.
    #[must_use]
    pub fn new(width: u32, height: u32, channels: u8) -> Self {
        Self { width, height, channels, data: vec![0; width as usize * height as usize * channels as usize] }
    }

    /// The pixel at column `x`, row `y` (gray images repeat the value).
    #[must_use]
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = (y as usize * self.width as usize + x as usize) * self.channels as usize;
        if self.channels == 1 { [self.data[i]; 3] } else { [self.data[i], self.data[i + 1], self.data[i + 2]] }
    }

    /// 64-bit FNV-1a hash of the pixels, for determinism checks.
    #[must_use]
    pub fn hash(&self) -> u64 {
        self.data.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
    }
}

/// A box standing on the ground (or floating, like an overpass deck) for the renderers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneBox {
    pub footprint: Obb,
    /// Height of the bottom face, metres.
    pub bottom: f32,
    /// Height of the top face, metres.
    pub top: f32,
    pub colour: [u8; 3],
}

/// Height of a car's body, metres.
pub const CAR_HEIGHT: f32 = 1.5;
