//! Runs the paper network's forward pass in a loop, for profilers (`valgrind --tool=callgrind`,
//! `perf record`): `cargo run --release -p agent --example forward -- 84x84x1 BATCH THREADS CALLS
//! [f32|bf16] [packed]` (bf16: the wide layers on the machine's bf16 kernel; packed: the kernels
//! laid out once, as an actor's `Inference` does, rather than on every call as training does).
//! Prints the Q values' checksum (so that the work cannot be optimised away) and, on stderr, the
//! median time per call.

use agent::NetShape;
use agent::fastnet::{FastNet, Params};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or_else(|| default.to_owned());
    let dims: Vec<usize> = arg(0, "84x84x1").split('x').map(|v| v.parse().expect("WxHxC")).collect();
    let (batch, threads, calls): (usize, usize, usize) =
        (arg(1, "1").parse().expect("batch"), arg(2, "1").parse().expect("threads"), arg(3, "20").parse().expect("calls"));
    let shape = NetShape { width: dims[0], height: dims[1], channels: dims[2], scalars: 2, actions: 6, filters: 64, hidden: 256 };
    let params = Params::init(shape, 1);
    let frame = shape.height * shape.width * shape.channels;
    let images: Vec<u8> = (0..batch * frame).map(|i| (i.wrapping_mul(2_654_435_761) >> 7) as u8).collect();
    let scalars = vec![0.5f32; batch * shape.scalars];
    let bf16 = match arg(4, "f32").as_str() {
        "f32" => false,
        "bf16" => true,
        other => panic!("precision {other:?}: f32 or bf16"),
    };
    let packed = arg(5, "") == "packed";
    let mut net = FastNet::with_precision(shape, threads, bf16);
    if packed {
        net.pack_for_inference(&params);
    }
    let mut sum = 0f64;
    let mut ms = Vec::with_capacity(calls);
    for _ in 0..calls {
        let start = std::time::Instant::now();
        let q = if packed { net.forward_packed(&params, &images, &scalars) } else { net.forward(&params, &images, &scalars) };
        sum += q.iter().map(|&q| f64::from(q)).sum::<f64>();
        ms.push(start.elapsed().as_secs_f64() * 1000.0);
    }
    ms.sort_by(f64::total_cmp);
    println!("{sum}");
    eprintln!("median {:.3} ms per call ({batch} images, {threads} threads)", ms[ms.len() / 2]);
}
