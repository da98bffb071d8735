//! Server reflection for `learner serve`, in both protocol revisions: `grpc.reflection.v1`
//! (grpcurl, current clients) and `grpc.reflection.v1alpha`, which many stock clients still speak
//! only (grpcio's Python `ProtoReflectionDescriptorDatabase`, older grpcurl builds, GUI clients).
//! It lives in the program, not the service library, so that the actor, which runs the library in
//! process for `actor train`, links no reflection.

use tonic::service::Routes;

/// The reflection services of the learner's and the health service's descriptors, to serve
/// beside the learner (`learner::serve::ServeOptions::extra_services`).
pub fn routes() -> Result<Routes, tonic_reflection::server::Error> {
    let builder = || {
        tonic_reflection::server::Builder::configure()
            .register_encoded_file_descriptor_set(proto::v1::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
    };
    Ok(Routes::new(builder().build_v1()?).add_service(builder().build_v1alpha()?))
}
