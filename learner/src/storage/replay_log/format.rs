//! The replay log's bytes: a segment header, then records, each a header (magic, payload length,
//! position, payload CRC-32, header CRC-32) and a payload (the actor, the episodes it finished, and
//! its steps with their frames, each frame once, and vector sensor readings). Little-endian throughout.
//! A step's flags byte holds terminated (bit 0), truncated (bit 1) and demonstration (bit 2, set on
//! every step of a demonstrator's batch; logs written before demonstrations never set it). A record is valid
//! only if both checksums match, so a write torn by a crash is recognised and cut off.

use std::borrow::Cow;

use sim_core::env::PATH_FEATURES;

use crate::storage::replay::StepRecord;

/// First bytes of a segment file, then the frame size (u32) and the vector sensor reading's
/// length (u32; 0 in segments written before the sensor, whose steps carry none).
pub const SEGMENT_MAGIC: &[u8; 8] = b"HDRLOG01";
pub const SEGMENT_HEADER: usize = 16;
/// First bytes of a record.
const RECORD_MAGIC: u32 = u32::from_le_bytes(*b"HDRR");
pub const RECORD_HEADER: usize = 24;
/// Bytes of a step besides its frame.
const STEP_FIXED: usize = 4 + 8 + 4 + 4 + 4 + 4 + 4 + 4 * PATH_FEATURES + 1;

/// What every step of a segment carries besides its fixed fields: a frame of `frame_bytes`
/// bytes and a vector sensor reading of `vector_len` values (either may be 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepShape {
    pub frame_bytes: usize,
    pub vector_len: usize,
}

impl StepShape {
    /// Steps with a frame of `frame_bytes` and no vector reading.
    #[must_use]
    pub fn frames(frame_bytes: usize) -> Self {
        Self { frame_bytes, vector_len: 0 }
    }

    fn variable_bytes(self) -> usize {
        self.frame_bytes + 4 * self.vector_len
    }
}

impl std::fmt::Display for StepShape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "frames of {} bytes", self.frame_bytes)?;
        if self.vector_len > 0 {
            write!(f, " and vector readings of {} values", self.vector_len)?;
        }
        Ok(())
    }
}

/// One logged batch, borrowing from the bytes it was read from.
#[derive(Debug, Clone, PartialEq)]
pub struct Record<'a> {
    pub actor: &'a str,
    /// Episode summaries the batch carried (for the episode counter).
    pub episodes: u32,
    pub steps: Vec<StepRecord<'a>>,
    /// The batch is a demonstrator's: its steps go to the replay's demonstration partition.
    pub demonstration: bool,
}

/// A step's flags bit that marks a demonstration.
const DEMONSTRATION: u8 = 4;

/// The segment header for steps of `shape`.
#[must_use]
pub fn segment_header(shape: StepShape) -> [u8; SEGMENT_HEADER] {
    let mut h = [0u8; SEGMENT_HEADER];
    h[..8].copy_from_slice(SEGMENT_MAGIC);
    h[8..12].copy_from_slice(&(shape.frame_bytes as u32).to_le_bytes());
    h[12..16].copy_from_slice(&(shape.vector_len as u32).to_le_bytes());
    h
}

/// The step shape a segment header states, or why it is not a segment header.
pub fn read_segment_header(bytes: &[u8]) -> Result<StepShape, String> {
    if bytes.len() < SEGMENT_HEADER || &bytes[..8] != SEGMENT_MAGIC {
        return Err("not a replay log segment (bad header)".into());
    }
    let word = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().expect("4 bytes")) as usize;
    Ok(StepShape { frame_bytes: word(8), vector_len: word(12) })
}

