//! The DQN update (Mnih et al. 2015): online and target networks, Huber loss on the TD error,
//! Adam, gradient clipping by global norm, optional double-DQN targets and importance weights.

use candle_core::{D, DType, Device, Result, Tensor, Var};
use candle_nn::VarMap;

use crate::config::AgentConfig;
use crate::net::{NetShape, QNetwork, copy_parameters, init_parameters, network};

/// A batch of transitions ready for an update.
#[derive(Debug, Clone)]
pub struct Batch {
    /// `[B, C, H, W]` in 0–1.
    pub images: Tensor,
    /// `[B, S]`.
    pub scalars: Tensor,
    /// Action indices `[B]` (u32).
    pub actions: Tensor,
    /// n-step discounted rewards `[B]`.
    pub rewards: Tensor,
    pub next_images: Tensor,
    pub next_scalars: Tensor,
    /// γ^n for bootstrapped transitions, 0 for terminal ones `[B]`.
    pub discounts: Tensor,
    /// Importance-sampling weights `[B]` (all 1 for uniform replay).
    pub weights: Tensor,
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
}

/// Adam (Kingma & Ba 2015) with its moments kept where checkpoints can reach them.
#[derive(Debug)]
pub struct Adam {
    pub lr: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub eps: f64,
    /// Steps taken.
    pub t: u64,
    /// (parameter name, variable, first moment, second moment), sorted by name.
    pub slots: Vec<(String, Var, Tensor, Tensor)>,
}

impl Adam {
    /// An optimizer over every variable of `vars`, moments at zero.
    pub fn new(vars: &VarMap, lr: f64) -> Result<Self> {
        let data = vars.data().lock().expect("var map lock");
        let mut slots: Vec<(String, Var, Tensor, Tensor)> = data
            .iter()
            .map(|(k, v)| Ok((k.clone(), v.clone(), v.as_tensor().zeros_like()?, v.as_tensor().zeros_like()?)))
            .collect::<Result<_>>()?;
        slots.sort_by(|a, b| a.0.cmp(&b.0));
        Ok(Self { lr, beta1: 0.9, beta2: 0.999, eps: 1e-8, t: 0, slots })
    }

    /// One step with the gradients of `loss`, rescaled so that their global norm is at most
    /// `clip`. Returns the norm before clipping.
    pub fn step(&mut self, grads: &candle_core::backprop::GradStore, clip: f32) -> Result<f32> {
        let mut sq = 0f32;
        for (_, var, _, _) in &self.slots {
            if let Some(g) = grads.get(var.as_tensor()) {
                sq += g.sqr()?.sum_all()?.to_scalar::<f32>()?;
            }
        }
        let norm = sq.sqrt();
        let scale = if norm > clip { f64::from(clip / norm) } else { 1.0 };
        self.t += 1;
        let bc1 = 1.0 - self.beta1.powi(self.t as i32);
        let bc2 = 1.0 - self.beta2.powi(self.t as i32);
        for (_, var, m, v) in &mut self.slots {
            let Some(g) = grads.get(var.as_tensor()) else { continue };
            let g = (g * scale)?;
            *m = ((&*m * self.beta1)? + (&g * (1.0 - self.beta1))?)?;
            *v = ((&*v * self.beta2)? + (g.sqr()? * (1.0 - self.beta2))?)?;
            let m_hat = (&*m / bc1)?;
            let v_hat = (&*v / bc2)?;
            let delta = ((m_hat / (v_hat.sqrt()? + self.eps)?)? * self.lr)?;
            var.set(&var.as_tensor().sub(&delta)?)?;
        }
        Ok(norm)
    }
}

/// The learning agent: online and target networks and the optimizer.
pub struct Dqn {
    pub shape: NetShape,
    pub device: Device,
    pub online_vars: VarMap,
    pub target_vars: VarMap,
    online: QNetwork,
    target: QNetwork,
    pub adam: Adam,
    pub huber_delta: f32,
    pub grad_clip_norm: f32,
    pub double_dqn: bool,
    /// Updates done.
    pub updates: u64,
    pub target_update_period: u64,
}

impl std::fmt::Debug for Dqn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Dqn").field("shape", &self.shape).field("updates", &self.updates).finish_non_exhaustive()
    }
}

