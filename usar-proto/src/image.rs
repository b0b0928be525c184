//! The image server's binary protocol (UPIS, TCP 5003; docs/camera.md), sans I/O: the
//! requests a client sends ([`RequestParser`]), the frames the server sends
//! ([`frame_header`], [`raw_payload`], [`crop`], [`FrameParser`], [`decode_raw`]).
//!
//! Requests: `OK` (a full frame) or `U` followed by x, y, width, height as u32
//! big-endian (a rectangle of it); any other byte is ignored, so `OK\r\n` works. A frame:
//! one type byte (0 raw, 1..5 JPEG of quality SUPER, GOOD, NORMAL, FAIR, BAD), the payload
//! size as u32 big-endian, the payload. A raw payload: width and height as u16 big-endian,
//! then the rows from the top, 3 bytes a pixel, each row padded to a multiple of 4 bytes
//! (FreeImage's pitch).

/// A client's request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageRequest {
    /// `OK`: the whole frame.
    Full,
    /// `U x y width height`: a rectangle of the frame (top-left corner and size, pixels).
    Rect {
        /// Left column.
        x: u32,
        /// Top row.
        y: u32,
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
    },
}

impl ImageRequest {
    /// The request's bytes on the wire.
    pub fn to_bytes(&self) -> Vec<u8> {
        match *self {
            Self::Full => b"OK".to_vec(),
            Self::Rect {
                x,
                y,
                width,
                height,
            } => {
                let mut out = vec![b'U'];
                for v in [x, y, width, height] {
                    out.extend_from_slice(&v.to_be_bytes());
                }
                out
            }
        }
    }
}

/// Reads requests from the bytes a client sends, as the original server does: one byte at
/// a time; `O` must be followed by `K` (otherwise both are dropped), `U` by 16 bytes;
/// anything else is skipped. Holds at most 16 bytes between calls.
#[derive(Debug, Default, Clone)]
pub struct RequestParser {
    state: State,
    rect: [u8; 16],
    /// Bytes skipped so far (neither a request nor part of one).
    pub skipped: u64,
}

#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
enum State {
    #[default]
    Idle,
    /// Read `O`, waiting for `K`.
    O,
    /// Read `U` and this many bytes of its rectangle.
    U(usize),
}

impl RequestParser {
    /// Feeds `bytes`; complete requests are appended to `out`.
    pub fn push(&mut self, bytes: &[u8], out: &mut Vec<ImageRequest>) {
        for &b in bytes {
            self.state = match self.state {
                State::Idle => match b {
                    b'O' => State::O,
                    b'U' => State::U(0),
                    _ => {
                        self.skipped += 1;
                        State::Idle
                    }
                },
                State::O => {
                    if b == b'K' {
                        out.push(ImageRequest::Full);
                    } else {
                        self.skipped += 2;
                    }
                    State::Idle
                }
                State::U(n) => {
                    self.rect[n] = b;
                    if n + 1 < 16 {
                        State::U(n + 1)
                    } else {
                        let v = |i: usize| {
                            u32::from_be_bytes([
                                self.rect[4 * i],
                                self.rect[4 * i + 1],
                                self.rect[4 * i + 2],
                                self.rect[4 * i + 3],
                            ])
                        };
                        out.push(ImageRequest::Rect {
                            x: v(0),
                            y: v(1),
                            width: v(2),
                            height: v(3),
                        });
                        State::Idle
                    }
                }
            };
        }
    }

    /// Whether a request has begun and not ended (a truncated `U` at the end of a stream).
    pub fn is_partial(&self) -> bool {
        self.state != State::Idle
    }
}

/// The type byte of a raw frame.
pub const RAW: u8 = 0;

/// The JPEG quality (1-100) of each type byte 1..=5 (FreeImage's `JPEG_QUALITYSUPERB`,
/// `GOOD`, `NORMAL`, `AVERAGE`, `BAD`).
pub const JPEG_QUALITY: [u8; 5] = [100, 75, 50, 25, 10];

/// The five header bytes of a frame of type `kind` with a payload of `len` bytes.
pub fn frame_header(kind: u8, len: u32) -> [u8; 5] {
    let n = len.to_be_bytes();
    [kind, n[0], n[1], n[2], n[3]]
}

/// Bytes per row of a raw payload: 3 a pixel, rounded up to a multiple of 4.
pub fn raw_pitch(width: u16) -> usize {
    (usize::from(width) * 3).div_ceil(4) * 4
}

