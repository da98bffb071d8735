//! The machine a benchmark ran on: its model, its load, and its practical limit (a GEMM
//! calibration on the network's own kernels), and the arithmetic figures read against it.

use std::time::Instant;

use agent::NetShape;

/// The system's 1-minute load average, to print beside timings (2-thread figures collapse on a
/// busy machine).
pub fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg").ok()?.split_whitespace().next()?.parse().ok()
}

/// The CPU's model name (`/proc/cpuinfo`), to print beside timings.
pub fn cpu_model() -> Option<String> {
    let text = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("model name"))?;
    Some(line.split_once(':')?.1.trim().to_owned())
}

/// Side of the square matrices the calibration multiplies.
pub const CALIBRATION_N: usize = 1024;

/// The machine's practical limit: GFLOP/s of a square `CALIBRATION_N` f32 matrix product on
/// `threads` threads through the same `gemm` crate the network uses (the median of `reps`
/// products after a warm-up). The figures below are read as fractions of it.
#[must_use]
pub fn gemm_peak_gflops(threads: usize, reps: usize) -> f64 {
    use agent::fastnet::gemm::{View, matmul};
    let n = CALIBRATION_N;
    let a: Vec<f32> = (0..n * n).map(|i| ((i * 7 + 3) % 1000) as f32 / 500.0 - 1.0).collect();
    let b: Vec<f32> = (0..n * n).map(|i| ((i * 13 + 5) % 1000) as f32 / 500.0 - 1.0).collect();
    let mut c = vec![0f32; n * n];
    let v = View::rows(0, n, n, n);
    let ms = median_ms(reps, || matmul(&mut c, v, false, &a, v, &b, v, threads));
    2.0 * (n * n * n) as f64 / (ms * 1e6)
}

/// Floating-point operations of one DQN update of `batch` transitions: the target network's
/// forward pass on the next states (and the online network's too for double DQN), the online
/// forward pass and its backward pass. The optimizer's few element-wise passes are left out.
#[must_use]
pub fn update_flops(shape: &NetShape, batch: usize, double_dqn: bool) -> f64 {
    let forwards = if double_dqn { 3.0 } else { 2.0 };
    batch as f64 * (forwards * shape.forward_flops() + shape.backward_flops())
}

/// GFLOP/s of `flops` done in `ms`, and that as a fraction of `peak` GFLOP/s.
pub fn rate(flops: f64, ms: f64, peak: f64) -> (f64, f64) {
    let gflops = flops / (ms * 1e6);
    (gflops, gflops / peak)
}

/// The machine's bf16 limit as this code reaches it: GFLOP/s of a square `CALIBRATION_N` bf16
/// product on one thread through the machine's bf16 kernel (`agent::fastnet::bf16_matmul`: AMX or
/// AVX512-BF16), median of `reps`.
pub fn bf16_peak_gflops(reps: usize) -> f64 {
    use agent::fastnet::bf16_matmul::{AView, PackedB, matmul};
    use agent::fastnet::gemm::View;
    let n = CALIBRATION_N;
    // Aligned as the network's operands are (`fastnet::aligned`).
    let a: Vec<u16> = (0..n * n).map(|i| agent::fastnet::bf16::from_f32(((i * 7 + 3) % 1000) as f32 / 500.0 - 1.0)).collect();
    let a = agent::fastnet::aligned::Aligned::from_slice(&a);
    let b: Vec<f32> = (0..n * n).map(|i| ((i * 13 + 5) % 1000) as f32 / 500.0 - 1.0).collect();
    let mut packed = PackedB::default();
    packed.pack(&b, View::rows(0, n, n, n));
    let mut c = agent::fastnet::aligned::Aligned::<f32>::zeroed(n * n);
    let ms = median_ms(reps, || matmul(&mut c, View::rows(0, n, n, n), false, &a, AView::rows(0, n, n, n), &packed));
    2.0 * (n * n * n) as f64 / (ms * 1e6)
}

/// Milliseconds per call of `f`, the median of `reps` timed calls after one warm-up call.
pub fn median_ms(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut t: Vec<f64> = (0..reps.max(1))
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1000.0
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}
