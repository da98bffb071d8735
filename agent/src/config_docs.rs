//! The configuration file with comments: `learner config` prints every field with what it means,
//! its unit and its default, so that the file it writes explains itself. The descriptions follow
//! the fields' doc comments in `RunConfig` and the structs it gathers; a test checks that every
//! field printed has one.

use crate::config::RunConfig;

/// Every field and table of the configuration file by dotted path, and what it means.
pub const FIELD_DOCS: &[(&str, &str)] = &[
    (
        "env.variant",
        "`hybrid` (the paper's agent: the network sees d, the reward has r_w) or `end_to_end` (camera and speed only, no r_w).",
    ),
    (
        "env.map",
        "The town to train on: `default_town` (default), `held_out_town` or a map file (text format or OpenDRIVE `.xodr`, relative to the learner's directory); the learner sends it to every actor.",
    ),
    ("env.dt", "Simulation step, seconds (default 0.1, the paper's 10 Hz)."),
    ("env.waypoint_spacing", "Spacing of the planner's waypoints along the route, metres (default 8, the paper's)."),
    ("env.route_length_min", "Shortest random training route, metres (default 50)."),
    ("env.route_length_max", "Longest random training route, metres (default 150)."),
    ("env.time_limit", "Steps before a training episode is truncated (default 200)."),
    ("env.eval_time_limit", "Steps before an evaluation route is truncated (default 300: waiting at junctions takes time)."),
    ("env.reward", "The paper's reward: r = β_v·r_v + β_l·r_l + β_w·r_w per step, collision and arrival rewards at the end."),
    ("env.traffic", "Other cars."),
    ("env.vehicle", "The ego vehicle (kinematic bicycle model)."),
    ("env.camera", "The front camera (omit the table for none)."),
    (
        "env.planner",
        "The planner giving the waypoints (d, path features, the model-based driver): `astar` (the global route, default) or `astar+avoid` (bent around perceived hazards and obstacles).",
    ),
    (
        "env.hazards",
        "Hazards the planner does not know: stalled car, pedestrian crossing, cut-in, hard brake, construction, opposite overtaker.",
    ),
    ("env.hazards.rate", "Probability that an episode gets a hazard, 0 to 1 (default 0: none)."),
    (
        "env.hazards.kinds",
        "The kinds drawn from (stalled_car, pedestrian_crossing, cut_in, hard_brake, construction, opposite_overtaker, junction_runner; default all).",
    ),
    ("env.hazards.distance", "Route distance from the start to the hazard, metres (default 45–75)."),
    ("env.hazards.distance.min", "Lower end of the range."),
    ("env.hazards.distance.max", "Upper end of the range."),
    ("env.hazards.trigger_time", "Seconds before the ego would reach a walker's crossing when it steps out (default 1.5–2.3)."),
    ("env.hazards.trigger_time.min", "Lower end of the range."),
    ("env.hazards.trigger_time.max", "Upper end of the range."),
    ("env.hazards.walker_speed", "Walking speed, m/s (default 1.3–1.8)."),
    ("env.hazards.walker_speed.min", "Lower end of the range."),
    ("env.hazards.walker_speed.max", "Upper end of the range."),
    ("env.hazards.closure_length", "Length of a construction closure, metres (default 12–20)."),
    ("env.hazards.closure_length.min", "Lower end of the range."),
    ("env.hazards.closure_length.max", "Upper end of the range."),
    ("env.hazards.stop_time", "Seconds a hard-braking leader stands still before driving on (default 2–4)."),
    ("env.hazards.stop_time.min", "Lower end of the range."),
    ("env.hazards.stop_time.max", "Upper end of the range."),
    ("env.hazards.cut_in_gap", "Bumper-to-bumper gap a cut-in leaves in front of the ego, metres (default 6–10)."),
    ("env.hazards.cut_in_gap.min", "Lower end of the range."),
    ("env.hazards.cut_in_gap.max", "Upper end of the range."),
    ("env.hazards.runner_speed", "Speed a junction runner crosses at, m/s (default 8–11)."),
    ("env.hazards.runner_speed.min", "Lower end of the range."),
    ("env.hazards.runner_speed.max", "Upper end of the range."),
    ("env.traffic.vehicles", "Moving traffic cars (0 = empty roads; 20 = default; 60+ = dense on the default town)."),
    ("env.traffic.parked_cars", "Cars parked on the roads' parking shoulders (default 12)."),
    (
        "env.traffic.parked_car_ahead",
        "The paper code's option: a parked car on the route, this many metres ahead of the start, standing in the lane (default: none).",
    ),
    ("env.traffic.spawn_clearance", "Traffic keeps at least this far from the ego vehicle when placed, metres (default 25)."),
    ("env.traffic.idm", "The Intelligent Driver Model of the traffic cars."),
    ("env.traffic.idm.accel", "Maximum acceleration, m/s² (default 2.0)."),
    ("env.traffic.idm.comfort_decel", "Comfortable deceleration, m/s² (default 2.0)."),
    ("env.traffic.idm.max_decel", "Hardest braking, m/s² (default 9.0)."),
    ("env.traffic.idm.min_gap", "Minimum bumper-to-bumper gap, metres (default 2.0)."),
    ("env.traffic.idm.headway", "Desired time headway, seconds (default 1.2)."),
    ("env.vehicle.length", "Body length, metres (default 4.5)."),
    ("env.vehicle.width", "Body width, metres (default 1.9)."),
    ("env.vehicle.wheelbase", "Distance between axles, metres (default 2.7)."),
    ("env.vehicle.max_accel", "Acceleration at full throttle from standstill, m/s² (default 3.5); falls linearly to 0 at `max_speed`."),
    ("env.vehicle.max_brake", "Deceleration at full brake, m/s² (default 8.0)."),
    ("env.vehicle.coast_decel", "Deceleration when coasting (rolling resistance and drag), m/s² (default 0.3)."),
    ("env.vehicle.max_speed", "Top speed, m/s (default 30)."),
    ("env.vehicle.max_steer", "Front-wheel angle at full lock when slow, radians (default 0.6)."),
    (
        "env.vehicle.steer_halving_speed",
        "Speed at which the usable lock has halved, m/s (default 10): steering is gentler when fast, as in driving games and CARLA, so that a full-lock command is a lane change, not a spin.",
    ),
    ("env.vehicle.steer_rate", "How fast the wheels turn toward the commanded angle, radians per second (default 2.0)."),
    ("env.reward.collision", "Reward of a collision step, r_c (default −1)."),
    ("env.reward.arrival", "Reward of the arrival step (default 100)."),
    ("env.reward.arrival_radius", "Arrival radius ε around the destination, metres (default 5)."),
    ("env.reward.v0_kmh", "Desired speed v0, km/h (default 50)."),
    ("env.reward.d0", "Waypoint distance scale d0, metres (default 8)."),
    ("env.reward.beta_v", "Weight β_v of the speed term (default 1)."),
    ("env.reward.beta_l", "Weight β_l of the progress term (default 1)."),
    ("env.reward.beta_w", "Weight β_w of the waypoint term (default 1)."),
    ("env.reward.clip", "If set, the per-step shaped reward (not collision or arrival) is clipped to ±this."),
    ("env.camera.width", "Image width, pixels (default 84)."),
    ("env.camera.height", "Image height, pixels (default 84)."),
    ("env.camera.rgb", "RGB (3 bytes per pixel) instead of gray (1 byte) (default false)."),
    ("env.camera.hfov_deg", "Horizontal field of view, degrees (default 90)."),
    ("env.camera.mount_height", "Height of the lens above the ground, metres (default 1.6)."),
    ("env.camera.mount_forward", "Distance of the lens ahead of the vehicle's centre, metres (default 1.0)."),
    ("env.camera.pitch_deg", "Downward tilt, degrees, realised as a lens shift (default 8)."),
    ("env.camera.max_distance", "Nothing farther than this is drawn, metres (default 150)."),
    ("agent.action_set", "Discrete actions (default `paper6`, the paper code's six)."),
    ("agent.conv_filters", "Filters of each of the three convolution layers (default 64, the paper's)."),
    ("agent.hidden", "Units of each of the two hidden fully connected layers (default 256, the paper's)."),
    (
        "agent.precision",
        "Arithmetic of the wide convolutions: \"auto\" (bf16 on AMX where the CPU has it, else f32; default), \"f32\", or \"bf16\" (refused without AMX).",
    ),
    ("agent.gamma", "Discount γ (default 0.99)."),
    ("agent.learning_rate", "Adam learning rate (default 2.5e-4)."),
    ("agent.batch_size", "Transitions per update (default 32)."),
    ("agent.replay_capacity", "Replay capacity, transitions (default 100 000)."),
    ("agent.replay_max_bytes", "Replay memory cap, bytes, frames included (default 2 GiB)."),
    ("agent.min_replay", "Transitions stored before training starts (default 1 000)."),
    ("agent.replay_ratio", "Samples trained per transition inserted (default 0.25: one batch of 32 per 128 steps)."),
    ("agent.target_update_period", "Updates between target-network copies (default 1 000)."),
    ("agent.grad_clip_norm", "Gradients are rescaled to at most this global L2 norm (default 10)."),
    ("agent.huber_delta", "Huber loss threshold δ (default 1)."),
    (
        "agent.double_dqn",
        "Extension switch: double DQN targets, the online network choosing the next action and the target network valuing it (van Hasselt 2016) (default false: the paper's plain DQN).",
    ),
    (
        "agent.prioritized_replay",
        "Extension switch: prioritized replay, sampling by TD error (Schaul 2016) (default false: uniform, the paper's).",
    ),
    ("agent.priority_alpha", "Prioritization exponent α of prioritized replay (default 0.6)."),
    ("agent.priority_beta", "Importance-sampling exponent β of prioritized replay (default 0.4)."),
    ("agent.n_step", "Extension switch: n-step returns, 1..=32 (default 1, the paper's one-step targets)."),
    (
        "agent.path_features",
        "Extension switch, hybrid agent only: the network also sees the planner's path as signed numbers (lateral offset, heading angles to the route near and 25 m ahead; sim-core's `Env::path_features`), not only the paper's unsigned d (default false).",
    ),
    (
        "agent.epsilon_start",
        "Exploration: ε decays linearly from `epsilon_start` (default 1.0) to `epsilon_end` over `epsilon_decay_steps` environment steps.",
    ),
    ("agent.epsilon_end", "Exploration rate at the end of the decay (default 0.05)."),
    ("agent.epsilon_decay_steps", "Environment steps of the decay (default 200 000)."),
    (
        "agent.per_actor_epsilon",
        "Extension switch: per-actor ε (Ape-X: ε_i = ε^(1 + α·i/(N−1)), i the actor's index, N = `apex_actors`) instead of the schedule (default false; ε = 0.4, α = 7, N = 8).",
    ),
    ("agent.apex_epsilon", "Ape-X base ε (default 0.4), with `per_actor_epsilon`."),
    ("agent.apex_alpha", "Ape-X exponent α (default 7), with `per_actor_epsilon`."),
    ("agent.apex_actors", "Ape-X actor count N the exponents are spread over (default 8), with `per_actor_epsilon`."),
    ("agent.publish_every_updates", "Updates between weight publications to actors (default 10)."),
    ("agent.seed", "Seed of network initialisation and replay sampling (default 0)."),
    ("service.listen", "gRPC listen address (default 127.0.0.1:50051)."),
    ("service.run_dir", "Run directory: effective config, checkpoints, metrics (default `runs/default`)."),
    (
        "service.checkpoint_interval_secs",
        "Seconds between checkpoints (default 300; a fresh run writes one before it serves, the first after training starts comes within 30 s, and a failed write is retried with backoff).",
    ),
    (
        "service.max_message_bytes",
        "Largest gRPC message accepted or sent, bytes (default 64 MiB: a weights message is ~7 MB for the paper network, a batch of 256 84×84 RGB transitions ~5.4 MB).",
    ),
    (
        "service.actor_timeout_secs",
        "An actor counts as connected while an experience stream of it is open and it was heard from within this many seconds (default 10).",
    ),
    ("service.stats_window", "Episodes in the rolling statistics of the status (default 100)."),
    (
        "service.durability",
        "`ack` (default): a batch is acknowledged only once it is in the replay log on disk (RUN_DIR/replay-log/, group-committed) and --resume rebuilds the replay from it; `none`: acknowledged once in memory, the replay starts empty after a restart.",
    ),
    (
        "service.replay_log_segment_bytes",
        "Bytes per replay log segment (default 64 MiB); segments whose transitions have all left the replay are deleted.",
    ),
    (
        "service.tls_cert",
        "PEM certificate the learner serves TLS with, gRPC and metrics (default empty: plaintext); with tls_key; re-read on SIGHUP and when it changes (--tls-cert).",
    ),
    ("service.tls_key", "PEM private key of tls_cert (default empty; --tls-key)."),
    (
        "service.tls_client_ca",
        "PEM CA that clients' certificates must be signed by: mutual TLS (default empty: no client certificate needed; needs tls_cert; --tls-client-ca).",
    ),
    (
        "preset",
        "A named preset the file starts from (`paper`, `end-to-end`, `hybrid-tuned`, `end-to-end-tuned`); the file's other values override it, table by table.",
    ),
    ("env", "The simulated world: the environment every actor runs."),
    ("agent", "The DQN agent: network sizes, learning, replay, exploration."),
    ("service", "The learner service (`learner serve`; `actor train` sets listen and run_dir itself)."),
];