/// A raw payload of `width` × `height` pixels from R, G, B bytes (row by row from the
/// top); `bgr` writes each pixel as B, G, R (what the original server sent: docs/camera.md).
/// `rgb` must hold `3 · width · height` bytes.
pub fn raw_payload(width: u16, height: u16, rgb: &[u8], bgr: bool, out: &mut Vec<u8>) {
    let (w, h) = (usize::from(width), usize::from(height));
    let pitch = raw_pitch(width);
    out.clear();
    out.reserve(4 + pitch * h);
    out.extend_from_slice(&width.to_be_bytes());
    out.extend_from_slice(&height.to_be_bytes());
    for row in rgb.chunks_exact(3 * w.max(1)).take(h) {
        if bgr {
            for px in row.chunks_exact(3) {
                out.extend_from_slice(&[px[2], px[1], px[0]]);
            }
        } else {
            out.extend_from_slice(row);
        }
        out.resize(out.len() + pitch - 3 * w, 0);
    }
}

/// The part of a `width` × `height` frame of R, G, B pixels that a `U` request asks for
/// (top-left corner `x`, `y` and size), clipped to the frame: its width, height and pixels
/// (`None`: nothing of it is in the frame). `rgb` must hold `3 · width · height` bytes.
pub fn crop(
    width: u16,
    height: u16,
    rgb: &[u8],
    x: u32,
    y: u32,
    w: u32,
    h: u32,
) -> Option<(u16, u16, Vec<u8>)> {
    let (fw, fh) = (u32::from(width), u32::from(height));
    let (x1, y1) = (x.saturating_add(w).min(fw), y.saturating_add(h).min(fh));
    if x >= x1 || y >= y1 {
        return None;
    }
    let mut out = Vec::with_capacity(3 * ((x1 - x) * (y1 - y)) as usize);
    for row in y..y1 {
        let start = 3 * (row * fw + x) as usize;
        out.extend_from_slice(&rgb[start..start + 3 * (x1 - x) as usize]);
    }
    Some(((x1 - x) as u16, (y1 - y) as u16, out))
}

/// A frame as a client receives it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// The type byte: [`RAW`] or 1..=5 (JPEG).
    pub kind: u8,
    /// The payload (a raw payload or a JPEG file).
    pub payload: Vec<u8>,
}

/// What is wrong with a frame a server sent.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// The header announces more bytes than the reader accepts.
    #[error("frame of {size} bytes announced, more than the limit of {limit} bytes")]
    TooLarge {
        /// Announced payload size.
        size: u32,
        /// The reader's limit.
        limit: usize,
    },
    /// A raw payload whose size does not match its width and height.
    #[error("raw frame of {width}x{height} needs {expected} bytes, got {got}")]
    BadRaw {
        /// Announced width.
        width: u16,
        /// Announced height.
        height: u16,
        /// 4 + height × pitch.
        expected: usize,
        /// The payload's size.
        got: usize,
    },
}

/// Reassembles frames from the bytes a server sends (any split), as UsarCommander does
/// from the 5-byte header alone.
#[derive(Debug, Clone)]
pub struct FrameParser {
    buf: Vec<u8>,
    limit: usize,
}

impl FrameParser {
    /// A parser that refuses payloads larger than `limit` bytes.
    pub fn new(limit: usize) -> Self {
        Self {
            buf: Vec::new(),
            limit,
        }
    }

    /// Feeds bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// The next complete frame, if one has arrived. After an error the stream cannot be
    /// followed any more (the client should close it).
    pub fn next_frame(&mut self) -> Result<Option<Frame>, FrameError> {
        if self.buf.len() < 5 {
            return Ok(None);
        }
        let size = u32::from_be_bytes([self.buf[1], self.buf[2], self.buf[3], self.buf[4]]);
        if size as usize > self.limit {
            return Err(FrameError::TooLarge {
                size,
                limit: self.limit,
            });
        }
        let end = 5 + size as usize;
        if self.buf.len() < end {
            return Ok(None);
        }
        let kind = self.buf[0];
        let payload = self.buf[5..end].to_vec();
        self.buf.drain(..end);
        Ok(Some(Frame { kind, payload }))
    }
}

