//! The frame stack: the last N camera frames as one image of N·C channels, so that a network sees
//! motion (a braking leader, a car cutting in) that a single frame cannot show.
//!
//! Layout, shared with the learner's replay (which stores each frame once and stacks on
//! sampling): one image of the camera's width and height whose pixel p holds, for k = 0 (the
//! oldest) to N − 1 (the newest), frame k's C channels of pixel p — channel k·C + c is channel c
//! of frame k. At an episode's start the history is the first frame repeated.

use std::collections::VecDeque;

use super::image::Image;

/// Interleaves `frames` (oldest first, each `channels` bytes per pixel, all of one size) into
/// `out` in the stack's layout.
pub fn interleave_frames(frames: &[&[u8]], channels: usize, out: &mut Vec<u8>) {
    let n = frames.len();
    let frame_bytes = frames.first().map_or(0, |f| f.len());
    debug_assert!(frames.iter().all(|f| f.len() == frame_bytes), "frames of one size");
    out.clear();
    out.resize(n * frame_bytes, 0);
    if n == 1 {
        out.copy_from_slice(frames[0]);
        return;
    }
    for (k, frame) in frames.iter().enumerate() {
        for (p, px) in frame.chunks_exact(channels).enumerate() {
            let at = (p * n + k) * channels;
            out[at..at + channels].copy_from_slice(px);
        }
    }
}

/// The last `depth` frames of an episode and their stacked image.
#[derive(Debug, Clone)]
pub struct FrameStack {
    depth: usize,
    frames: VecDeque<Vec<u8>>,
    stacked: Image,
}

impl FrameStack {
    /// A stack of `depth` (≥ 1) frames, empty until [`FrameStack::reset`].
    #[must_use]
    pub fn new(depth: usize) -> Self {
        Self { depth: depth.max(1), frames: VecDeque::new(), stacked: Image::new(0, 0, 1) }
    }

    /// Starts an episode: the history is `first` repeated.
    pub fn reset(&mut self, first: &Image) {
        self.frames.clear();
        self.frames.extend((0..self.depth).map(|_| first.data.clone()));
        self.restack(first);
    }

    /// Adds the newest frame, dropping the oldest.
    pub fn push(&mut self, newest: &Image) {
        let mut recycled = self.frames.pop_front().unwrap_or_default();
        recycled.clear();
        recycled.extend_from_slice(&newest.data);
        self.frames.push_back(recycled);
        self.restack(newest);
    }

    fn restack(&mut self, like: &Image) {
        let frames: Vec<&[u8]> = self.frames.iter().map(Vec::as_slice).collect();
        let channels = usize::from(like.channels);
        self.stacked.width = like.width;
        self.stacked.height = like.height;
        self.stacked.channels = u8::try_from(channels * self.depth).expect("validated: stack × channels fits a byte");
        interleave_frames(&frames, channels, &mut self.stacked.data);
    }

    /// The stacked image.
    #[must_use]
    pub fn image(&self) -> &Image {
        &self.stacked
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(v: u8, channels: u8) -> Image {
        Image { width: 2, height: 1, channels, data: (0..2 * channels).map(|i| v * 10 + i).collect() }
    }

    #[test]
    fn stacks_oldest_first_interleaved_and_pads_with_the_first_frame() {
        let mut s = FrameStack::new(3);
        s.reset(&frame(1, 1));
        assert_eq!(s.image().data, [10, 10, 10, 11, 11, 11]);
        s.push(&frame(2, 1));
        assert_eq!(s.image().data, [10, 10, 20, 11, 11, 21]);
        s.push(&frame(3, 1));
        s.push(&frame(4, 1));
        assert_eq!(s.image().data, [20, 30, 40, 21, 31, 41]);
        assert_eq!((s.image().width, s.image().height, s.image().channels), (2, 1, 3));
        // RGB: each frame's three channels stay together.
        let mut rgb = FrameStack::new(2);
        rgb.reset(&frame(1, 3));
        rgb.push(&frame(2, 3));
        assert_eq!(rgb.image().data, [10, 11, 12, 20, 21, 22, 13, 14, 15, 23, 24, 25]);
    }

    #[test]
    fn a_single_frame_stack_is_the_frame() {
        let mut s = FrameStack::new(1);
        s.reset(&frame(1, 3));
        s.push(&frame(5, 3));
        assert_eq!(s.image(), &frame(5, 3));
    }
}
