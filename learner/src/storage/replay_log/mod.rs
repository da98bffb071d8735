//! The replay log: every accepted batch, written before it is acknowledged, so that an
//! acknowledged transition survives a SIGKILL (`service.durability = "ack"`).
//!
//! Batches are appended in the order they enter the replay (the caller holds the replay's lock),
//! each at a position (1, 2, …; never reused within a run). A committer thread syncs the log to
//! disk (`fdatasync`) and publishes the highest position synced; an acknowledgement waits for its
//! position. Appends that arrive while a sync runs are covered by the next one: one sync commits
//! every batch written since the last (group commit), so the cost of a sync is shared by all the
//! actors that sent in the meantime.
//!
//! The log is a directory of segment files (`<first position, 20 digits>.seg`, each up to
//! `service.replay_log_segment_bytes`). Each segment remembers the replay's frame count after its
//! last batch; once every frame of a segment has left the replay's ring, nothing of it is in the
//! replay and the segment is deleted. Disk use is thus about the replay's own bytes plus one
//! segment.
//!
//! On start, [`ReplayLog::open`] reads the segments in order and hands every valid record to the
//! caller (which rebuilds the replay from them), cuts off a torn tail (a crash mid-write), and
//! starts a new segment.

pub mod format;

use std::collections::VecDeque;
use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex};

pub use format::{Record, StepShape};

/// The directory of the log inside the run directory.
pub const DIR: &str = "replay-log";

/// Why the log could not be read or written.
#[derive(Debug, Clone, thiserror::Error)]
pub enum LogError {
    #[error("replay log: {action} {}: {reason}", path.display())]
    Io { path: PathBuf, action: &'static str, reason: String },
    #[error("replay log segment {} is unusable: {reason}", path.display())]
    Corrupt { path: PathBuf, reason: String },
    #[error("replay log failed earlier ({0}); nothing more is acknowledged")]
    Failed(Arc<str>),
    #[error(
        "replay log segment {} is damaged: {reason}. Every batch up to position {intact_to} is intact; to resume from \
         the intact part, resume again with --truncate-log: it drops the {dropped} batches from the damage on (the \
         damaged segments are kept in {})",
        path.display(),
        DAMAGED_DIR
    )]
    Damaged { path: PathBuf, reason: String, intact_to: u64, dropped: u64 },
}

/// Where `--truncate-log` moves what it cuts off, inside the run directory (never read back).
pub const DAMAGED_DIR: &str = "replay-log.damaged";

/// What to do with a log that cannot be read whole (a record out of order, one that does not
/// decode, a segment of another camera): refuse, naming the damage, or keep what is before it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnDamage {
    #[default]
    Refuse,
    /// Keep every batch before the damage; set the rest aside in [`DAMAGED_DIR`].
    Truncate,
}

/// What reading the log at start found.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Recovered {
    pub records: u64,
    pub segments: usize,
    /// The last position read.
    pub last_position: u64,
    /// Bytes cut off torn or corrupt segment ends.
    pub cut_bytes: u64,
    /// Batches set aside after damage (with [`OnDamage::Truncate`]).
    pub dropped_batches: u64,
}

/// Disk use and positions, for the status.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LogStats {
    pub bytes: u64,
    pub segments: u32,
    /// The first position of the oldest segment kept.
    pub first_position: u64,
    /// Every batch up to here is on disk.
    pub durable_position: u64,
}

#[derive(Debug)]
struct Segment {
    path: PathBuf,
    first: u64,
    bytes: u64,
    /// The replay's frame count after this segment's last batch.
    frame_end: u64,
}

#[derive(Debug)]
struct Writer {
    file: Arc<File>,
    segments: VecDeque<Segment>,
    next_position: u64,
    /// The last position written to a file (not necessarily synced).
    written: u64,
    /// Closed segments not yet synced.
    to_sync: Vec<Arc<File>>,
    /// A segment was created since the last sync: the directory needs a sync too.
    dir_dirty: bool,
    stop: bool,
    failed: Option<Arc<str>>,
}

#[derive(Debug, Clone, Default)]
struct Durable {
    position: u64,
    failed: Option<Arc<str>>,
}

