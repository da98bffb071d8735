//! The bf16 path (AMX or AVX512-BF16, whichever the machine runs; `FASTNET_BF16_KERNEL` picks one
//! where it has both) against the f32 path of the same network: Q values and every gradient
//! within bf16's rounding (8 significant bits), bit-identical on repeat and across thread counts.
//! Skipped, with a message saying so, where neither is present.

use agent::NetShape;
use agent::fastnet::{FastNet, Params, bf16_matmul};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn skip(test: &str) -> bool {
    match bf16_matmul::available() {
        Ok(_) => false,
        Err(why) => {
            eprintln!("SKIPPED {test}: no bf16 kernel here ({why}); only the f32 path runs on this machine");
            true
        }
    }
}

fn inputs(shape: NetShape, batch: usize, seed: u64) -> (Vec<u8>, Vec<f32>, Vec<f32>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let images = (0..batch * shape.image_bytes()).map(|_| (rng.next_u32() & 0xff) as u8).collect();
    let mut float = || rng.next_u32() as f32 / u32::MAX as f32 * 2.0 - 1.0;
    let scalars = (0..batch * shape.scalars).map(|_| float()).collect();
    let coef = (0..batch * shape.actions).map(|_| float()).collect();
    (images, scalars, coef)
}

/// ‖a − b‖ / ‖b‖.
fn rel_l2(a: &[f32], b: &[f32]) -> f64 {
    let (mut d, mut n) = (0f64, 0f64);
    for (&x, &y) in a.iter().zip(b) {
        d += f64::from(x - y).powi(2);
        n += f64::from(y).powi(2);
    }
    (d / n.max(1e-30)).sqrt()
}

fn run(shape: NetShape, bf16: bool, threads: usize, batch: usize, seed: u64) -> (Vec<f32>, Params) {
    let params = Params::init(shape, seed);
    let (images, scalars, coef) = inputs(shape, batch, seed + 1);
    let mut net = FastNet::with_precision(shape, threads, bf16);
    let q = net.forward(&params, &images, &scalars).to_vec();
    let mut grads = Params::zeros(shape);
    net.backward(&params, &coef, &mut grads);
    (q, grads)
}

const PAPER_48: NetShape = NetShape { height: 48, width: 48, channels: 1, scalars: 2, actions: 6, filters: 64, hidden: 256 };

#[test]
fn bf16_matches_f32_within_bf16_rounding() {
    if skip("bf16_matches_f32_within_bf16_rounding") {
        return;
    }
    let small = NetShape { height: 21, width: 19, channels: 3, filters: 32, hidden: 16, ..PAPER_48 };
    for (shape, batch) in [(PAPER_48, 3), (small, 2)] {
        let (q32, g32) = run(shape, false, 2, batch, 7);
        let (q16, g16) = run(shape, true, 2, batch, 7);
        let e = rel_l2(&q16, &q32);
        assert!(e < 1e-2, "{shape:?}: Q values {e:.2e} apart");
        for (((name, _), a), b) in g16.names.iter().zip(&g16.values).zip(&g32.values) {
            let e = rel_l2(a, b);
            // bf16 keeps 8 significant bits (relative rounding 2^-9 ≈ 2e-3): the dense layers'
            // gradients agree to ~3e-3. The convolutions' differ by 2–4 % (measured 2.1e-2 to
            // 3.6e-2 here), mostly from ReLU masks that flip where a pre-activation rounds across
            // zero (conv3's bias gradient, which no bf16 product touches, differs as much); the
            // kernels themselves agree with f32 on rounded inputs to 1e-4 (`conv_bf16`'s tests).
            let tolerance = if name.starts_with("conv") { 6e-2 } else { 1e-2 };
            assert!(e < tolerance, "{shape:?}: gradient of {name} {e:.2e} apart");
        }
        assert_ne!(q16, q32, "{shape:?}: the bf16 path computed exactly the f32 values (did it run?)");
    }
}

/// The learner's batch, where fc1 runs on the bf16 kernel too (`dense_bf16::MIN_BATCH`). Over 32
/// random images more pre-activations sit near zero, so more ReLU masks flip between the paths
/// and every layer's gradient but the Q head's is 7–12 % apart (measured: 10–12 % with fc1 in f32
/// as well, so the flips, not fc1's products, set the figure; those are checked against their
/// definition in `dense_bf16`'s tests). A wrong layout or transpose would be 100 % apart.
#[test]
fn bf16_matches_f32_at_the_learners_batch() {
    if skip("bf16_matches_f32_at_the_learners_batch") {
        return;
    }
    let (q32, g32) = run(PAPER_48, false, 2, 32, 7);
    let (q16, g16) = run(PAPER_48, true, 2, 32, 7);
    let e = rel_l2(&q16, &q32);
    assert!(e < 1e-2, "Q values {e:.2e} apart");
    for (((name, _), a), b) in g16.names.iter().zip(&g16.values).zip(&g32.values) {
        let e = rel_l2(a, b);
        let tolerance = if name.starts_with('q') { 1e-2 } else { 0.2 };
        assert!(e < tolerance, "gradient of {name} {e:.2e} apart");
    }
}

