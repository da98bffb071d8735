//! The metrics log: appends the run's records (`crate::telemetry::records`) to `episodes.jsonl` and
//! `train.jsonl` in the run directory, and the same figures as TensorBoard scalars to this
//! session's `events.out.tfevents.*` file there (`crate::telemetry::tfevents`), with env steps as the step.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::Mutex;

use crate::telemetry::records::{EPISODES_FILE, EVAL_FILE, EpisodeRecord, EvalRecord, TRAIN_FILE, TrainRecord};
use crate::telemetry::tfevents::EventWriter;

/// Appends JSON lines to the run directory's metrics files.
#[derive(Debug)]
pub struct MetricsLog {
    episodes: Mutex<BufWriter<File>>,
    train: Mutex<BufWriter<File>>,
    eval: Mutex<BufWriter<File>>,
    events: EventWriter,
}

impl MetricsLog {
    /// Opens (appending) the files in `run_dir`.
    pub fn open(run_dir: &Path) -> std::io::Result<Self> {
        let open = |name: &str| OpenOptions::new().create(true).append(true).open(run_dir.join(name)).map(BufWriter::new);
        Ok(Self {
            episodes: Mutex::new(open(EPISODES_FILE)?),
            train: Mutex::new(open(TRAIN_FILE)?),
            eval: Mutex::new(open(EVAL_FILE)?),
            events: EventWriter::create(run_dir)?,
        })
    }

    /// Writes one episode line, and its scalars ([`episode_scalars`]).
    pub fn episode(&self, e: &EpisodeRecord) -> std::io::Result<()> {
        writeln!(self.episodes.lock().expect("metrics lock"), "{}", serde_json::to_string(e)?)?;
        let scalars = episode_scalars(e);
        let tags: Vec<(&str, Option<f64>)> = scalars.iter().map(|(tag, v)| (tag.as_str(), *v)).collect();
        self.events.scalars(e.env_steps, &tags)
    }

    /// Writes one interval line, and flushes both files.
    pub fn interval(&self, t: &TrainRecord) -> std::io::Result<()> {
        writeln!(self.train.lock().expect("metrics lock"), "{}", serde_json::to_string(t)?)?;
        self.events.scalars(t.env_steps, &scalars(t))?;
        self.flush()
    }

    /// Writes one periodic evaluation line, flushed at once (they are few).
    pub fn eval(&self, e: &EvalRecord) -> std::io::Result<()> {
        let mut f = self.eval.lock().expect("metrics lock");
        writeln!(f, "{}", serde_json::to_string(e)?)?;
        f.flush()
    }

    /// Flushes both files.
    pub fn flush(&self) -> std::io::Result<()> {
        self.episodes.lock().expect("metrics lock").flush()?;
        self.train.lock().expect("metrics lock").flush()?;
        self.events.flush()
    }
}

/// The TensorBoard scalars of an episode: `episode/return` and `episode/steps`; and with a hazard,
/// under `episode/hazard/KIND/`, `success` (1 when it arrived, else 0), `collision` (1 when it
/// collided, else 0) and `return`, so that each kind's learning has curves of its own.
#[must_use]
pub fn episode_scalars(e: &EpisodeRecord) -> Vec<(String, Option<f64>)> {
    let mut scalars = vec![("episode/return".to_owned(), Some(e.episode_return)), ("episode/steps".to_owned(), Some(f64::from(e.steps)))];
    // The learner refuses unknown kinds (`service::validate`), so the name is safe in a tag.
    if let Some(kind) = &e.hazard {
        let flag = |b: bool| Some(if b { 1.0 } else { 0.0 });
        scalars.push((format!("episode/hazard/{kind}/success"), flag(e.arrived)));
        scalars.push((format!("episode/hazard/{kind}/collision"), flag(e.collision.is_some())));
        scalars.push((format!("episode/hazard/{kind}/return"), Some(e.episode_return)));
    }
    scalars
}

/// The TensorBoard scalars of an interval: tag and value (`None` is left out).
#[must_use]
pub fn scalars(t: &TrainRecord) -> Vec<(&'static str, Option<f64>)> {
    vec![
        ("train/loss", t.loss),
        ("train/margin_loss", t.margin_loss),
        ("train/demo_batch_share", t.demo_batch_share),
        ("train/mean_q", t.mean_q),
        ("train/epsilon", Some(t.epsilon)),
        ("episodes/return_mean", t.episode_return_mean),
        ("episodes/completion_rate", t.completion_rate),
        ("episodes/collision_rate", t.collision_rate),
        ("throughput/env_steps_per_sec", Some(t.env_steps_per_sec)),
        ("throughput/updates_per_sec", Some(t.updates_per_sec)),
        ("actors/weights_lag_mean", t.weights_lag_mean),
        ("replay/size", Some(t.replay_size as f64)),
        ("train/updates", Some(t.learner_step as f64)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn episode(hazard: Option<&str>, arrived: bool, collision: Option<&str>) -> EpisodeRecord {
        EpisodeRecord {
            time_secs: 1.0,
            episode_index: 1,
            actor_id: "a".into(),
            env: 0,
            episode_return: 4.5,
            steps: 30,
            arrived,
            collision: collision.map(str::to_owned),
            scenario: "random".into(),
            hazard: hazard.map(str::to_owned),
            outcome: String::new(),
            learner_step: 0,
            env_steps: 30,
        }
    }

    #[test]
    fn hazard_episodes_add_their_kinds_scalars() {
        let tags = |e: &EpisodeRecord| episode_scalars(e).into_iter().map(|(t, v)| (t, v.unwrap())).collect::<Vec<_>>();
        assert_eq!(tags(&episode(None, true, None)), [("episode/return".to_owned(), 4.5), ("episode/steps".to_owned(), 30.0)]);
        let hit = tags(&episode(Some("cut_in"), false, Some("vehicle")));
        assert_eq!(
            hit[2..],
            [
                ("episode/hazard/cut_in/success".to_owned(), 0.0),
                ("episode/hazard/cut_in/collision".to_owned(), 1.0),
                ("episode/hazard/cut_in/return".to_owned(), 4.5)
            ]
        );
        let arrived = tags(&episode(Some("stalled_car"), true, None));
        assert_eq!((arrived[2].1, arrived[3].1), (1.0, 0.0));
    }

    #[test]
    fn an_episode_with_a_hazard_is_written_to_both_files() {
        let dir = tempfile::tempdir().unwrap();
        let log = MetricsLog::open(dir.path()).unwrap();
        log.episode(&EpisodeRecord { outcome: "collision".into(), ..episode(Some("hard_brake"), false, Some("vehicle")) }).unwrap();
        log.flush().unwrap();
        let read = crate::telemetry::records::read_episodes(&dir.path().join(EPISODES_FILE)).unwrap();
        assert_eq!((read[0].hazard.as_deref(), read[0].outcome.as_str()), (Some("hard_brake"), "collision"));
        let events = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.file_name().unwrap().to_str().unwrap().starts_with("events.out.tfevents."));
        let bytes = std::fs::read(events.unwrap()).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.contains("episode/hazard/hard_brake/success") && text.contains("episode/hazard/hard_brake/collision"));
    }
}
