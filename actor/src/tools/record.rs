//! Writing what the sensors see to disk: numbered PNGs per step, and optionally an animated GIF of
//! the front camera per run.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use sim_core::camera::Image;

/// Writes an image as PNG (gray or RGB, 8 bits).
pub fn write_png(path: &Path, img: &Image) -> Result<()> {
    let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut enc = png::Encoder::new(BufWriter::new(file), img.width, img.height);
    enc.set_color(if img.channels == 1 { png::ColorType::Grayscale } else { png::ColorType::Rgb });
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().with_context(|| format!("writing {}", path.display()))?;
    w.write_image_data(&img.data).with_context(|| format!("writing {}", path.display()))?;
    w.finish().with_context(|| format!("finishing {}", path.display()))?;
    Ok(())
}

/// Records one run: `DIR/front_00000.png`, `DIR/bev_00000.png`, … and, if asked, `DIR/front.gif`.
#[derive(Debug)]
pub struct RunRecorder {
    dir: PathBuf,
    frames: Vec<Image>,
    gif: bool,
}

impl RunRecorder {
    /// Creates the run's directory.
    pub fn new(dir: PathBuf, gif: bool) -> Result<Self> {
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Self { dir, frames: Vec::new(), gif })
    }

    /// Writes the frames of step `k`.
    pub fn frame(&mut self, k: u32, front: &Image, bev: &Image) -> Result<()> {
        write_png(&self.dir.join(format!("front_{k:05}.png")), front)?;
        write_png(&self.dir.join(format!("bev_{k:05}.png")), bev)?;
        if self.gif {
            self.frames.push(front.clone());
        }
        Ok(())
    }

    /// Writes the GIF, if asked for.
    pub fn finish(self) -> Result<()> {
        if !self.gif || self.frames.is_empty() {
            return Ok(());
        }
        let path = self.dir.join("front.gif");
        let first = &self.frames[0];
        let file = File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        let (w, h) = (u16::try_from(first.width)?, u16::try_from(first.height)?);
        let mut enc = gif::Encoder::new(BufWriter::new(file), w, h, &[]).with_context(|| format!("writing {}", path.display()))?;
        enc.set_repeat(gif::Repeat::Infinite)?;
        for img in &self.frames {
            let rgb: Vec<u8> = if img.channels == 1 { img.data.iter().flat_map(|&g| [g, g, g]).collect() } else { img.data.clone() };
            // 10 fps, the simulation's rate.
            let mut frame = gif::Frame::from_rgb_speed(w, h, &rgb, 10);
            frame.delay = 10;
            enc.write_frame(&frame).with_context(|| format!("writing {}", path.display()))?;
        }
        Ok(())
    }
}
