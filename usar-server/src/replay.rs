//! Serves a recorded server stream to clients: our recordings (docs/recording.md) or a plain
//! capture of server lines (such as the real UDK-USARSim output in `shared/testdata`).
//!
//! Each connecting client gets the whole stream from the start. What clients send is read
//! and logged, never answered.

use std::path::Path;
use std::sync::Arc;

use futures::StreamExt;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Semaphore;
use tokio_util::codec::FramedRead;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{info, warn};
use usar_proto::codec::LineCodec;
use usar_proto::record::{self, Direction};
use usar_proto::shown::Repeats;
use usar_proto::{Message, ServerMessage};

/// The longest line a recording or capture may hold (bytes): 1 MiB. Files of any size are
/// read line by line, so memory stays bounded by this and the send buffer.
pub const MAX_REPLAY_LINE: usize = 1 << 20;

/// The recording format version this server reads (`# usar-record 1`).
const RECORD_VERSION: &str = "1";

/// One server line of a recording and the simulated time it was sent at.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayLine {
    /// Simulated seconds, if known.
    pub time: Option<f64>,
    /// The line, without terminator.
    pub text: String,
}

/// How fast to send.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pace {
    /// Keep the recorded spacing of the time stamps (scaled by the factor: 2.0 = twice as fast).
    Timestamps(f64),
    /// As fast as the client reads.
    Fast,
}

/// A recording that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The file could not be read.
    #[error("cannot read {path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// Why (shown in this error's text, so not its `source`).
        error: std::io::Error,
    },
    /// The file is not a regular file (a FIFO, a device, a folder).
    #[error("{path}: not a regular file")]
    NotAFile {
        /// The file.
        path: String,
    },
    /// A recording line is malformed.
    #[error("{path}:{line}: {what}")]
    Format {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        what: String,
    },
    /// Nothing to replay.
    #[error("{path}: no server lines to replay")]
    Empty {
        /// The file.
        path: String,
    },
}

/// A recording or capture checked by [`open`], read again from the file for each client.
#[derive(Debug, Clone)]
pub struct ReplayFile {
    path: std::path::PathBuf,
    lines: usize,
}

impl ReplayFile {
    /// The server lines it holds.
    pub fn lines(&self) -> usize {
        self.lines
    }

    /// Reads its server lines from the start.
    fn read(&self) -> Result<Lines<std::io::BufReader<std::fs::File>>, ReplayError> {
        let name = self.path.display().to_string();
        let file = std::fs::File::open(&self.path).map_err(|error| ReplayError::Io {
            path: name.clone(),
            error,
        })?;
        Ok(Lines::new(
            std::io::BufReader::with_capacity(64 * 1024, file),
            name,
        ))
    }
}

/// Checks a recording or capture, reading it once line by line (memory does not grow with
/// its size): `usar-record` files keep their `S` lines with their times; any other text is
/// taken as a capture, one line per line, of which the server messages (NFO, STA, SEN, CONF,
/// GEO, ASTA, EFF, DIE, …) are kept, timed by their `{Time t}` (lines without one keep the
/// previous time). Blank lines, `#` comments and client commands are skipped.
///
/// Refused, naming the file (and line): anything but a regular file, lines longer than
/// [`MAX_REPLAY_LINE`], time stamps that are not finite, a recording version other than 1,
/// and files without a server line.
pub fn open(path: &Path) -> Result<ReplayFile, ReplayError> {
    let name = path.display().to_string();
    let meta = std::fs::metadata(path).map_err(|error| ReplayError::Io {
        path: name.clone(),
        error,
    })?;
    if !meta.is_file() {
        return Err(ReplayError::NotAFile { path: name });
    }
    let file = ReplayFile {
        path: path.to_owned(),
        lines: 0,
    };
    let mut lines = 0;
    for line in file.read()? {
        line?;
        lines += 1;
    }
    if lines == 0 {
        return Err(ReplayError::Empty { path: name });
    }
    Ok(ReplayFile { lines, ..file })
}

/// Reads the text of a recording or capture (as [`open`] does; errors name `path`).
pub fn parse(text: &str, path: &str) -> Result<Vec<ReplayLine>, ReplayError> {
    let lines = Lines::new(text.as_bytes(), path.to_owned()).collect::<Result<Vec<_>, _>>()?;
    if lines.is_empty() {
        return Err(ReplayError::Empty {
            path: path.to_owned(),
        });
    }
    Ok(lines)
}

/// The server lines of a recording or capture, read one line at a time.
struct Lines<R> {
    input: R,
    path: String,
    /// Lines read so far.
    number: usize,
    /// `None` until the first line says which kind of file this is.
    record: Option<bool>,
    /// A capture's latest `{Time t}`.
    time: Option<f64>,
    buffer: Vec<u8>,
    failed: bool,
}

