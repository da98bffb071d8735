//! The DQN update (Mnih et al. 2015): online and target networks, Huber loss on the TD error,
//! Adam, gradient clipping by global norm, optional double-DQN targets and importance weights,
//! and on demonstrations DQfD's large-margin loss (Hester et al. 2018) added to the TD loss.
//! The networks run on the fast CPU implementation ([`crate::fastnet`]).

use agent::NetShape;
use agent::config::AgentConfig;
use agent::fastnet::{Adam, FastNet, Params, argmax, default_threads};

/// A batch of transitions ready for an update.
#[derive(Debug, Clone, Default)]
pub struct Batch {
    /// Frames, `H × W × C` bytes each, back to back.
    pub images: Vec<u8>,
    /// Scalar inputs, `S` per transition.
    pub scalars: Vec<f32>,
    /// Action indices.
    pub actions: Vec<u32>,
    /// n-step discounted rewards.
    pub rewards: Vec<f32>,
    pub next_images: Vec<u8>,
    pub next_scalars: Vec<f32>,
    /// γ^n for bootstrapped transitions, 0 for terminal ones.
    pub discounts: Vec<f32>,
    /// Importance-sampling weights (all 1 for uniform replay).
    pub weights: Vec<f32>,
    /// The last `demos` transitions are demonstrations: the large-margin loss applies to them.
    pub demos: usize,
}

impl Batch {
    /// Transitions in the batch.
    #[must_use]
    pub fn len(&self) -> usize {
        self.actions.len()
    }

    /// Whether the batch holds no transition.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.actions.is_empty()
    }
}

/// What an update measured.
#[derive(Debug, Clone, PartialEq)]
pub struct UpdateStats {
    pub loss: f32,
    pub mean_q: f32,
    /// |TD error| per transition (for prioritized replay).
    pub td_abs: Vec<f32>,
    /// Global gradient norm before clipping.
    pub grad_norm: f32,
    /// The large-margin loss J_E, mean over the batch's demonstrations (unweighted by λ); none
    /// without demonstrations.
    pub margin_loss: Option<f32>,
}

/// The learning agent: online and target parameters, the optimizer, and the network's buffers.
#[derive(Debug)]
pub struct Dqn {
    pub shape: NetShape,
    pub online: Params,
    pub target: Params,
    pub adam: Adam,
    net: FastNet,
    grads: Params,
    pub huber_delta: f32,
    pub grad_clip_norm: f32,
    pub double_dqn: bool,
    /// Updates done.
    pub updates: u64,
    pub target_update_period: u64,
    /// Polyak averaging of the target after every update; 0 copies it every
    /// `target_update_period` updates instead.
    pub target_tau: f32,
    /// DQfD's margin l (`agent.demo_margin`).
    pub demo_margin: f32,
    /// Weight λ of the large-margin loss (`agent.demo_margin_weight`; 0: off).
    pub demo_margin_weight: f32,
}

impl Dqn {
    /// A fresh agent on every core: both networks initialised from `cfg.seed` (identical), Adam
    /// at zero.
    #[must_use]
    pub fn new(shape: NetShape, cfg: &AgentConfig) -> Self {
        Self::with_threads(shape, cfg, default_threads())
    }

    /// As [`Dqn::new`], computing on `threads` threads.
    #[must_use]
    ///
    /// # Panics
    /// If `cfg.precision` cannot run here (`bf16` without a bf16 kernel): check it with
    /// `Precision::resolve` first, as `learner serve` does.
    pub fn with_threads(shape: NetShape, cfg: &AgentConfig, threads: usize) -> Self {
        let chosen = cfg.precision.resolve().unwrap_or_else(|e| panic!("Dqn: {e}"));
        let online = Params::init(shape, cfg.seed);
        Self {
            shape,
            target: online.clone(),
            online,
            adam: Adam::new(shape, cfg.learning_rate),
            net: FastNet::with_precision(shape, threads, chosen.bf16),
            grads: Params::zeros(shape),
            huber_delta: cfg.huber_delta,
            grad_clip_norm: cfg.grad_clip_norm,
            double_dqn: cfg.double_dqn,
            updates: 0,
            target_update_period: cfg.target_update_period,
            target_tau: cfg.target_tau,
            demo_margin: cfg.demo_margin,
            demo_margin_weight: cfg.demo_margin_weight,
        }
    }

