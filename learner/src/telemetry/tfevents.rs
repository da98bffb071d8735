//! TensorBoard event files (`events.out.tfevents.*`) beside the JSON Lines metrics, so that
//! `tensorboard --logdir runs/` shows a run. A file is a sequence of TFRecords — length (u64 LE),
//! masked CRC-32C of the length, the data, masked CRC-32C of the data — each holding a serialized
//! `tensorflow.Event` protobuf: first one naming the file version, then summaries of scalars.
//! The messages are the subset of TensorFlow's `event.proto` and `summary.proto` that scalars
//! need, declared here with prost's derive (field numbers as in TensorFlow's files).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use prost::Message;

/// `tensorflow.Event`: one record of an event file.
#[derive(Clone, PartialEq, Message)]
pub struct Event {
    /// Seconds since the Unix epoch.
    #[prost(double, tag = "1")]
    pub wall_time: f64,
    /// The x axis of TensorBoard's charts.
    #[prost(int64, tag = "2")]
    pub step: i64,
    /// The `what` oneof's `file_version` (first record of a file).
    #[prost(string, optional, tag = "3")]
    pub file_version: Option<String>,
    /// The `what` oneof's `summary`.
    #[prost(message, optional, tag = "5")]
    pub summary: Option<Summary>,
}

/// `tensorflow.Summary`.
#[derive(Clone, PartialEq, Message)]
pub struct Summary {
    #[prost(message, repeated, tag = "1")]
    pub value: Vec<SummaryValue>,
}

/// `tensorflow.Summary.Value` with its `simple_value` (a scalar).
#[derive(Clone, PartialEq, Message)]
pub struct SummaryValue {
    #[prost(string, tag = "1")]
    pub tag: String,
    #[prost(float, optional, tag = "2")]
    pub simple_value: Option<f32>,
}

/// The version string TensorBoard expects in a file's first event.
pub const FILE_VERSION: &str = "brain.Event:2";

/// TFRecord's masked CRC-32C (TensorFlow's `crc32c::Mask`).
#[must_use]
pub fn masked_crc(data: &[u8]) -> u32 {
    let crc = crc32c::crc32c(data);
    crc.rotate_right(15).wrapping_add(0xa282_ead8)
}

/// Appends one TFRecord holding `data`.
pub fn write_record(out: &mut impl Write, data: &[u8]) -> std::io::Result<()> {
    let len = (data.len() as u64).to_le_bytes();
    out.write_all(&len)?;
    out.write_all(&masked_crc(&len).to_le_bytes())?;
    out.write_all(data)?;
    out.write_all(&masked_crc(data).to_le_bytes())
}

/// An event file being written: one per learner session, in the run directory.
#[derive(Debug)]
pub struct EventWriter {
    path: PathBuf,
    out: Mutex<BufWriter<File>>,
}

impl EventWriter {
    /// Creates `dir/events.out.tfevents.SECONDS.HOST.PID` and writes its version record.
    pub fn create(dir: &Path) -> std::io::Result<Self> {
        let now = wall_time();
        let host = std::fs::read_to_string("/etc/hostname").map(|h| h.trim().to_owned()).unwrap_or_default();
        let host = if host.is_empty() { "localhost".to_owned() } else { host };
        let path = dir.join(format!("events.out.tfevents.{}.{host}.{}", now as u64, std::process::id()));
        let mut out = BufWriter::new(File::options().create(true).append(true).open(&path)?);
        let first = Event { wall_time: now, step: 0, file_version: Some(FILE_VERSION.to_owned()), summary: None };
        write_record(&mut out, &first.encode_to_vec())?;
        out.flush()?;
        Ok(Self { path, out: Mutex::new(out) })
    }

    /// The file's path.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes scalars at `step`; values that are `None` or not finite are left out.
    pub fn scalars(&self, step: u64, values: &[(&str, Option<f64>)]) -> std::io::Result<()> {
        let value: Vec<SummaryValue> = values
            .iter()
            .filter_map(|&(tag, v)| v.filter(|x| x.is_finite()).map(|x| SummaryValue { tag: tag.to_owned(), simple_value: Some(x as f32) }))
            .collect();
        if value.is_empty() {
            return Ok(());
        }
        let event = Event { wall_time: wall_time(), step: step as i64, file_version: None, summary: Some(Summary { value }) };
        write_record(&mut *self.out.lock().expect("event file lock"), &event.encode_to_vec())
    }

    /// Flushes the file.
    pub fn flush(&self) -> std::io::Result<()> {
        self.out.lock().expect("event file lock").flush()
    }
}

fn wall_time() -> f64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default().as_secs_f64()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reads TFRecords back, checking both checksums.
    fn read_records(mut bytes: &[u8]) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        while !bytes.is_empty() {
            let (len, rest) = bytes.split_at(8);
            let n = u64::from_le_bytes(len.try_into().unwrap()) as usize;
            assert_eq!(u32::from_le_bytes(rest[..4].try_into().unwrap()), masked_crc(len));
            let data = &rest[4..4 + n];
            assert_eq!(u32::from_le_bytes(rest[4 + n..8 + n].try_into().unwrap()), masked_crc(data));
            out.push(data.to_vec());
            bytes = &rest[8 + n..];
        }
        out
    }

    #[test]
    fn masked_crc_matches_tensorflows_reference_values() {
        // CRC-32C of "123456789" is 0xE3069283 (RFC 3720's check value); masked as TensorFlow does:
        // ((crc >> 15) | (crc << 17)) + 0xa282ead8.
        // For 0xE3069283 that gives 0xC78AB0E5 (computed separately, in Python, from the formula).
        assert_eq!(crc32c::crc32c(b"123456789"), 0xE306_9283);
        assert_eq!(masked_crc(b"123456789"), 0xC78A_B0E5);
    }

    #[test]
    fn scalars_round_trip_through_the_record_framing() {
        let dir = tempfile::tempdir().unwrap();
        let w = EventWriter::create(dir.path()).unwrap();
        w.scalars(1200, &[("train/loss", Some(0.5)), ("train/mean_q", None), ("x", Some(f64::NAN))]).unwrap();
        w.scalars(1300, &[("train/mean_q", None)]).unwrap();
        w.flush().unwrap();
        assert!(w.path().file_name().unwrap().to_str().unwrap().starts_with("events.out.tfevents."));
        let records = read_records(&std::fs::read(w.path()).unwrap());
        assert_eq!(records.len(), 2, "the version record and one summary (an empty one is not written)");
        let first = Event::decode(records[0].as_slice()).unwrap();
        assert_eq!(first.file_version.as_deref(), Some(FILE_VERSION));
        let second = Event::decode(records[1].as_slice()).unwrap();
        assert_eq!(second.step, 1200);
        assert_eq!(second.summary.unwrap().value, vec![SummaryValue { tag: "train/loss".into(), simple_value: Some(0.5) }]);
    }
}