/// Optional fields that are absent by default: shown commented out in their table, with a value
/// to start from.
const OPTIONAL: &[(&str, &str)] = &[("env.map", "\"Town01.xodr\""), ("env.traffic.parked_car_ahead", "10.0"), ("env.reward.clip", "1.0")];

/// What a field or table means, by dotted path (`agent.gamma`, `env.camera`).
#[must_use]
pub fn field_doc(path: &str) -> Option<&'static str> {
    FIELD_DOCS.iter().find(|(p, _)| *p == path).map(|(_, d)| *d)
}

/// `cfg` as TOML with a comment above every table and field (the same values as
/// [`RunConfig::to_toml`]: comments only).
#[must_use]
pub fn commented_toml(cfg: &RunConfig) -> String {
    let mut out = String::from(
        "# hybrid-drive run configuration (TOML). Every field is shown with its value; a file may\n\
         # set only some of them: the rest take these defaults. Units are in the comments.\n\
         # Use with `learner serve --config FILE` or `actor train --config FILE`;\n\
         # `learner config --config FILE` checks a file and prints it completed.\n\n",
    );
    let mut table = String::new();
    for line in cfg.to_toml().lines() {
        let trimmed = line.trim();
        if let Some(name) = trimmed.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
            table = name.to_owned();
            if let Some(doc) = field_doc(name) {
                comment(&mut out, doc);
            }
            out.push_str(line);
            out.push('\n');
            for (path, example) in OPTIONAL {
                if let Some(key) = path.strip_prefix(&format!("{table}.")).filter(|k| !k.contains('.'))
                    && !cfg.to_toml().contains(&format!("\n{key} = "))
                {
                    comment(&mut out, field_doc(path).unwrap_or_default());
                    out.push_str(&format!("# {key} = {example}\n"));
                }
            }
            continue;
        }
        if let Some((key, _)) = trimmed.split_once(" = ") {
            let path = if table.is_empty() { key.to_owned() } else { format!("{table}.{key}") };
            if let Some(doc) = field_doc(&path) {
                comment(&mut out, doc);
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// Appends `doc` as `# ` lines of at most ~100 characters.
fn comment(out: &mut String, doc: &str) {
    let mut line = String::from("#");
    for word in doc.split_whitespace() {
        if line.len() + word.len() > 99 {
            out.push_str(&line);
            out.push('\n');
            line = String::from("#");
        }
        line.push(' ');
        line.push_str(word);
    }
    out.push_str(&line);
    out.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every table and field of `toml` by dotted path.
    fn paths(toml: &str) -> Vec<String> {
        let mut table = String::new();
        let mut out = Vec::new();
        for line in toml.lines() {
            if let Some(name) = line.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
                table = name.to_owned();
                out.push(table.clone());
            } else if let Some((key, _)) = line.split_once(" = ") {
                out.push(if table.is_empty() { key.to_owned() } else { format!("{table}.{key}") });
            }
        }
        out
    }

    #[test]
    fn every_field_of_every_preset_is_explained_and_the_file_reads_back_the_same() {
        for name in [None, Some("paper"), Some("end-to-end"), Some("hybrid-tuned"), Some("end-to-end-tuned")] {
            let cfg = name.map_or_else(RunConfig::default, |n| RunConfig::preset(n).unwrap());
            let text = commented_toml(&cfg);
            for path in paths(&cfg.to_toml()) {
                assert!(field_doc(&path).is_some(), "no description for `{path}`: add it to FIELD_DOCS");
            }
            assert_eq!(RunConfig::from_toml(&text, "commented").unwrap(), cfg, "{name:?}");
            assert!(text.contains("# Discount γ (default 0.99).\ngamma = "), "{text}");
            assert!(text.contains("# clip = 1.0\n") && text.contains("# parked_car_ahead = 10.0\n"), "{text}");
            assert!(text.lines().all(|l| l.chars().count() <= 110), "a line is too long");
        }
    }

    #[test]
    fn optional_fields_that_are_set_are_not_repeated_as_comments() {
        let mut cfg = RunConfig::default();
        cfg.env.reward.clip = Some(2.0);
        let text = commented_toml(&cfg);
        assert!(text.contains("\nclip = 2.0\n") && !text.contains("# clip = 1.0"), "{text}");
    }
}
