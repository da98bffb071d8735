//! The run's metrics records, as the learner writes them to its run directory and `learner plot`
//! reads them back: `episodes.jsonl` (one line per finished episode) and `train.jsonl` (one line
//! per reporting interval), JSON Lines. One definition of each record serves both sides.

use std::fs;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// The file of finished episodes in a run directory.
pub const EPISODES_FILE: &str = "episodes.jsonl";
/// The file of periodic training reports in a run directory.
pub const TRAIN_FILE: &str = "train.jsonl";

/// The file of periodic greedy evaluations in a run directory (written by `actor train`).
pub const EVAL_FILE: &str = "eval.jsonl";

/// One greedy evaluation of the learner's weights during training: a line of `eval.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalRecord {
    /// Seconds since the run started (summed over resumes), when the weights were taken.
    pub time_secs: f64,
    pub env_steps: u64,
    pub learner_step: u64,
    pub weights_version: u64,
    /// The town driven (`default_town`, `held_out_town`).
    pub town: String,
    /// Runs per route.
    pub runs: u32,
    /// Route types completed in at least half of their runs (of 7).
    pub route_types_mastered: u32,
    /// Mean over routes of the mean return.
    pub mean_return: f64,
    /// Completed runs over all runs.
    pub completion_rate: f64,
    pub routes: Vec<EvalRouteRecord>,
    /// The field's driving score (`actor eval --suite clean`) over the same runs. Absent from
    /// records written before it was measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub driving_score: Option<f64>,
    /// The driving score on the hazard suite (`actor eval --suite hazards`, `runs` per kind), for
    /// a run that trains with hazards.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hazard_driving_score: Option<f64>,
    /// The hazard suite's driving score per hazard kind, in the suite's order (the learning
    /// curves per kind of docs/RESULTS.md).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hazard_kinds: Vec<EvalKindRecord>,
    /// What `best/` is chosen by: the mean of the driving scores measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub selection_score: Option<f64>,
    /// Whether these weights became the run's `best/` checkpoint.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub best: bool,
}

/// One hazard kind of an [`EvalRecord`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalKindRecord {
    pub kind: String,
    pub driving_score: f64,
}

/// One route of an [`EvalRecord`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalRouteRecord {
    pub route: String,
    pub completed: u32,
    pub mean_return: f64,
}

/// How a training episode ends ([`EpisodeRecord::outcome`], and the wire's
/// `EpisodeSummary.outcome`): it reached its destination, it collided, or it hit its time limit.
pub const OUTCOMES: [&str; 3] = [OUTCOME_ARRIVED, OUTCOME_COLLISION, OUTCOME_TIMEOUT];
/// The episode reached its destination.
pub const OUTCOME_ARRIVED: &str = proto::v1::outcome::ARRIVED;
/// The episode ended in a collision.
pub const OUTCOME_COLLISION: &str = proto::v1::outcome::COLLISION;
/// The episode hit its time limit (truncated).
pub const OUTCOME_TIMEOUT: &str = proto::v1::outcome::TIMEOUT;

/// The outcome of a finished episode from its `arrived` flag and whether it collided: for
/// summaries of actors that predate the outcome field. An episode that neither arrived nor
/// collided can only have ended at its time limit, as long as those are the simulator's only
/// three endings; a future ending would be misread as a timeout here.
#[must_use]
pub fn derived_outcome(arrived: bool, collided: bool) -> &'static str {
    if arrived {
        OUTCOME_ARRIVED
    } else if collided {
        OUTCOME_COLLISION
    } else {
        OUTCOME_TIMEOUT
    }
}

/// One finished training episode: a line of `episodes.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeRecord {
    /// Seconds since the run started.
    pub time_secs: f64,
    /// Global count of finished episodes in the run, 1-based and increasing.
    pub episode_index: u64,
    pub actor_id: String,
    /// The actor's environment the episode ran in.
    pub env: u32,
    /// The undiscounted sum of rewards.
    #[serde(rename = "return")]
    pub episode_return: f64,
    pub steps: u32,
    pub arrived: bool,
    /// What the ego vehicle hit, if the episode ended in a collision.
    pub collision: Option<String>,
    pub scenario: String,
    /// The episode's hazard kind (`stalled_car`, `cut_in`, …: sim-core's `HazardKind::name`), if
    /// it had one. Absent from lines written before hazards were recorded: read as none.
    #[serde(default)]
    pub hazard: Option<String>,
    /// How the episode ended: one of [`OUTCOMES`] (`arrived`, `collision`, `timeout`). Absent from
    /// lines written before outcomes were recorded: read as empty.
    #[serde(default)]
    pub outcome: String,
    /// The learner's update count when the episode was received.
    pub learner_step: u64,
    /// Environment steps received by the learner so far.
    pub env_steps: u64,
}

