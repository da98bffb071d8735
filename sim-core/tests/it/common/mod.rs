//! What the map fuzzers share.

use proptest::test_runner::{Config as ProptestConfig, RngSeed};

/// Fuzzing with a fixed seed, so that CI is the same run every time (a random draw once hung CI
/// for hours on an input no one could replay); `PROPTEST_RNG_SEED=random` or a number explores.
pub fn fuzz_config(cases: u32) -> ProptestConfig {
    let config = ProptestConfig { cases, ..ProptestConfig::default() };
    match std::env::var("PROPTEST_RNG_SEED") {
        Ok(v) if v == "random" => ProptestConfig { rng_seed: RngSeed::Random, ..config },
        Ok(_) => config,
        Err(_) => ProptestConfig { rng_seed: RngSeed::Fixed(0x5eed_0d12), ..config },
    }
}
