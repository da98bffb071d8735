//! What the learner reports: Prometheus metrics, TensorBoard event files, the metrics files of a
//! run directory and the progress line.

pub mod metrics_log;
pub mod progress;
pub mod prometheus;
pub mod records;
pub mod status_report;
pub mod tfevents;
