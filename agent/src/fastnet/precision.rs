//! Which arithmetic the network's wide convolutions run in: the run configuration's
//! `[agent] precision`, resolved once against what the machine has.

use serde::{Deserialize, Serialize};

use super::amx;

/// `[agent] precision`: `auto` (bf16 where AMX is present and the OS grants its tile state, else
/// f32), `f32`, or `bf16` (refused where AMX is absent).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    #[default]
    Auto,
    F32,
    Bf16,
}

/// A precision that cannot run here.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("precision = \"bf16\" needs AMX-BF16, and {why}; use precision = \"auto\" or \"f32\" on this machine")]
pub struct PrecisionError {
    pub why: &'static str,
}

/// The precision a network runs in, and why (for the log line that says which path runs).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Chosen {
    pub bf16: bool,
    pub reason: String,
}

impl Precision {
    /// What this request runs as on this machine.
    ///
    /// # Errors
    /// `bf16` where AMX is not available, naming why.
    pub fn resolve(self) -> Result<Chosen, PrecisionError> {
        let amx = amx::available();
        match (self, amx) {
            (Self::F32, _) => Ok(Chosen { bf16: false, reason: "precision = \"f32\" asked for".into() }),
            (Self::Bf16 | Self::Auto, Ok(())) => {
                Ok(Chosen { bf16: true, reason: format!("precision = \"{}\" and the CPU has AMX-BF16", self.name()) })
            }
            (Self::Bf16, Err(why)) => Err(PrecisionError { why }),
            (Self::Auto, Err(why)) => Ok(Chosen { bf16: false, reason: format!("precision = \"auto\" and {why}") }),
        }
    }

    /// What this request runs as here, falling back to f32 where `bf16` cannot run (an actor on a
    /// machine without AMX acting for a run that trains in bf16): the reason then says so.
    #[must_use]
    pub fn resolve_or_f32(self) -> Chosen {
        self.resolve().unwrap_or_else(|e| Chosen { bf16: false, reason: format!("{e} (falling back to f32)") })
    }

    /// The configuration's spelling.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::F32 => "f32",
            Self::Bf16 => "bf16",
        }
    }
}

impl std::str::FromStr for Precision {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Self::Auto),
            "f32" => Ok(Self::F32),
            "bf16" => Ok(Self::Bf16),
            other => Err(format!("precision {other:?}: expected auto, f32 or bf16")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_always_runs_and_bf16_only_with_amx() {
        assert_eq!(Precision::F32.resolve().map(|c| c.bf16), Ok(false));
        match amx::available() {
            Ok(()) => {
                assert!(Precision::Auto.resolve().unwrap().bf16);
                assert!(Precision::Bf16.resolve().unwrap().bf16);
            }
            Err(why) => {
                let auto = Precision::Auto.resolve().unwrap();
                assert!(!auto.bf16 && auto.reason.contains(why), "{auto:?}");
                let refused = Precision::Bf16.resolve().unwrap_err().to_string();
                assert!(refused.contains(why) && refused.contains("\"f32\""), "{refused}");
            }
        }
        assert_eq!("bf16".parse(), Ok(Precision::Bf16));
        assert!("fp16".parse::<Precision>().unwrap_err().contains("auto, f32 or bf16"));
    }
}
