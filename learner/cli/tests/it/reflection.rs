//! Server reflection as a stock client speaks it, over real gRPC on 127.0.0.1:0: both protocol
//! revisions (`grpc.reflection.v1alpha`, which grpcio's Python client and older grpcurl builds
//! speak, and `grpc.reflection.v1`) list the services and describe `hybriddrive.v1.Learner`, and
//! the method the descriptor names answers when called by that name. (`.ci/run` also runs grpcio's
//! own `ProtoReflectionDescriptorDatabase` against a learner: `tests/interop/test_reflection.py`.)

use std::path::Path;

use agent::config::RunConfig;
use learner::serve::{Running, ServeOptions, start};
use prost::Message;
use tonic_reflection::pb::{v1, v1alpha};

async fn start_tiny(dir: &Path) -> Running {
    let cfg_path = dir.join("run.toml");
    std::fs::write(&cfg_path, RunConfig::tiny(&dir.join("run")).to_toml()).unwrap();
    let extra_services = Some(learner_cli::reflection::routes().unwrap());
    start(ServeOptions { config: Some(cfg_path), extra_services, ..ServeOptions::default() }).await.unwrap()
}

async fn channel(r: &Running) -> tonic::transport::Channel {
    tonic::transport::Channel::from_shared(format!("http://{}", r.addr)).unwrap().connect().await.unwrap()
}

/// The methods of service `name` in a set of serialized `FileDescriptorProto`s.
fn methods_of(files: &[Vec<u8>], name: &str) -> Vec<String> {
    let (package, service) = name.rsplit_once('.').unwrap();
    files
        .iter()
        .map(|b| prost_types::FileDescriptorProto::decode(b.as_slice()).unwrap())
        .filter(|f| f.package() == package)
        .flat_map(|f| f.service)
        .filter(|s| s.name() == service)
        .flat_map(|s| s.method.into_iter().map(|m| m.name().to_owned()))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn v1alpha_lists_and_describes_the_learner_and_the_named_method_answers() {
    use v1alpha::server_reflection_client::ServerReflectionClient;
    use v1alpha::server_reflection_request::MessageRequest;
    use v1alpha::server_reflection_response::MessageResponse;
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path()).await;
    let mut client = ServerReflectionClient::new(channel(&running).await);
    let requests = [MessageRequest::ListServices(String::new()), MessageRequest::FileContainingSymbol("hybriddrive.v1.Learner".into())];
    let requests: Vec<_> =
        requests.into_iter().map(|r| v1alpha::ServerReflectionRequest { host: String::new(), message_request: Some(r) }).collect();
    let mut responses = client.server_reflection_info(tokio_stream::iter(requests)).await.unwrap().into_inner();

    let listed = match responses.message().await.unwrap().unwrap().message_response.unwrap() {
        MessageResponse::ListServicesResponse(l) => l.service.into_iter().map(|s| s.name).collect::<Vec<_>>(),
        other => panic!("list_services answered {other:?}"),
    };
    for want in ["hybriddrive.v1.Learner", "grpc.health.v1.Health", "grpc.reflection.v1alpha.ServerReflection"] {
        assert!(listed.iter().any(|s| s == want), "{want} not in {listed:?}");
    }
    let files = match responses.message().await.unwrap().unwrap().message_response.unwrap() {
        MessageResponse::FileDescriptorResponse(f) => f.file_descriptor_proto,
        other => panic!("file_containing_symbol answered {other:?}"),
    };
    let methods = methods_of(&files, "hybriddrive.v1.Learner");
    for want in ["Register", "StreamExperience", "GetWeights", "Status"] {
        assert!(methods.iter().any(|m| m == want), "{want} not in {methods:?}");
    }

    // Call the method by the name reflection gave, as a dynamic client would.
    let mut grpc = tonic::client::Grpc::new(channel(&running).await);
    grpc.ready().await.unwrap();
    let path = tonic::codegen::http::uri::PathAndQuery::from_static("/hybriddrive.v1.Learner/Status");
    let codec = tonic_prost::ProstCodec::<proto::v1::StatusRequest, proto::v1::StatusResponse>::default();
    let status = grpc.unary(tonic::Request::new(proto::v1::StatusRequest {}), path, codec).await.unwrap().into_inner();
    assert_eq!(status.run_id, running.shared.run_id);
    running.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn v1_lists_and_describes_the_learner() {
    use v1::server_reflection_client::ServerReflectionClient;
    use v1::server_reflection_request::MessageRequest;
    use v1::server_reflection_response::MessageResponse;
    let dir = tempfile::tempdir().unwrap();
    let running = start_tiny(dir.path()).await;
    let mut client = ServerReflectionClient::new(channel(&running).await);
    let requests = [MessageRequest::ListServices(String::new()), MessageRequest::FileContainingSymbol("hybriddrive.v1.Learner".into())];
    let requests: Vec<_> =
        requests.into_iter().map(|r| v1::ServerReflectionRequest { host: String::new(), message_request: Some(r) }).collect();
    let mut responses = client.server_reflection_info(tokio_stream::iter(requests)).await.unwrap().into_inner();
    match responses.message().await.unwrap().unwrap().message_response.unwrap() {
        MessageResponse::ListServicesResponse(l) => assert!(l.service.iter().any(|s| s.name == "hybriddrive.v1.Learner"), "{l:?}"),
        other => panic!("list_services answered {other:?}"),
    }
    match responses.message().await.unwrap().unwrap().message_response.unwrap() {
        MessageResponse::FileDescriptorResponse(f) => {
            assert!(methods_of(&f.file_descriptor_proto, "hybriddrive.v1.Learner").iter().any(|m| m == "Status"));
        }
        other => panic!("file_containing_symbol answered {other:?}"),
    }
    running.stop().await.unwrap();
}