    /// Q values of the online network, `batch × actions` row-major.
    pub fn q_values(&mut self, images: &[u8], scalars: &[f32]) -> Vec<f32> {
        self.net.forward(&self.online, images, scalars).to_vec()
    }

    /// The bootstrap targets y = r + discount · Q_target(s', a*) with a* the target network's
    /// greedy action (or the online network's, for double DQN).
    pub fn targets(&mut self, b: &Batch) -> Vec<f32> {
        let a = self.shape.actions;
        let q_next = self.net.forward(&self.target, &b.next_images, &b.next_scalars).to_vec();
        let chosen: Vec<usize> = if self.double_dqn {
            self.net.forward(&self.online, &b.next_images, &b.next_scalars).chunks_exact(a).map(argmax).collect()
        } else {
            q_next.chunks_exact(a).map(argmax).collect()
        };
        (0..b.len()).map(|i| b.rewards[i] + b.discounts[i] * q_next[i * a + chosen[i]]).collect()
    }

    /// One gradient step on `batch`; then moves the target `target_tau` of the way to the online
    /// network, or (τ = 0) copies the online network into it every `target_update_period` updates.
    pub fn update(&mut self, b: &Batch) -> UpdateStats {
        let (n, a) = (b.len(), self.shape.actions);
        let y = self.targets(b);
        let q = self.net.forward(&self.online, &b.images, &b.scalars);
        let mut dq = vec![0f32; n * a];
        let (mut loss, mut q_sum) = (0f64, 0f64);
        let mut td_abs = Vec::with_capacity(n);
        for (i, ((&target, &action), &weight)) in y.iter().zip(&b.actions).zip(&b.weights).enumerate() {
            let k = i * a + action as usize;
            let td = q[k] - target;
            loss += f64::from(weight * huber(td, self.huber_delta));
            q_sum += f64::from(q[k]);
            td_abs.push(td.abs());
            // d/dq of the batch mean of w·huber(q − y).
            dq[k] = weight * td.clamp(-self.huber_delta, self.huber_delta) / n as f32;
        }
        let margin_loss = add_margin_loss(self.demo_margin, self.demo_margin_weight, a, q, b, &mut dq, &mut loss);
        self.net.backward(&self.online, &dq, &mut self.grads);
        let grad_norm = self.adam.step(&mut self.online, &self.grads, self.grad_clip_norm, self.net.threads());
        self.updates += 1;
        if self.target_tau > 0.0 {
            self.average_target();
        } else if self.updates.is_multiple_of(self.target_update_period) {
            self.sync_target();
        }
        UpdateStats { loss: (loss / n as f64) as f32, mean_q: (q_sum / n as f64) as f32, td_abs, grad_norm, margin_loss }
    }

    /// Copies the online parameters into the target network.
    pub fn sync_target(&mut self) {
        self.target.clone_from(&self.online);
    }

    /// θ' ← θ' + τ(θ − θ'), element by element in one order: deterministic.
    fn average_target(&mut self) {
        let tau = self.target_tau;
        for (t, o) in self.target.values.iter_mut().zip(&self.online.values) {
            for (x, &y) in t.iter_mut().zip(o) {
                *x += tau * (y - *x);
            }
        }
    }
}

