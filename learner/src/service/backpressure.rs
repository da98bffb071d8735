//! Backpressure for the replay ratio. The training thread may do `replay_ratio / batch_size`
//! updates per stored transition and no more; where it is slower than the actors (a weak machine,
//! a large camera, many actors) the ratio was only a ceiling, and the run trained on less than
//! its configuration says. An experience stream therefore stores no batch while the learner owes
//! more than `service.update_lag_limit` updates: the actor's outbox fills, and its stepping thread
//! waits for room (`actor/src/link.rs`), so the run's updates per env step are what it asked for.

use std::time::{Duration, Instant};

use crate::state::Shared;

/// How often a held stream looks again: an update takes tens of milliseconds at the least.
const POLL: Duration = Duration::from_millis(2);

/// Returns once the learner owes at most `service.update_lag_limit` updates (at once with a limit
/// of 0, or when the learner is stopping or has failed), adding the time waited to `held_secs`.
pub async fn until_learner_catches_up(shared: &Shared) {
    let limit = shared.cfg.service.update_lag_limit;
    if limit == 0 || shared.updates_owed() <= limit {
        return;
    }
    let started = Instant::now();
    while shared.updates_owed() > limit && !shared.stopping() && shared.failure().is_none() {
        tokio::time::sleep(POLL).await;
    }
    shared.stats.lock().expect("stats lock").held_secs += started.elapsed().as_secs_f64();
}
