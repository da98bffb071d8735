//! The client end of the wire, shared by every program that calls a learner (actors, `learner
//! status`, benchmarks, tests): the HTTP/2 settings both ends agree on, the bearer token, and
//! connecting — the one place that builds an endpoint, plaintext or TLS, from a [`Target`]. A
//! connection is proven by one health call before it is handed out, so that every way of failing
//! (TLS refused either way, plaintext against TLS) ends within the connect timeout with a sentence
//! that says which ([`crate::failure`]).

use std::path::{Path, PathBuf};
use std::time::Duration;

use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Channel, Endpoint};
use tonic_health::pb::HealthCheckRequest;
use tonic_health::pb::health_client::HealthClient;

use crate::failure::Attempt;
pub use crate::target::{Target, TargetError, TlsFiles};
use crate::v1::learner_client::LearnerClient;

/// How long connecting may take, TCP, TLS and the first exchange together.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// HTTP/2 flow-control windows, bytes (server and clients). Batches of frames are large: HTTP/2's
/// default 64 KiB window would stall each one on window updates.
pub const STREAM_WINDOW: u32 = 8 << 20;
pub const CONNECTION_WINDOW: u32 = 16 << 20;

/// Largest message a client sends or accepts, bytes (the learner's own limit is its
/// `service.max_message_bytes`).
pub const CLIENT_MAX_MESSAGE_BYTES: usize = 256 << 20;

/// Request metadata key an actor sets on `StreamExperience` to its actor id, so that the learner
/// knows whose stream it is before the first batch arrives (and when a batch cannot be decoded).
pub const ACTOR_ID_HEADER: &str = "x-actor-id";

/// A client of the learner service that sends the auth token, if any.
pub type Client = LearnerClient<InterceptedService<Channel, TokenInterceptor>>;

/// Why a client could not connect, or a token file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error(transparent)]
    Target(#[from] TargetError),
    #[error("`{addr}` is not a valid address (expected host:port)")]
    BadAddress {
        addr: String,
        #[source]
        source: tonic::transport::Error,
    },
    #[error("connecting to the learner at {url}: {reason}")]
    Connect { url: String, reason: String },
    #[error(
        "no answer from the learner at {url} within {secs} s (connect timeout): is it listening there, and running \
         (not stopped)?"
    )]
    Timeout { url: String, secs: f64 },
    #[error("reading auth token file {}", path.display())]
    ReadToken {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("auth token file {} is empty", path.display())]
    EmptyToken { path: PathBuf },
}

/// Connects to a learner at `addr` (`host:port` or `http://host:port`, plaintext), with an
/// optional token.
pub async fn connect(addr: &str, token: Option<String>) -> Result<Client, ClientError> {
    connect_to(&Target::plain(addr)?, token).await
}

/// Connects to `target` (plaintext or TLS), with an optional token: refuses first to send a
/// token in clear to a non-loopback address ([`Target::check_token_safety`]).
pub async fn connect_to(target: &Target, token: Option<String>) -> Result<Client, ClientError> {
    if token.is_some() {
        target.check_token_safety().await?;
    }
    let channel = open(target, CONNECT_TIMEOUT).await?;
    Ok(LearnerClient::with_interceptor(channel, TokenInterceptor(token))
        .max_decoding_message_size(CLIENT_MAX_MESSAGE_BYTES)
        .max_encoding_message_size(CLIENT_MAX_MESSAGE_BYTES))
}

/// The endpoint of `target`: the HTTP/2 settings both ends agree on, and TLS when it says so.
pub fn endpoint(target: &Target, connect_timeout: Duration) -> Result<Endpoint, ClientError> {
    let mut endpoint = Endpoint::from_shared(target.url.clone())
        .map_err(|source| ClientError::BadAddress { addr: target.url.clone(), source })?
        .connect_timeout(connect_timeout)
        .initial_stream_window_size(Some(STREAM_WINDOW))
        .initial_connection_window_size(Some(CONNECTION_WINDOW))
        // A silently dead path (a cut network, a peer that moved) is noticed within ~30 s, not
        // after TCP's own retransmission timeout of many minutes, so actors reconnect.
        .http2_keep_alive_interval(Duration::from_secs(10))
        .keep_alive_timeout(Duration::from_secs(20))
        .keep_alive_while_idle(true);
    if let Some(tls) = target.client_tls_config()? {
        endpoint = endpoint
            .tls_config(tls.timeout(connect_timeout))
            .map_err(|e| ClientError::Connect { url: target.url.clone(), reason: format!("TLS configuration: {e}") })?;
    }
    Ok(endpoint)
}

/// Opens a channel to `target` and proves it with one `grpc.health.v1` call (any answer will
/// do: it shows that TCP, TLS both ways and HTTP/2 work), all within `timeout`.
pub async fn open(target: &Target, timeout: Duration) -> Result<Channel, ClientError> {
    let endpoint = endpoint(target, timeout)?;
    let attempt = Attempt {
        tls: target.tls.is_some(),
        client_cert: target.tls.as_ref().is_some_and(|t| t.identity.is_some()),
        host: &target.host,
        connected: false,
    };
    let failed = |e: &(dyn std::error::Error + 'static), connected: bool| ClientError::Connect {
        url: target.url.clone(),
        reason: crate::failure::describe(e, &Attempt { connected, ..attempt }),
    };
    let attempt = async {
        let channel = endpoint.connect().await.map_err(|e| failed(&e, false))?;
        let probe = HealthClient::new(channel.clone()).check(HealthCheckRequest { service: String::new() }).await;
        match probe {
            // A status made by the server (even UNIMPLEMENTED) went through; one made on this
            // side from a transport error carries that error as its source.
            Err(status) if std::error::Error::source(&status).is_some() => Err(failed(&status, true)),
            _ => Ok(channel),
        }
    };
    match tokio::time::timeout(timeout, attempt).await {
        Ok(result) => result,
        Err(_) => Err(ClientError::Timeout { url: target.url.clone(), secs: timeout.as_secs_f64() }),
    }
}

/// Reads a token file: its first line, trimmed; empty files are refused.
pub fn read_token(path: &Path) -> Result<String, ClientError> {
    let text = std::fs::read_to_string(path).map_err(|source| ClientError::ReadToken { path: path.to_owned(), source })?;
    let token = text.lines().next().unwrap_or("").trim().to_owned();
    if token.is_empty() {
        return Err(ClientError::EmptyToken { path: path.to_owned() });
    }
    Ok(token)
}

/// Adds `authorization: Bearer TOKEN` to every call when a token is set.
#[derive(Debug, Clone)]
pub struct TokenInterceptor(pub Option<String>);

impl tonic::service::Interceptor for TokenInterceptor {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some(t) = &self.0 {
            let v = format!("Bearer {t}")
                .parse()
                .map_err(|_| tonic::Status::invalid_argument("the auth token has characters not allowed in a header"))?;
            req.metadata_mut().insert("authorization", v);
        }
        Ok(req)
    }
}