impl Dqn {
    /// A fresh agent: both networks initialised from `cfg.seed` (identical), Adam at zero.
    pub fn new(shape: NetShape, cfg: &AgentConfig, device: &Device) -> Result<Self> {
        let online_vars = init_parameters(&shape, cfg.seed, device)?;
        let target_vars = init_parameters(&shape, cfg.seed, device)?;
        let online = network(&online_vars, shape, device)?;
        let target = network(&target_vars, shape, device)?;
        let adam = Adam::new(&online_vars, cfg.learning_rate)?;
        Ok(Self {
            shape,
            device: device.clone(),
            online_vars,
            target_vars,
            online,
            target,
            adam,
            huber_delta: cfg.huber_delta,
            grad_clip_norm: cfg.grad_clip_norm,
            double_dqn: cfg.double_dqn,
            updates: 0,
            target_update_period: cfg.target_update_period,
        })
    }

    /// Q values of the online network.
    pub fn q_values(&self, images: &Tensor, scalars: &Tensor) -> Result<Tensor> {
        self.online.forward(images, scalars)
    }

    /// The bootstrap targets y = r + discount · Q_target(s', a*) with a* the target network's
    /// greedy action (or the online network's, for double DQN). No gradient flows through them.
    pub fn targets(&self, b: &Batch) -> Result<Tensor> {
        let q_next_target = self.target.forward(&b.next_images, &b.next_scalars)?;
        let best = if self.double_dqn {
            let a = self.online.forward(&b.next_images, &b.next_scalars)?.argmax_keepdim(D::Minus1)?;
            q_next_target.gather(&a, 1)?.squeeze(1)?
        } else {
            q_next_target.max(D::Minus1)?
        };
        (&b.rewards + (&b.discounts * best)?)?.detach().to_dtype(DType::F32)
    }

    /// One gradient step on `batch`; copies the online network into the target every
    /// `target_update_period` updates.
    pub fn update(&mut self, b: &Batch) -> Result<UpdateStats> {
        let y = self.targets(b)?;
        let q = self.online.forward(&b.images, &b.scalars)?;
        let q_taken = q.gather(&b.actions.unsqueeze(1)?, 1)?.squeeze(1)?;
        let td = (&q_taken - &y)?;
        let per = huber(&td, self.huber_delta)?;
        let loss = (per * &b.weights)?.mean_all()?;
        let grads = loss.backward()?;
        let grad_norm = self.adam.step(&grads, self.grad_clip_norm)?;
        self.updates += 1;
        if self.updates.is_multiple_of(self.target_update_period) {
            self.sync_target()?;
        }
        Ok(UpdateStats {
            loss: loss.to_scalar::<f32>()?,
            mean_q: q_taken.mean_all()?.to_scalar::<f32>()?,
            td_abs: td.abs()?.to_vec1::<f32>()?,
            grad_norm,
        })
    }

    /// Copies the online parameters into the target network.
    pub fn sync_target(&mut self) -> Result<()> {
        copy_parameters(&self.online_vars, &self.target_vars)
    }
}

