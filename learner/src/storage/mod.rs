//! What the learner keeps: the replay buffer, the replay log on disk, checkpoints and the other
//! files of a run directory.

pub mod checkpoint;
pub mod replay;
pub mod replay_log;
pub mod run_lock;
pub mod run_map;
pub mod sum_tree;
pub mod versions;
