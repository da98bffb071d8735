//! The one progress format of `actor train` and `learner serve`: a single line per interval built
//! from the learner's status ([`line`]), drawn in place by `indicatif` when stderr is a terminal and
//! printed as a plain line (no ANSI codes) otherwise ([`Reporter`]); and the rates in it
//! ([`RateMeter`]), measured over a sliding window of this session's counters, so that a resumed
//! run's totals never count as progress of its first seconds.

use std::collections::VecDeque;
use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use proto::v1 as pb;

/// A rate (per second) of a growing counter over the last `window` seconds of samples.
#[derive(Debug, Clone)]
pub struct RateMeter {
    window: f64,
    samples: VecDeque<(f64, u64)>,
}

impl RateMeter {
    /// A meter over `window_secs` seconds.
    #[must_use]
    pub fn new(window_secs: f64) -> Self {
        Self { window: window_secs, samples: VecDeque::new() }
    }

    /// Adds the counter's value at time `t` (seconds, any origin, increasing). The first sample
    /// is the baseline: whatever the counter held before (a resumed run's total) is not a rate.
    pub fn push(&mut self, t: f64, count: u64) {
        self.samples.push_back((t, count));
        // Keep the newest sample at or before the window's start, so the span covers the window.
        while self.samples.len() > 2 && self.samples[1].0 <= t - self.window {
            self.samples.pop_front();
        }
    }

    /// Counts per second between the oldest and newest samples kept; 0 before two samples.
    #[must_use]
    pub fn rate(&self) -> f64 {
        match (self.samples.front(), self.samples.back()) {
            (Some(&(t0, c0)), Some(&(t1, c1))) if t1 > t0 => c1.saturating_sub(c0) as f64 / (t1 - t0),
            _ => 0.0,
        }
    }
}

/// The progress line: this session's time, then env steps and their rate, episodes and the recent
/// window's mean return and completion, updates and their rate, the loss, the weights version,
/// replay and connected actors.
#[must_use]
pub fn line(session_secs: f64, s: &pb::StatusResponse) -> String {
    let ep = s.episodes.unwrap_or_default();
    let connected = s.actors.iter().filter(|a| a.connected).count();
    let loss = if s.loss.is_finite() { format!("{:.4}", s.loss) } else { "-".to_owned() };
    format!(
        "[{:>6.0}s] env steps {} ({:.0}/s)  episodes {}  mean return {:.2}  completed {:.0}%  updates {} ({:.2}/s)  loss {}  weights v{}  replay {}  actors {}",
        session_secs,
        s.transitions_received,
        s.env_steps_per_sec,
        ep.episodes_total,
        ep.mean_return,
        100.0 * ep.completion_rate,
        s.learner_step,
        s.updates_per_sec,
        loss,
        s.weights_version,
        s.replay_size,
        connected
    ) + &demo_note(s)
        + &stall_note(session_secs, s, connected)
}

/// The demonstrations, once there are any: how many the replay holds and their share of the last
/// batches (with the margin loss once a batch held one).
fn demo_note(s: &pb::StatusResponse) -> String {
    if s.demo_replay_size == 0 {
        return String::new();
    }
    let margin = if s.margin_loss.is_finite() { format!(", margin loss {:.3}", s.margin_loss) } else { String::new() };
    format!("  demos {} ({:.0}% of batches{margin})", s.demo_replay_size, 100.0 * s.demo_batch_share)
}

/// A session younger than this is starting (actors connecting, the replay filling), not stalled.
const STARTING_SECS: f64 = 10.0;

/// Why training is not moving, where the status says (empty while it moves): what a user must
/// see on the one line they watch, not only in a log.
fn stall_note(session_secs: f64, s: &pb::StatusResponse, connected: usize) -> String {
    if !s.training_error.is_empty() {
        return format!("  STOPPED: {}", s.training_error);
    }
    if s.env_steps_per_sec >= 1.0 || session_secs < STARTING_SECS {
        return String::new();
    }
    if !s.recent_refusal.is_empty() {
        format!("  stalled: batches refused: {}", s.recent_refusal)
    } else if connected == 0 {
        "  stalled: no actor connected".to_owned()
    } else {
        String::new()
    }
}

