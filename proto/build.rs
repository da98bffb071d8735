//! Generates the gRPC code from `proto/hybriddrive/v1/*.proto` with a vendored `protoc` (no
//! system package needed), and the file descriptor set that server reflection serves.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut config = tonic_prost_build::Config::new();
    config.protoc_executable(protoc_bin_vendored::protoc_bin_path()?);
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    tonic_prost_build::configure().file_descriptor_set_path(out.join("hybriddrive_v1_descriptor.bin")).compile_with_config(
        config,
        &["proto/hybriddrive/v1/learner.proto"],
        &["proto"],
    )?;
    println!("cargo:rerun-if-changed=proto");
    Ok(())
}
