//! Serves a recorded server stream to clients: our recordings (docs/recording.md) or a plain
//! capture of server lines (such as the real UDK-USARSim output in `shared/testdata`).
//!
//! Each connecting client gets the whole stream from the start. What clients send is read
//! and logged, never answered.

use std::path::Path;

use futures::StreamExt;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio_util::codec::FramedRead;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{info, warn};
use usar_proto::codec::LineCodec;
use usar_proto::record::{self, Direction};
use usar_proto::{Message, ServerMessage};

/// The largest recording or capture `load` reads (bytes): 256 MiB.
pub const MAX_REPLAY_FILE: u64 = 256 << 20;

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
    /// The file is larger than [`MAX_REPLAY_FILE`].
    #[error("{path}: {size} bytes is more than the limit of {MAX_REPLAY_FILE} bytes")]
    TooLarge {
        /// The file.
        path: String,
        /// Its size.
        size: u64,
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

/// Reads a recording: `usar-record` files keep their `S` lines with their times; any other
/// text is taken as a capture, one line per line, of which the server messages (NFO, STA,
/// SEN, CONF, GEO, ASTA, EFF, DIE, …) are kept, timed by their `{Time t}` (lines without one
/// keep the previous time). Blank lines, `#` comments and client commands are skipped.
///
/// Files past [`MAX_REPLAY_FILE`] bytes are refused unread; time stamps must be finite.
pub fn load(path: &Path) -> Result<Vec<ReplayLine>, ReplayError> {
    use std::io::Read;
    let name = path.display().to_string();
    let io = |error| ReplayError::Io {
        path: name.clone(),
        error,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    let mut text = Vec::new();
    file.take(MAX_REPLAY_FILE + 1)
        .read_to_end(&mut text)
        .map_err(io)?;
    if size.max(text.len() as u64) > MAX_REPLAY_FILE {
        return Err(ReplayError::TooLarge {
            path: name,
            size: size.max(text.len() as u64),
        });
    }
    parse(&String::from_utf8_lossy(&text), &name)
}

/// Reads the text of a recording or capture (as [`load`] does; errors name `path`).
pub fn parse(text: &str, path: &str) -> Result<Vec<ReplayLine>, ReplayError> {
    let lines = if text.starts_with(record::HEADER) {
        parse_record(text, path)?
    } else {
        parse_capture(text)
    };
    if lines.is_empty() {
        return Err(ReplayError::Empty {
            path: path.to_owned(),
        });
    }
    Ok(lines)
}

fn parse_record(text: &str, path: &str) -> Result<Vec<ReplayLine>, ReplayError> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let entry = record::parse_entry(raw).map_err(|e| ReplayError::Format {
            path: path.to_owned(),
            line: i + 1,
            what: e.to_string(),
        })?;
        if let Some(entry) = entry
            && entry.direction == Direction::Server
        {
            lines.push(ReplayLine {
                time: Some(entry.time),
                text: entry.text.to_owned(),
            });
        }
    }
    Ok(lines)
}

fn parse_capture(text: &str) -> Vec<ReplayLine> {
    let mut time = None;
    text.lines()
        .map(|l| l.trim_end_matches('\r'))
        .filter(|l| !l.starts_with('#') && ServerMessage::is_server_word(Message::word(l)))
        .map(|l| {
            if let Some(t) = Message::parse(l).ok().and_then(|p| {
                p.message
                    .get("Time")
                    .and_then(|t| t.trim().parse::<f64>().ok())
                    .filter(|t| t.is_finite())
            }) {
                time = Some(t);
            }
            ReplayLine {
                time,
                text: l.to_owned(),
            }
        })
        .collect()
}

/// Serves `lines` to every client that connects until `shutdown` is cancelled.
pub async fn serve(
    listener: TcpListener,
    lines: Vec<ReplayLine>,
    pace: Pace,
    shutdown: CancellationToken,
) -> std::io::Result<()> {
    let lines: std::sync::Arc<[ReplayLine]> = lines.into();
    let tracker = TaskTracker::new();
    loop {
        tokio::select! {
            _ = shutdown.cancelled() => break,
            accepted = listener.accept() => {
                let (stream, peer) = accepted?;
                info!(%peer, "replaying");
                let lines = lines.clone();
                let token = shutdown.child_token();
                tracker.spawn(async move {
                    tokio::select! {
                        _ = token.cancelled() => {}
                        result = replay_to(stream, &lines, pace) => match result {
                            Ok(()) => info!(%peer, "replay finished"),
                            Err(error) => info!(%peer, %error, "client left"),
                        },
                    }
                });
            }
        }
    }
    tracker.close();
    tracker.wait().await;
    Ok(())
}

async fn replay_to(stream: TcpStream, lines: &[ReplayLine], pace: Pace) -> std::io::Result<()> {
    let (read, mut write) = stream.into_split();
    let peer = write.peer_addr()?;
    // Read and log what the client says, so that it never blocks on a full socket.
    let reader = tokio::spawn(async move {
        let mut framed = FramedRead::new(read, LineCodec::new(64 * 1024));
        while let Some(Ok(line)) = framed.next().await {
            match line {
                Ok(line) => info!(%peer, %line, "client says (ignored in replay)"),
                Err(error) => warn!(%peer, %error, "unreadable line"),
            }
        }
    });
    let start = tokio::time::Instant::now();
    let first = lines.iter().find_map(|l| l.time).unwrap_or(0.0);
    let mut batch = Vec::new();
    for line in lines {
        if let (Pace::Timestamps(factor), Some(t)) = (pace, line.time) {
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
        let lines = parse_record(text, "r").unwrap();
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[1].time, Some(0.1));
        assert_eq!(lines[1].text, "STA {Time 0.1000} {Battery 99999}");
    }

    #[test]
    fn a_capture_keeps_its_server_lines() {
        let text = "# a capture\nINIT {ClassName USARBot.P3AT}\n\nNFO {Level X}\nSEN {Time 1.5000} {Type Camera} \nSEN {Type INS} {Name I}\n";
        let lines = parse_capture(text);
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
        let error = parse_record(text, "r.usarlog").unwrap_err().to_string();
        assert_eq!(error, "r.usarlog:3: bad time stamp 'abc'");
    }
}
