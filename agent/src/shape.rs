//! The paper's Q-network, defined once: three identical convolution layers (F filters 3×3, 'same'
//! padding, ReLU), each followed by 2×2 average pooling; flatten; concatenate the scalar inputs
//! (speed, and d for the hybrid agent); two fully connected layers with ReLU; a linear output of
//! one Q value per action. [`NetShape`] gives its sizes and the name and shape of every parameter;
//! `fastnet` computes it and `reference` (candle) is the version it is tested against.
//!
//! A shape with no image (height, width and channels 0: [`NetShape::has_image`] is false) is the
//! same network without its convolution stack: a multilayer perceptron over the scalar inputs
//! alone (a vector observation's values are those inputs), fc1 `[hidden × scalars]` → ReLU → fc2
//! → ReLU → q. It has no convolution parameters, and fc1, fc2 and q keep their names. With an
//! image, vector values are more scalar inputs after the convolution features.

/// Sizes of the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NetShape {
    pub height: usize,
    pub width: usize,
    pub channels: usize,
    /// Scalar inputs besides the image.
    pub scalars: usize,
    pub actions: usize,
    pub filters: usize,
    pub hidden: usize,
}

impl NetShape {
    /// The multilayer perceptron over `scalars` inputs: the shape with no image.
    #[must_use]
    pub fn mlp(scalars: usize, hidden: usize, actions: usize) -> Self {
        Self { height: 0, width: 0, channels: 0, scalars, actions, filters: 0, hidden }
    }

    /// Whether the network has an image input and so its convolution stack; without one
    /// (a zero height, width or channel count) it is the multilayer perceptron over the scalar
    /// inputs (see the module's documentation).
    #[must_use]
    pub fn has_image(&self) -> bool {
        self.image_bytes() > 0
    }

    /// Bytes of one input image (`H × W × C`; 0 without an image).
    #[must_use]
    pub fn image_bytes(&self) -> usize {
        self.height * self.width * self.channels
    }

    /// Height and width after the three pooling layers ((0, 0) without an image).
    #[must_use]
    pub fn pooled(&self) -> (usize, usize) {
        if !self.has_image() {
            return (0, 0);
        }
        (self.height / 8, self.width / 8)
    }

    /// Inputs of the first fully connected layer.
    #[must_use]
    pub fn flat(&self) -> usize {
        let (h, w) = self.pooled();
        self.filters * h * w + self.scalars
    }

    /// Every parameter: name and shape, in a fixed order (the convolutions', where there is an
    /// image, then the dense layers').
    #[must_use]
    pub fn parameters(&self) -> Vec<(String, Vec<usize>)> {
        let (c, f, h) = (self.channels, self.filters, self.hidden);
        let conv = [
            ("conv1.weight".into(), vec![f, c, 3, 3]),
            ("conv1.bias".into(), vec![f]),
            ("conv2.weight".into(), vec![f, f, 3, 3]),
            ("conv2.bias".into(), vec![f]),
            ("conv3.weight".into(), vec![f, f, 3, 3]),
            ("conv3.bias".into(), vec![f]),
        ];
        let dense = [
            ("fc1.weight".into(), vec![h, self.flat()]),
            ("fc1.bias".into(), vec![h]),
            ("fc2.weight".into(), vec![h, h]),
            ("fc2.bias".into(), vec![h]),
            ("q.weight".into(), vec![self.actions, h]),
            ("q.bias".into(), vec![self.actions]),
        ];
        let conv = if self.has_image() { &conv[..] } else { &[] };
        conv.iter().cloned().chain(dense).collect()
    }

    /// The convolution layers' `(height, width, input channels)`, first to last (each output has
    /// `filters` channels at the same size; pooling halves the size for the next layer); none
    /// without an image.
    #[must_use]
    pub fn conv_layers(&self) -> Vec<(usize, usize, usize)> {
        if !self.has_image() {
            return Vec::new();
        }
        let (h, w) = (self.height, self.width);
        vec![(h, w, self.channels), (h / 2, w / 2, self.filters), (h / 4, w / 4, self.filters)]
    }

