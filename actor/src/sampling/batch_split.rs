//! Fitting batches to what the learner accepts: `Register` says the largest message
//! (`max_message_bytes`) and the most steps per batch (`max_batch_steps`); a batch over either is
//! cut, in order, into pieces below both, before it is sent.

use prost::Message;
use proto::v1 as pb;

/// Steps per batch a learner accepts when it does not say (learners before `max_batch_steps`).
pub const DEFAULT_MAX_BATCH_STEPS: usize = 4096;

/// Bytes kept free below the limit for the batch's other fields (actor id, counters, episode
/// summaries are counted separately) and the gRPC frame.
const MARGIN: usize = 4096;

/// What a batch must fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    pub max_bytes: usize,
    pub max_steps: usize,
}

impl Limits {
    /// The limits a `Register` answer states.
    #[must_use]
    pub fn from_register(r: &pb::RegisterResponse) -> Self {
        let max_steps = if r.max_batch_steps == 0 { DEFAULT_MAX_BATCH_STEPS } else { r.max_batch_steps as usize };
        Self { max_bytes: usize::try_from(r.max_message_bytes).unwrap_or(usize::MAX), max_steps }
    }
}

/// A step too large to send at all (its image alone is over the learner's limit).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepTooLarge {
    pub bytes: usize,
    pub limit: usize,
}

/// A piece of a batch: its steps and the episode summaries it carries.
pub type Piece = (Vec<pb::Step>, Vec<pb::EpisodeSummary>);

/// Bytes `step` takes inside a batch (the field's tag and length included).
fn step_bytes(step: &pb::Step) -> usize {
    let len = step.encoded_len();
    len + 1 + prost::length_delimiter_len(len)
}

/// Cuts `steps` (with the `episodes` finished among them, which go with the last piece) into
/// pieces that fit `limits`, in order. One piece, the input itself, when it fits.
pub fn split(steps: Vec<pb::Step>, episodes: Vec<pb::EpisodeSummary>, limits: Limits) -> Result<Vec<Piece>, StepTooLarge> {
    let episodes_bytes: usize = episodes.iter().map(|e| e.encoded_len() + 8).sum();
    let budget = limits.max_bytes.saturating_sub(MARGIN + episodes_bytes);
    let max_steps = limits.max_steps.max(1);
    let mut pieces: Vec<Vec<pb::Step>> = vec![Vec::new()];
    let mut used = 0usize;
    for step in steps {
        let n = step_bytes(&step);
        if n > budget {
            return Err(StepTooLarge { bytes: n, limit: limits.max_bytes });
        }
        let current = pieces.last_mut().expect("one piece at least");
        if !current.is_empty() && (used + n > budget || current.len() >= max_steps) {
            pieces.push(Vec::new());
            used = 0;
        }
        used += n;
        pieces.last_mut().expect("one piece at least").push(step);
    }
    let last = pieces.len() - 1;
    let mut episodes = Some(episodes);
    Ok(pieces.into_iter().enumerate().map(|(k, s)| (s, if k == last { episodes.take().unwrap_or_default() } else { Vec::new() })).collect())
}

/// Whether a batch of these steps and episodes, sent as is, fits `limits`.
#[must_use]
pub fn fits(steps: &[pb::Step], episodes: &[pb::EpisodeSummary], limits: Limits) -> bool {
    let episodes_bytes: usize = episodes.iter().map(|e| e.encoded_len() + 8).sum();
    steps.len() <= limits.max_steps && steps.iter().map(step_bytes).sum::<usize>() + episodes_bytes + MARGIN <= limits.max_bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steps(n: u32, image: usize) -> Vec<pb::Step> {
        (0..n)
            .map(|t| pb::Step {
                env: t % 3,
                t,
                obs: Some(pb::Observation { image: vec![7; image], speed: 1.0, d: 2.0, path: vec![0.1, 0.2, 0.3], vector: Vec::new() }),
                action: 2,
                reward: 0.5,
                ..pb::Step::default()
            })
            .collect()
    }

    fn episode() -> pb::EpisodeSummary {
        pb::EpisodeSummary { env: 1, episode: 4, episode_return: 3.0, steps: 17, scenario: "random".into(), ..Default::default() }
    }

    /// 200 steps of 84×84 RGB (~4.2 MB) against a 1 MiB learner: the case that used to be refused
    /// whole, forever.
    #[test]
    fn a_batch_over_the_limit_is_cut_in_order_into_pieces_that_fit() {
        let limits = Limits { max_bytes: 1 << 20, max_steps: 4096 };
        let input = steps(200, 84 * 84 * 3);
        assert!(!fits(&input, &[], limits));
        let pieces = split(input.clone(), vec![episode()], limits).unwrap();
        assert!(pieces.len() >= 5, "{}", pieces.len());
        for (k, (s, e)) in pieces.iter().enumerate() {
            assert!(fits(s, e, limits), "piece {k}");
            let batch = pb::ExperienceBatch {
                actor_id: "run-1-a0-0".into(),
                seq: u64::MAX,
                steps: s.clone(),
                episodes: e.clone(),
                ..Default::default()
            };
            assert!(batch.encoded_len() <= limits.max_bytes, "piece {k}: {} bytes encoded", batch.encoded_len());
            assert_eq!(e.len(), usize::from(k == pieces.len() - 1), "episodes go with the last piece");
        }
        let rejoined: Vec<pb::Step> = pieces.into_iter().flat_map(|(s, _)| s).collect();
        assert_eq!(rejoined, input);
    }

    #[test]
    fn the_step_count_limit_cuts_too_and_a_fitting_batch_stays_whole() {
        let limits = Limits { max_bytes: 64 << 20, max_steps: 64 };
        let pieces = split(steps(150, 16), Vec::new(), limits).unwrap();
        assert_eq!(pieces.iter().map(|p| p.0.len()).collect::<Vec<_>>(), vec![64, 64, 22]);
        let whole = split(steps(10, 16), vec![episode()], limits).unwrap();
        assert_eq!((whole.len(), whole[0].0.len(), whole[0].1.len()), (1, 10, 1));
        assert!(fits(&whole[0].0, &whole[0].1, limits));
    }

    #[test]
    fn a_step_larger_than_the_limit_cannot_be_sent() {
        let limits = Limits { max_bytes: 1 << 20, max_steps: 4096 };
        let e = split(steps(2, 2 << 20), Vec::new(), limits).unwrap_err();
        assert_eq!(e.limit, 1 << 20);
        assert!(e.bytes > 2 << 20);
    }
}