#[derive(Debug)]
struct Inner {
    dir: PathBuf,
    shape: StepShape,
    segment_bytes: u64,
    writer: Mutex<Writer>,
    /// Wakes the committer.
    wake: Condvar,
    durable: tokio::sync::watch::Sender<Durable>,
    /// The same, for threads that wait without a runtime.
    durable_sync: (Mutex<Durable>, Condvar),
}

/// `--truncate-log`: copies a damaged segment and every later one to [`DAMAGED_DIR`], then cuts
/// the damaged one to its intact first `intact_bytes` (removed if nothing of it is intact) and
/// removes the later ones from the log.
fn set_aside<'a>(run_dir: &Path, damaged: &Path, intact_bytes: usize, later: impl Iterator<Item = &'a Path>) -> Result<(), LogError> {
    let aside = run_dir.join(DAMAGED_DIR);
    fs::create_dir_all(&aside).map_err(io(&aside, "creating"))?;
    let keep = |p: &Path| -> Result<PathBuf, LogError> {
        let to = aside.join(p.file_name().unwrap_or_default());
        fs::copy(p, &to).map_err(io(p, "copying aside"))?;
        File::open(&to).and_then(|f| f.sync_all()).map_err(io(&to, "syncing"))?;
        Ok(to)
    };
    keep(damaged)?;
    for p in later {
        keep(p)?;
        fs::remove_file(p).map_err(io(p, "removing"))?;
    }
    sync_dir(&aside)?;
    if intact_bytes > format::SEGMENT_HEADER {
        let f = fs::OpenOptions::new().write(true).open(damaged).map_err(io(damaged, "opening"))?;
        f.set_len(intact_bytes as u64).map_err(io(damaged, "truncating"))?;
        f.sync_all().map_err(io(damaged, "syncing"))?;
    } else {
        fs::remove_file(damaged).map_err(io(damaged, "removing"))?;
    }
    Ok(())
}

/// The replay log of a run (see the module documentation).
#[derive(Debug)]
pub struct ReplayLog {
    inner: Arc<Inner>,
    committer: Option<std::thread::JoinHandle<()>>,
}

