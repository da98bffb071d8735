//! The layout of a frame stack: N camera frames of H×W pixels with C channels each, handed to
//! the network as ONE image of H×W pixels with N·C channels. The replay assembles it when
//! sampling and the environment must assemble the same when acting, so the layout lives here, once.

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

#[cfg(test)]
mod tests {
    use super::*;

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
