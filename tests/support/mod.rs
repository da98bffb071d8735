//! What the cross-process tests share: processes that are killed when a test ends (also when it
//! fails), free loopback ports, status polls with deadlines, and signals sent without running
//! `kill`. tests/it/main.rs includes it as `mod support;` (unused parts are allowed: not every
//! test uses everything).
#![allow(dead_code)]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use proto::v1 as pb;
pub use rustix::process::Signal;

/// A child process that is killed when the test ends, also when it fails: an actor reconnects
/// for ever, so one left behind by a failed assertion would keep a core busy.
#[derive(Debug)]
pub struct Process(pub Child);

impl Process {
    /// Starts `command`, its stderr into `log` (created), stdout discarded.
    pub fn spawn(mut command: Command, log: &Path) -> Self {
        let log = std::fs::File::create(log).unwrap_or_else(|e| panic!("creating {}: {e}", log.display()));
        Self(command.stdout(Stdio::null()).stderr(log).spawn().expect("starting a test process"))
    }

    pub fn pid(&self) -> u32 {
        self.0.id()
    }

    /// Sends SIGKILL and reaps it.
    pub fn kill9(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }

    /// Waits up to `secs` for it to exit by itself; its status, or `None` if it still runs.
    pub fn wait_exit(&mut self, secs: u64) -> Option<std::process::ExitStatus> {
        let deadline = Instant::now() + Duration::from_secs(secs);
        loop {
            if let Some(status) = self.0.try_wait().expect("polling a test process") {
                return Some(status);
            }
            if Instant::now() >= deadline {
                return None;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        self.kill9();
    }
}

/// `actor --learner ADDR --envs 2 --name NAME` plus `extra`, RUST_LOG=info.
pub fn actor_command(addr: &str, name: &str, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_actor"));
    c.args(["--learner", addr, "--envs", "2", "--name", name]).args(extra).env("RUST_LOG", "info");
    c
}

/// An actor process of `actor_command`, logging to `log`.
pub fn spawn_actor(addr: &str, name: &str, extra: &[&str], log: &Path) -> Process {
    Process::spawn(actor_command(addr, name, extra), log)
}

/// A free loopback port (bound and released), so that a restarted learner can come back on it.
pub fn free_port() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().to_string()
}

/// The learner's status.
pub async fn status(addr: &str) -> pb::StatusResponse {
    let mut c = proto::client::connect(addr, None).await.unwrap();
    c.status(pb::StatusRequest {}).await.unwrap().into_inner()
}

/// Polls the status until `ok` holds, for at most `secs`; fails with the status it last saw.
pub async fn wait_for(addr: &str, secs: u64, what: &str, ok: impl Fn(&pb::StatusResponse) -> bool) -> pb::StatusResponse {
    let deadline = Instant::now() + Duration::from_secs(secs);
    loop {
        let s = status(addr).await;
        if ok(&s) {
            return s;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}; last status: {s:#?}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// The actor record of `name` (the most recently heard one if there are several).
pub fn actor<'a>(s: &'a pb::StatusResponse, name: &str) -> Option<&'a pb::ActorStatus> {
    s.actors.iter().filter(|a| a.name == name).min_by(|x, y| x.last_seen_secs.total_cmp(&y.last_seen_secs))
}

/// Waits up to `secs` until `path` exists and `ok` holds for its text.
pub fn wait_for_file(path: &Path, secs: u64, what: &str, ok: impl Fn(&str) -> bool) -> String {
    let deadline = Instant::now() + Duration::from_secs(secs);
    loop {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        if ok(&text) {
            return text;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what} in {}; it holds:\n{text}", path.display());
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The JSON lines of an `--ack-log` file.
pub fn ack_lines(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path).unwrap_or_default().lines().filter_map(|l| serde_json::from_str(l).ok()).collect()
}

/// The processes whose parent is `pid` (from /proc).
pub fn children_of(pid: u32) -> Vec<u32> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir("/proc").into_iter().flatten().flatten() {
        let Ok(child) = entry.file_name().to_string_lossy().parse::<u32>() else { continue };
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else { continue };
        // pid (comm) state ppid …: comm may hold spaces, so read after its closing parenthesis.
        let fields: Vec<&str> = stat.rsplit_once(')').map(|(_, rest)| rest.split_whitespace().collect()).unwrap_or_default();
        if fields.get(1).and_then(|p| p.parse::<u32>().ok()) == Some(pid) {
            out.push(child);
        }
    }
    out
}

/// Whether process `pid` is alive (not gone, not a zombie).
pub fn alive(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| s.rsplit_once(')').map(|(_, rest)| !rest.trim_start().starts_with('Z')))
        .unwrap_or(false)
}

/// Sends `signal` to process `pid`; false if it could not (the process is gone).
pub fn signal(pid: u32, signal: Signal) -> bool {
    rustix::process::Pid::from_raw(pid as i32).is_some_and(|p| rustix::process::kill_process(p, signal).is_ok())
}
