//! The paper's Q-network, defined once: three identical convolution layers (F filters 3×3, 'same'
//! padding, ReLU), each followed by 2×2 average pooling; flatten; concatenate the scalar inputs
//! (speed, and d for the hybrid agent); two fully connected layers with ReLU; a linear output of
//! one Q value per action. [`NetShape`] gives its sizes and the name and shape of every parameter;
//! `fastnet` computes it and `reference` (candle) is the version it is tested against.

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
    /// Height and width after the three pooling layers.
    #[must_use]
    pub fn pooled(&self) -> (usize, usize) {
        (self.height / 8, self.width / 8)
    }

    /// Inputs of the first fully connected layer.
    #[must_use]
    pub fn flat(&self) -> usize {
        let (h, w) = self.pooled();
        self.filters * h * w + self.scalars
    }

    /// Every parameter: name and shape, in a fixed order.
    #[must_use]
    pub fn parameters(&self) -> Vec<(String, Vec<usize>)> {
        let (c, f, h) = (self.channels, self.filters, self.hidden);
        vec![
            ("conv1.weight".into(), vec![f, c, 3, 3]),
            ("conv1.bias".into(), vec![f]),
            ("conv2.weight".into(), vec![f, f, 3, 3]),
            ("conv2.bias".into(), vec![f]),
            ("conv3.weight".into(), vec![f, f, 3, 3]),
            ("conv3.bias".into(), vec![f]),
            ("fc1.weight".into(), vec![h, self.flat()]),
            ("fc1.bias".into(), vec![h]),
            ("fc2.weight".into(), vec![h, h]),
            ("fc2.bias".into(), vec![h]),
            ("q.weight".into(), vec![self.actions, h]),
            ("q.bias".into(), vec![self.actions]),
        ]
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