impl ReplayLog {
    /// Opens (or creates) the log in `run_dir/replay-log/` for steps of `shape`, calling
    /// `apply(position, record)` for every valid record in order; `apply` returns the replay's
    /// frame count after the record. Torn or corrupt ends of segments are cut off (and logged);
    /// later segments are still read. New batches go to a new segment, at positions above the
    /// log's last one and above `after` (a checkpoint's position, should the log have lost its
    /// tail).
    ///
    /// A log that cannot be read whole is refused with [`LogError::Damaged`], naming the damage
    /// and what truncating would drop, unless `on_damage` is [`OnDamage::Truncate`].
    pub fn open(
        run_dir: &Path,
        shape: StepShape,
        segment_bytes: u64,
        after: u64,
        on_damage: OnDamage,
        mut apply: impl FnMut(u64, &Record<'_>) -> u64,
    ) -> Result<(Self, Recovered), LogError> {
        let dir = run_dir.join(DIR);
        fs::create_dir_all(&dir).map_err(io(&dir, "creating"))?;
        let mut names: Vec<(u64, PathBuf)> = fs::read_dir(&dir)
            .map_err(io(&dir, "listing"))?
            .filter_map(|e| e.ok())
            .filter_map(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                let first = name.strip_suffix(".seg")?.parse::<u64>().ok()?;
                Some((first, e.path()))
            })
            .collect();
        names.sort();
        let mut rec = Recovered::default();
        let mut segments = VecDeque::new();
        let mut frame_end = 0u64;
        for (k, (first, path)) in names.iter().enumerate() {
            let (first, path) = (*first, path.clone());
            let bytes = fs::read(&path).map_err(io(&path, "reading"))?;
            if bytes.len() <= format::SEGMENT_HEADER {
                // Created but never written to (the last segment of an earlier process).
                fs::remove_file(&path).map_err(io(&path, "removing an empty segment"))?;
                continue;
            }
            // Damage: (byte offset where the intact part ends, records from there on, why).
            let mut damage: Option<(usize, u64, String)> = match format::read_segment_header(&bytes) {
                Err(reason) => Some((0, format::records(&bytes).0.len() as u64, reason)),
                Ok(theirs) if theirs != shape => Some((
                    0,
                    format::records(&bytes).0.len() as u64,
                    format!("it holds {theirs}; this run's camera and vector sensor make {shape}"),
                )),
                Ok(_) => None,
            };
            let (records, valid, why) = format::records(&bytes);
            let total = records.len() as u64;
            let mut offset = format::SEGMENT_HEADER;
            for (i, (position, payload)) in records.into_iter().enumerate() {
                if damage.is_some() {
                    break;
                }
                let bad = if position <= rec.last_position {
                    Some(format!("position {position} follows {}: the log is out of order", rec.last_position))
                } else {
                    format::decode(payload, shape).err().map(|reason| format!("record {position}: {reason}"))
                };
                if let Some(reason) = bad {
                    damage = Some((offset, total - i as u64, reason));
                    break;
                }
                let record = format::decode(payload, shape).expect("decoded above");
                frame_end = apply(position, &record);
                rec.last_position = position;
                rec.records += 1;
                offset += format::RECORD_HEADER + payload.len();
            }
            if let Some((intact_bytes, here, reason)) = damage {
                let later = &names[k + 1..];
                let dropped = here + later.iter().map(|(_, p)| fs::read(p).map_or(0, |b| format::records(&b).0.len() as u64)).sum::<u64>();
                if on_damage == OnDamage::Refuse {
                    return Err(LogError::Damaged { path, reason, intact_to: rec.last_position, dropped });
                }
                set_aside(run_dir, &path, intact_bytes, later.iter().map(|(_, p)| p.as_path()))?;
                tracing::warn!(
                    segment = %path.display(),
                    intact_to = rec.last_position,
                    dropped_batches = dropped,
                    "replay log damaged ({reason}): kept every batch up to position {}, dropped {dropped} batches (kept aside in {}/{DAMAGED_DIR})",
                    rec.last_position,
                    run_dir.display()
                );
                rec.dropped_batches = dropped;
                if intact_bytes > format::SEGMENT_HEADER {
                    segments.push_back(Segment { path, first, bytes: intact_bytes as u64, frame_end });
                }
                break;
            }
            if valid <= format::SEGMENT_HEADER {
                tracing::warn!(segment = %path.display(), "replay log: {}; the segment holds no readable batch and is removed", why.as_deref().unwrap_or("empty"));
                rec.cut_bytes += (bytes.len() - valid) as u64;
                fs::remove_file(&path).map_err(io(&path, "removing an unreadable segment"))?;
                continue;
            }
            if let Some(why) = why {
                let cut = (bytes.len() - valid) as u64;
                tracing::warn!(segment = %path.display(), cut_bytes = cut, "replay log: {why}; cutting the segment there (a write torn by a crash: those batches were never acknowledged)");
                let f = fs::OpenOptions::new().write(true).open(&path).map_err(io(&path, "opening"))?;
                f.set_len(valid as u64).map_err(io(&path, "truncating"))?;
                f.sync_all().map_err(io(&path, "syncing"))?;
                rec.cut_bytes += cut;
            }
            segments.push_back(Segment { path, first, bytes: valid as u64, frame_end });
        }
        rec.segments = segments.len();
        // What was read counts as durable from here on: make sure it is (the previous process may
        // have written batches it never synced, nor acknowledged).
        if let Some(last) = segments.back() {
            File::open(&last.path).and_then(|f| f.sync_all()).map_err(io(&last.path, "syncing"))?;
        }
        let next_position = rec.last_position.max(after) + 1;
        let (file, seg) = create_segment(&dir, next_position, shape, frame_end)?;
        segments.push_back(seg);
        sync_dir(&dir)?;
        let durable = Durable { position: next_position - 1, failed: None };
        let inner = Arc::new(Inner {
            dir,
            shape,
            segment_bytes,
            writer: Mutex::new(Writer {
                file: Arc::new(file),
                segments,
                next_position,
                written: next_position - 1,
                to_sync: Vec::new(),
                dir_dirty: false,
                stop: false,
                failed: None,
            }),
            wake: Condvar::new(),
            durable: tokio::sync::watch::Sender::new(durable.clone()),
            durable_sync: (Mutex::new(durable), Condvar::new()),
        });
        let committer = {
            let inner = inner.clone();
            std::thread::Builder::new().name("replay-log".into()).spawn(move || commit_loop(&inner)).map_err(|e| LogError::Io {
                path: run_dir.join(DIR),
                action: "starting the committer of",
                reason: e.to_string(),
            })?
        };
        Ok((Self { inner, committer: Some(committer) }, rec))
    }

