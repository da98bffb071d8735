//! What `learner bench train` times: the network of an image input `WIDTHxHEIGHTxCHANNELS` (the
//! convolutional Q-network) or of a vector input `vector:N` (the multilayer perceptron over N
//! values, `NetShape::has_image` false), parsed from `--input`.

use std::fmt;

use agent::NetShape;
use agent::config::AgentConfig;

/// A benchmark's input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    Image {
        width: usize,
        height: usize,
        channels: usize,
    },
    /// A vector observation of this many values: the network's scalar inputs, and its only ones.
    Vector(usize),
}

impl Input {
    /// The network for this input with `actions` outputs and `agent`'s filters and hidden units;
    /// an image also gets the paper's two scalar inputs.
    #[must_use]
    pub fn shape(&self, actions: usize, agent: &AgentConfig) -> NetShape {
        match *self {
            Self::Image { width, height, channels } => {
                NetShape { height, width, channels, scalars: 2, actions, filters: agent.conv_filters, hidden: agent.hidden }
            }
            Self::Vector(n) => NetShape::mlp(n, agent.hidden, actions),
        }
    }
}

impl fmt::Display for Input {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Image { width, height, channels } => write!(f, "{width}x{height}x{channels}"),
            Self::Vector(n) => write!(f, "vector:{n}"),
        }
    }
}

/// Parses `WxHxC` (e.g. `84x84x3`) or `vector:N` (e.g. `vector:150`).
pub fn parse_input(s: &str) -> Result<Input, String> {
    if let Some(n) = s.strip_prefix("vector:") {
        return match n.parse::<usize>() {
            Ok(n) if (1..=65536).contains(&n) => Ok(Input::Vector(n)),
            _ => Err(format!("`{s}`: vector:N takes N in 1..=65536")),
        };
    }
    let parts: Vec<&str> = s.split('x').collect();
    let [w, h, c] = parts.as_slice() else {
        return Err(format!("`{s}` is not WIDTHxHEIGHTxCHANNELS (e.g. 84x84x3) or vector:N (e.g. vector:150)"));
    };
    let num = |v: &str| v.parse::<usize>().map_err(|_| format!("`{v}` in `{s}` is not a whole number"));
    let (width, height, channels) = (num(w)?, num(h)?, num(c)?);
    if !(8..=1024).contains(&width) || !(8..=1024).contains(&height) || !(channels == 1 || channels == 3) {
        return Err(format!("`{s}`: width and height must be 8..=1024 and channels 1 or 3"));
    }
    Ok(Input::Image { width, height, channels })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn images_and_vectors_parse_and_print_back() {
        for s in ["84x84x3", "48x64x1", "vector:150"] {
            assert_eq!(parse_input(s).unwrap().to_string(), s);
        }
        let mlp = parse_input("vector:150").unwrap().shape(27, &AgentConfig::default());
        assert!(!mlp.has_image());
        assert_eq!((mlp.scalars, mlp.actions), (150, 27));
        for bad in ["84x84", "vector:", "vector:0", "4x84x3", "84x84x2"] {
            assert!(parse_input(bad).is_err(), "{bad}");
        }
    }
}
