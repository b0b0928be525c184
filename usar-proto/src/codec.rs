//! Codec (stub).
use bytes::BytesMut;
use tokio_util::codec::Decoder;
use crate::{Command, Parsed};
/// Line error.
#[derive(Debug, thiserror::Error)]
#[error("line error")]
pub struct LineError;
/// Codec.
#[derive(Debug)]
pub struct CommandCodec;
impl CommandCodec {
    /// New.
    pub fn new(_max: usize) -> Self { Self }
}
impl Decoder for CommandCodec {
    type Item = Result<Parsed<Command>, LineError>;
    type Error = std::io::Error;
    fn decode(&mut self, _src: &mut BytesMut) -> Result<Option<Self::Item>, Self::Error> { Ok(None) }
}
