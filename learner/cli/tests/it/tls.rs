//! TLS and mutual TLS seen from a client, over real gRPC on 127.0.0.1:0 with certificates made
//! at test time (`learner_cli::certs`): an actor-side client streams and gets weights; each way of
//! failing ends with a message that says which (never the connect timeout's); certificates
//! rotate without a restart; a token is refused before connecting to a non-loopback address in
//! clear.

use std::path::{Path, PathBuf};

use agent::config::RunConfig;
use learner::serve::{Running, ServeOptions, start};
use learner_cli::certs::{Ca, Pem, Validity};
use proto::client::{ClientError, Target, TargetError, TlsFiles, connect_to};
use proto::v1 as pb;
use time::{Duration, OffsetDateTime};

const HOST: &str = "127.0.0.1";

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A CA's certificate file and a certificate with its key, written under `dir` as `NAME.pem`,
/// `NAME-key.pem`.
fn write_pem(dir: &Path, name: &str, pem: &Pem) -> (PathBuf, PathBuf) {
    (write(dir, &format!("{name}.pem"), &pem.cert), write(dir, &format!("{name}-key.pem"), &pem.key))
}

fn valid() -> Validity {
    Validity::days_from_now(1)
}

async fn start_tls(dir: &Path, cert: &(PathBuf, PathBuf), client_ca: Option<&Path>) -> Running {
    let cfg_path = dir.join("run.toml");
    std::fs::write(&cfg_path, RunConfig::tiny(&dir.join("run")).to_toml()).unwrap();
    start(ServeOptions {
        config: Some(cfg_path),
        tls_cert: Some(cert.0.clone()),
        tls_key: Some(cert.1.clone()),
        tls_client_ca: client_ca.map(Path::to_path_buf),
        ..ServeOptions::default()
    })
    .await
    .unwrap()
}

fn target(r: &Running, ca: &Path, identity: Option<&(PathBuf, PathBuf)>) -> Target {
    let files = TlsFiles { ca: ca.to_owned(), identity: identity.cloned() };
    Target::new(&format!("{HOST}:{}", r.addr.port()), Some(files), false).unwrap()
}

/// Registers, streams one batch (acknowledged) and gets the weights, as an actor does.
async fn act(r: &Running, t: &Target) {
    let mut c = connect_to(t, None).await.unwrap();
    let reg = c.register(register_request("tls")).await.unwrap().into_inner();
    let steps = (0..3)
        .map(|t| pb::Step {
            t,
            obs: Some(pb::Observation { image: vec![9; r.shared.frame_bytes], speed: 1.0, d: 0.5, path: Vec::new(), vector: Vec::new() }),
            action: 1,
            reward: 0.1,
            ..Default::default()
        })
        .collect();
    let batch = pb::ExperienceBatch { actor_id: reg.actor_id.clone(), seq: 1, steps, epsilon: 0.5, ..Default::default() };
    let mut acks = c.stream_experience(tokio_stream::iter(vec![batch])).await.unwrap().into_inner();
    assert_eq!(acks.message().await.unwrap().unwrap().seq, 1);
    let w = c.get_weights(pb::GetWeightsRequest { actor_id: reg.actor_id, have_version: 0 }).await.unwrap().into_inner();
    assert!(!w.safetensors.is_empty() && w.version > 0);
}

