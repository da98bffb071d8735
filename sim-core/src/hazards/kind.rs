//! The hazard kinds, after CARLA scenario_runner's scenarios and Bench2Drive's ability groups.

use serde::{Deserialize, Serialize};

/// What kind of hazard an episode has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HazardKind {
    /// A car stopped in the ego's lane (overtake it).
    StalledCar,
    /// A walker steps out from behind a parked car and crosses the ego's lane (emergency brake).
    PedestrianCrossing,
    /// A car in the adjacent lane changes into the ego's lane with a short gap.
    CutIn,
    /// The car ahead brakes at its limit to a stop.
    HardBrake,
    /// Cones and a barrier close the ego's lane for a stretch.
    Construction,
    /// An oncoming car pulls into the ego's lane to pass.
    OppositeOvertaker,
    /// A car crosses the junction the ego crosses, without right of way (runs the red light).
    JunctionRunner,
}

impl HazardKind {
    /// Every kind, in the order.
    pub const ALL: [HazardKind; 7] = [
        HazardKind::StalledCar,
        HazardKind::PedestrianCrossing,
        HazardKind::CutIn,
        HazardKind::HardBrake,
        HazardKind::Construction,
        HazardKind::OppositeOvertaker,
        HazardKind::JunctionRunner,
    ];

    /// The kind's name in configuration and reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            HazardKind::StalledCar => "stalled_car",
            HazardKind::PedestrianCrossing => "pedestrian_crossing",
            HazardKind::CutIn => "cut_in",
            HazardKind::HardBrake => "hard_brake",
            HazardKind::Construction => "construction",
            HazardKind::OppositeOvertaker => "opposite_overtaker",
            HazardKind::JunctionRunner => "junction_runner",
        }
    }

    /// The kind with this name.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// All names, comma-separated (for error messages).
    #[must_use]
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for k in HazardKind::ALL {
            assert_eq!(HazardKind::from_name(k.name()), Some(k));
        }
        assert_eq!(HazardKind::from_name("meteor"), None);
        assert!(HazardKind::names().starts_with("stalled_car, pedestrian_crossing"));
    }
}