    /// Appends a batch's payload ([`format::encode`]) and returns its position. The caller holds
    /// the replay's lock, so that the log's order is the replay's. Nothing is on disk yet: wait
    /// for [`durable`](Self::durable) before acknowledging.
    pub fn append(&self, payload: &[u8]) -> Result<u64, LogError> {
        let inner = &self.inner;
        let mut w = inner.writer.lock().expect("replay log lock");
        if let Some(f) = &w.failed {
            return Err(LogError::Failed(f.clone()));
        }
        let len = (format::RECORD_HEADER + payload.len()) as u64;
        let current = w.segments.back().expect("a current segment");
        if current.bytes > format::SEGMENT_HEADER as u64 && current.bytes + len > inner.segment_bytes {
            let frame_end = current.frame_end;
            let (file, seg) = create_segment(&inner.dir, w.next_position, inner.shape, frame_end)?;
            let old = std::mem::replace(&mut w.file, Arc::new(file));
            w.to_sync.push(old);
            w.segments.push_back(seg);
            w.dir_dirty = true;
        }
        let position = w.next_position;
        let header = format::record_header(position, payload);
        let file = w.file.clone();
        let written = (&*file).write_all(&header).and_then(|()| (&*file).write_all(payload));
        let seg = w.segments.back_mut().expect("a current segment");
        if let Err(e) = written {
            // Cut the partial record off, so that the next one does not follow garbage.
            let path = seg.path.clone();
            if let Err(cut) = file.set_len(seg.bytes) {
                let reason: Arc<str> = format!("writing {} failed ({e}) and cutting it back failed ({cut})", path.display()).into();
                w.failed = Some(reason.clone());
                return Err(LogError::Failed(reason));
            }
            return Err(LogError::Io { path, action: "writing", reason: e.to_string() });
        }
        seg.bytes += len;
        w.written = position;
        w.next_position += 1;
        drop(w);
        inner.wake.notify_one();
        Ok(position)
    }

    /// Records the replay's frame count after the last appended batch, and deletes the oldest
    /// segments whose frames have all left the replay (`first_live_frame` is the oldest frame the
    /// replay holds).
    pub fn note_frames(&self, frame_end: u64, first_live_frame: u64) {
        let mut w = self.inner.writer.lock().expect("replay log lock");
        w.segments.back_mut().expect("a current segment").frame_end = frame_end;
        while w.segments.len() > 1 && w.segments.front().is_some_and(|s| s.frame_end <= first_live_frame) {
            let s = w.segments.pop_front().expect("checked");
            if let Err(e) = fs::remove_file(&s.path) {
                tracing::warn!(segment = %s.path.display(), "replay log: removing a segment whose transitions have all left the replay: {e}");
            }
        }
    }

    /// Completes once every batch up to `position` is on disk.
    pub async fn durable(&self, position: u64) -> Result<(), LogError> {
        let mut rx = self.inner.durable.subscribe();
        let d = rx
            .wait_for(|d| d.position >= position || d.failed.is_some())
            .await
            .map_err(|_| LogError::Failed("the committer stopped".into()))?
            .clone();
        match d.failed {
            Some(f) if d.position < position => Err(LogError::Failed(f)),
            _ => Ok(()),
        }
    }