/// A batch's payload.
#[must_use]
pub fn encode(actor: &str, episodes: u32, steps: &[StepRecord<'_>]) -> Vec<u8> {
    encode_batch(actor, episodes, steps, false)
}

/// A demonstrator's batch's payload: [`encode`], every step marked as a demonstration.
#[must_use]
pub fn encode_demonstrations(actor: &str, episodes: u32, steps: &[StepRecord<'_>]) -> Vec<u8> {
    encode_batch(actor, episodes, steps, true)
}

fn encode_batch(actor: &str, episodes: u32, steps: &[StepRecord<'_>], demonstration: bool) -> Vec<u8> {
    let demo = if demonstration { DEMONSTRATION } else { 0 };
    let frame = steps.first().map_or(0, |s| s.image.len());
    let mut out = Vec::with_capacity(2 + actor.len() + 8 + steps.len() * (STEP_FIXED + frame));
    let name = &actor.as_bytes()[..actor.len().min(u16::MAX as usize)];
    out.extend_from_slice(&(name.len() as u16).to_le_bytes());
    out.extend_from_slice(name);
    out.extend_from_slice(&episodes.to_le_bytes());
    out.extend_from_slice(&(steps.len() as u32).to_le_bytes());
    for s in steps {
        out.extend_from_slice(&s.env.to_le_bytes());
        out.extend_from_slice(&s.episode.to_le_bytes());
        out.extend_from_slice(&s.t.to_le_bytes());
        out.extend_from_slice(&s.action.to_le_bytes());
        for x in [s.reward, s.speed, s.d].into_iter().chain(s.path) {
            out.extend_from_slice(&x.to_le_bytes());
        }
        out.push(u8::from(s.terminated) | (u8::from(s.truncated) << 1) | demo);
        out.extend_from_slice(s.image);
        for x in s.vector.iter() {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    out
}

/// Reads a payload back; every step has the frame and vector reading of `shape`.
pub fn decode(payload: &[u8], shape: StepShape) -> Result<Record<'_>, String> {
    let mut r = Reader { bytes: payload, at: 0 };
    let name_len = usize::from(u16::from_le_bytes(r.take(2)?.try_into().expect("2 bytes")));
    let actor = std::str::from_utf8(r.take(name_len)?).map_err(|_| "actor id is not UTF-8".to_owned())?;
    let episodes = r.u32()?;
    let n = r.u32()? as usize;
    if n.saturating_mul(STEP_FIXED + shape.variable_bytes()) > payload.len() {
        return Err(format!("{n} steps do not fit a payload of {} bytes", payload.len()));
    }
    let mut steps = Vec::with_capacity(n);
    let mut demonstration = false;
    for _ in 0..n {
        let env = r.u32()?;
        let episode = u64::from_le_bytes(r.take(8)?.try_into().expect("8 bytes"));
        let t = r.u32()?;
        let action = r.u32()?;
        let (reward, speed, d) = (r.f32()?, r.f32()?, r.f32()?);
        let mut path = [0f32; PATH_FEATURES];
        for p in &mut path {
            *p = r.f32()?;
        }
        let flags = r.take(1)?[0];
        demonstration |= flags & DEMONSTRATION != 0;
        let image = r.take(shape.frame_bytes)?;
        let vector = r.take(4 * shape.vector_len)?.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes"))).collect();
        steps.push(StepRecord {
            env,
            episode,
            t,
            image,
            speed,
            d,
            path,
            vector: Cow::Owned(vector),
            action,
            reward,
            terminated: flags & 1 != 0,
            truncated: flags & 2 != 0,
        });
    }
    if r.at != payload.len() {
        return Err(format!("{} bytes after the last step", payload.len() - r.at));
    }
    Ok(Record { actor, episodes, steps, demonstration })
}

/// The header of the record at `position` with `payload`.
#[must_use]
pub fn record_header(position: u64, payload: &[u8]) -> [u8; RECORD_HEADER] {
    let mut h = [0u8; RECORD_HEADER];
    h[..4].copy_from_slice(&RECORD_MAGIC.to_le_bytes());
    h[4..8].copy_from_slice(&(payload.len() as u32).to_le_bytes());
    h[8..16].copy_from_slice(&position.to_le_bytes());
    h[16..20].copy_from_slice(&crc32fast::hash(payload).to_le_bytes());
    let crc = crc32fast::hash(&h[..20]);
    h[20..24].copy_from_slice(&crc.to_le_bytes());
    h
}

/// What [`records`] found: (position, payload) of each valid record, where the valid part ends,
/// and why reading stopped early, if it did (a torn or corrupt record).
pub type Scan<'a> = (Vec<(u64, &'a [u8])>, usize, Option<String>);

/// The valid records of a segment's bytes (after its header).
#[must_use]
pub fn records(bytes: &[u8]) -> Scan<'_> {
    let mut out = Vec::new();
    let mut at = SEGMENT_HEADER.min(bytes.len());
    while at < bytes.len() {
        let rest = &bytes[at..];
        if rest.len() < RECORD_HEADER {
            return (out, at, Some(format!("a torn record header ({} bytes)", rest.len())));
        }
        let h = &rest[..RECORD_HEADER];
        let word = |i: usize| u32::from_le_bytes(h[i..i + 4].try_into().expect("4 bytes"));
        if word(0) != RECORD_MAGIC || word(20) != crc32fast::hash(&h[..20]) {
            return (out, at, Some("a record header that fails its checksum".into()));
        }
        let len = word(4) as usize;
        let position = u64::from_le_bytes(h[8..16].try_into().expect("8 bytes"));
        let Some(payload) = rest.get(RECORD_HEADER..RECORD_HEADER + len) else {
            return (out, at, Some(format!("a torn record: {len} bytes announced, {} present", rest.len() - RECORD_HEADER)));
        };
        if crc32fast::hash(payload) != word(16) {
            return (out, at, Some(format!("record {position} fails its checksum")));
        }
        out.push((position, payload));
        at += RECORD_HEADER + len;
    }
    (out, at, None)
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or_else(|| "payload ends early".to_owned())?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }

    fn f32(&mut self) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(t: u32, image: &[u8]) -> StepRecord<'_> {
        StepRecord {
            env: 3,
            episode: 1 << 40,
            t,
            image,
            speed: 1.5,
            d: -0.25,
            path: [0.1, -0.2, 0.3],
            vector: Cow::Borrowed(&[]),
            action: 5,
            reward: -1.0,
            terminated: t == 2,
            truncated: false,
        }
    }

    #[test]
    fn vector_readings_round_trip_and_a_segment_states_their_length() {
        let readings = [[0.5f32, -1.0, 0.25], [1.0, 0.0, -0.125]];
        let steps: Vec<StepRecord<'_>> =
            readings.iter().enumerate().map(|(t, v)| StepRecord { vector: Cow::Borrowed(v), ..step(t as u32, &[]) }).collect();
        let shape = StepShape { frame_bytes: 0, vector_len: 3 };
        let payload = encode("a", 0, &steps);
        assert_eq!(decode(&payload, shape).unwrap().steps, steps);
        assert!(decode(&payload, StepShape { vector_len: 2, ..shape }).is_err(), "another length does not parse");
        assert_eq!(read_segment_header(&segment_header(shape)), Ok(shape));
        // A segment written before the sensor states 0 (its reserved bytes were zero).
        let mut old = segment_header(StepShape::frames(8));
        old[12..16].fill(0);
        assert_eq!(read_segment_header(&old), Ok(StepShape::frames(8)));
    }

    #[test]
    fn a_batch_round_trips_and_damage_is_recognised() {
        let imgs = [[1u8; 8], [2u8; 8], [3u8; 8]];
        let steps: Vec<StepRecord<'_>> = imgs.iter().enumerate().map(|(t, i)| step(t as u32, i)).collect();
        let payload = encode("run-1-a0-0", 2, &steps);
        let back = decode(&payload, StepShape::frames(8)).unwrap();
        assert_eq!(back, Record { actor: "run-1-a0-0", episodes: 2, steps: steps.clone(), demonstration: false });
        // A demonstrator's batch differs in the flag alone, which reads back.
        let demo = encode_demonstrations("run-1-a0-0", 2, &steps);
        assert_eq!(demo.len(), payload.len());
        assert_eq!(decode(&demo, StepShape::frames(8)).unwrap(), Record { demonstration: true, ..back.clone() });
        assert!(decode(&payload, StepShape::frames(7)).is_err(), "another frame size does not parse");

        let mut seg = segment_header(StepShape::frames(8)).to_vec();
        for p in [7u64, 8] {
            seg.extend_from_slice(&record_header(p, &payload));
            seg.extend_from_slice(&payload);
        }
        let full = seg.len();
        let (recs, end, why) = records(&seg);
        assert_eq!((recs.len(), end, why), (2, full, None));
        assert_eq!((recs[0].0, recs[1].0), (7, 8));
        // Torn: the second record cut short. The first stays valid; reading stops where the torn
        // one begins.
        let first_end = SEGMENT_HEADER + RECORD_HEADER + payload.len();
        let (recs, end, why) = records(&seg[..full - 5]);
        assert_eq!((recs.len(), end), (1, first_end));
        assert!(why.unwrap().starts_with("a torn record"));
        // A flipped bit in the second payload.
        let mut bad = seg.clone();
        bad[full - 3] ^= 4;
        let (recs, end, why) = records(&bad);
        assert_eq!((recs.len(), end, why.as_deref()), (1, first_end, Some("record 8 fails its checksum")));
        assert_eq!(read_segment_header(&seg), Ok(StepShape::frames(8)));
        assert!(read_segment_header(b"garbage garbage!").is_err());
    }
}