/// Adds λ·J_E/n for each demonstration of the batch to `loss` (a sum over the batch, as the
/// TD loss's) and its gradient to `dq`, where J_E = max_a [Q(s,a) + l(a_E,a)] − Q(s,a_E),
/// l = `margin` for a ≠ a_E and 0 for a_E. Its gradient is +1 at the maximising action
/// and −1 at a_E (nothing when a_E maximises). Returns the mean J_E over the demonstrations.
fn add_margin_loss(margin: f32, weight: f32, a: usize, q: &[f32], b: &Batch, dq: &mut [f32], loss: &mut f64) -> Option<f32> {
    let n = b.len();
    if b.demos == 0 {
        return None;
    }
    let scale = weight / n as f32;
    let mut sum = 0f64;
    for i in n - b.demos..n {
        let row = &q[i * a..(i + 1) * a];
        let demonstrated = b.actions[i] as usize;
        let (best, value) = margin_argmax(row, demonstrated, margin);
        let j = value - row[demonstrated];
        sum += f64::from(j);
        if weight > 0.0 && best != demonstrated {
            *loss += f64::from(weight * j);
            dq[i * a + best] += scale;
            dq[i * a + demonstrated] -= scale;
        }
    }
    Some((sum / b.demos as f64) as f32)
}

/// The action maximising Q(s,a) + l(a_E,a) over a row of Q values, and that maximum (the first
/// action of a tie; `demonstrated` wins a tie, so J_E is 0 there and has no gradient).
#[must_use]
pub fn margin_argmax(row: &[f32], demonstrated: usize, margin: f32) -> (usize, f32) {
    let mut best = (demonstrated, row[demonstrated]);
    for (k, &x) in row.iter().enumerate() {
        let v = if k == demonstrated { x } else { x + margin };
        if v > best.1 {
            best = (k, v);
        }
    }
    best
}