/// Huber loss per element: ½x² for |x| ≤ δ, δ(|x| − ½δ) beyond.
pub fn huber(x: &Tensor, delta: f32) -> Result<Tensor> {
    let abs = x.abs()?;
    let quad = (x.sqr()? * 0.5)?;
    let lin = ((&abs - f64::from(delta) * 0.5)? * f64::from(delta))?;
    abs.le(f64::from(delta))?.where_cond(&quad, &lin)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::{images_tensor, to_safetensors};

    fn shape() -> NetShape {
        NetShape { height: 8, width: 8, channels: 1, scalars: 2, actions: 2, filters: 2, hidden: 4 }
    }

    fn batch(dqn: &Dqn, rewards: &[f32], discounts: &[f32]) -> Batch {
        let dev = &dqn.device;
        let n = rewards.len();
        let imgs: Vec<Vec<u8>> = (0..n).map(|i| vec![(i * 40) as u8; 64]).collect();
        let refs: Vec<&[u8]> = imgs.iter().map(Vec::as_slice).collect();
        let images = images_tensor(&refs, &dqn.shape, dev).unwrap();
        let scalars = Tensor::zeros((n, 2), DType::F32, dev).unwrap();
        Batch {
            images: images.clone(),
            scalars: scalars.clone(),
            actions: Tensor::from_vec((0..n as u32).map(|i| i % 2).collect::<Vec<_>>(), n, dev).unwrap(),
            rewards: Tensor::from_slice(rewards, n, dev).unwrap(),
            next_images: images,
            next_scalars: scalars,
            discounts: Tensor::from_slice(discounts, n, dev).unwrap(),
            weights: Tensor::ones(n, DType::F32, dev).unwrap(),
        }
    }

    #[test]
    fn huber_matches_its_definition() {
        let x = Tensor::new(&[-3.0f32, -1.0, -0.5, 0.0, 0.5, 2.0], &Device::Cpu).unwrap();
        let h: Vec<f32> = huber(&x, 1.0).unwrap().to_vec1().unwrap();
        // ½x² inside ±1, |x| − ½ outside.
        assert_eq!(h, vec![2.5, 0.5, 0.125, 0.0, 0.125, 1.5]);
    }

    #[test]
    fn targets_match_hand_computation() {
        let dqn = Dqn::new(shape(), &AgentConfig::default(), &Device::Cpu).unwrap();
        let b = batch(&dqn, &[1.0, -1.0, 0.5], &[0.99, 0.0, 0.5]);
        let q_next: Vec<Vec<f32>> = dqn.target.forward(&b.next_images, &b.next_scalars).unwrap().to_vec2().unwrap();
        let y: Vec<f32> = dqn.targets(&b).unwrap().to_vec1().unwrap();
        // y = r + discount · max_a Q_target(s', a); terminal (discount 0) is just r.
        for (i, (r, g)) in [(1.0f32, 0.99f32), (-1.0, 0.0), (0.5, 0.5)].iter().enumerate() {
            let expected = r + g * q_next[i][0].max(q_next[i][1]);
            assert!((y[i] - expected).abs() < 1e-6, "{i}: {} vs {expected}", y[i]);
        }
        assert_eq!(y[1], -1.0);
    }

    #[test]
    fn an_update_moves_q_toward_the_target_and_syncs_the_target_on_schedule() {
        let cfg = AgentConfig { learning_rate: 1e-2, target_update_period: 5, ..AgentConfig::default() };
        let mut dqn = Dqn::new(shape(), &cfg, &Device::Cpu).unwrap();
        let b = batch(&dqn, &[1.0, 1.0, 1.0, 1.0], &[0.0; 4]);
        let first = dqn.update(&b).unwrap().loss;
        let target_before = to_safetensors(&dqn.target_vars).unwrap();
        for _ in 0..3 {
            dqn.update(&b).unwrap();
        }
        assert_eq!(to_safetensors(&dqn.target_vars).unwrap(), target_before, "target frozen between syncs");
        let last = dqn.update(&b).unwrap().loss;
        assert!(last < first, "loss should fall on a fixed batch: {first} -> {last}");
        assert_eq!(dqn.updates, 5);
        assert_eq!(to_safetensors(&dqn.target_vars).unwrap(), to_safetensors(&dqn.online_vars).unwrap(), "synced at update 5");
    }

    #[test]
    fn adam_first_step_moves_each_parameter_by_the_learning_rate() {
        // With bias correction, Adam's first step is lr · g/|g| (up to eps) for every non-zero
        // gradient element: a hand-checkable property.
        let dev = Device::Cpu;
        let vars = VarMap::new();
        let w = Var::from_tensor(&Tensor::new(&[1.0f32, -2.0, 3.0], &dev).unwrap()).unwrap();
        vars.data().lock().unwrap().insert("w".into(), w.clone());
        let mut adam = Adam::new(&vars, 0.1).unwrap();
        let loss = (w.as_tensor() * Tensor::new(&[2.0f32, -4.0, 0.5], &dev).unwrap()).unwrap().sum_all().unwrap();
        adam.step(&loss.backward().unwrap(), 1e9).unwrap();
        let after: Vec<f32> = w.as_tensor().to_vec1().unwrap();
        for (a, e) in after.iter().zip([0.9f32, -1.9, 2.9]) {
            assert!((a - e).abs() < 1e-5, "{after:?}");
        }
    }

    #[test]
    fn gradients_are_clipped_to_the_global_norm() {
        let dev = Device::Cpu;
        let vars = VarMap::new();
        let w = Var::from_tensor(&Tensor::new(&[0.0f32, 0.0], &dev).unwrap()).unwrap();
        vars.data().lock().unwrap().insert("w".into(), w.clone());
        let mut adam = Adam::new(&vars, 0.1).unwrap();
        // Gradient (3, 4): norm 5, reported before clipping.
        let loss = (w.as_tensor() * Tensor::new(&[3.0f32, 4.0], &dev).unwrap()).unwrap().sum_all().unwrap();
        let norm = adam.step(&loss.backward().unwrap(), 1.0).unwrap();
        assert!((norm - 5.0).abs() < 1e-6);
        // Clipped to (0.6, 0.8): the first moment is (1 − β1)·g.
        let m: Vec<f32> = adam.slots[0].2.to_vec1().unwrap();
        assert!((m[0] - 0.06).abs() < 1e-6 && (m[1] - 0.08).abs() < 1e-6, "{m:?}");
    }
}