    /// Blocks until every batch up to `position` is on disk (for threads without a runtime).
    pub fn wait_durable(&self, position: u64) -> Result<(), LogError> {
        let (lock, cv) = &self.inner.durable_sync;
        let mut d = lock.lock().expect("replay log lock");
        while d.position < position && d.failed.is_none() {
            d = cv.wait(d).expect("replay log lock");
        }
        match &d.failed {
            Some(f) if d.position < position => Err(LogError::Failed(f.clone())),
            _ => Ok(()),
        }
    }

    /// Disk use and positions.
    #[must_use]
    pub fn stats(&self) -> LogStats {
        let w = self.inner.writer.lock().expect("replay log lock");
        LogStats {
            bytes: w.segments.iter().map(|s| s.bytes).sum(),
            segments: w.segments.len() as u32,
            first_position: w.segments.front().map_or(0, |s| s.first),
            durable_position: self.inner.durable.borrow().position,
        }
    }

    /// Why the log stopped working, if it did.
    #[must_use]
    pub fn failure(&self) -> Option<Arc<str>> {
        self.inner.writer.lock().expect("replay log lock").failed.clone()
    }

    /// Syncs what was written and stops the committer.
    pub fn close(mut self) -> Result<(), LogError> {
        self.stop();
        match self.failure() {
            Some(f) => Err(LogError::Failed(f)),
            None => Ok(()),
        }
    }

    fn stop(&mut self) {
        self.inner.writer.lock().expect("replay log lock").stop = true;
        self.inner.wake.notify_one();
        if let Some(c) = self.committer.take() {
            let _ = c.join();
        }
    }
}

impl Drop for ReplayLog {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The committer: syncs whatever was written since the last sync, publishes the position, and
/// waits for more. Stops after a final sync once asked to, or at the first failed sync (after
/// which nothing is acknowledged again: the data may or may not be on disk, Linux having dropped
/// the dirty pages, and the process must restart and read the log back).
fn commit_loop(inner: &Inner) {
    let mut synced = inner.durable.borrow().position;
    loop {
        let (files, dir, upto) = {
            let mut w = inner.writer.lock().expect("replay log lock");
            while w.written <= synced && !w.stop && !w.dir_dirty {
                w = inner.wake.wait(w).expect("replay log lock");
            }
            if w.written <= synced && !w.dir_dirty && w.stop {
                return;
            }
            let mut files = std::mem::take(&mut w.to_sync);
            files.push(w.file.clone());
            (files, std::mem::take(&mut w.dir_dirty), w.written)
        };
        let result = files
            .iter()
            .try_for_each(|f| f.sync_data().map_err(|e| format!("syncing a segment: {e}")))
            .and_then(|()| if dir { sync_dir(&inner.dir).map_err(|e| e.to_string()) } else { Ok(()) });
        let update = match result {
            Ok(()) => {
                synced = upto;
                Durable { position: upto, failed: None }
            }
            Err(reason) => {
                let reason: Arc<str> = format!("{reason} ({})", inner.dir.display()).into();
                tracing::error!("replay log: {reason}; no batch is acknowledged from now on");
                inner.writer.lock().expect("replay log lock").failed = Some(reason.clone());
                Durable { position: synced, failed: Some(reason) }
            }
        };
        let failed = update.failed.is_some();
        inner.durable.send_replace(update.clone());
        *inner.durable_sync.0.lock().expect("replay log lock") = update;
        inner.durable_sync.1.notify_all();
        if failed {
            return;
        }
    }
}

/// One batch as an audit sees it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    pub position: u64,
    pub actor: String,
    pub steps: usize,
}

