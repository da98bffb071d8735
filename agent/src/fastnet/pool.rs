//! Bias, ReLU and 2×2 average pooling fused in one pass over a convolution's output (conv-out
//! layout, see `conv`), and its backward pass. Odd sizes drop the last row or column, as candle's
//! `avg_pool2d` does. The ReLU mask is recomputed from the kept pre-activations (branch-free), so
//! no activation is stored twice.

/// Where pooled values go: element (i, j, f) of the `hp × wp × f` output at
/// `base + i·row + j·col + f·chan` of the destination slice. The next layer's padded input and the
/// first dense layer's NCHW-flattened input are both such layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Strided {
    pub base: usize,
    pub row: usize,
    pub col: usize,
    pub chan: usize,
}

impl Strided {
    /// The interior of a padded image of width `wp` with `c` channels.
    #[must_use]
    pub fn padded(wp: usize, c: usize) -> Self {
        Self { base: (wp + 3) * c, row: (wp + 2) * c, col: c, chan: 1 }
    }

    /// An `h × w × c` image in conv-out layout (padded width `w + 2`).
    #[must_use]
    pub fn conv_out(w: usize, c: usize) -> Self {
        Self { base: 0, row: (w + 2) * c, col: c, chan: 1 }
    }

    /// The channel-major (`c × h × w`) flattening candle's NCHW layers use.
    #[must_use]
    pub fn channel_major(h: usize, w: usize) -> Self {
        Self { base: 0, row: w, col: 1, chan: h * w }
    }

    pub(super) fn at(&self, i: usize, j: usize) -> usize {
        self.base + i * self.row + j * self.col
    }
}

/// Pools `relu(pre + bias)` of one `h × w × c` image (`pre` in conv-out layout) into `out`.
pub fn forward(pre: &[f32], bias: &[f32], h: usize, w: usize, out: &mut [f32], to: Strided) {
    let c = bias.len();
    let pw = w + 2;
    let mut acc = vec![0f32; c];
    for i in 0..h / 2 {
        for j in 0..w / 2 {
            acc.fill(0.0);
            for (di, dj) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let p = ((2 * i + di) * pw + 2 * j + dj) * c;
                for ((a, &x), &b) in acc.iter_mut().zip(&pre[p..p + c]).zip(bias) {
                    *a += (x + b).max(0.0);
                }
            }
            let o = to.at(i, j);
            if to.chan == 1 {
                for (d, &a) in out[o..o + c].iter_mut().zip(&acc) {
                    *d = 0.25 * a;
                }
            } else {
                for (f, &a) in acc.iter().enumerate() {
                    out[o + f * to.chan] = 0.25 * a;
                }
            }
        }
    }
}

/// The backward pass of [`forward`] for one image: from the gradient of the pooled output (read
/// through `from`), writes the gradient of the pre-activation into the interior of the padded
/// buffer `grad_padded` (`(h + 2) × (w + 2) × c`, whose border stays zero) and adds the bias
/// gradient to `dbias`.
#[allow(clippy::too_many_arguments)]
pub fn backward(
    pre: &[f32],
    bias: &[f32],
    h: usize,
    w: usize,
    grad_out: &[f32],
    from: Strided,
    grad_padded: &mut [f32],
    dbias: &mut [f32],
) {
    let c = bias.len();
    let pw = w + 2;
    let mut g = vec![0f32; c];
    for i in 0..h / 2 {
        for j in 0..w / 2 {
            let o = from.at(i, j);
            if from.chan == 1 {
                for (d, &x) in g.iter_mut().zip(&grad_out[o..o + c]) {
                    *d = 0.25 * x;
                }
            } else {
                for (f, d) in g.iter_mut().enumerate() {
                    *d = 0.25 * grad_out[o + f * from.chan];
                }
            }
            for (di, dj) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let (y, x) = (2 * i + di, 2 * j + dj);
                let p = (y * pw + x) * c;
                let q = ((y + 1) * pw + x + 1) * c;
                for ((((d, db), &gv), &pre_v), &b) in
                    grad_padded[q..q + c].iter_mut().zip(dbias.iter_mut()).zip(&g).zip(&pre[p..p + c]).zip(bias)
                {
                    // ReLU's derivative as a multiply by 0 or 1.
                    let v = gv * f32::from(u8::from(pre_v + b > 0.0));
                    *d = v;
                    *db += v;
                }
            }
        }
    }
}