/// One reporting interval of the learner: a line of `train.jsonl` (and the scalars of its
/// TensorBoard events, `crate::telemetry::tfevents`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TrainRecord {
    pub time_secs: f64,
    pub learner_step: u64,
    pub env_steps: u64,
    pub transitions_stored: u64,
    /// Mean training loss over the interval; `None` before training starts.
    pub loss: Option<f64>,
    /// Mean Q-value over the interval; `None` before training starts.
    pub mean_q: Option<f64>,
    pub updates_per_sec: f64,
    pub env_steps_per_sec: f64,
    pub epsilon: f64,
    pub replay_size: u64,
    pub weights_version: u64,
    /// Episodes finished so far.
    pub episodes: u64,
    /// Over the recent episodes (`service.stats_window`): mean return, and the shares that
    /// reached their goal and that collided; `None` before the first episode (and in files
    /// written before these fields existed).
    #[serde(default)]
    pub episode_return_mean: Option<f64>,
    #[serde(default)]
    pub completion_rate: Option<f64>,
    #[serde(default)]
    pub collision_rate: Option<f64>,
    /// Mean versions the connected actors' weights are behind; `None` without actors.
    #[serde(default)]
    pub weights_lag_mean: Option<f64>,
    /// DQfD's large-margin loss on demonstrations (smoothed, unweighted by λ), and the share of
    /// demonstrations in the last batches; absent from runs without demonstrations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub margin_loss: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub demo_batch_share: Option<f64>,
}

/// A metrics file that could not be read.
#[derive(Debug, thiserror::Error)]
pub enum RecordsError {
    #[error("reading {}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: line {line}: {source}", path.display())]
    Parse { path: PathBuf, line: usize, source: serde_json::Error },
}

/// Reads `episodes.jsonl`. See [`read_jsonl`] for how bad lines are handled.
pub fn read_episodes(path: &Path) -> Result<Vec<EpisodeRecord>, RecordsError> {
    read_jsonl(path)
}

/// Reads `eval.jsonl`. See [`read_jsonl`] for how bad lines are handled.
pub fn read_eval(path: &Path) -> Result<Vec<EvalRecord>, RecordsError> {
    read_jsonl(path)
}

/// Reads `train.jsonl`. See [`read_jsonl`] for how bad lines are handled.
pub fn read_train(path: &Path) -> Result<Vec<TrainRecord>, RecordsError> {
    read_jsonl(path)
}

/// Reads a JSON Lines file of records. Blank lines are skipped; so is a last line that does not
/// parse (a run killed mid-write truncates it), with a warning. Any other line that does not parse
/// is an error naming the file and the 1-based line number. Unknown fields are ignored.
pub fn read_jsonl<T: DeserializeOwned>(path: &Path) -> Result<Vec<T>, RecordsError> {
    let bytes = fs::read(path).map_err(|source| RecordsError::Io { path: path.to_path_buf(), source })?;
    let lines: Vec<&[u8]> = bytes.split(|&b| b == b'\n').collect();
    let last = lines.iter().rposition(|line| !line.trim_ascii().is_empty());
    let mut records = Vec::with_capacity(lines.len());
    for (i, line) in lines.iter().enumerate() {
        let line = line.trim_ascii();
        if line.is_empty() {
            continue;
        }
        match serde_json::from_slice(line) {
            Ok(record) => records.push(record),
            Err(e) if Some(i) == last => {
                tracing::warn!("{}: skipping unparsable last line {} (truncated?): {e}", path.display(), i + 1);
            }
            Err(source) => return Err(RecordsError::Parse { path: path.to_path_buf(), line: i + 1, source }),
        }
    }
    Ok(records)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_with_the_documented_field_names() {
        let e = EpisodeRecord {
            time_secs: 1.5,
            episode_index: 3,
            actor_id: "actor-0".into(),
            env: 1,
            episode_return: -2.5,
            steps: 40,
            arrived: false,
            collision: None,
            scenario: "right_turn".into(),
            hazard: Some("cut_in".into()),
            outcome: OUTCOME_TIMEOUT.into(),
            learner_step: 10,
            env_steps: 400,
        };
        let json = serde_json::to_value(&e).unwrap();
        assert_eq!(json["return"], -2.5);
        assert!(json["collision"].is_null());
        assert_eq!((json["hazard"].as_str(), json["outcome"].as_str()), (Some("cut_in"), Some("timeout")));
        assert_eq!(serde_json::from_value::<EpisodeRecord>(json).unwrap(), e);
    }

    #[test]
    fn an_episode_line_from_before_hazards_and_outcomes_still_parses() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(EPISODES_FILE);
        let old = r#"{"time_secs":1.5,"episode_index":3,"actor_id":"actor-0","env":1,"return":-2.5,"steps":40,"arrived":false,"collision":"vehicle","scenario":"random","learner_step":10,"env_steps":400}"#;
        std::fs::write(&path, format!("{old}\n{old}\n")).unwrap();
        let read = read_episodes(&path).unwrap();
        assert_eq!(read.len(), 2);
        assert_eq!((read[0].hazard.as_deref(), read[0].outcome.as_str()), (None, ""));
        assert_eq!((read[0].collision.as_deref(), read[0].steps), (Some("vehicle"), 40));
    }

    #[test]
    fn outcomes_derive_from_the_flags_of_older_actors() {
        assert_eq!(derived_outcome(true, false), OUTCOME_ARRIVED);
        assert_eq!(derived_outcome(false, true), OUTCOME_COLLISION);
        assert_eq!(derived_outcome(false, false), OUTCOME_TIMEOUT);
        assert!(OUTCOMES.contains(&derived_outcome(false, false)));
    }
}