impl<R: std::io::BufRead> Lines<R> {
    fn new(input: R, path: String) -> Self {
        Self {
            input,
            path,
            number: 0,
            record: None,
            time: None,
            buffer: Vec::new(),
            failed: false,
        }
    }

    fn error(&mut self, what: String) -> ReplayError {
        self.failed = true;
        ReplayError::Format {
            path: self.path.clone(),
            line: self.number,
            what,
        }
    }

    /// The next line of text (lossy UTF-8, without terminator); `None` at the end.
    fn next_text(&mut self) -> Option<Result<String, ReplayError>> {
        use std::io::{BufRead, Read};
        self.buffer.clear();
        let limit = MAX_REPLAY_LINE as u64 + 2;
        let read = (&mut self.input)
            .take(limit)
            .read_until(b'\n', &mut self.buffer);
        match read {
            Ok(0) => return None,
            Ok(_) => {}
            Err(error) => {
                self.failed = true;
                return Some(Err(ReplayError::Io {
                    path: self.path.clone(),
                    error,
                }));
            }
        }
        self.number += 1;
        let line = self.buffer.strip_suffix(b"\n").unwrap_or(&self.buffer);
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if line.len() > MAX_REPLAY_LINE {
            return Some(Err(self.error(format!(
                "line longer than the limit of {MAX_REPLAY_LINE} bytes"
            ))));
        }
        Some(Ok(String::from_utf8_lossy(line).into_owned()))
    }

    /// A recording's line: its server line, if it is one.
    fn record_line(&mut self, text: &str) -> Result<Option<ReplayLine>, ReplayError> {
        match record::parse_entry(text) {
            Ok(Some(entry)) if entry.direction == Direction::Server => Ok(Some(ReplayLine {
                time: Some(entry.time),
                text: entry.text.to_owned(),
            })),
            Ok(_) => Ok(None),
            Err(e) => Err(self.error(e.to_string())),
        }
    }

    /// A capture's line: kept if it is a server message.
    fn capture_line(&mut self, text: String) -> Option<ReplayLine> {
        if text.starts_with('#') || !ServerMessage::is_server_word(Message::word(&text)) {
            return None;
        }
        if let Some(t) = Message::parse(&text).ok().and_then(|p| {
            p.message
                .get("Time")
                .and_then(|t| t.trim().parse::<f64>().ok())
                .filter(|t| t.is_finite())
        }) {
            self.time = Some(t);
        }
        Some(ReplayLine {
            time: self.time,
            text,
        })
    }
}

impl<R: std::io::BufRead> Iterator for Lines<R> {
    type Item = Result<ReplayLine, ReplayError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.failed {
            let text = match self.next_text()? {
                Ok(text) => text,
                Err(e) => return Some(Err(e)),
            };
            let record = match self.record {
                Some(record) => record,
                None => {
                    // `# usar-record N`: our recording, if we know version N.
                    let version = text
                        .strip_prefix(RECORD_PREFIX)
                        .filter(|rest| rest.starts_with(' '))
                        .map(str::trim);
                    if let Some(version) = version
                        && version != RECORD_VERSION
                    {
                        return Some(Err(self.error(format!(
                            "unknown recording version {} (this usar-server reads version {RECORD_VERSION})",
                            usar_proto::shown::Shown(version)
                        ))));
                    }
                    self.record = Some(version.is_some());
                    if version.is_some() {
                        continue;
                    }
                    false
                }
            };
            let line = if record {
                match self.record_line(&text) {
                    Ok(line) => line,
                    Err(e) => return Some(Err(e)),
                }
            } else {
                self.capture_line(text)
            };
            if line.is_some() {
                return line.map(Ok);
            }
        }
        None
    }
}

/// What every recording's first line starts with (then the version).
const RECORD_PREFIX: &str = "# usar-record";

/// Clients served at once; more are closed on accept.
pub const MAX_REPLAY_CLIENTS: usize = 64;

