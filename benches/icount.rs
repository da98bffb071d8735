//! What the instruction-count harnesses (`sim-core/examples/icount_sim.rs`,
//! `learner/examples/icount_learner.rs`) print, in one place: each includes this file
//! (`#[path] mod icount;`), so that `scripts/bench_check.py` reads both the same way.

/// Prints the benches, one `NAME<TAB>WHAT` line each (`list`).
pub fn list(benches: &[(&str, &str)]) {
    for (name, what) in benches {
        println!("{name}\t{what}");
    }
}

/// Prints the JSON line of a counted run (`run NAME`): the bench, its iterations and the CPU class.
pub fn report(bench: &str, iterations: u64) {
    println!("{{\"bench\":\"{bench}\",\"iterations\":{iterations},\"cpu_class\":\"{}\"}}", cpu_class());
}

/// The x86 feature class this process runs (what `gemm` and glibc dispatch on).
fn cpu_class() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            "x86_64-avx512"
        } else if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
            "x86_64-avx2-fma"
        } else {
            "x86_64-baseline"
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        std::env::consts::ARCH
    }
}
