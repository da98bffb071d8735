//! What runs beside the service while it serves: the training thread, watched so that its death
//! fails the learner loudly, and the loops that turn counters into rates, metrics lines and the
//! progress line.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Result, bail};

use super::Trainer;
use crate::shared_state::Shared;
use crate::telemetry::progress::RateMeter;
use crate::training::dqn::Dqn;

/// Runs training, turning its end other than by a requested stop (an error or a panic) into a
/// failure of the learner.
pub(super) fn supervised_training(shared: &Arc<Shared>, dqn: Dqn, run_dir: &Path, train: Trainer) -> Result<Dqn> {
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| train(shared, dqn, run_dir)));
    let reason = match outcome {
        Ok(Ok(dqn)) if shared.stopping() => return Ok(dqn),
        Ok(Ok(_)) => "the training thread returned unexpectedly".to_owned(),
        Ok(Err(e)) => format!("training failed: {e:#}"),
        Err(panic) => {
            let what = panic.downcast_ref::<String>().cloned().or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()));
            format!("the training thread panicked: {}", what.unwrap_or_else(|| "(no message)".into()))
        }
    };
    shared.fail(reason.clone());
    bail!(reason)
}

/// Every second: this session's rates (over the last 10 s of counters); every 10 s: a
/// train.jsonl line.
pub(super) async fn report_loop(shared: Arc<Shared>) {
    let counters = || {
        let c = shared.counters.lock().expect("counters lock");
        (c.learner_step, c.env_steps)
    };
    let session = Instant::now();
    let (mut update_rate, mut step_rate) = (RateMeter::new(10.0), RateMeter::new(10.0));
    let (updates, steps) = counters();
    update_rate.push(0.0, updates);
    step_rate.push(0.0, steps);
    let mut tick = 0u64;
    loop {
        tokio::time::sleep(Duration::from_secs(1)).await;
        if shared.stopping() {
            return;
        }
        let (updates, steps) = counters();
        let t = session.elapsed().as_secs_f64();
        update_rate.push(t, updates);
        step_rate.push(t, steps);
        {
            let mut s = shared.stats.lock().expect("stats lock");
            s.updates_per_sec = update_rate.rate();
            s.env_steps_per_sec = step_rate.rate();
            s.epsilon = f64::from(shared.cfg.epsilon(0, steps));
        }
        tick += 1;
        if tick.is_multiple_of(10)
            && let Err(err) = shared.metrics.interval(&shared.train_record())
        {
            tracing::warn!(%err, "writing train.jsonl");
        }
    }
}

/// Shows the progress line (`crate::telemetry::progress`) every `every` until aborted.
pub async fn progress_loop(shared: Arc<Shared>, reporter: Arc<crate::telemetry::progress::Reporter>, every: Duration) {
    let session = Instant::now();
    loop {
        tokio::time::sleep(every).await;
        let status = crate::service::status(&shared);
        reporter.update(&crate::telemetry::progress::line(session.elapsed().as_secs_f64(), &status));
    }
}
