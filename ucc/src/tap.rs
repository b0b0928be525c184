//! `ucc tap`: a transparent proxy for debugging a client against a real USARSim host.
//!
//! Every byte is forwarded unchanged in both directions; on the side, the lines are split
//! out, recorded (docs/recording.md; the time stamp is the latest `{Time}` the server sent,
//! since a proxy cannot know the simulated time otherwise) and checked with usar-proto: a
//! line that does not parse, or that only parses by tolerating a deviation, is logged as a
//! warning.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{info, warn};
use ucc_client::runner::record_path;
use usar_proto::record::{Direction, RecordWriter};
use usar_proto::{Command, ServerMessage};

/// Longest line the tap splits out for recording; longer ones are forwarded but not recorded.
const MAX_LINE: usize = 256 * 1024;

/// Errors that end the tap.
#[derive(Debug, thiserror::Error)]
pub(crate) enum TapError {
    /// Accepting failed.
    #[error("listener failed: {0}")]
    Io(#[from] std::io::Error),
}

/// Accepts clients on `listener` and connects each to `upstream`, until `shutdown`.
pub(crate) async fn run(
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

async fn tap_one(client: TcpStream, upstream: &str, path: &Path) -> std::io::Result<()> {
    let server = TcpStream::connect(upstream)
        .await
        .map_err(|e| std::io::Error::new(e.kind(), format!("cannot connect to {upstream}: {e}")))?;
    let _ = (client.set_nodelay(true), server.set_nodelay(true));
    let recording = Arc::new(Mutex::new(RecordWriter::create(path)?));
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
        r.flush()?;
    }
    result
}

/// Forwards bytes from `from` to `to` unchanged, recording and checking each line.
async fn pump(
    mut from: impl AsyncReadExt + Unpin,
    mut to: impl AsyncWriteExt + Unpin,
    direction: Direction,
    recording: Arc<Mutex<RecordWriter>>,
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
fn observe(line: &str, direction: Direction, recording: &Mutex<RecordWriter>) {
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
                    r.set_time(t);
                }
                None
            }
            Err(e) => Some(e.to_string()),
        },
    };
    if let Some(problem) = problem {
        warn!(?direction, %line, %problem, "line does not parse cleanly");
    }
    if let Ok(mut r) = recording.lock()
        && let Err(error) = r.write(direction, line)
    {
        warn!(%error, "cannot record");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::{AsyncBufReadExt, BufReader};

    #[tokio::test]
    async fn the_tap_forwards_everything_and_records_both_directions() {
        let shutdown = CancellationToken::new();
        let upstream = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let upstream_addr = upstream.local_addr().unwrap().to_string();
        let server = tokio::spawn(usar_server::run(
            upstream,
            usar_server::ServerConfig {
                time_scale: usar_server::TimeScale::Factor(10.0),
                ..usar_server::ServerConfig::default()
            },
            shutdown.clone(),
        ));
        let dir = std::env::temp_dir().join(format!("ucc-tap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let record = dir.join("session.usarlog");
        let front = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let front_addr = front.local_addr().unwrap();
        let tap = tokio::spawn(run(front, upstream_addr, record.clone(), shutdown.clone()));

        let stream = tokio::net::TcpStream::connect(front_addr).await.unwrap();
        let (read, mut write) = stream.into_split();
        let mut lines = BufReader::new(read).lines();
        write
            .write_all(
                b"INIT {ClassName USARBot.stsAirRobot} {Location 0,0,-1}\r\nNOT A {COMMAND\r\n",
            )
            .await
            .unwrap();
        let mut received = Vec::new();
        while received.len() < 30 {
            received.push(lines.next_line().await.unwrap().unwrap());
        }
        assert!(received[0].starts_with("NFO {Gametype BotDeathMatch}"));
        assert!(received.iter().any(|l| l.starts_with("STA {Time ")));
        drop(write);
        drop(lines);
        // Give the tap a moment to see the close, then stop everything.
        tokio::time::sleep(std::time::Duration::from_millis(200)).await;
        shutdown.cancel();
        tap.await.unwrap().unwrap();
        server.await.unwrap().unwrap();

        let text = std::fs::read_to_string(&record).unwrap();
        let entries: Vec<&str> = text.lines().skip(1).collect();
        assert!(
            entries
                .iter()
                .any(|l| l.ends_with(" C INIT {ClassName USARBot.stsAirRobot} {Location 0,0,-1}")),
            "{text}"
        );
        assert!(
            entries.iter().any(|l| l.ends_with(" C NOT A {COMMAND")),
            "{text}"
        );
        // Every line the client received is in the recording, in order.
        let recorded: Vec<&str> = entries
            .iter()
            .filter_map(|l| l.split_once(" S ").map(|(_, line)| line))
            .collect();
        assert_eq!(&recorded[..received.len()], &received[..]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