/// Reads the log of `run_dir` without changing it (no learner may be writing it): every valid
/// batch in order, and the first position of the oldest segment (0 if there is none). Torn or
/// corrupt ends are skipped, as [`ReplayLog::open`] would cut them.
pub fn inventory(run_dir: &Path, shape: StepShape) -> Result<(Vec<Entry>, u64), LogError> {
    let dir = run_dir.join(DIR);
    let mut names: Vec<(u64, PathBuf)> = fs::read_dir(&dir)
        .map_err(io(&dir, "listing"))?
        .filter_map(|e| e.ok())
        .filter_map(|e| Some((e.file_name().to_string_lossy().strip_suffix(".seg")?.parse::<u64>().ok()?, e.path())))
        .collect();
    names.sort();
    let mut out = Vec::new();
    let mut first = 0;
    for (start, path) in names {
        let bytes = fs::read(&path).map_err(io(&path, "reading"))?;
        let (records, _, _) = format::records(&bytes);
        if records.is_empty() {
            continue;
        }
        if first == 0 {
            first = start;
        }
        for (position, payload) in records {
            let r = format::decode(payload, shape).map_err(|reason| LogError::Corrupt { path: path.clone(), reason })?;
            out.push(Entry { position, actor: r.actor.to_owned(), steps: r.steps.len() });
        }
    }
    Ok((out, first))
}

fn create_segment(dir: &Path, first: u64, shape: StepShape, frame_end: u64) -> Result<(File, Segment), LogError> {
    let path = dir.join(format!("{first:020}.seg"));
    let mut f = fs::OpenOptions::new().create(true).truncate(true).write(true).open(&path).map_err(io(&path, "creating"))?;
    f.write_all(&format::segment_header(shape)).map_err(io(&path, "writing"))?;
    Ok((f, Segment { path, first, bytes: format::SEGMENT_HEADER as u64, frame_end }))
}

fn sync_dir(dir: &Path) -> Result<(), LogError> {
    #[cfg(unix)]
    File::open(dir).and_then(|d| d.sync_all()).map_err(io(dir, "syncing the directory"))?;
    #[cfg(not(unix))]
    let _ = dir;
    Ok(())
}

