//! The frame stack: the last N camera frames as one image of N·C channels, so that a network sees
//! motion (a braking leader, a car cutting in) that a single frame cannot show.
//!
//! Layout, shared with the learner's replay (which stores each frame once and stacks on
//! sampling): one image of the camera's width and height whose pixel p holds, for k = 0 (the
//! oldest) to N − 1 (the newest), frame k's C channels of pixel p — channel k·C + c is channel c
//! of frame k. At an episode's start the history is the first frame repeated.

use std::collections::VecDeque;

use super::image::Image;

/// Appends to `out` the frames of a stack, interleaved per pixel.
///
/// Each frame is H·W·C bytes, row-major, its C channels interleaved per pixel (the camera's
/// layout). The result is H·W·N·C bytes, row-major, with N·C channels per pixel: for pixel `p`,
/// channel `k·C + c` is channel `c` of `frames[k]`. `frames[0]` is the OLDEST frame of the stack
/// and `frames[N − 1]` the newest (the current observation); where an episode has fewer than N
/// frames so far, the missing older ones are copies of its first frame. With one frame the result
/// is that frame's bytes unchanged.
///
/// # Panics
/// If `channels` is 0, or the frames differ in length or are not whole pixels of `channels`.
pub fn interleave_frames(frames: &[&[u8]], channels: usize, out: &mut Vec<u8>) {
    assert!(channels > 0, "a frame has at least one channel");
    let Some(first) = frames.first() else { return };
    let len = first.len();
    assert!(
        len.is_multiple_of(channels) && frames.iter().all(|f| f.len() == len),
        "frames of a stack are whole pixels of {channels} channels, all of one size"
    );
    if frames.len() == 1 {
        out.extend_from_slice(first);
        return;
    }
    let stride = frames.len() * channels;
    let start = out.len();
    out.resize(start + len * frames.len(), 0);
    let dst = &mut out[start..];
    for (k, frame) in frames.iter().enumerate() {
        for (pixel, src) in dst.chunks_exact_mut(stride).zip(frame.chunks_exact(channels)) {
            pixel[k * channels..(k + 1) * channels].copy_from_slice(src);
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
        self.stacked.data.clear();
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

    #[test]
    fn channels_of_each_pixel_are_the_frames_oldest_first() {
        // Two pixels of three channels; frame k's channel c of pixel p is 100·k + 10·p + c.
        let frames: Vec<Vec<u8>> = (0..3u8).map(|k| (0..2u8).flat_map(|p| (0..3u8).map(move |c| 100 * k + 10 * p + c)).collect()).collect();
        let refs: Vec<&[u8]> = frames.iter().map(Vec::as_slice).collect();
        let mut out = vec![9];
        interleave_frames(&refs, 3, &mut out);
        #[rustfmt::skip]
        let expected = [
            9,
            0, 1, 2, 100, 101, 102, 200, 201, 202,
            10, 11, 12, 110, 111, 112, 210, 211, 212,
        ];
        assert_eq!(out, expected, "appended after what `out` held");
    }

    #[test]
    fn one_frame_is_copied_unchanged() {
        let frame = [1u8, 2, 3, 4, 5, 6];
        let mut out = Vec::new();
        interleave_frames(&[&frame], 3, &mut out);
        assert_eq!(out, frame);
        interleave_frames(&[], 3, &mut out);
        assert_eq!(out, frame, "no frames, nothing appended");
    }
}
