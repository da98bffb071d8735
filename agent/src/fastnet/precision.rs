//! Which arithmetic the network's wide convolutions run in: the run configuration's
//! `[agent] precision`, resolved once against what the machine has.

use serde::{Deserialize, Serialize};

use super::bf16_matmul::{self, Kernel};

/// `[agent] precision`: `auto` (bf16 where the CPU has AMX-BF16 and the OS grants the tile state,
/// else f32), `f32`, or `bf16` (on AMX, else on AVX512-BF16; refused where neither is present).
/// `auto` leaves AVX512-BF16 alone: on Intel's cores it loses to f32, and on AMD Zen 4, where it
/// wins, choosing it was left to the issue that defined `auto` as AMX only (docs/PERFORMANCE.md#bf16).
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
#[error("precision = \"bf16\" needs AMX-BF16 or AVX512-BF16, and {why}; use precision = \"auto\" or \"f32\" on this machine")]
pub struct PrecisionError {
    pub why: &'static str,
}

/// The precision a network runs in, and why (for the log line that says which path runs).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Chosen {
    pub bf16: bool,
    /// The instruction set the bf16 products run on, when `bf16`.
    pub kernel: Option<Kernel>,
    pub reason: String,
}

impl Chosen {
    /// The arithmetic in a few words: "f32", or "bf16 on AMX-BF16" / "bf16 on AVX512-BF16".
    #[must_use]
    pub fn arithmetic(&self) -> String {
        self.kernel.map_or_else(|| "f32".to_string(), |k| format!("bf16 on {}", k.name()))
    }
}

impl Precision {
    /// What this request runs as on this machine.
    ///
    /// # Errors
    /// `bf16` where no bf16 kernel is available, naming why.
    pub fn resolve(self) -> Result<Chosen, PrecisionError> {
        self.resolve_on(bf16_matmul::available())
    }

    /// What this request runs as on a machine whose bf16 kernel is `kernel` (or none, and why).
    fn resolve_on(self, kernel: Result<Kernel, &'static str>) -> Result<Chosen, PrecisionError> {
        let f32 = |reason: String| Ok(Chosen { bf16: false, kernel: None, reason });
        match (self, kernel) {
            (Self::F32, _) => f32("precision = \"f32\" asked for".into()),
            (Self::Bf16, Ok(kernel)) | (Self::Auto, Ok(kernel @ Kernel::Amx)) => Ok(Chosen {
                bf16: true,
                kernel: Some(kernel),
                reason: format!("precision = \"{}\" and the CPU has {}", self.name(), kernel.name()),
            }),
            (Self::Auto, Ok(Kernel::Avx512Bf16)) => f32(
                "precision = \"auto\" and the CPU has AVX512-BF16 but no AMX, where bf16 is not known to be faster (precision = \"bf16\" runs it)".into(),
            ),
            (Self::Bf16, Err(why)) => Err(PrecisionError { why }),
            (Self::Auto, Err(why)) => f32(format!("precision = \"auto\" and {why}")),
        }
    }

    /// What this request runs as here, falling back to f32 where `bf16` cannot run (an actor on a
    /// machine without a bf16 kernel acting for a run that trains in bf16): the reason then says so.
    #[must_use]
    pub fn resolve_or_f32(self) -> Chosen {
        self.resolve().unwrap_or_else(|e| Chosen { bf16: false, kernel: None, reason: format!("{e} (falling back to f32)") })
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
    fn f32_always_runs_and_bf16_only_with_a_bf16_kernel() {
        assert_eq!(Precision::F32.resolve().map(|c| c.bf16), Ok(false));
        assert_eq!(Precision::Auto.resolve(), Precision::Auto.resolve_on(bf16_matmul::available()), "resolve reads this machine");
        // Every machine's answer, on any machine.
        let amx = Ok(Kernel::Amx);
        let avx = Ok(Kernel::Avx512Bf16);
        let none: Result<Kernel, &str> = Err("the CPU has no AMX-TILE and the CPU has no AVX-512F");
        for kernel in [amx, avx, none] {
            let f32 = Precision::F32.resolve_on(kernel).unwrap();
            assert!(!f32.bf16 && f32.kernel.is_none() && f32.arithmetic() == "f32", "{f32:?}");
        }
        let auto = Precision::Auto.resolve_on(amx).unwrap();
        assert!(auto.bf16 && auto.kernel == Some(Kernel::Amx) && auto.arithmetic() == "bf16 on AMX-BF16", "{auto:?}");
        let auto = Precision::Auto.resolve_on(avx).unwrap();
        assert!(!auto.bf16 && auto.reason.contains("AVX512-BF16 but no AMX") && auto.reason.contains("\"bf16\" runs it"), "{auto:?}");
        let auto = Precision::Auto.resolve_on(none).unwrap();
        assert!(!auto.bf16 && auto.reason.contains("no AVX-512F"), "{auto:?}");
        for kernel in [Kernel::Amx, Kernel::Avx512Bf16] {
            let bf16 = Precision::Bf16.resolve_on(Ok(kernel)).unwrap();
            assert!(bf16.bf16 && bf16.kernel == Some(kernel) && bf16.reason.contains(kernel.name()), "{bf16:?}");
        }
        let refused = Precision::Bf16.resolve_on(none).unwrap_err().to_string();
        assert!(refused.contains("no AVX-512F") && refused.contains("\"f32\""), "{refused}");
        assert_eq!("bf16".parse(), Ok(Precision::Bf16));
        assert!("fp16".parse::<Precision>().unwrap_err().contains("auto, f32 or bf16"));
    }
}