fn io(path: &Path, action: &'static str) -> impl Fn(std::io::Error) -> LogError + use<> {
    let path = path.to_owned();
    move |e| LogError::Io { path: path.clone(), action, reason: e.to_string() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::replay::StepRecord;
    use sim_core::env::PATH_FEATURES;

    fn payload(actor: &str, t0: u32, n: u32) -> (Vec<u8>, Vec<Vec<u8>>) {
        let imgs: Vec<Vec<u8>> = (t0..t0 + n).map(|t| vec![t as u8; 16]).collect();
        let steps: Vec<StepRecord<'_>> = imgs
            .iter()
            .enumerate()
            .map(|(k, img)| StepRecord {
                env: 0,
                episode: 0,
                t: t0 + k as u32,
                image: img,
                speed: 0.0,
                d: 0.0,
                path: [0.0; PATH_FEATURES],
                vector: Default::default(),
                action: 1,
                reward: 0.5,
                terminated: false,
                truncated: false,
            })
            .collect();
        (format::encode(actor, 0, &steps), imgs)
    }

    /// Reads a log back: (position, actor, first t, steps) of every record.
    fn read_back(dir: &Path) -> (Vec<(u64, String, u32, usize)>, Recovered) {
        let mut seen = Vec::new();
        let (log, rec) = ReplayLog::open(dir, StepShape::frames(16), 1 << 16, 0, OnDamage::Refuse, |p, r| {
            seen.push((p, r.actor.to_owned(), r.steps[0].t, r.steps.len()));
            p * 100
        })
        .unwrap();
        drop(log);
        (seen, rec)
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn appended_batches_are_durable_when_acknowledged_and_read_back_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let (log, rec) =
            ReplayLog::open(dir.path(), StepShape::frames(16), 1 << 16, 0, OnDamage::Refuse, |_, _| unreachable!("empty")).unwrap();
        assert_eq!(rec, Recovered::default());
        // 200 batches of 20 steps (~1.3 KB each) over several 64 KiB segments, from concurrent
        // tasks as actors send; each waits for its own position (group commit).
        let log = Arc::new(log);
        let order = Arc::new(Mutex::new(()));
        let mut tasks = Vec::new();
        for a in 0..4u32 {
            let (log, order) = (log.clone(), order.clone());
            tasks.push(tokio::spawn(async move {
                for b in 0..50u32 {
                    let (p, _) = payload(&format!("a{a}"), b * 20, 20);
                    let position = {
                        let _replay = order.lock().unwrap();
                        log.append(&p).unwrap()
                    };
                    log.durable(position).await.unwrap();
                    assert!(log.stats().durable_position >= position);
                }
            }));
        }
        for t in tasks {
            t.await.unwrap();
        }
        let stats = log.stats();
        assert_eq!(stats.durable_position, 200);
        assert!(stats.segments >= 4, "{stats:?}");
        drop(log);
        let (seen, rec) = read_back(dir.path());
        assert_eq!(rec.records, 200);
        assert_eq!(seen.iter().map(|s| s.0).collect::<Vec<_>>(), (1..=200).collect::<Vec<u64>>());
        for a in 0..4 {
            let ts: Vec<u32> = seen.iter().filter(|s| s.1 == format!("a{a}")).map(|s| s.2).collect();
            assert_eq!(ts, (0..50).map(|b| b * 20).collect::<Vec<_>>(), "actor a{a}'s batches in order");
        }
        // Reopened, positions continue after the last one.
        let (log, _) = ReplayLog::open(dir.path(), StepShape::frames(16), 1 << 16, 0, OnDamage::Refuse, |p, _| p).unwrap();
        assert_eq!(log.append(&payload("z", 0, 1).0).unwrap(), 201);
    }

    #[test]
    fn a_torn_tail_is_cut_off_and_later_batches_still_land() {
        let dir = tempfile::tempdir().unwrap();
        {
            let (log, _) = ReplayLog::open(dir.path(), StepShape::frames(16), 1 << 20, 0, OnDamage::Refuse, |_, _| 0).unwrap();
            for b in 0..3 {
                let p = log.append(&payload("a", b * 5, 5).0).unwrap();
                log.wait_durable(p).unwrap();
            }
        }
        // A crash mid-write: half a record at the end of the segment.
        let seg = dir.path().join(DIR).join(format!("{:020}.seg", 1));
        let (p, _) = payload("a", 15, 5);
        let mut bytes = fs::read(&seg).unwrap();
        bytes.extend_from_slice(&format::record_header(4, &p));
        bytes.extend_from_slice(&p[..p.len() / 2]);
        fs::write(&seg, &bytes).unwrap();
        let (seen, rec) = read_back(dir.path());
        assert_eq!(seen.len(), 3);
        assert!(rec.cut_bytes > 0);
        // Cut for good: the next opening finds nothing to cut, and new batches follow.
        let (log, rec) = ReplayLog::open(dir.path(), StepShape::frames(16), 1 << 20, 0, OnDamage::Refuse, |_, _| 0).unwrap();
        assert_eq!((rec.records, rec.cut_bytes), (3, 0));
        let p = log.append(&payload("b", 0, 2).0).unwrap();
        log.wait_durable(p).unwrap();
        drop(log);
        let (seen, _) = read_back(dir.path());
        assert_eq!(seen.last().unwrap(), &(4, "b".to_owned(), 0, 2));
    }

    #[test]
    fn segments_whose_frames_left_the_replay_are_deleted() {
        let dir = tempfile::tempdir().unwrap();
        let (log, _) = ReplayLog::open(dir.path(), StepShape::frames(16), 64 << 10, 0, OnDamage::Refuse, |_, _| 0).unwrap();
        // Each batch adds 40 frames; the replay (say) keeps the newest 400.
        let mut frames = 0u64;
        for b in 0..200 {
            log.append(&payload("a", b * 40, 40).0).unwrap();
            frames += 40;
            log.note_frames(frames, frames.saturating_sub(400));
        }
        let s = log.stats();
        // 64 KiB segments hold ~27 batches (~1080 frames); at most two are needed for 400 frames,
        // plus the one being written.
        assert!(s.segments <= 3, "{s:?}");
        assert!(s.bytes <= 3 * (64 << 10), "{s:?}");
        assert!(s.first_position > 100, "{s:?}");
        drop(log);
        let (seen, _) = read_back(dir.path());
        assert_eq!(seen.first().unwrap().0, s.first_position);
        assert!(seen.iter().map(|r| r.3 as u64).sum::<u64>() >= 400, "the kept segments still hold the replay's frames");
    }
}
