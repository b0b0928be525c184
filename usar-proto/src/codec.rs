//! The tokio-util line codecs shared by the server and the client (feature `codec`).
//!
//! * [`LineCodec`]: lines of text. Any CR/LF mix ends a line (`\r\n`, `\n`, `\r`), empty
//!   lines are skipped, a line may arrive in pieces or several per read. Items are
//!   `Result<String, LineError>` so that one bad line does not end the stream; the codec's
//!   own `Error` is `io::Error` (from the transport only).
//! * [`CommandCodec`] (server side): decodes client commands, encodes server messages.
//! * [`ServerCodec`] (client side): decodes server messages, encodes client commands.
//!
//! Rules:
//!
//! * **Maximum line length** ([`DEFAULT_MAX_LINE`] unless set): a longer line gives one
//!   [`LineError::TooLong`] item as soon as the limit is passed; its remaining bytes are
//!   dropped as they arrive (never buffered) and decoding resumes after the next line ending.
//! * **EOF in the middle of a line**: the partial text is reported as
//!   [`LineError::Unterminated`] (the real server would never have processed it; a client
//!   knows the last line was cut). Never lost silently, never a panic.
//! * **Non-UTF-8 bytes** are decoded lossily (U+FFFD); the protocol is ASCII, so such a line
//!   then usually fails to parse, which is reported per line.
//! * Encoding appends the line and `\r\n` (what UDK sends, and what clients send).
//!
//! ```
//! use bytes::BytesMut;
//! use tokio_util::codec::Decoder;
//! use usar_proto::{Command, codec::CommandCodec};
//!
//! let mut codec = CommandCodec::default();
//! let mut buf = BytesMut::from("GETSTARTPOSES\r\nGETCONF {Ty");
//! let first = codec.decode(&mut buf).unwrap().unwrap().unwrap();
//! assert_eq!(first.message, Command::GetStartPoses);
//! assert!(codec.decode(&mut buf).unwrap().is_none()); // waits for the rest
//! ```

use crate::error::ParseError;
use crate::message::Parsed;
use crate::messages::{Command, ServerMessage};
use bytes::{Buf, BytesMut};
use std::io;
use tokio_util::codec::{Decoder, Encoder};

/// The default maximum line length in bytes (a 228-beam laser line is about 1.3 KB).
pub const DEFAULT_MAX_LINE: usize = 64 * 1024;

/// A line the codec could not deliver.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LineError {
    /// The line was longer than the limit; it was skipped up to its line ending.
    #[error("line longer than the limit of {limit} bytes skipped")]
    TooLong {
        /// The limit in bytes.
        limit: usize,
    },
    /// The stream ended in the middle of a line.
    #[error("stream ended in the middle of a line: {partial:?}")]
    Unterminated {
        /// The text received for that line.
        partial: String,
    },
}

/// A line that could not be delivered or read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecodeError {
    /// The line codec could not deliver the line.
    #[error(transparent)]
    Line(#[from] LineError),
    /// The line arrived but could not be read as a message.
    #[error("cannot read {line:?}: {error}")]
    Parse {
        /// The line as received.
        line: String,
        /// Why.
        error: ParseError,
    },
}

/// Splits a byte stream into text lines (module docs).
#[derive(Debug, Clone)]
pub struct LineCodec {
    max_len: usize,
    /// Bytes of the buffered partial line already searched for a line ending.
    searched: usize,
    /// Dropping the rest of a too-long line.
    discarding: bool,
}

impl Default for LineCodec {
    fn default() -> Self {
        Self::new(DEFAULT_MAX_LINE)
    }
}

