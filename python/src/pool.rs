//! `Stepper`: N environments and the threads that step them, the calling thread working beside
//! them.
//!
//! A batch (step every environment, or reset every one) is a job: its environments are claimed
//! one at a time from a shared counter by the caller and by `threads - 1` workers, so a worker that
//! the OS has not scheduled yet delays nothing — the caller claims its share, and a batch never
//! takes longer than the caller stepping everything alone plus the environment in flight. (A
//! general pool such as rayon's parks the caller until its workers have run, which on a machine
//! busy with other work costs a scheduling delay per batch, more than the stepping itself.)
//!
//! The counter holds the job's generation in its upper 32 bits, so a worker that wakes late can
//! never claim an environment of a newer job with an older job's actions. Everything is safe Rust:
//! each environment sits behind its own (uncontended) mutex.

use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sim_core::env::{EnvError, Observation};
use sim_core::vehicle::Action;

use crate::slot::Slot;

/// What a batch does to each environment.
#[derive(Debug, Clone)]
pub enum Job {
    /// Reset environment i with `seeds[i]`, or without seeds with its stream's next seed.
    Reset { seeds: Option<Vec<u64>> },
    /// Step environment i under `actions[i]`, or reset it if its episode has ended (auto-reset).
    Step { actions: Vec<Action> },
}

/// One environment's outcome of a batch.
#[derive(Debug)]
pub struct Outcome {
    pub observation: Observation,
    pub reward: f32,
    pub terminated: bool,
    pub truncated: bool,
    pub info: sim_core::env::StepInfo,
    pub seed: u64,
}

#[derive(Debug)]
pub struct Stepper {
    shared: Arc<Shared>,
    workers: Vec<JoinHandle<()>>,
}

#[derive(Debug)]
struct Shared {
    slots: Vec<Mutex<Slot>>,
    outcomes: Vec<Mutex<Option<Result<Outcome, RunError>>>>,
    /// The current job and its generation.
    job: Mutex<(u32, Job)>,
    /// Generation << 32 | next environment to claim.
    ticket: AtomicU64,
    /// Environments of the current job done.
    finished: AtomicUsize,
    /// The generation workers wait for (under this mutex, so no wake-up is lost).
    generation: Mutex<u32>,
    wake: Condvar,
    stop: AtomicBool,
}

/// How long a worker polls for the next job (yielding its core) before it parks: about the time
/// Python takes between two `step` calls, so that a tight loop never waits for a wake-up.
const SPIN: Duration = Duration::from_micros(60);

/// Why an environment of a batch failed.
#[derive(Debug)]
pub enum RunError {
    Env(EnvError),
    /// The simulator panicked (a bug): the message.
    Panic(String),
}

impl Stepper {
    /// Runs `slots` on the calling thread and `threads - 1` workers.
    pub fn new(slots: Vec<Slot>, threads: usize) -> std::io::Result<Self> {
        let n = slots.len();
        let shared = Arc::new(Shared {
            slots: slots.into_iter().map(Mutex::new).collect(),
            outcomes: (0..n).map(|_| Mutex::new(None)).collect(),
            job: Mutex::new((0, Job::Reset { seeds: None })),
            // Generation 0 has no environments left to claim.
            ticket: AtomicU64::new(n as u64),
            finished: AtomicUsize::new(0),
            generation: Mutex::new(0),
            wake: Condvar::new(),
            stop: AtomicBool::new(false),
        });
        let workers = (1..threads.max(1))
            .map(|k| {
                let shared = shared.clone();
                std::thread::Builder::new().name(format!("hybrid-drive-{k}")).spawn(move || shared.work())
            })
            .collect::<std::io::Result<_>>()?;
        Ok(Self { shared, workers })
    }

    pub fn len(&self) -> usize {
        self.shared.slots.len()
    }

    /// The threads stepping, the caller's included.
    pub fn threads(&self) -> usize {
        self.workers.len() + 1
    }

