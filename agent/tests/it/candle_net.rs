//! The fast network against candle's network (`agent::candle_net::QNetwork`): same Q values and same
//! gradients within 1e-4 relative error, over odd sizes, batch splits and thread counts; and its
//! gradients against finite differences; the same for the multilayer perceptron (a shape with no
//! image).

use agent::NetShape;
use agent::candle_net::{images_tensor, network, var_map};
use agent::fastnet::{FastNet, Params};
use candle_core::{Device, Tensor};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_bytes(n: usize, seed: u64) -> Vec<u8> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| (rng.next_u32() & 0xff) as u8).collect()
}

fn random_floats(n: usize, seed: u64) -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| rng.next_u32() as f32 / u32::MAX as f32 * 2.0 - 1.0).collect()
}

/// Candle's Q values and the gradients of `Σ q·coef` for every parameter.
fn reference(shape: NetShape, params: &Params, images: &[u8], scalars: &[f32], coef: &[f32]) -> (Vec<f32>, Params) {
    let dev = Device::Cpu;
    let vars = var_map(params).unwrap();
    let net = network(&vars, shape, &dev).unwrap();
    let b = coef.len() / shape.actions;
    let frame = shape.image_bytes();
    let refs: Vec<&[u8]> = (0..b).map(|i| &images[i * frame..(i + 1) * frame]).collect();
    let x = images_tensor(&refs, &shape, &dev).unwrap();
    let s = Tensor::from_slice(scalars, (b, shape.scalars), &dev).unwrap();
    let q = net.forward(&x, &s).unwrap();
    let c = Tensor::from_slice(coef, (b, shape.actions), &dev).unwrap();
    let grads = (&q * &c).unwrap().sum_all().unwrap().backward().unwrap();
    let mut out = Params::zeros(shape);
    let data = vars.data().lock().unwrap();
    for ((name, _), v) in out.names.iter().zip(&mut out.values) {
        *v = grads.get(data[name].as_tensor()).unwrap().flatten_all().unwrap().to_vec1().unwrap();
    }
    (q.flatten_all().unwrap().to_vec1().unwrap(), out)
}

