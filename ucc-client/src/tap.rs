//! `ucc tap`: a transparent proxy for debugging a client against a real USARSim host.
//!
//! Every byte is forwarded unchanged in both directions; on the side, the lines are split
//! out, recorded (docs/recording.md; the time stamp is the latest `{Time}` the server sent,
//! since a proxy cannot know the simulated time otherwise) and checked with usar-proto: a
//! line that does not parse, or that only parses by tolerating a deviation, is logged as a
//! warning.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{info, warn};
use usar_proto::record::{self, Direction};
use usar_proto::{Command, ServerMessage};

/// Longest line the tap splits out for recording; longer ones are forwarded but not recorded.
const MAX_LINE: usize = 256 * 1024;

/// Errors that end the tap.
#[derive(Debug, thiserror::Error)]
pub enum TapError {
    /// Accepting failed.
    #[error("listener failed: {0}")]
    Io(#[from] std::io::Error),
}

/// The recording file of the `n`-th connection (1-based): `FILE` for the first,
/// `FILE-2`, `FILE-3`, … (before the extension) for the next.
pub fn record_path(base: &Path, n: usize) -> PathBuf {
    if n <= 1 {
        return base.to_owned();
    }
    let stem = base
        .file_stem()
        .map_or_else(Default::default, |s| s.to_string_lossy());
    let name = match base.extension() {
        Some(ext) => format!("{stem}-{n}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{n}"),
    };
    base.with_file_name(name)
}

/// Accepts clients on `listener` and connects each to `upstream`, until `shutdown`.
pub async fn run(
    listener: TcpListener,
    upstream: String,
    record: PathBuf,
    shutdown: CancellationToken,
) -> Result<(), TapError> {
    let tracker = TaskTracker::new();
    let mut connections = 0;
    loop {
        let (client, peer) = tokio::select! {
            _ = shutdown.cancelled() => break,
            accepted = listener.accept() => accepted?,
        };
        connections += 1;
        let path = record_path(&record, connections);
        let upstream = upstream.clone();
        let token = shutdown.child_token();
        tracker.spawn(async move {
            info!(%peer, upstream, record = %path.display(), "tapping");
            tokio::select! {
                _ = token.cancelled() => {}
                result = tap_one(client, &upstream, &path) => match result {
                    Ok(()) => info!(%peer, "connection closed"),
                    Err(error) => warn!(%peer, %error, "connection ended"),
                },
            }
        });
    }
    tracker.close();
    tracker.wait().await;
    Ok(())
}

/// What both directions of one connection share: the recording and the latest server time.
struct Recording {
    file: std::io::BufWriter<std::fs::File>,
    time: f64,
}

async fn tap_one(client: TcpStream, upstream: &str, path: &Path) -> std::io::Result<()> {
    let server = TcpStream::connect(upstream)
        .await
        .map_err(|e| std::io::Error::new(e.kind(), format!("cannot connect to {upstream}: {e}")))?;
    let _ = (client.set_nodelay(true), server.set_nodelay(true));
    let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(file, "{}", record::HEADER)?;
    let recording = Arc::new(Mutex::new(Recording { file, time: 0.0 }));
    let (client_read, client_write) = client.into_split();
    let (server_read, server_write) = server.into_split();
    let up = pump(
        client_read,
        server_write,
        Direction::Client,
        recording.clone(),
    );
    let down = pump(
        server_read,
        client_write,
        Direction::Server,
        recording.clone(),
    );
    let result = tokio::select! {
        r = up => r,
        r = down => r,
    };
    if let Ok(mut r) = recording.lock() {
        r.file.flush()?;
    }
    result
}

/// Forwards bytes from `from` to `to` unchanged, recording and checking each line.
async fn pump(
    mut from: impl AsyncReadExt + Unpin,
    mut to: impl AsyncWriteExt + Unpin,
    direction: Direction,
    recording: Arc<Mutex<Recording>>,
) -> std::io::Result<()> {
    let mut buffer = vec![0; 16 * 1024];
    let mut line = Vec::new();
    let mut overlong = false;
    loop {
        let n = from.read(&mut buffer).await?;
        if n == 0 {
            to.shutdown().await?;
            return Ok(());
        }
        to.write_all(&buffer[..n]).await?;
        for &byte in &buffer[..n] {
            if byte == b'\n' || byte == b'\r' {
                if !line.is_empty() && !overlong {
                    observe(&String::from_utf8_lossy(&line), direction, &recording);
                }
                line.clear();
                overlong = false;
            } else if line.len() < MAX_LINE {
                line.push(byte);
            } else if !overlong {
                overlong = true;
                warn!(
                    ?direction,
                    max = MAX_LINE,
                    "over-long line forwarded, not recorded"
                );
            }
        }
    }
}

/// Records one line and warns when usar-proto cannot read it cleanly.
fn observe(line: &str, direction: Direction, recording: &Mutex<Recording>) {
    let problem = match direction {
        Direction::Client => match Command::parse(line) {
            Ok(p) => (!p.deviations.is_empty()).then(|| {
                let list: Vec<String> = p.deviations.iter().map(ToString::to_string).collect();
                list.join("; ")
            }),
            Err(e) => Some(e.to_string()),
        },
        Direction::Server => match ServerMessage::parse(line) {
            Ok(p) => {
                if let Some(t) = p.message.time()
                    && let Ok(mut r) = recording.lock()
                {
                    r.time = t;
                }
                None
            }
            Err(e) => Some(e.to_string()),
        },
    };
    if let Some(problem) = problem {
        warn!(?direction, %line, %problem, "line does not parse cleanly");
    }
    if let Ok(mut r) = recording.lock() {
        let time = r.time;
        let _ = record::write_entry(&mut r.file, time, direction, line);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_connection_gets_its_own_file() {
        let base = Path::new("/tmp/run.usarlog");
        assert_eq!(record_path(base, 1), PathBuf::from("/tmp/run.usarlog"));
        assert_eq!(record_path(base, 3), PathBuf::from("/tmp/run-3.usarlog"));
        assert_eq!(record_path(Path::new("log"), 2), PathBuf::from("log-2"));
    }
}
