//! The learner: replay buffer, DQN training, checkpoints, weight broadcast and status. It arrives
//! with the learner service issue; the crate exists now so that the workspace has its final shape.