/// Where progress lines go: an in-place line on a terminal, plain lines elsewhere.
#[derive(Debug)]
pub struct Reporter {
    bar: Option<ProgressBar>,
}

impl Reporter {
    /// On stderr: `indicatif` when it is a terminal, plain lines otherwise.
    #[must_use]
    pub fn stderr() -> Self {
        if !std::io::stderr().is_terminal() {
            return Self { bar: None };
        }
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
        bar.set_style(ProgressStyle::with_template("{spinner} {msg}").expect("a valid template"));
        bar.enable_steady_tick(Duration::from_millis(250));
        Self { bar: Some(bar) }
    }

    /// Shows a new progress line.
    pub fn update(&self, line: &str) {
        match &self.bar {
            Some(bar) => bar.set_message(line.to_owned()),
            None => eprintln!("{line}"),
        }
    }

    /// Prints a message above the progress line.
    pub fn println(&self, message: &str) {
        match &self.bar {
            Some(bar) => bar.suspend(|| eprintln!("{message}")),
            None => eprintln!("{message}"),
        }
    }

    /// Leaves the last progress line on the terminal and stops redrawing it.
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.abandon();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_resumed_total_is_a_baseline_not_a_rate() {
        let mut m = RateMeter::new(10.0);
        m.push(0.0, 49_956);
        assert_eq!(m.rate(), 0.0, "one sample is no rate");
        m.push(1.0, 49_966);
        assert_eq!(m.rate(), 10.0);
        m.push(2.0, 49_986);
        assert_eq!(m.rate(), 15.0);
    }

    #[test]
    fn the_rate_follows_the_window() {
        let mut m = RateMeter::new(10.0);
        for t in 0..=10 {
            m.push(f64::from(t), 100 * u64::from(t as u32));
        }
        assert!((m.rate() - 100.0).abs() < 1e-9);
        // The counter stops: after a full window without growth the rate is 0.
        for t in 11..=21 {
            m.push(f64::from(t), 1000);
        }
        assert_eq!(m.rate(), 0.0);
        // Growth again is measured over the window (12 s to 22 s), not diluted by older history.
        m.push(22.0, 1100);
        assert!((m.rate() - 10.0).abs() < 1e-9, "{}", m.rate());
    }

    #[test]
    fn the_line_is_one_plain_line_with_every_figure() {
        let s = pb::StatusResponse {
            transitions_received: 1234,
            env_steps_per_sec: 56.4,
            learner_step: 78,
            updates_per_sec: 2.5,
            loss: f64::NAN,
            weights_version: 9,
            replay_size: 1000,
            episodes: Some(pb::EpisodeStats { episodes_total: 12, mean_return: -3.25, completion_rate: 0.25, ..Default::default() }),
            actors: vec![pb::ActorStatus { connected: true, ..Default::default() }, pb::ActorStatus::default()],
            ..Default::default()
        };
        let l = line(42.0, &s);
        assert_eq!(
            l,
            "[    42s] env steps 1234 (56/s)  episodes 12  mean return -3.25  completed 25%  updates 78 (2.50/s)  loss -  weights v9  replay 1000  actors 1"
        );
        assert!(!l.contains('\n') && !l.contains('\u{1b}'));
    }

    #[test]
    fn a_stalled_run_says_why_on_the_line() {
        let disk = "the learner could not make the batch durable: writing the replay log: No space left on device";
        let mut s = pb::StatusResponse { recent_refusal: disk.into(), ..Default::default() };
        assert!(line(20.0, &s).ends_with(&format!("actors 0  stalled: batches refused: {disk}")), "{}", line(20.0, &s));
        s.recent_refusal.clear();
        assert!(line(20.0, &s).ends_with("actors 0  stalled: no actor connected"));
        // Starting: actors are still connecting.
        assert!(line(2.0, &s).ends_with("actors 0"));
        // Moving: nothing to say, whatever happened before.
        s.env_steps_per_sec = 100.0;
        s.recent_refusal = disk.into();
        assert!(line(20.0, &s).ends_with("actors 0"));
        s.training_error = "training failed: boom".into();
        assert!(line(20.0, &s).ends_with("actors 0  STOPPED: training failed: boom"));
    }
}