#[test]
fn bf16_is_bit_identical_on_repeat_and_across_thread_counts() {
    if skip("bf16_is_bit_identical_on_repeat_and_across_thread_counts") {
        return;
    }
    // An actor's batch (fc1 in f32) and the learner's (fc1 on the bf16 kernel).
    for batch in [4, 32] {
        let (q1, g1) = run(PAPER_48, true, 1, batch, 3);
        let (q2, g2) = run(PAPER_48, true, 2, batch, 3);
        let (q3, g3) = run(PAPER_48, true, 2, batch, 3);
        assert_eq!(q2, q3, "batch {batch}");
        assert_eq!(g2.values, g3.values, "batch {batch}");
        // Each image runs on one thread whatever the count; the kernel sums in a fixed order.
        assert_eq!(q1, q2, "batch {batch}");
        for (((name, _), a), b) in g1.names.iter().zip(&g1.values).zip(&g2.values) {
            assert!(rel_l2(a, b) < 1e-5, "{name}: 1 vs 2 threads, batch {batch}");
        }
    }
}

#[test]
fn one_image_split_across_threads_matches_one_thread_in_bf16() {
    if skip("one_image_split_across_threads_matches_one_thread_in_bf16") {
        return;
    }
    let params = Params::init(PAPER_48, 5);
    let (images, scalars, _) = inputs(PAPER_48, 1, 6);
    let one = FastNet::with_precision(PAPER_48, 1, true).forward(&params, &images, &scalars).to_vec();
    let split = FastNet::with_precision(PAPER_48, 2, true).forward(&params, &images, &scalars).to_vec();
    assert!(rel_l2(&split, &one) < 1e-5, "{split:?} vs {one:?}");
}

#[test]
fn bf16_is_refused_where_no_bf16_kernel_runs() {
    if let Ok(kernel) = bf16_matmul::available() {
        eprintln!("SKIPPED bf16_is_refused_where_no_bf16_kernel_runs: this machine has {}", kernel.name());
        return;
    }
    let refused = std::panic::catch_unwind(|| FastNet::with_precision(PAPER_48, 1, true)).expect_err("bf16 accepted without a bf16 kernel");
    let message = refused.downcast_ref::<String>().cloned().unwrap_or_default();
    assert!(message.contains("bf16 without a bf16 kernel"), "{message}");
}

/// A network used again keeps its bf16 buffers (packed operands, transposed inputs, their zeroed
/// padding) and rewrites only the values: after other batches and other weights, the same call
/// gives the bits of a fresh network.
#[test]
fn bf16_buffers_reused_across_calls_leak_nothing() {
    if skip("bf16_buffers_reused_across_calls_leak_nothing") {
        return;
    }
    let (fresh_q, fresh_g) = run(PAPER_48, true, 2, 32, 5);
    let params = Params::init(PAPER_48, 5);
    let mut net = FastNet::with_precision(PAPER_48, 2, true);
    for (batch, seed) in [(17, 9), (32, 8), (3, 7)] {
        let other = Params::init(PAPER_48, seed);
        let (images, scalars, coef) = inputs(PAPER_48, batch, seed + 1);
        net.forward(&other, &images, &scalars);
        net.backward(&other, &coef, &mut Params::zeros(PAPER_48));
    }
    let (images, scalars, coef) = inputs(PAPER_48, 32, 6);
    let q = net.forward(&params, &images, &scalars).to_vec();
    let mut grads = Params::zeros(PAPER_48);
    net.backward(&params, &coef, &mut grads);
    assert_eq!(q, fresh_q);
    assert_eq!(grads.values, fresh_g.values);
}

/// The multilayer perceptron (no image) stays f32 on the bf16 path (`FastNet::fc1_on_bf16`): at
/// the learner's batch too, bit for bit.
#[test]
fn the_mlp_is_f32_on_the_bf16_path() {
    if skip("the_mlp_is_f32_on_the_bf16_path") {
        return;
    }
    let mlp = NetShape::mlp(150, 256, 27);
    for batch in [1, 4, 256] {
        let (q32, g32) = run(mlp, false, 2, batch, 7);
        let (q16, g16) = run(mlp, true, 2, batch, 7);
        assert_eq!(q16, q32, "batch {batch}");
        assert_eq!(g16.values, g32.values, "batch {batch}");
    }
}
