//! Criterion benches of each layer of the paper's network at 84×84×3 (the convolutions at 84×84,
//! 42×42 and 21×21 with 64 filters; the dense layers at batch 32), forward and backward, one
//! thread, one image per convolution call (the network runs its convolutions image by image);
//! and the whole network's forward at batch 1 and full update at batch 32 on every core.
//! `cargo bench -p learner --bench layers`.

use std::hint::black_box;

use agent::NetShape;
use agent::config::AgentConfig;
use agent::fastnet::conv::{self, ConvGeom};
use agent::fastnet::gemm::{View, matmul};
use agent::fastnet::pool::{self, Strided};
use agent::fastnet::{FastNet, Params, default_threads};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use learner::training::dqn::{Batch, Dqn};

fn noise(n: usize, seed: u32) -> Vec<f32> {
    (0..n as u32).map(|i| ((i.wrapping_mul(2_654_435_761) ^ seed) % 1000) as f32 / 500.0 - 1.0).collect()
}

fn convolutions(c: &mut Criterion) {
    let mut group = c.benchmark_group("conv_one_image");
    for (name, g) in [
        ("conv1_84x84x3", ConvGeom { h: 84, w: 84, cin: 3, cout: 64 }),
        ("conv2_42x42x64", ConvGeom { h: 42, w: 42, cin: 64, cout: 64 }),
        ("conv3_21x21x64", ConvGeom { h: 21, w: 21, cin: 64, cout: 64 }),
    ] {
        let input = noise(g.padded_in(), 1);
        let weights = noise(9 * g.cin * g.cout, 2);
        let (mut k_major, mut flipped) = (Vec::new(), Vec::new());
        conv::kernel_k_major(&weights, &g, &mut k_major);
        conv::kernel_flipped(&weights, &g, &mut flipped);
        let mut out = vec![0f32; g.out_len()];
        let mut patches = vec![0f32; g.patches_len().max(g.transposed().patches_len())];
        let grad = noise(g.padded_out(), 3);
        let mut dk = vec![0f32; 9 * g.cin * g.cout];
        let mut din = vec![0f32; g.in_grad_len()];
        group.bench_with_input(BenchmarkId::new("forward", name), &(), |b, ()| {
            b.iter(|| conv::forward(black_box(&input), &k_major, &g, &mut out, &mut patches, 1));
        });
        group.bench_with_input(BenchmarkId::new("kernel_grad", name), &(), |b, ()| {
            b.iter(|| conv::kernel_grad(black_box(&input), &grad, &g, &mut dk, &mut patches, 1));
        });
        if g.cin > 3 {
            group.bench_with_input(BenchmarkId::new("input_grad", name), &(), |b, ()| {
                b.iter(|| conv::input_grad(black_box(&grad), &flipped, &g, &mut din, &mut patches, 1));
            });
        }
        let bias = noise(g.cout, 4);
        let mut pooled = vec![0f32; (g.h / 2 + 2) * (g.w / 2 + 2) * g.cout];
        group.bench_with_input(BenchmarkId::new("bias_relu_pool", name), &(), |b, ()| {
            b.iter(|| pool::forward(black_box(&out), &bias, g.h, g.w, &mut pooled, Strided::padded(g.w / 2, g.cout)));
        });
        let mut grad_padded = vec![0f32; g.padded_out()];
        let mut db = vec![0f32; g.cout];
        group.bench_with_input(BenchmarkId::new("bias_relu_pool_backward", name), &(), |b, ()| {
            b.iter(|| {
                pool::backward(black_box(&out), &bias, g.h, g.w, &pooled, Strided::padded(g.w / 2, g.cout), &mut grad_padded, &mut db)
            });
        });
    }
    group.finish();
}

fn dense(c: &mut Criterion) {
    let mut group = c.benchmark_group("dense_batch32");
    let b = 32;
    for (name, k, n) in [("fc1_6402x256", 64 * 10 * 10 + 2, 256), ("fc2_256x256", 256, 256), ("q_256x6", 256, 6)] {
        let x = noise(b * k, 5);
        let w = noise(n * k, 6);
        let up = noise(b * n, 7);
        let mut out = vec![0f32; b * n];
        let mut dw = vec![0f32; n * k];
        let mut dx = vec![0f32; b * k];
        group.bench_with_input(BenchmarkId::new("forward", name), &(), |bch, ()| {
            bch.iter(|| {
                matmul(&mut out, View::rows(0, b, n, n), false, black_box(&x), View::rows(0, b, k, k), &w, View::rows(0, n, k, k).t(), 1)
            });
        });
        group.bench_with_input(BenchmarkId::new("weight_grad", name), &(), |bch, ()| {
            bch.iter(|| {
                matmul(&mut dw, View::rows(0, n, k, k), false, black_box(&up), View::rows(0, b, n, n).t(), &x, View::rows(0, b, k, k), 1)
            });
        });
        group.bench_with_input(BenchmarkId::new("input_grad", name), &(), |bch, ()| {
            bch.iter(|| {
                matmul(&mut dx, View::rows(0, b, k, k), false, black_box(&up), View::rows(0, b, n, n), &w, View::rows(0, n, k, k), 1)
            });
        });
    }
    group.finish();
}

/// The machine's reach: a square single-thread GEMM of the size of the middle layer's work,
/// against which the layers' times can be read (GFLOP/s = 2·512³ / time).
fn calibration(c: &mut Criterion) {
    let n = 512;
    let a = noise(n * n, 8);
    let b = noise(n * n, 9);
    let mut out = vec![0f32; n * n];
    c.bench_function("gemm_512_square_one_thread", |bch| {
        bch.iter(|| matmul(&mut out, View::rows(0, n, n, n), false, black_box(&a), View::rows(0, n, n, n), &b, View::rows(0, n, n, n), 1));
    });
}

fn network(c: &mut Criterion) {
    let mut group = c.benchmark_group("network");
    group.sample_size(10);
    let shape = NetShape { height: 84, width: 84, channels: 3, scalars: 2, actions: 6, filters: 64, hidden: 256 };
    let params = Params::init(shape, 1);
    let frame = 84 * 84 * 3;
    let image: Vec<u8> = (0..frame).map(|i| (i % 251) as u8).collect();
    let mut net = FastNet::new(shape, default_threads());
    group.bench_function("forward_batch1_84x84x3", |b| b.iter(|| black_box(net.forward(&params, &image, &[0.5, 0.1]).len())));
    let mut dqn = Dqn::new(shape, &AgentConfig::default());
    let n = 32;
    let images: Vec<u8> = (0..n * frame).map(|i| (i % 253) as u8).collect();
    let batch = Batch {
        next_images: images.iter().rev().copied().collect(),
        images,
        scalars: vec![0.5; 2 * n],
        next_scalars: vec![0.4; 2 * n],
        actions: (0..n as u32).map(|i| i % 6).collect(),
        rewards: vec![0.1; n],
        discounts: vec![0.99; n],
        weights: vec![1.0; n],
        demos: 0,
    };
    group.bench_function("update_batch32_84x84x3", |b| b.iter(|| black_box(dqn.update(&batch).loss)));
    group.finish();
}

criterion_group!(benches, calibration, convolutions, dense, network);
criterion_main!(benches);