    /// Runs `job` on every environment; the outcomes in environment order.
    pub fn run(&self, job: Job) -> Result<Vec<Outcome>, RunError> {
        let s = &*self.shared;
        let n = s.slots.len();
        let generation = {
            let mut current = lock(&s.job);
            let generation = current.0.wrapping_add(1);
            *current = (generation, job.clone());
            generation
        };
        // The previous job's environments are all finished (this thread waited for them), so no
        // claim can race these stores.
        s.finished.store(0, Ordering::Relaxed);
        s.ticket.store(u64::from(generation) << 32, Ordering::Release);
        if !self.workers.is_empty() {
            *lock(&s.generation) = generation;
            s.wake.notify_all();
        }
        s.drain(generation, &job);
        while s.finished.load(Ordering::Acquire) < n {
            std::thread::yield_now();
        }
        s.outcomes.iter().map(|o| lock(o).take().expect("every environment ran")).collect()
    }

    /// Environment `i` (between batches).
    pub fn slot(&self, i: usize) -> MutexGuard<'_, Slot> {
        lock(&self.shared.slots[i])
    }
}

impl Drop for Stepper {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        {
            let _generation = lock(&self.shared.generation);
            self.shared.wake.notify_all();
        }
        for worker in self.workers.drain(..) {
            let _ = worker.join();
        }
    }
}

impl Shared {
    /// A worker's life: wait for a job, claim its environments until none is left, repeat.
    fn work(&self) {
        let mut seen = 0u32;
        loop {
            let start = Instant::now();
            while (self.ticket.load(Ordering::Acquire) >> 32) as u32 == seen && start.elapsed() < SPIN {
                std::thread::yield_now();
            }
            {
                let mut generation = lock(&self.generation);
                while *generation == seen && (self.ticket.load(Ordering::Acquire) >> 32) as u32 == seen {
                    if self.stop.load(Ordering::Acquire) {
                        return;
                    }
                    generation = self.wake.wait(generation).unwrap_or_else(std::sync::PoisonError::into_inner);
                }
            }
            if self.stop.load(Ordering::Acquire) {
                return;
            }
            let (generation, job) = lock(&self.job).clone();
            seen = generation;
            self.drain(generation, &job);
        }
    }

    /// Claims and runs environments of job `generation` until none is left.
    fn drain(&self, generation: u32, job: &Job) {
        let n = self.slots.len() as u64;
        let mut ticket = self.ticket.load(Ordering::Acquire);
        loop {
            if (ticket >> 32) as u32 != generation || ticket & 0xffff_ffff >= n {
                return;
            }
            match self.ticket.compare_exchange_weak(ticket, ticket + 1, Ordering::AcqRel, Ordering::Acquire) {
                Ok(_) => {
                    let i = (ticket & 0xffff_ffff) as usize;
                    // A panic must not leave the batch waiting for this environment forever.
                    let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| run_one(&mut lock(&self.slots[i]), i, job)))
                        .unwrap_or_else(|panic| Err(RunError::Panic(panic_message(&*panic))));
                    *lock(&self.outcomes[i]) = Some(outcome);
                    self.finished.fetch_add(1, Ordering::AcqRel);
                    ticket = self.ticket.load(Ordering::Acquire);
                }
                Err(current) => ticket = current,
            }
        }
    }
}

fn run_one(slot: &mut Slot, i: usize, job: &Job) -> Result<Outcome, RunError> {
    let reset = |slot: &mut Slot, seed: Option<u64>| -> Result<Outcome, RunError> {
        let observation = slot.reset(seed).map_err(RunError::Env)?;
        Ok(Outcome {
            observation,
            reward: 0.0,
            terminated: false,
            truncated: false,
            info: slot.env.info().clone(),
            seed: slot.episode_seed(),
        })
    };
    match job {
        Job::Reset { seeds } => reset(slot, seeds.as_ref().map(|s| s[i])),
        Job::Step { .. } if slot.env.is_done() => reset(slot, None),
        Job::Step { actions } => {
            let r = slot.step(actions[i]).map_err(RunError::Env)?;
            Ok(Outcome {
                observation: r.observation,
                reward: r.reward,
                terminated: r.terminated,
                truncated: r.truncated,
                info: r.info,
                seed: slot.episode_seed(),
            })
        }
    }
}

fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// Locks `m`; a panic elsewhere while holding it leaves the data as it was, which is still
/// consistent (every update is one assignment).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}