/// Largest |a − b| relative to the largest |b| (so that near-zero elements do not dominate).
fn rel_err(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(0f32, |m, x| m.max(x.abs())).max(1e-6);
    a.iter().zip(b).fold(0f32, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// Compares Q values, and gradients when `grads` (candle's average-pooling gradient is wrong
/// where a pooled size is odd: see the finite-difference test of odd sizes).
fn check_against_candle(shape: NetShape, batch: usize, threads: usize, seed: u64, grads: bool) {
    let params = Params::init(shape, seed);
    let images = random_bytes(batch * shape.image_bytes(), seed + 1);
    let scalars = random_floats(batch * shape.scalars, seed + 2);
    let coef = random_floats(batch * shape.actions, seed + 3);
    let (q_ref, g_ref) = reference(shape, &params, &images, &scalars, &coef);
    let mut net = FastNet::new(shape, threads);
    let q = net.forward(&params, &images, &scalars).to_vec();
    let what = format!("{shape:?}, batch {batch}, {threads} threads");
    assert!(rel_err(&q, &q_ref) < 1e-4, "Q values differ by {} ({what})", rel_err(&q, &q_ref));
    if !grads {
        return;
    }
    let mut grads = Params::zeros(shape);
    net.backward(&params, &coef, &mut grads);
    for (((name, _), g), r) in grads.names.iter().zip(&grads.values).zip(&g_ref.values) {
        let e = rel_err(g, r);
        assert!(e < 1e-4, "gradient of {name} differs by {e} ({what})");
    }
}

#[test]
fn matches_candle_on_a_small_network() {
    let shape = NetShape { height: 16, width: 16, channels: 1, scalars: 2, actions: 3, filters: 8, hidden: 16 };
    check_against_candle(shape, 1, 1, 1, true);
    check_against_candle(shape, 3, 2, 2, true);
}

#[test]
fn matches_candle_on_odd_sizes_colour_and_uneven_batch_splits() {
    // 21×18 pools to 10×9, 5×4, 2×2: the pooling drops a row or a column somewhere on each layer.
    let odd = NetShape { height: 21, width: 18, channels: 3, scalars: 1, actions: 6, filters: 16, hidden: 32 };
    check_against_candle(odd, 5, 2, 3, false);
    check_against_candle(odd, 1, 2, 5, false);
    // 24×16 pools evenly (12×8, 6×4, 3×2) but is neither square nor a power of two.
    let even = NetShape { height: 24, width: 16, ..odd };
    check_against_candle(even, 5, 2, 3, true);
    check_against_candle(even, 5, 3, 4, true);
    check_against_candle(even, 1, 2, 5, true);
}

#[test]
fn matches_candle_at_the_paper_width() {
    let shape = NetShape { height: 32, width: 32, channels: 3, scalars: 2, actions: 6, filters: 64, hidden: 256 };
    check_against_candle(shape, 4, 2, 6, true);
    // One image split across 2 and 3 threads (bands of lines and of units), at the actors' size.
    let actor = NetShape { height: 84, width: 84, channels: 1, ..shape };
    check_against_candle(actor, 1, 2, 7, false);
    check_against_candle(actor, 1, 3, 8, false);
}

/// Splitting one image across threads changes only the order of the dense layers' sums: the Q
/// values stay within 1e-5 (relative) of one thread's, at every thread count and odd sizes.
#[test]
fn one_image_split_across_threads_matches_one_thread() {
    for shape in [
        NetShape { height: 84, width: 84, channels: 3, scalars: 2, actions: 6, filters: 64, hidden: 256 },
        NetShape { height: 21, width: 18, channels: 1, scalars: 2, actions: 6, filters: 16, hidden: 32 },
    ] {
        let params = Params::init(shape, 21);
        let image = random_bytes(shape.height * shape.width * shape.channels, 22);
        let scalars = random_floats(shape.scalars, 23);
        let one = FastNet::new(shape, 1).forward(&params, &image, &scalars).to_vec();
        for threads in [2, 3, 4] {
            let split = FastNet::new(shape, threads).forward(&params, &image, &scalars).to_vec();
            assert!(rel_err(&split, &one) < 1e-5, "{threads} threads: {split:?} vs {one:?} ({shape:?})");
        }
    }
}

#[test]
fn the_mlp_matches_candle() {
    let shape = NetShape::mlp(37, 16, 5);
    check_against_candle(shape, 1, 1, 31, true);
    check_against_candle(shape, 1, 2, 32, true);
    check_against_candle(shape, 7, 2, 33, true);
    check_against_candle(NetShape::mlp(3, 5, 2), 4, 3, 34, true);
}

/// The vector run's network at the learner's batch of 256 (where fc1 would run on the bf16
/// kernel on that path) and one actor's observation split across threads.
#[test]
fn the_mlp_matches_candle_at_the_vector_runs_size() {
    let shape = NetShape::mlp(150, 256, 27);
    check_against_candle(shape, 256, 2, 35, true);
    check_against_candle(shape, 1, 2, 36, false);
    check_against_candle(shape, 4, 1, 37, false);
}

#[test]
fn repeated_calls_reuse_buffers_without_leaking_state() {
    let shape = NetShape { height: 16, width: 12, channels: 3, scalars: 2, actions: 4, filters: 8, hidden: 8 };
    let params = Params::init(shape, 9);
    let mut net = FastNet::new(shape, 2);
    let a = random_bytes(4 * 16 * 12 * 3, 10);
    let b = random_bytes(2 * 16 * 12 * 3, 11);
    let (sa, sb) = (random_floats(8, 12), random_floats(4, 13));
    let first = net.forward(&params, &a, &sa).to_vec();
    let mut g1 = Params::zeros(shape);
    net.backward(&params, &[1.0; 16], &mut g1);
    net.forward(&params, &b, &sb);
    let again = net.forward(&params, &a, &sa).to_vec();
    let mut g2 = Params::zeros(shape);
    net.backward(&params, &[1.0; 16], &mut g2);
    assert_eq!(first, again, "same inputs, same Q values, bit for bit");
    assert_eq!(g1, g2, "same gradients, bit for bit");
}

#[test]
fn the_mlp_reuses_buffers_without_leaking_state() {
    let shape = NetShape::mlp(11, 8, 4);
    let params = Params::init(shape, 9);
    let mut net = FastNet::new(shape, 2);
    let (sa, sb) = (random_floats(4 * 11, 12), random_floats(2 * 11, 13));
    let first = net.forward(&params, &[], &sa).to_vec();
    let mut g1 = Params::zeros(shape);
    net.backward(&params, &[1.0; 16], &mut g1);
    net.forward(&params, &[], &sb);
    let again = net.forward(&params, &[], &sa).to_vec();
    let mut g2 = Params::zeros(shape);
    net.backward(&params, &[1.0; 16], &mut g2);
    assert_eq!(first, again, "same inputs, same Q values, bit for bit");
    assert_eq!(g1, g2, "same gradients, bit for bit");
}

#[test]
fn gradients_agree_with_finite_differences() {
    finite_differences(NetShape { height: 8, width: 8, channels: 2, scalars: 2, actions: 2, filters: 3, hidden: 5 });
}

#[test]
fn gradients_agree_with_finite_differences_on_odd_sizes() {
    // 14×18 pools to 7×9 and then 3×4: the second pooling drops a row and a column. Here candle's
    // own average-pooling gradient is wrong (it upsamples by nearest neighbour, which maps odd
    // sizes onto the wrong 2×2 blocks), so finite differences are the reference.
    finite_differences(NetShape { height: 14, width: 18, channels: 3, scalars: 1, actions: 2, filters: 3, hidden: 5 });
}

#[test]
fn the_mlps_gradients_agree_with_finite_differences() {
    finite_differences(NetShape::mlp(37, 16, 5));
    finite_differences(NetShape::mlp(3, 5, 2));
}

/// f64 central differences of the f32 network on a tiny shape: a check of the backward pass
/// that does not rely on candle.
fn finite_differences(shape: NetShape) {
    let mut params = Params::init(shape, 21);
    let images = random_bytes(2 * shape.image_bytes(), 22);
    let scalars = random_floats(2 * shape.scalars, 23);
    let coef = random_floats(2 * shape.actions, 24);
    let mut net = FastNet::new(shape, 1);
    let loss = |net: &mut FastNet, p: &Params| -> f64 {
        net.forward(p, &images, &scalars).iter().zip(&coef).map(|(q, c)| f64::from(*q) * f64::from(*c)).sum()
    };
    loss(&mut net, &params);
    let mut grads = Params::zeros(shape);
    net.backward(&params, &coef, &mut grads);
    let mut rng = ChaCha8Rng::seed_from_u64(25);
    let mut checked = 0;
    for t in 0..params.values.len() {
        for _ in 0..6 {
            let i = (rng.next_u32() as usize) % params.values[t].len();
            let h = 2e-3f32;
            let x0 = params.values[t][i];
            params.values[t][i] = x0 + h;
            let up = loss(&mut net, &params);
            params.values[t][i] = x0 - h;
            let down = loss(&mut net, &params);
            params.values[t][i] = x0;
            let numeric = (up - down) / (2.0 * f64::from(h));
            let analytic = f64::from(grads.values[t][i]);
            // ReLU kinks make a few differences inexact; the tolerance allows f32 rounding only.
            let ok = (numeric - analytic).abs() <= 2e-3 + 2e-2 * analytic.abs();
            assert!(ok, "{}[{i}]: analytic {analytic}, numeric {numeric}", params.names[t].0);
            checked += 1;
        }
    }
    assert_eq!(checked, 6 * params.values.len());
}
