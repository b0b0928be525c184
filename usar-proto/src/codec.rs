//! Codec (stub).
use crate::{Command, Parsed};
use bytes::BytesMut;
use tokio_util::codec::Decoder;
/// Line error.
#[derive(Debug, thiserror::Error)]
#[error("line error")]
pub struct LineError;
/// Codec.
#[derive(Debug)]
pub struct CommandCodec;
impl CommandCodec {
    /// New.
    pub fn new(_max: usize) -> Self {
        Self
    }
}
impl Decoder for CommandCodec {
    type Item = Result<Parsed<Command>, LineError>;
    type Error = std::io::Error;
    fn decode(&mut self, _src: &mut BytesMut) -> Result<Option<Self::Item>, Self::Error> {
        Ok(None)
    }
}
/// Line codec (stub).
#[derive(Debug)]
pub struct LineCodec;
impl LineCodec {
    /// New.
    pub fn new(_max: usize) -> Self {
        Self
    }
}
impl Decoder for LineCodec {
    type Item = Result<String, LineError>;
    type Error = std::io::Error;
    fn decode(&mut self, _src: &mut BytesMut) -> Result<Option<Self::Item>, Self::Error> {
        Ok(None)
    }
}
