//! `[env.hazards]`: which hazards an episode may get, how often, and the ranges their parameters
//! are drawn from. Off by default (`rate = 0`), which leaves every episode as it was.

use serde::{Deserialize, Serialize};

use super::kind::HazardKind;
use crate::config::error::ConfigError;

/// A closed range `[min, max]` a parameter is drawn from uniformly.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Range {
    /// Lower end of the range.
    pub min: f32,
    /// Upper end of the range.
    pub max: f32,
}

impl Range {
    #[must_use]
    pub const fn new(min: f32, max: f32) -> Self {
        Self { min, max }
    }

    fn validate(&self, field: &str, lowest: f32) -> Result<(), ConfigError> {
        if !(self.min.is_finite() && self.max.is_finite() && self.min >= lowest && self.max >= self.min) {
            return Err(ConfigError {
                field: field.to_owned(),
                message: format!("[{}, {}] must be finite with {lowest} <= min <= max", self.min, self.max),
            });
        }
        Ok(())
    }
}

/// The hazards of episodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HazardsConfig {
    /// Probability that an episode gets a hazard, 0 (none) to 1.
    pub rate: f32,
    /// The kinds drawn from, uniformly.
    pub kinds: Vec<HazardKind>,
    /// Route distance from the start to the hazard, metres.
    pub distance: Range,
    /// Seconds before the ego would reach a walker's crossing when it steps out.
    pub trigger_time: Range,
    /// Walking speed, m/s.
    pub walker_speed: Range,
    /// Length of a construction closure, metres.
    pub closure_length: Range,
    /// Seconds a hard-braking leader stands still before driving on.
    pub stop_time: Range,
    /// Bumper-to-bumper gap a cut-in leaves in front of the ego, metres.
    pub cut_in_gap: Range,
    /// Speed a junction runner crosses at, m/s.
    pub runner_speed: Range,
}

impl Default for HazardsConfig {
    fn default() -> Self {
        Self {
            rate: 0.0,
            kinds: HazardKind::ALL.to_vec(),
            distance: Range::new(45.0, 75.0),
            trigger_time: Range::new(1.5, 2.3),
            walker_speed: Range::new(1.3, 1.8),
            closure_length: Range::new(12.0, 20.0),
            stop_time: Range::new(2.0, 4.0),
            cut_in_gap: Range::new(6.0, 10.0),
            runner_speed: Range::new(8.0, 11.0),
        }
    }
}

impl HazardsConfig {
    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(self.rate.is_finite() && (0.0..=1.0).contains(&self.rate)) {
            return Err(ConfigError { field: "hazards.rate".into(), message: format!("{} must be between 0 and 1", self.rate) });
        }
        if self.rate > 0.0 && self.kinds.is_empty() {
            return Err(ConfigError {
                field: "hazards.kinds".into(),
                message: format!("is empty but hazards.rate is {}; name at least one of {}", self.rate, HazardKind::names()),
            });
        }
        self.distance.validate("hazards.distance", 15.0)?;
        self.trigger_time.validate("hazards.trigger_time", 0.1)?;
        self.walker_speed.validate("hazards.walker_speed", 0.2)?;
        self.closure_length.validate("hazards.closure_length", 4.0)?;
        self.stop_time.validate("hazards.stop_time", 0.0)?;
        self.cut_in_gap.validate("hazards.cut_in_gap", 2.0)?;
        self.runner_speed.validate("hazards.runner_speed", 2.0)?;
        Ok(())
    }

    /// Only `kind`, in every episode (what the hazard suite drives).
    #[must_use]
    pub fn only(kind: HazardKind) -> Self {
        Self { rate: 1.0, kinds: vec![kind], ..Self::default() }
    }

    /// Only `kind`, in every episode, with every parameter drawn beyond the range training draws
    /// it from, on the side that leaves the ego less room (`actor eval --suite hazards-robust`):
    /// a walker that steps out later and walks faster, a shorter cut-in gap, a longer closure and
    /// stop, a faster junction runner. The distance to the hazard is the suite's.
    #[must_use]
    pub fn beyond_training(kind: HazardKind) -> Self {
        Self {
            trigger_time: Range::new(1.0, 1.5),
            walker_speed: Range::new(1.8, 2.4),
            closure_length: Range::new(20.0, 30.0),
            stop_time: Range::new(4.0, 8.0),
            cut_in_gap: Range::new(3.0, 6.0),
            runner_speed: Range::new(11.0, 14.0),
            ..Self::only(kind)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_off_and_valid_and_errors_name_the_field() {
        let c = HazardsConfig::default();
        assert_eq!(c.rate, 0.0);
        c.validate().unwrap();
        let bad = HazardsConfig { rate: 1.5, ..HazardsConfig::default() };
        assert_eq!(bad.validate().unwrap_err().field, "hazards.rate");
        let bad = HazardsConfig { rate: 0.5, kinds: vec![], ..HazardsConfig::default() };
        assert!(bad.validate().unwrap_err().to_string().contains("stalled_car"));
        let bad = HazardsConfig { distance: Range::new(80.0, 40.0), ..HazardsConfig::default() };
        assert_eq!(bad.validate().unwrap_err().field, "hazards.distance");
    }

    #[test]
    fn beyond_training_draws_every_parameter_outside_the_training_range_on_the_harder_side() {
        let (t, b) = (HazardsConfig::default(), HazardsConfig::beyond_training(HazardKind::ALL[0]));
        b.validate().unwrap();
        // Less time, a shorter gap: below the training range; the rest above it.
        for (name, train, hard, below) in [
            ("trigger_time", t.trigger_time, b.trigger_time, true),
            ("cut_in_gap", t.cut_in_gap, b.cut_in_gap, true),
            ("walker_speed", t.walker_speed, b.walker_speed, false),
            ("closure_length", t.closure_length, b.closure_length, false),
            ("stop_time", t.stop_time, b.stop_time, false),
            ("runner_speed", t.runner_speed, b.runner_speed, false),
        ] {
            let outside = if below { hard.max <= train.min } else { hard.min >= train.max };
            assert!(outside && hard.min < hard.max, "{name}: {hard:?} is not beyond {train:?}");
        }
        assert_eq!((b.rate, b.kinds.as_slice(), b.distance), (1.0, &HazardKind::ALL[..1], t.distance));
    }
}
