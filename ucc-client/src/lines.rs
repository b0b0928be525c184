//! Line framing of the TCP stream with usar-proto's [`LineCodec`], the codec the server uses
//! too: any CR/LF mix ends a line, empty lines are skipped, a line longer than
//! [`MAX_LINE_LENGTH`] is skipped (with a warning) without being buffered. Commands are sent
//! with `\r\n`.

use futures::StreamExt;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt};
use tokio_util::codec::FramedRead;
use usar_proto::codec::{LineCodec, LineError};

/// Longest accepted server line, bytes (a 228-beam scan is about 1.3 KB).
pub const MAX_LINE_LENGTH: usize = usar_proto::codec::DEFAULT_MAX_LINE;

/// Reads server lines, without their terminator.
#[derive(Debug)]
pub struct LineReader<R> {
    inner: FramedRead<R, LineCodec>,
}

impl<R: AsyncRead + Unpin> LineReader<R> {
    /// Frames `reader` into lines.
    pub fn new(reader: R) -> Self {
        Self {
            inner: FramedRead::new(reader, LineCodec::new(MAX_LINE_LENGTH)),
        }
    }

    /// The next line; `Ok(None)` at the end of the stream. A line cut by the end of the
    /// stream is still returned (the server closed mid-line); an over-long one is skipped.
    pub async fn next_line(&mut self) -> std::io::Result<Option<String>> {
        loop {
            match self.inner.next().await {
                None => return Ok(None),
                Some(Err(e)) => return Err(e),
                Some(Ok(Ok(line))) => return Ok(Some(line)),
                Some(Ok(Err(LineError::Unterminated { partial }))) => return Ok(Some(partial)),
                Some(Ok(Err(error @ LineError::TooLong { .. }))) => {
                    tracing::warn!(%error, "server line skipped");
                }
            }
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
    async fn any_line_ending_and_a_cut_last_line() {
        let data: &[u8] = b"NFO {Level x}\r\nSTA {Time 1}\n\rSEN {Time 2}\rlast";
        let mut reader = LineReader::new(data);
        for want in ["NFO {Level x}", "STA {Time 1}", "SEN {Time 2}", "last"] {
            assert_eq!(reader.next_line().await.unwrap().as_deref(), Some(want));
        }
        assert_eq!(reader.next_line().await.unwrap(), None);
    }

    #[tokio::test]
    async fn an_over_long_line_is_skipped() {
        let mut data = vec![b'x'; MAX_LINE_LENGTH + 10];
        data.extend_from_slice(b"\r\nSTA {Time 1}\r\n");
        let mut reader = LineReader::new(&data[..]);
        assert_eq!(
            reader.next_line().await.unwrap().as_deref(),
            Some("STA {Time 1}")
        );
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
