//! The client end of the wire, shared by every program that calls a learner (actors, `learner
//! status`, benchmarks, tests): the HTTP/2 settings both ends agree on, the bearer token, and
//! connecting.

use std::path::{Path, PathBuf};
use std::time::Duration;

use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Channel, Endpoint};

use crate::v1::learner_client::LearnerClient;

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
    #[error("`{addr}` is not a valid address (expected host:port)")]
    BadAddress {
        addr: String,
        #[source]
        source: tonic::transport::Error,
    },
    #[error("connecting to the learner at {url}")]
    Connect {
        url: String,
        #[source]
        source: tonic::transport::Error,
    },
    #[error("reading auth token file {}", path.display())]
    ReadToken {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("auth token file {} is empty", path.display())]
    EmptyToken { path: PathBuf },
}

/// Connects to a learner at `addr` (`host:port` or `http://host:port`), with an optional token.
pub async fn connect(addr: &str, token: Option<String>) -> Result<Client, ClientError> {
    let url = if addr.starts_with("http://") || addr.starts_with("https://") { addr.to_owned() } else { format!("http://{addr}") };
    let channel = Endpoint::from_shared(url.clone())
        .map_err(|source| ClientError::BadAddress { addr: addr.to_owned(), source })?
        .connect_timeout(Duration::from_secs(5))
        .initial_stream_window_size(Some(STREAM_WINDOW))
        .initial_connection_window_size(Some(CONNECTION_WINDOW))
        // A silently dead path (a cut network, a peer that moved) is noticed within ~30 s, not
        // after TCP's own retransmission timeout of many minutes, so actors reconnect.
        .http2_keep_alive_interval(Duration::from_secs(10))
        .keep_alive_timeout(Duration::from_secs(20))
        .keep_alive_while_idle(true)
        .connect()
        .await
        .map_err(|source| ClientError::Connect { url, source })?;
    Ok(LearnerClient::with_interceptor(channel, TokenInterceptor(token))
        .max_decoding_message_size(CLIENT_MAX_MESSAGE_BYTES)
        .max_encoding_message_size(CLIENT_MAX_MESSAGE_BYTES))
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