/// The pixels of a raw payload as R, G, B bytes without row padding (`bgr`: the payload's
/// pixels are B, G, R): width, height and the pixels.
pub fn decode_raw(payload: &[u8], bgr: bool) -> Result<(u16, u16, Vec<u8>), FrameError> {
    let (width, height) = match payload {
        [a, b, c, d, ..] => (u16::from_be_bytes([*a, *b]), u16::from_be_bytes([*c, *d])),
        _ => (0, 0),
    };
    let pitch = raw_pitch(width);
    let expected = 4 + pitch * usize::from(height);
    if payload.len() != expected {
        return Err(FrameError::BadRaw {
            width,
            height,
            expected,
            got: payload.len(),
        });
    }
    let w = usize::from(width);
    let mut rgb = Vec::with_capacity(3 * w * usize::from(height));
    for row in payload[4..]
        .chunks_exact(pitch.max(1))
        .take(usize::from(height))
    {
        for px in row[..3 * w].chunks_exact(3) {
            if bgr {
                rgb.extend_from_slice(&[px[2], px[1], px[0]]);
            } else {
                rgb.extend_from_slice(px);
            }
        }
    }
    Ok((width, height, rgb))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_read_byte_by_byte_like_the_original_server() {
        let mut parser = RequestParser::default();
        let mut out = Vec::new();
        let rect = ImageRequest::Rect {
            x: 320,
            y: 0,
            width: 320,
            height: 240,
        };
        let mut bytes = b"OK\r\nOXOK".to_vec();
        bytes.extend(rect.to_bytes());
        bytes.extend(b"\x00garbage\xff");
        // Split anywhere: the same requests.
        for cut in 0..bytes.len() {
            out.clear();
            let mut p = RequestParser::default();
            p.push(&bytes[..cut], &mut out);
            p.push(&bytes[cut..], &mut out);
            assert_eq!(
                out,
                [ImageRequest::Full, ImageRequest::Full, rect],
                "cut {cut}"
            );
        }
        // A truncated U is held, not read as anything.
        parser.push(&rect.to_bytes()[..9], &mut out);
        assert!(parser.is_partial());
    }

    #[test]
    fn raw_frames_round_trip_with_padding_and_either_byte_order() {
        let rgb: Vec<u8> = (0..3 * 5 * 2).map(|i| i as u8).collect();
        let mut payload = Vec::new();
        raw_payload(5, 2, &rgb, true, &mut payload);
        // 5 pixels = 15 bytes, padded to 16 a row.
        assert_eq!(payload.len(), 4 + 2 * 16);
        assert_eq!(&payload[..7], &[0, 5, 0, 2, 2, 1, 0]);
        assert_eq!(decode_raw(&payload, true).unwrap(), (5, 2, rgb.clone()));
        let mut stream = frame_header(RAW, payload.len() as u32).to_vec();
        stream.extend(&payload);
        stream.extend(frame_header(3, 2));
        stream.extend([0xff, 0xd8]);
        let mut parser = FrameParser::new(1 << 20);
        for b in &stream {
            parser.push(std::slice::from_ref(b));
        }
        let first = parser.next_frame().unwrap().unwrap();
        assert_eq!((first.kind, first.payload), (RAW, payload));
        let second = parser.next_frame().unwrap().unwrap();
        assert_eq!((second.kind, second.payload), (3, vec![0xff, 0xd8]));
        assert_eq!(parser.next_frame(), Ok(None));
        let mut huge = FrameParser::new(100);
        huge.push(&frame_header(0, 1 << 30));
        assert!(matches!(
            huge.next_frame(),
            Err(FrameError::TooLarge { .. })
        ));
        assert!(decode_raw(&[0, 5, 0, 2, 1, 2], true).is_err());
    }

    #[test]
    fn rectangles_are_clipped_to_the_frame() {
        let rgb: Vec<u8> = (0..24).collect();
        assert_eq!(
            crop(4, 2, &rgb, 1, 1, 2, 1),
            Some((2, 1, vec![15, 16, 17, 18, 19, 20]))
        );
        assert_eq!(
            crop(4, 2, &rgb, 3, 0, 100, u32::MAX).map(|c| (c.0, c.1)),
            Some((1, 2))
        );
        assert_eq!(crop(4, 2, &rgb, 4, 0, 1, 1), None);
        assert_eq!(crop(4, 2, &rgb, 0, 0, 0, 5), None);
        assert_eq!(
            crop(4, 2, &rgb, u32::MAX, u32::MAX, u32::MAX, u32::MAX),
            None
        );
    }
}