/// Serves `file` to every client that connects until `shutdown` is cancelled; each client
/// gets the whole stream from the start, read from the file as it is sent. At most
/// [`MAX_REPLAY_CLIENTS`] at once; a failing accept (out of file descriptors) is waited out,
/// never the end of the server.
pub async fn serve(
    listener: TcpListener,
    file: ReplayFile,
    pace: Pace,
    shutdown: CancellationToken,
) -> std::io::Result<()> {
    let tracker = TaskTracker::new();
    let slots = Arc::new(Semaphore::new(MAX_REPLAY_CLIENTS));
    let (mut refused, mut failed) = (Repeats::default(), Repeats::default());
    loop {
        tokio::select! {
            _ = shutdown.cancelled() => break,
            accepted = listener.accept() => {
                let (stream, peer) = match accepted {
                    Ok(x) => x,
                    Err(error) if crate::net::is_transient(&error) => {
                        if let Some(count) = failed.note() {
                            warn!(%error, count, "accept failed; waiting");
                        }
                        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
                        continue;
                    }
                    Err(error) => return Err(error),
                };
                let Ok(permit) = slots.clone().try_acquire_owned() else {
                    if let Some(count) = refused.note() {
                        warn!(%peer, max = MAX_REPLAY_CLIENTS, count, "too many clients; closing");
                    }
                    continue;
                };
                info!(%peer, "replaying");
                let file = file.clone();
                let token = shutdown.child_token();
                tracker.spawn(async move {
                    tokio::select! {
                        _ = token.cancelled() => {}
                        result = replay_to(stream, &file, pace) => match result {
                            Ok(()) => info!(%peer, "replay finished"),
                            Err(error) => info!(%peer, %error, "client left"),
                        },
                    }
                    drop(permit);
                });
            }
        }
    }
    tracker.close();
    tracker.wait().await;
    Ok(())
}

async fn replay_to(stream: TcpStream, file: &ReplayFile, pace: Pace) -> std::io::Result<()> {
    let (read, mut write) = stream.into_split();
    let peer = write.peer_addr()?;
    // Read and log what the client says, so that it never blocks on a full socket.
    let reader = tokio::spawn(async move {
        let mut framed = FramedRead::new(read, LineCodec::new(64 * 1024));
        while let Some(Ok(line)) = framed.next().await {
            match line {
                Ok(line) => info!(%peer, line = %usar_proto::shown::Shown(&line),
                    "client says (ignored in replay)"),
                Err(error) => warn!(%peer, %error, "unreadable line"),
            }
        }
    });
    let mut lines = file.read().map_err(std::io::Error::other)?;
    let start = tokio::time::Instant::now();
    let mut first = None;
    let mut batch = Vec::new();
    // The file is read on the runtime's thread in blocks of 64 KiB: short reads, like the
    // socket writes around them.
    for line in &mut lines {
        let line = line.map_err(std::io::Error::other)?;
        if let (Pace::Timestamps(factor), Some(t)) = (pace, line.time) {
            let first = *first.get_or_insert(t);
            let offset = crate::net::wait_of((t - first) / factor);
            let due = start.checked_add(offset).unwrap_or(start);
            if due > tokio::time::Instant::now() {
                write.write_all(&batch).await?;
                batch.clear();
                tokio::time::sleep_until(due).await;
            }
        }
        batch.extend_from_slice(line.text.as_bytes());
        batch.extend_from_slice(b"\r\n");
        if batch.len() > 64 * 1024 {
            write.write_all(&batch).await?;
            batch.clear();
        }
    }
    write.write_all(&batch).await?;
    write.shutdown().await?;
    reader.abort();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recording_keeps_server_lines_with_their_times() {
        let text = "# usar-record 1\n0.0000 S NFO {Gametype BotDeathMatch} {Level X} {TimeLimit 20}\n0.0000 C INIT {ClassName USARBot.AirRobot}\n0.1000 S STA {Time 0.1000} {Battery 99999}\n";
        let lines = parse(text, "r").unwrap();
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[1].time, Some(0.1));
        assert_eq!(lines[1].text, "STA {Time 0.1000} {Battery 99999}");
    }

    #[test]
    fn a_capture_keeps_its_server_lines() {
        let text = "# a capture\nINIT {ClassName USARBot.P3AT}\n\nNFO {Level X}\nSEN {Time 1.5000} {Type Camera} \nSEN {Type INS} {Name I}\n";
        let lines = parse(text, "c").unwrap();
        let texts: Vec<&str> = lines.iter().map(|l| l.text.as_str()).collect();
        assert_eq!(
            texts,
            [
                "NFO {Level X}",
                "SEN {Time 1.5000} {Type Camera} ",
                "SEN {Type INS} {Name I}"
            ]
        );
        assert_eq!(
            lines.iter().map(|l| l.time).collect::<Vec<_>>(),
            [None, Some(1.5), Some(1.5)]
        );
    }

    #[test]
    fn a_broken_recording_names_the_line() {
        let text = "# usar-record 1\n0.0000 S NFO\nabc S STA\n";
        let error = parse(text, "r.usarlog").unwrap_err().to_string();
        assert_eq!(error, "r.usarlog:3: bad time stamp 'abc'");
    }
}