fn is_end(b: &u8) -> bool {
    *b == b'\r' || *b == b'\n'
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

impl LineCodec {
    /// A codec that rejects lines longer than `max_len` bytes.
    pub fn new(max_len: usize) -> Self {
        Self {
            max_len,
            searched: 0,
            discarding: false,
        }
    }

    /// The maximum line length in bytes.
    pub fn max_len(&self) -> usize {
        self.max_len
    }

    /// Whether a too-long line is being skipped (its end has not arrived yet). With the
    /// framed reader's buffer, this tells a half-sent line from silence between lines.
    pub fn skipping(&self) -> bool {
        self.discarding
    }
}

impl Decoder for LineCodec {
    type Item = Result<String, LineError>;
    type Error = io::Error;

    fn decode(&mut self, buf: &mut BytesMut) -> io::Result<Option<Self::Item>> {
        loop {
            if self.searched == 0 && !self.discarding {
                let skip = buf.iter().take_while(|b| is_end(b)).count();
                buf.advance(skip);
            }
            let from = self.searched.min(buf.len());
            let end = buf[from..].iter().position(is_end).map(|i| i + from);
            match end {
                Some(end) if self.discarding => {
                    buf.advance(end);
                    self.discarding = false;
                    self.searched = 0;
                }
                Some(end) => {
                    let line = buf.split_to(end);
                    self.searched = 0;
                    if line.len() > self.max_len {
                        return Ok(Some(Err(LineError::TooLong {
                            limit: self.max_len,
                        })));
                    }
                    return Ok(Some(Ok(text(&line))));
                }
                None if self.discarding => {
                    buf.clear();
                    return Ok(None);
                }
                None if buf.len() > self.max_len => {
                    buf.clear();
                    self.discarding = true;
                    self.searched = 0;
                    return Ok(Some(Err(LineError::TooLong {
                        limit: self.max_len,
                    })));
                }
                None => {
                    self.searched = buf.len();
                    return Ok(None);
                }
            }
        }
    }

    fn decode_eof(&mut self, buf: &mut BytesMut) -> io::Result<Option<Self::Item>> {
        if let Some(item) = self.decode(buf)? {
            return Ok(Some(item));
        }
        self.searched = 0;
        let rest = buf.split();
        if std::mem::take(&mut self.discarding) || rest.iter().all(|b| *b == b' ' || *b == b'\t') {
            return Ok(None);
        }
        Ok(Some(Err(LineError::Unterminated {
            partial: text(&rest),
        })))
    }
}

impl Encoder<&str> for LineCodec {
    type Error = io::Error;

    fn encode(&mut self, line: &str, dst: &mut BytesMut) -> io::Result<()> {
        dst.reserve(line.len() + 2);
        dst.extend_from_slice(line.as_bytes());
        dst.extend_from_slice(b"\r\n");
        Ok(())
    }
}

impl Encoder<String> for LineCodec {
    type Error = io::Error;

    fn encode(&mut self, line: String, dst: &mut BytesMut) -> io::Result<()> {
        Encoder::<&str>::encode(self, &line, dst)
    }
}

/// Decodes one typed item per non-blank line.
fn decode_typed<T>(
    lines: &mut LineCodec,
    buf: &mut BytesMut,
    eof: bool,
    parse: fn(&str) -> Result<Parsed<T>, ParseError>,
) -> io::Result<Option<Result<Parsed<T>, DecodeError>>> {
    loop {
        let item = if eof {
            lines.decode_eof(buf)?
        } else {
            lines.decode(buf)?
        };
        return Ok(Some(match item {
            None => return Ok(None),
            Some(Err(e)) => Err(e.into()),
            Some(Ok(line)) if line.trim().is_empty() => continue,
            Some(Ok(line)) => parse(&line).map_err(|error| DecodeError::Parse { line, error }),
        }));
    }
}

/// The server side: decodes client commands, encodes server messages.
#[derive(Debug, Clone, Default)]
pub struct CommandCodec {
    lines: LineCodec,
}

impl CommandCodec {
    /// A codec that rejects lines longer than `max_len` bytes.
    pub fn new(max_len: usize) -> Self {
        Self {
            lines: LineCodec::new(max_len),
        }
    }
}

impl Decoder for CommandCodec {
    type Item = Result<Parsed<Command>, DecodeError>;
    type Error = io::Error;

    fn decode(&mut self, buf: &mut BytesMut) -> io::Result<Option<Self::Item>> {
        decode_typed(&mut self.lines, buf, false, Command::parse)
    }

    fn decode_eof(&mut self, buf: &mut BytesMut) -> io::Result<Option<Self::Item>> {
        decode_typed(&mut self.lines, buf, true, Command::parse)
    }
}

impl Encoder<&ServerMessage> for CommandCodec {
    type Error = io::Error;

    fn encode(&mut self, item: &ServerMessage, dst: &mut BytesMut) -> io::Result<()> {
        item.write_line(dst);
        Ok(())
    }
}

impl Encoder<&[ServerMessage]> for CommandCodec {
    type Error = io::Error;

    /// A batch (one tick's lines) in one buffer.
    fn encode(&mut self, items: &[ServerMessage], dst: &mut BytesMut) -> io::Result<()> {
        for item in items {
            item.write_line(dst);
        }
        Ok(())
    }
}

/// The client side: decodes server messages, encodes client commands.
#[derive(Debug, Clone, Default)]
pub struct ServerCodec {
    lines: LineCodec,
}

impl ServerCodec {
    /// A codec that rejects lines longer than `max_len` bytes.
    pub fn new(max_len: usize) -> Self {
        Self {
            lines: LineCodec::new(max_len),
        }
    }
}

impl Decoder for ServerCodec {
    type Item = Result<Parsed<ServerMessage>, DecodeError>;
    type Error = io::Error;

    fn decode(&mut self, buf: &mut BytesMut) -> io::Result<Option<Self::Item>> {
        decode_typed(&mut self.lines, buf, false, ServerMessage::parse)
    }

    fn decode_eof(&mut self, buf: &mut BytesMut) -> io::Result<Option<Self::Item>> {
        decode_typed(&mut self.lines, buf, true, ServerMessage::parse)
    }
}

impl Encoder<&Command> for ServerCodec {
    type Error = io::Error;

    /// Refuses a command whose values would break the line ([`Command::check`]) with an
    /// [`io::ErrorKind::InvalidInput`] error that says why.
    fn encode(&mut self, item: &Command, dst: &mut BytesMut) -> io::Result<()> {
        item.check()
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
        item.write_line(dst);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(codec: &mut LineCodec, chunks: &[&[u8]]) -> Vec<Result<String, LineError>> {
        let mut buf = BytesMut::new();
        let mut out = Vec::new();
        for c in chunks {
            buf.extend_from_slice(c);
            while let Some(item) = codec.decode(&mut buf).unwrap() {
                out.push(item);
            }
        }
        while let Some(item) = codec.decode_eof(&mut buf).unwrap() {
            out.push(item);
        }
        out
    }

    #[test]
    fn splits_any_line_ending_and_skips_empty_lines() {
        let got = lines(
            &mut LineCodec::default(),
            &[b"\r\nA {x 1}\r", b"\nB", b" {y 2}\n\n\rC\r\r"],
        );
        assert_eq!(
            got,
            vec![Ok("A {x 1}".into()), Ok("B {y 2}".into()), Ok("C".into())]
        );
    }

    #[test]
    fn too_long_lines_are_skipped_without_buffering() {
        let mut codec = LineCodec::new(8);
        let mut buf = BytesMut::from(&b"OK\r\n0123456789"[..]);
        assert_eq!(codec.decode(&mut buf).unwrap(), Some(Ok("OK".into())));
        assert_eq!(
            codec.decode(&mut buf).unwrap(),
            Some(Err(LineError::TooLong { limit: 8 }))
        );
        assert!(buf.is_empty());
        buf.extend_from_slice(b"more junk without end");
        assert_eq!(codec.decode(&mut buf).unwrap(), None);
        assert!(buf.is_empty());
        assert!(codec.skipping(), "still inside the long line");
        buf.extend_from_slice(b"junk\nNEXT\n");
        assert_eq!(codec.decode(&mut buf).unwrap(), Some(Ok("NEXT".into())));
        assert!(!codec.skipping());
        assert_eq!(
            LineError::TooLong { limit: 8 }.to_string(),
            "line longer than the limit of 8 bytes skipped"
        );
    }

    #[test]
    fn eof_mid_line_is_reported() {
        let got = lines(&mut LineCodec::default(), &[b"A\nDRIVE {Le"]);
        assert_eq!(
            got,
            vec![
                Ok("A".into()),
                Err(LineError::Unterminated {
                    partial: "DRIVE {Le".into()
                })
            ]
        );
        assert_eq!(
            lines(&mut LineCodec::default(), &[b"A\n  "]),
            vec![Ok("A".into())]
        );
    }

    #[test]
    fn non_utf8_is_lossy() {
        let got = lines(&mut LineCodec::default(), &[b"A \xff\n"]);
        assert_eq!(got, vec![Ok("A \u{fffd}".into())]);
    }

    #[test]
    fn typed_codecs_encode_with_crlf() {
        let mut dst = BytesMut::new();
        let sta = ServerMessage::parse("STA {Time 1.0000} {Battery 99999}")
            .unwrap()
            .message;
        CommandCodec::default()
            .encode(&[sta.clone(), sta][..], &mut dst)
            .unwrap();
        assert_eq!(
            &dst[..],
            b"STA {Time 1.0000} {Battery 99999}\r\nSTA {Time 1.0000} {Battery 99999}\r\n"
        );
        let mut dst = BytesMut::new();
        ServerCodec::default()
            .encode(&Command::GetStartPoses, &mut dst)
            .unwrap();
        assert_eq!(&dst[..], b"GETSTARTPOSES\r\n");
    }

    #[test]
    fn the_client_encoder_refuses_line_injection() {
        let init = Command::parse("INIT {ClassName USARBot.stsAirRobot} {Name UAV1}")
            .unwrap()
            .message;
        let Command::Init(mut bad) = init.clone() else {
            unreachable!()
        };
        bad.name = Some("UAV1\r\nGETSTARTPOSES".into());
        let mut dst = BytesMut::new();
        let error = ServerCodec::default()
            .encode(&Command::Init(bad), &mut dst)
            .unwrap_err();
        assert_eq!(error.kind(), io::ErrorKind::InvalidInput);
        assert!(error.to_string().contains("carriage return"), "{error}");
        assert!(dst.is_empty(), "nothing written");
        ServerCodec::default().encode(&init, &mut dst).unwrap();
        assert_eq!(
            &dst[..],
            b"INIT {ClassName USARBot.stsAirRobot} {Name UAV1}\r\n"
        );
    }
}