/// The message a connection attempt fails with; never the connect timeout's.
async fn refusal(t: &Target) -> String {
    let e = connect_to(t, None).await.map(|_| ()).unwrap_err();
    assert!(!matches!(e, ClientError::Timeout { .. }), "{e}");
    e.to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_actor_streams_and_gets_weights_over_tls_and_mutual_tls() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ca = Ca::new(valid()).unwrap();
    let ca_file = write(d, "ca.pem", &ca.pem.cert);
    let server = write_pem(d, "server", &ca.server(&[HOST.into(), "localhost".into()], valid()).unwrap());
    let client = write_pem(d, "client", &ca.client("actor-1", valid()).unwrap());

    std::fs::create_dir(d.join("tls")).unwrap();
    let tls = start_tls(&d.join("tls"), &server, None).await;
    act(&tls, &target(&tls, &ca_file, None)).await;

    std::fs::create_dir(d.join("mtls")).unwrap();
    let mtls = start_tls(&d.join("mtls"), &server, Some(&ca_file)).await;
    act(&mtls, &target(&mtls, &ca_file, Some(&client))).await;

    // Under mutual TLS: no client certificate, or one from a CA the learner does not trust.
    let m = refusal(&target(&mtls, &ca_file, None)).await;
    assert!(m.contains("requires a client certificate (mutual TLS): give --tls-cert FILE and --tls-key FILE"), "{m}");
    let stranger = Ca::new(valid()).unwrap();
    let foreign = write_pem(d, "foreign", &stranger.client("intruder", valid()).unwrap());
    let m = refusal(&target(&mtls, &ca_file, Some(&foreign))).await;
    assert!(m.contains("the learner refused this client's certificate"), "{m}");
    // Health and reflection share the TLS listener: plaintext gets neither.
    let plain = Target::plain(&mtls.addr.to_string()).unwrap();
    let m = refusal(&plain).await;
    assert!(m.contains("it may serve TLS (then connect with https://HOST:PORT and --tls-ca FILE)"), "{m}");
    mtls.stop().await.unwrap();
    tls.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_tls_failure_says_which_and_certificates_rotate_without_a_restart() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ca = Ca::new(valid()).unwrap();
    let ca_file = write(d, "ca.pem", &ca.pem.cert);
    let server = write_pem(d, "server", &ca.server(&[HOST.into()], valid()).unwrap());
    let running = start_tls(d, &server, None).await;
    let tls = running.tls.clone().unwrap();
    let good = target(&running, &ca_file, None);
    connect_to(&good, None).await.unwrap();

    // The wrong CA.
    let other = Ca::new(valid()).unwrap();
    let other_file = write(d, "other-ca.pem", &other.pem.cert);
    let m = refusal(&target(&running, &other_file, None)).await;
    assert!(m.contains("is not signed by the CA in --tls-ca"), "{m}");

    // Plaintext to the TLS port.
    let m = refusal(&Target::plain(&running.addr.to_string()).unwrap()).await;
    assert!(m.contains("without speaking HTTP/2 in clear: it may serve TLS"), "{m}");

    // The server's certificate replaced on disk and reloaded (as SIGHUP or the file watch do):
    // expired, not yet valid, for another name. New connections see each at once.
    let now = OffsetDateTime::now_utc();
    let swap = |pem: Pem| {
        write_pem(d, "server", &pem);
        tls.reload().unwrap();
    };
    swap(ca.server(&[HOST.into()], Validity { not_before: now - Duration::days(10), not_after: now - Duration::days(1) }).unwrap());
    let m = refusal(&good).await;
    assert!(m.contains("the learner's certificate has expired"), "{m}");
    swap(ca.server(&[HOST.into()], Validity { not_before: now + Duration::days(1), not_after: now + Duration::days(10) }).unwrap());
    let m = refusal(&good).await;
    assert!(m.contains("the learner's certificate is not valid yet"), "{m}");
    swap(ca.server(&["learner.example".into()], valid()).unwrap());
    let m = refusal(&good).await;
    assert!(m.contains("hostname mismatch: the learner's certificate is not valid for `127.0.0.1`"), "{m}");

    // Rotation to a new CA: old clients are refused, clients with the new CA connect; a broken
    // file is refused by the reload and the previous certificate kept.
    swap(other.server(&[HOST.into()], valid()).unwrap());
    assert!(refusal(&good).await.contains("is not signed by the CA in --tls-ca"));
    let rotated = target(&running, &other_file, None);
    act(&running, &rotated).await;
    std::fs::write(&server.1, "not a key").unwrap();
    let e = tls.reload().unwrap_err().to_string();
    assert!(e.contains("--tls-key") && e.contains("server-key.pem"), "{e}");
    connect_to(&rotated, None).await.unwrap();
    running.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tls_to_a_plaintext_port_says_so() {
    let listener = tokio::net::TcpListener::bind((HOST, 0)).await.unwrap();
    let addr = listener.local_addr().unwrap();
    let (_reporter, health) = tonic_health::server::health_reporter();
    tokio::spawn(
        tonic::transport::Server::builder()
            .add_service(health)
            .serve_with_incoming(tokio_stream::wrappers::TcpListenerStream::new(listener)),
    );
    // The plaintext server answers plaintext clients.
    proto::client::open(&Target::plain(&addr.to_string()).unwrap(), proto::client::CONNECT_TIMEOUT).await.unwrap();
    let dir = tempfile::tempdir().unwrap();
    let ca = Ca::new(valid()).unwrap();
    let files = TlsFiles { ca: write(dir.path(), "ca.pem", &ca.pem.cert), identity: None };
    let m = refusal(&Target::new(&addr.to_string(), Some(files), false).unwrap()).await;
    assert!(m.contains("it may serve plaintext (then connect with http:// and no --tls-ca)"), "{m}");
}

#[tokio::test]
async fn a_token_is_refused_in_clear_to_a_non_loopback_address_before_connecting() {
    // 192.0.2.1 (TEST-NET-1) answers nothing: were a connection tried, this would be a timeout.
    let t = Target::plain("192.0.2.1:50051").unwrap();
    let e = connect_to(&t, Some("s3cret".into())).await.map(|_| ()).unwrap_err();
    assert!(matches!(e, ClientError::Target(TargetError::TokenInClear { .. })), "{e}");
    assert!(e.to_string().contains("pass --insecure-plaintext"), "{e}");
    // The override lets it try (and fail to connect, which is not a refusal).
    let t = Target::new("192.0.2.1:50051", None, true).unwrap();
    let e = connect_to(&t, Some("s3cret".into())).await.map(|_| ()).unwrap_err();
    assert!(!matches!(e, ClientError::Target(_)), "{e}");
}

/// A registration of one environment. `..Default::default()` keeps this compiling as
/// `RegisterRequest` gains fields (today it has no others).
#[allow(clippy::needless_update)]
fn register_request(name: &str) -> pb::RegisterRequest {
    pb::RegisterRequest { name: name.into(), envs: 1, protocol: proto::v1::PROTOCOL, ..Default::default() }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_metrics_endpoint_serves_the_same_tls() {
    use std::sync::Arc;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ca = Ca::new(valid()).unwrap();
    let server = write_pem(d, "server", &ca.server(&[HOST.into()], valid()).unwrap());
    let cfg_path = d.join("run.toml");
    std::fs::write(&cfg_path, RunConfig::tiny(&d.join("run")).to_toml()).unwrap();
    let running = start(ServeOptions {
        config: Some(cfg_path),
        tls_cert: Some(server.0.clone()),
        tls_key: Some(server.1.clone()),
        metrics_listen: Some("0".into()),
        ..ServeOptions::default()
    })
    .await
    .unwrap();
    // A bare port binds loopback.
    let addr: std::net::SocketAddr = std::fs::read_to_string(d.join("run/metrics.addr")).unwrap().trim().parse().unwrap();
    assert!(addr.ip().is_loopback(), "{addr}");

    let mut roots = rustls::RootCertStore::empty();
    roots.add(rustls::pki_types::CertificateDer::from(ca_der(&ca.pem.cert))).unwrap();
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let config = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_root_certificates(roots)
        .with_no_client_auth();
    let tcp = tokio::net::TcpStream::connect(addr).await.unwrap();
    let name = rustls::pki_types::ServerName::try_from(HOST).unwrap();
    let mut tls = tokio_rustls::TlsConnector::from(Arc::new(config)).connect(name, tcp).await.unwrap();
    tls.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n").await.unwrap();
    let mut text = String::new();
    tls.read_to_string(&mut text).await.ok();
    assert!(text.starts_with("HTTP/1.1 200") && text.contains("learner_updates_total"), "{text}");
    // Plain HTTP gets no metrics.
    let mut plain = tokio::net::TcpStream::connect(addr).await.unwrap();
    plain.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n").await.unwrap();
    let mut answer = Vec::new();
    plain.read_to_end(&mut answer).await.ok();
    assert!(!String::from_utf8_lossy(&answer).contains("learner_updates_total"));
    running.stop().await.unwrap();
}

fn ca_der(pem: &str) -> Vec<u8> {
    use rustls::pki_types::pem::PemObject;
    rustls::pki_types::CertificateDer::from_pem_slice(pem.as_bytes()).unwrap().to_vec()
}