/// Huber loss: ½x² for |x| ≤ δ, δ(|x| − ½δ) beyond.
#[must_use]
pub fn huber(x: f32, delta: f32) -> f32 {
    if x.abs() <= delta { 0.5 * x * x } else { delta * (x.abs() - 0.5 * delta) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape() -> NetShape {
        NetShape { height: 8, width: 8, channels: 1, scalars: 2, actions: 2, filters: 2, hidden: 4 }
    }

    fn batch(rewards: &[f32], discounts: &[f32]) -> Batch {
        let n = rewards.len();
        let images: Vec<u8> = (0..n).flat_map(|i| vec![(i * 40) as u8; 64]).collect();
        Batch {
            images: images.clone(),
            scalars: vec![0.0; 2 * n],
            actions: (0..n as u32).map(|i| i % 2).collect(),
            rewards: rewards.to_vec(),
            next_images: images,
            next_scalars: vec![0.0; 2 * n],
            discounts: discounts.to_vec(),
            weights: vec![1.0; n],
            demos: 0,
        }
    }

    /// J_E by hand: Q = (1.0, 0.5, 0.9), demonstrated action 1, margin 0.8: Q + l = (1.8, 0.5,
    /// 1.7), max 1.8 at action 0, J_E = 1.8 − 0.5 = 1.3. With margin 0.3: (1.3, 0.5, 1.2) → 0.8.
    /// Demonstrated action 0 with margin 0.05: (1.0, 0.55, 0.95) → the demonstration itself, 0.
    #[test]
    fn the_margin_loss_matches_hand_computation() {
        let row = [1.0f32, 0.5, 0.9];
        let (best, v) = margin_argmax(&row, 1, 0.8);
        assert_eq!(best, 0);
        assert!((v - row[1] - 1.3).abs() < 1e-6, "{}", v - row[1]);
        let (best, v) = margin_argmax(&row, 1, 0.3);
        assert!(best == 0 && (v - row[1] - 0.8).abs() < 1e-6);
        assert_eq!(margin_argmax(&row, 0, 0.05), (0, 1.0));
    }

    /// The update's margin term on a real network: the reported J_E is the hand formula applied to
    /// the online network's Q values; its gradient is λ/n at the maximising action and −λ/n at the
    /// demonstrated one, so the loss (TD + λ·J_E/n) and the gradient norm grow with λ, and λ = 0
    /// leaves the update exactly as without demonstrations.
    #[test]
    fn the_update_adds_the_margin_loss_on_demonstrations_only() {
        let mut b = batch(&[0.0, 0.0, 0.0, 0.0], &[0.0; 4]);
        let cfg = |weight: f32| AgentConfig { demo_margin: 0.8, demo_margin_weight: weight, grad_clip_norm: 1e9, ..AgentConfig::default() };
        // The last two are demonstrations; make each demonstrate its worse action.
        b.demos = 2;
        let mut probe = Dqn::new(shape(), &cfg(1.0));
        let q = probe.q_values(&b.images, &b.scalars);
        for i in 2..4 {
            b.actions[i] = if q[2 * i] < q[2 * i + 1] { 0 } else { 1 };
        }
        let expected: f32 = (2..4)
            .map(|i| {
                let (d, other) = (b.actions[i] as usize, 1 - b.actions[i] as usize);
                (q[2 * i + other] + 0.8).max(q[2 * i + d]) - q[2 * i + d]
            })
            .sum::<f32>()
            / 2.0;
        let with = Dqn::new(shape(), &cfg(1.0)).update(&b);
        let margin = with.margin_loss.unwrap();
        assert!((margin - expected).abs() < 1e-5, "{margin} vs {expected} (by hand from the Q values)");
        assert!(expected > 0.8, "each demonstrated action is the worse one: J_E > l");
        let off = Dqn::new(shape(), &cfg(0.0)).update(&b);
        let plain = Dqn::new(shape(), &cfg(1.0)).update(&Batch { demos: 0, ..b.clone() });
        assert_eq!((off.loss, off.grad_norm), (plain.loss, plain.grad_norm), "λ = 0 is the update without demonstrations");
        assert_eq!(plain.margin_loss, None);
        // Loss: the TD part plus λ·ΣJ_E/n = 1 · (2·expected)/4.
        assert!((with.loss - (plain.loss + expected / 2.0)).abs() < 1e-5, "{} vs {} + {}", with.loss, plain.loss, expected / 2.0);
    }

    #[test]
    fn huber_matches_its_definition() {
        let h: Vec<f32> = [-3.0f32, -1.0, -0.5, 0.0, 0.5, 2.0].iter().map(|&x| huber(x, 1.0)).collect();
        // ½x² inside ±1, |x| − ½ outside.
        assert_eq!(h, vec![2.5, 0.5, 0.125, 0.0, 0.125, 1.5]);
    }

    #[test]
    fn targets_match_hand_computation() {
        let mut dqn = Dqn::new(shape(), &AgentConfig::default());
        let b = batch(&[1.0, -1.0, 0.5], &[0.99, 0.0, 0.5]);
        let q_next = FastNet::new(shape(), 1).forward(&dqn.target, &b.next_images, &b.next_scalars).to_vec();
        let y = dqn.targets(&b);
        // y = r + discount · max_a Q_target(s', a); terminal (discount 0) is just r.
        for (i, (r, g)) in [(1.0f32, 0.99f32), (-1.0, 0.0), (0.5, 0.5)].iter().enumerate() {
            let expected = r + g * q_next[2 * i].max(q_next[2 * i + 1]);
            assert!((y[i] - expected).abs() < 1e-6, "{i}: {} vs {expected}", y[i]);
        }
        assert_eq!(y[1], -1.0);
    }

    #[test]
    fn an_update_moves_q_toward_the_target_and_syncs_the_target_on_schedule() {
        let cfg = AgentConfig { learning_rate: 1e-2, target_update_period: 5, ..AgentConfig::default() };
        let mut dqn = Dqn::new(shape(), &cfg);
        let b = batch(&[1.0, 1.0, 1.0, 1.0], &[0.0; 4]);
        let first = dqn.update(&b).loss;
        let target_before = dqn.target.clone();
        for _ in 0..3 {
            dqn.update(&b);
        }
        assert_eq!(dqn.target, target_before, "target frozen between syncs");
        let last = dqn.update(&b).loss;
        assert!(last < first, "loss should fall on a fixed batch: {first} -> {last}");
        assert_eq!(dqn.updates, 5);
        assert_eq!(dqn.target, dqn.online, "synced at update 5");
    }

    #[test]
    fn with_tau_the_target_moves_tau_of_the_way_to_the_online_network_after_every_update() {
        let cfg = AgentConfig { learning_rate: 1e-2, target_update_period: 1, target_tau: 0.25, ..AgentConfig::default() };
        let mut dqn = Dqn::new(shape(), &cfg);
        let b = batch(&[1.0, 1.0, 1.0, 1.0], &[0.0; 4]);
        for _ in 0..3 {
            let before = dqn.target.clone();
            dqn.update(&b);
            assert_ne!(dqn.target, dqn.online, "averaged, not copied (the period of 1 goes unused)");
            for ((t, t0), o) in dqn.target.values.iter().zip(&before.values).zip(&dqn.online.values) {
                for ((&x, &x0), &y) in t.iter().zip(t0).zip(o) {
                    assert_eq!(x, x0 + 0.25 * (y - x0));
                }
            }
        }
        let full = AgentConfig { target_tau: 1.0, ..cfg };
        let mut dqn = Dqn::new(shape(), &full);
        dqn.update(&b);
        assert_eq!(dqn.target, dqn.online, "τ = 1 is a copy after every update");
    }

    #[test]
    fn the_loss_gradient_is_the_clipped_td_error() {
        // With δ = 1 and one transition of TD error −3 (y = q + 3), dq = −1 (clipped): the
        // gradient norm equals that of the network's output gradient scaled by 1, whatever the
        // magnitude of the error beyond δ.
        let mut cfg = AgentConfig { huber_delta: 1.0, ..AgentConfig::default() };
        cfg.grad_clip_norm = 1e9;
        let norm_for = |reward_shift: f32| {
            let mut dqn = Dqn::new(shape(), &cfg);
            let mut b = batch(&[0.0], &[0.0]);
            let q = dqn.q_values(&b.images, &b.scalars);
            b.rewards[0] = q[0] + reward_shift;
            dqn.update(&b).grad_norm
        };
        let (a, b) = (norm_for(3.0), norm_for(30.0));
        assert!((a - b).abs() <= 1e-6 * a, "clipped: {a} vs {b}");
        let c = norm_for(0.5);
        assert!((c - 0.5 * a).abs() <= 1e-5 * a, "inside δ the gradient is linear in the error: {c} vs {}", 0.5 * a);
    }

    #[test]
    fn adam_first_step_moves_each_parameter_by_the_learning_rate() {
        // With bias correction, Adam's first step is lr · g/|g| (up to eps) for every non-zero
        // gradient element: a hand-checkable property.
        let mut params = Params::zeros(shape());
        let mut grads = Params::zeros(shape());
        params.values[1] = vec![1.0, -2.0];
        grads.values[1] = vec![2.0, -4.0];
        let mut adam = Adam::new(shape(), 0.1);
        adam.step(&mut params, &grads, 1e9, 1);
        assert!((params.values[1][0] - 0.9).abs() < 1e-5 && (params.values[1][1] + 1.9).abs() < 1e-5, "{:?}", params.values[1]);
        assert!(params.values[0].iter().all(|&x| x == 0.0), "zero gradient, no move");
    }

    #[test]
    fn gradients_are_clipped_to_the_global_norm() {
        let mut params = Params::zeros(shape());
        let mut grads = Params::zeros(shape());
        // Gradient (3, 4): norm 5, reported before clipping.
        grads.values[1] = vec![3.0, 4.0];
        let mut adam = Adam::new(shape(), 0.1);
        let norm = adam.step(&mut params, &grads, 1.0, 2);
        assert!((norm - 5.0).abs() < 1e-6);
        // Clipped to (0.6, 0.8): the first moment is (1 − β1)·g.
        let m = &adam.m.values[1];
        assert!((m[0] - 0.06).abs() < 1e-6 && (m[1] - 0.08).abs() < 1e-6, "{m:?}");
    }
}
