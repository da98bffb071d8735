//! Running one program of a step: printed as it is run (`+ cargo fmt ...`), in the repository's
//! root, its failure an error that names the command and its exit status.

use std::ffi::OsStr;
use std::fmt;
use std::path::Path;
use std::process::Command;

/// A program of a step that did not succeed: what ran and how it ended.
#[derive(Debug)]
pub struct Failed {
    /// The command line as it was printed.
    pub command: String,
    /// Its exit status; `None` when a signal ended it or it could not be started.
    pub code: Option<i32>,
    /// Why it could not be started, when it could not.
    pub spawn_error: Option<String>,
}

impl fmt::Display for Failed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.spawn_error, self.code) {
            (Some(e), _) => write!(f, "`{}` could not be started: {e}", self.command),
            (None, Some(code)) => write!(f, "`{}` exited with status {code}", self.command),
            (None, None) => write!(f, "`{}` was ended by a signal", self.command),
        }
    }
}

impl std::error::Error for Failed {}

/// `program args...`, run in `root` with the environment of this process plus `envs`.
#[derive(Debug)]
pub struct Cmd {
    command: Command,
    shown: String,
}

impl Cmd {
    pub fn new(root: &Path, program: impl AsRef<OsStr>) -> Self {
        let program = program.as_ref();
        let mut command = Command::new(program);
        command.current_dir(root);
        Self { command, shown: program.to_string_lossy().into_owned() }
    }

    /// Shows the program as `name` in the printed command line (`cargo` for `$CARGO`).
    #[must_use]
    pub fn shown_as(mut self, name: &str) -> Self {
        name.clone_into(&mut self.shown);
        self
    }

    #[must_use]
    pub fn args<I, S>(mut self, args: I) -> Self
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        for a in args {
            let a = a.as_ref();
            self.shown.push(' ');
            self.shown.push_str(&a.to_string_lossy());
            self.command.arg(a);
        }
        self
    }

    /// Sets `key=value` for the program (shown before the command line).
    #[must_use]
    pub fn env(mut self, key: &str, value: impl AsRef<OsStr>) -> Self {
        let value = value.as_ref();
        self.shown = format!("{key}={} {}", value.to_string_lossy(), self.shown);
        self.command.env(key, value);
        self
    }

    /// Runs it to its end, its output on the terminal; an error unless it exited with 0.
    pub fn run(mut self) -> Result<(), Failed> {
        eprintln!("+ {}", self.shown);
        match self.command.status() {
            Ok(s) if s.success() => Ok(()),
            Ok(s) => Err(Failed { command: self.shown, code: s.code(), spawn_error: None }),
            Err(e) => Err(Failed { command: self.shown, code: None, spawn_error: Some(e.to_string()) }),
        }
    }

    /// Runs it quietly (its output discarded): whether it exited with 0. For probes such as
    /// `docker info`, whose failure is an answer rather than an error.
    pub fn succeeds(mut self) -> bool {
        self.command.stdout(std::process::Stdio::null()).stderr(std::process::Stdio::null()).status().is_ok_and(|s| s.success())
    }

    /// Runs it quietly and returns its standard output when it exited with 0.
    pub fn output(mut self) -> Option<String> {
        let out = self.command.stderr(std::process::Stdio::null()).output().ok()?;
        out.status.success().then(|| String::from_utf8_lossy(&out.stdout).into_owned())
    }
}