    /// Floating-point operations (a multiply-add counts 2) of one image's forward pass: the
    /// convolutions' and the dense layers' products, counted over the useful outputs only
    /// (biases, activations and pooling are left out). The figure the benchmarks divide by.
    /// Without an image, the dense layers' alone.
    #[must_use]
    pub fn forward_flops(&self) -> f64 {
        let conv: usize = self.conv_layers().iter().map(|&(h, w, c)| 2 * h * w * 9 * c * self.filters).sum();
        let dense = 2 * (self.flat() * self.hidden + self.hidden * self.hidden + self.hidden * self.actions);
        (conv + dense) as f64
    }

    /// Floating-point operations of one image's backward pass to every parameter's gradient:
    /// each convolution's kernel gradient, the input gradients of the second and third
    /// convolutions (the first needs none), and two products per dense layer; without an image,
    /// fc1's input gradient is not computed either (nothing is upstream of it).
    #[must_use]
    pub fn backward_flops(&self) -> f64 {
        let conv: usize = self
            .conv_layers()
            .iter()
            .enumerate()
            .map(|(l, &(h, w, c))| 2 * h * w * 9 * c * self.filters * if l == 0 { 1 } else { 2 })
            .sum();
        let fc1 = if self.has_image() { 4 } else { 2 } * self.flat() * self.hidden;
        let dense = fc1 + 4 * (self.hidden * self.hidden + self.hidden * self.actions);
        (conv + dense) as f64
    }

    /// The fan-in of the layer parameter `name` belongs to (weights: the product of all but the
    /// first dimension; biases: their layer's).
    #[must_use]
    pub fn fan_in(&self, name: &str) -> usize {
        match name.split('.').next().unwrap_or("") {
            "conv1" => self.channels * 9,
            "conv2" | "conv3" => self.filters * 9,
            "fc1" => self.flat(),
            _ => self.hidden,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_network_at_84x84_gray_costs_about_174_mflop_per_forward() {
        let s = NetShape { height: 84, width: 84, channels: 1, scalars: 2, actions: 6, filters: 64, hidden: 256 };
        // conv1 8.13, conv2 130.1, conv3 32.5, fc1 3.28, fc2 0.13 MFLOP.
        let conv = 2.0 * 64.0 * 9.0 * (84.0 * 84.0 + 42.0 * 42.0 * 64.0 + 21.0 * 21.0 * 64.0);
        let dense = 2.0 * (6402.0 * 256.0 + 256.0 * 256.0 + 256.0 * 6.0);
        assert_eq!(s.forward_flops(), conv + dense);
        assert!((s.forward_flops() / 1e6 - 174.1).abs() < 0.05, "{}", s.forward_flops());
        assert_eq!(s.backward_flops(), conv * 2.0 - 2.0 * 64.0 * 9.0 * 84.0 * 84.0 + 2.0 * dense);
    }

    #[test]
    fn the_mlp_has_dense_layers_only_and_their_flops() {
        let s = NetShape::mlp(150, 256, 27);
        assert!(!s.has_image() && s.conv_layers().is_empty() && s.pooled() == (0, 0));
        assert_eq!(s.flat(), 150);
        let names: Vec<String> = s.parameters().into_iter().map(|(n, _)| n).collect();
        assert_eq!(names, ["fc1.weight", "fc1.bias", "fc2.weight", "fc2.bias", "q.weight", "q.bias"]);
        assert_eq!(s.parameters()[0].1, [256, 150]);
        assert_eq!(s.parameters()[4].1, [27, 256]);
        // fc1 76.8, fc2 131.1, q 13.8 kFLOP per sample; backward: fc1's weight gradient only.
        let (fc1, rest) = (2.0 * 150.0 * 256.0, 2.0 * (256.0 * 256.0 + 256.0 * 27.0));
        assert_eq!(s.forward_flops(), fc1 + rest);
        assert_eq!(s.backward_flops(), fc1 + 2.0 * rest);
        assert_eq!((s.fan_in("fc1.weight"), s.fan_in("fc2.bias"), s.fan_in("q.weight")), (150, 256, 256));
        // Only a zero height, width or channel count means no image.
        assert!(NetShape { height: 8, width: 8, channels: 1, filters: 4, ..s }.has_image());
    }
}
