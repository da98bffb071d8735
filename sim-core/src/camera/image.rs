//! [`Image`]: the 8-bit frames both renderers write and the observation carries.

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
        crate::hash::fnv1a64(&self.data)
    }
}
