//! Line framing of the TCP stream with usar-proto's [`LineCodec`], the codec the server uses
//! too: any CR/LF mix ends a line, empty lines are skipped, a line longer than
//! [`MAX_LINE_LENGTH`] is skipped (with a warning) without being buffered. Commands are sent
//! with `\r\n`. [`LineReader`] reads an async stream, [`BlockingLines`] a blocking one (a
//! std `TcpStream` with a read time-out: the Python package's driver).

use futures::StreamExt;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt};
use tokio_util::bytes::BytesMut;
use tokio_util::codec::{Decoder, FramedRead};
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

/// Reads server lines from a blocking reader, framed as [`LineReader`] frames them: at most
/// [`MAX_LINE_LENGTH`] bytes of a line are ever buffered.
#[derive(Debug)]
pub struct BlockingLines<R> {
    reader: R,
    codec: LineCodec,
    buf: BytesMut,
    ended: bool,
}

impl<R: std::io::Read> BlockingLines<R> {
    /// Frames `reader` into lines.
    pub fn new(reader: R) -> Self {
        Self {
            reader,
            codec: LineCodec::new(MAX_LINE_LENGTH),
            buf: BytesMut::new(),
            ended: false,
        }
    }

    /// The reader (to set its time-out).
    pub fn get_ref(&self) -> &R {
        &self.reader
    }

    /// The next line; `Ok(None)` at the end of the stream. A read that times out is the
    /// reader's error (`WouldBlock` or `TimedOut`); the part of a line read so far is kept
    /// for the next call.
    pub fn next_line(&mut self) -> std::io::Result<Option<String>> {
        loop {
            let item = if self.ended {
                self.codec.decode_eof(&mut self.buf)?
            } else {
                self.codec.decode(&mut self.buf)?
            };
            match item {
                Some(Ok(line)) => return Ok(Some(line)),
                Some(Err(LineError::Unterminated { partial })) => return Ok(Some(partial)),
                Some(Err(error @ LineError::TooLong { .. })) => {
                    tracing::warn!(%error, "server line skipped");
                    continue;
                }
                None if self.ended => return Ok(None),
                None => {}
            }
            let mut chunk = [0; 4096];
            let n = self.reader.read(&mut chunk)?;
            if n == 0 {
                self.ended = true;
            }
            self.buf.extend_from_slice(&chunk[..n]);
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

    #[test]
    fn blocking_lines_frame_as_the_async_reader_and_keep_a_line_cut_by_a_time_out() {
        /// Hands out its parts one read at a time; `None` is a read that timed out.
        struct Parts(Vec<Option<Vec<u8>>>);
        impl std::io::Read for Parts {
            fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
                if self.0.is_empty() {
                    return Ok(0);
                }
                match self.0.remove(0) {
                    None => Err(std::io::ErrorKind::WouldBlock.into()),
                    Some(mut part) => {
                        let n = part.len().min(buf.len());
                        buf[..n].copy_from_slice(&part[..n]);
                        if n < part.len() {
                            self.0.insert(0, Some(part.split_off(n)));
                        }
                        Ok(n)
                    }
                }
            }
        }
        let mut long = vec![b'x'; MAX_LINE_LENGTH + 10];
        long.extend_from_slice(b"\r\n");
        let mut lines = BlockingLines::new(Parts(vec![
            Some(b"NFO {Level x}\r\nSTA {Ti".to_vec()),
            None,
            Some(b"me 1}\n\r".to_vec()),
            Some(long),
            Some(b"SEN {Time 2}\rlast".to_vec()),
        ]));
        assert_eq!(lines.next_line().unwrap().as_deref(), Some("NFO {Level x}"));
        let timed_out = lines.next_line().unwrap_err();
        assert_eq!(timed_out.kind(), std::io::ErrorKind::WouldBlock);
        for want in ["STA {Time 1}", "SEN {Time 2}", "last"] {
            assert_eq!(lines.next_line().unwrap().as_deref(), Some(want));
        }
        assert_eq!(lines.next_line().unwrap(), None);
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
