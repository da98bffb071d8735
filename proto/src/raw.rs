//! Raw bytes as gRPC messages: what a broken or hostile client can put on the wire, for the tests
//! and probes that must send what no typed client would (garbage, an oversized message).

use tonic::codec::{Codec, DecodeBuf, Decoder, EncodeBuf, Encoder};
use tonic::codegen::tokio_stream;
use tonic::transport::Channel;

use crate::client::ACTOR_ID_HEADER;

/// A codec whose messages are any bytes, sent and received as they are.
#[derive(Debug, Clone, Copy, Default)]
pub struct RawCodec;

impl Codec for RawCodec {
    type Encode = Vec<u8>;
    type Decode = Vec<u8>;
    type Encoder = RawCodec;
    type Decoder = RawCodec;
    fn encoder(&mut self) -> RawCodec {
        RawCodec
    }
    fn decoder(&mut self) -> RawCodec {
        RawCodec
    }
}

impl Encoder for RawCodec {
    type Item = Vec<u8>;
    type Error = tonic::Status;
    fn encode(&mut self, item: Vec<u8>, dst: &mut EncodeBuf<'_>) -> Result<(), tonic::Status> {
        bytes::BufMut::put_slice(dst, &item);
        Ok(())
    }
}

impl Decoder for RawCodec {
    type Item = Vec<u8>;
    type Error = tonic::Status;
    fn decode(&mut self, src: &mut DecodeBuf<'_>) -> Result<Option<Vec<u8>>, tonic::Status> {
        let n = bytes::Buf::remaining(src);
        Ok(Some(bytes::Buf::copy_to_bytes(src, n).to_vec()))
    }
}

/// Streams `messages` as they are to `StreamExperience` on `channel` (declaring `actor` in the
/// metadata, as actors do, when given) and returns the replies, or the status the stream ended with.
///
/// # Errors
/// The status the learner ended the stream with, or `UNAVAILABLE` when the channel is not ready.
pub async fn stream_experience(channel: Channel, actor: Option<&str>, messages: Vec<Vec<u8>>) -> Result<Vec<Vec<u8>>, tonic::Status> {
    let mut grpc = tonic::client::Grpc::new(channel);
    grpc.ready().await.map_err(|e| tonic::Status::unavailable(e.to_string()))?;
    let mut req = tonic::Request::new(tokio_stream::iter(messages));
    if let Some(id) = actor {
        let value = id.parse().map_err(|_| tonic::Status::invalid_argument(format!("actor id `{id}` is not a header value")))?;
        req.metadata_mut().insert(ACTOR_ID_HEADER, value);
    }
    let path = tonic::codegen::http::uri::PathAndQuery::from_static("/hybriddrive.v1.Learner/StreamExperience");
    let mut replies = grpc.streaming(req, path, RawCodec).await?.into_inner();
    let mut out = Vec::new();
    while let Some(m) = replies.message().await? {
        out.push(m);
    }
    Ok(out)
}
