//! Line framing of the TCP stream: the one place to swap for `usar-proto`'s codec.
//!
//! Server lines end with `\r\n` (a bare `\n` is accepted too); commands are sent with `\r\n`.

use futures::StreamExt;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt};
use tokio_util::codec::{FramedRead, LinesCodec, LinesCodecError};

/// Longest accepted server line, bytes (a 228-beam scan is about 1.2 KB).
pub const MAX_LINE_LENGTH: usize = 64 * 1024;

/// Reads server lines, without their terminator.
#[derive(Debug)]
pub struct LineReader<R> {
    inner: FramedRead<R, LinesCodec>,
}

impl<R: AsyncRead + Unpin> LineReader<R> {
    /// Frames `reader` into lines.
    pub fn new(reader: R) -> Self {
        Self {
            inner: FramedRead::new(reader, LinesCodec::new_with_max_length(MAX_LINE_LENGTH)),
        }
    }

    /// The next line; `Ok(None)` at a clean end of stream.
    pub async fn next_line(&mut self) -> std::io::Result<Option<String>> {
        match self.inner.next().await {
            None => Ok(None),
            Some(Ok(line)) => Ok(Some(line)),
            Some(Err(LinesCodecError::Io(e))) => Err(e),
            Some(Err(LinesCodecError::MaxLineLengthExceeded)) => Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("server line longer than {MAX_LINE_LENGTH} bytes"),
            )),
        }
    }
}

/// Writes one line followed by `\r\n`, in a single write.
pub async fn write_line<W: AsyncWrite + Unpin>(writer: &mut W, line: &str) -> std::io::Result<()> {
    let mut buf = Vec::with_capacity(line.len() + 2);
    buf.extend_from_slice(line.as_bytes());
    buf.extend_from_slice(b"\r\n");
    writer.write_all(&buf).await?;
    writer.flush().await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn crlf_and_lf() {
        let data: &[u8] = b"NFO {Level x}\r\nSTA {Time 1}\nlast";
        let mut reader = LineReader::new(data);
        assert_eq!(
            reader.next_line().await.unwrap().as_deref(),
            Some("NFO {Level x}")
        );
        assert_eq!(
            reader.next_line().await.unwrap().as_deref(),
            Some("STA {Time 1}")
        );
        assert_eq!(reader.next_line().await.unwrap().as_deref(), Some("last"));
        assert_eq!(reader.next_line().await.unwrap(), None);
    }

    #[tokio::test]
    async fn writes_crlf() {
        let mut out = Vec::new();
        write_line(&mut out, "DRIVE {Normalized true}")
            .await
            .unwrap();
        assert_eq!(out, b"DRIVE {Normalized true}\r\n");
    }
}
