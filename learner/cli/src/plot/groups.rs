//! Which runs make one line of a plot: a [`RunGroup`] is one run directory, or one agent trained
//! over several seeds under a label, and its command-line form (`--run-dir DIR` or
//! `--run-dir LABEL=DIR1,DIR2,...`).

use std::path::{PathBuf, is_separator};
use std::str::FromStr;

use super::error::PlotError;

/// One line of a plot: a single run directory (named after it in the legend), or a labelled group
/// of runs of one agent, one per seed, drawn as their mean with a band.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunGroup {
    label: Option<String>,
    dirs: Vec<PathBuf>,
}

impl RunGroup {
    /// A single run, named in the legend after its directory.
    pub fn single(dir: impl Into<PathBuf>) -> Self {
        Self { label: None, dirs: vec![dir.into()] }
    }

    /// A labelled group of runs: at least one directory, none twice, and a label that is not empty
    /// and has no path separator.
    pub fn labelled(label: &str, dirs: Vec<PathBuf>) -> Result<Self, PlotError> {
        let arg = || format!("{label}={}", dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(","));
        let bad = |reason: String| PlotError::RunArg { arg: arg(), reason };
        let label = label.trim();
        if label.is_empty() {
            return Err(bad("the label before `=` is empty".into()));
        }
        if label.chars().any(is_separator) {
            return Err(bad(format!("the label `{label}` contains a path separator")));
        }
        if dirs.is_empty() {
            return Err(bad("no run directory after `=`".into()));
        }
        if let Some(i) = dirs.iter().position(|d| d.as_os_str().is_empty()) {
            return Err(bad(format!("run directory {} of the list is empty (two commas, or one at the end?)", i + 1)));
        }
        if let Some((i, d)) = dirs.iter().enumerate().find(|&(i, d)| dirs[..i].contains(d)) {
            return Err(bad(format!("run directory {} (`{}`) is already in the list", i + 1, d.display())));
        }
        Ok(Self { label: Some(label.to_string()), dirs })
    }

    /// Parses a `--run-dir` argument: `DIR`, one run; or `LABEL=DIR1,DIR2,...`, one agent over
    /// several seeds. A directory whose name contains `=` is taken as `DIR` when a path separator
    /// comes before the `=` (write `./a=b` for a directory `a=b`); a plain `DIR` may contain
    /// commas. Errors name the argument.
    pub fn parse(arg: &str) -> Result<Self, PlotError> {
        if arg.trim().is_empty() {
            return Err(PlotError::RunArg { arg: arg.into(), reason: "it is empty".into() });
        }
        match arg.split_once('=') {
            Some((label, list)) if !label.chars().any(is_separator) => {
                let dirs = if list.trim().is_empty() { Vec::new() } else { list.split(',').map(|d| PathBuf::from(d.trim())).collect() };
                Self::labelled(label, dirs).map_err(|e| match e {
                    // Name the argument as typed, not as rebuilt from its parts.
                    PlotError::RunArg { reason, .. } => PlotError::RunArg { arg: arg.into(), reason },
                    other => other,
                })
            }
            _ => Ok(Self::single(arg)),
        }
    }

    /// The label given, if any (`None` for a single run).
    pub fn label(&self) -> Option<&str> {
        self.label.as_deref()
    }

    /// The run directories, in the order given (at least one).
    pub fn dirs(&self) -> &[PathBuf] {
        &self.dirs
    }
}

impl FromStr for RunGroup {
    type Err = PlotError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dirs(g: &RunGroup) -> Vec<&str> {
        g.dirs().iter().map(|d| d.to_str().unwrap()).collect()
    }

    #[test]
    fn a_directory_is_a_single_run() {
        let g = RunGroup::parse("runs/hybrid").unwrap();
        assert_eq!((g.label(), dirs(&g)), (None, vec!["runs/hybrid"]));
        assert_eq!(g, RunGroup::single("runs/hybrid"));
        // A separator before the `=`: a directory with `=` in its name, not a label.
        let g = RunGroup::parse("./lr=0.1").unwrap();
        assert_eq!((g.label(), dirs(&g)), (None, vec!["./lr=0.1"]));
        let g = RunGroup::parse("runs/a,b").unwrap();
        assert_eq!((g.label(), dirs(&g)), (None, vec!["runs/a,b"]));
    }

    #[test]
    fn a_label_names_several_seeds() {
        let g: RunGroup = "hybrid=runs/h1,runs/h2, runs/h3".parse().unwrap();
        assert_eq!((g.label(), dirs(&g)), (Some("hybrid"), vec!["runs/h1", "runs/h2", "runs/h3"]));
        let g = RunGroup::parse("end to end = runs/e1").unwrap();
        assert_eq!((g.label(), dirs(&g)), (Some("end to end"), vec!["runs/e1"]));
    }

    #[test]
    fn bad_forms_are_errors_naming_the_argument() {
        for (arg, reason) in [
            ("", "empty"),
            ("  ", "empty"),
            ("=runs/a,runs/b", "label"),
            ("hybrid=", "no run directory"),
            ("hybrid=runs/a,,runs/b", "run directory 2 of the list is empty"),
            ("hybrid=runs/a,", "run directory 2 of the list is empty"),
            ("hybrid=runs/a,runs/b,runs/a", "run directory 3 (`runs/a`) is already in the list"),
        ] {
            let err = RunGroup::parse(arg).unwrap_err();
            assert!(matches!(&err, PlotError::RunArg { arg: a, .. } if a == arg), "{arg}: {err:?}");
            let msg = err.to_string();
            assert!(msg.contains(&format!("`{arg}`")) && msg.contains(reason), "{arg}: {msg}");
            assert!(msg.contains("LABEL=DIR1,DIR2"), "says what is valid: {msg}");
        }
        let err = RunGroup::labelled("a/b", vec!["x".into()]).unwrap_err();
        assert!(err.to_string().contains("`a/b=x`") && err.to_string().contains("path separator"), "{err}");
    }
}
