//! `ucc tap`: a transparent proxy for debugging a client against a real USARSim host.
//!
//! Every byte is forwarded unchanged in both directions; on the side, the lines are split
//! out, recorded (docs/recording.md; the time stamp is the latest `{Time}` the server sent,
//! since a proxy cannot know the simulated time otherwise) and checked with usar-proto: a
//! line that does not parse, or that only parses by tolerating a deviation, is logged as a
//! warning.
//!
//! The client's bytes go upstream only once its first line is known not to be HTTP (a
//! request line or a header, `usar_proto::http`): a web page that sends a form POST to the
//! tap's port is closed and logged, so its body's INIT and DRIVE lines never reach a USARSim
//! server, which would run them (docs/security.md). Real clients wait for the server's `NFO`
//! before they write, so holding their first line back costs them nothing.
//!
//! Limits (docs/limits.md): at most `max_connections` sessions at once (more are closed on
//! accept, and a failing accept — out of file descriptors — is waited out, never the end of
//! the tap); lines longer than [`MAX_LINE`] are forwarded but neither checked nor recorded;
//! the log shows a peer's text escaped and cut, and each kind of warning about one session
//! in full 8 times, then at powers of two (`usar_proto::shown`); a recording that cannot be
//! written is reported once, naming the file, and the session goes on unrecorded; at exit
//! [`Tap::run`] returns the recordings that are incomplete, and the program names them and
//! exits with status 1.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{info, warn};
use ucc_client::runner::record_path;
use usar_proto::record::{Direction, RecordFile, RecordWriter};
use usar_proto::shown::{Repeats, Shown};
use usar_proto::{Command, ServerMessage};

/// Longest line the tap splits out for checking and recording (the server's limit); longer
/// ones are forwarded but not recorded.
const MAX_LINE: usize = usar_proto::codec::DEFAULT_MAX_LINE;

/// The default of `--max-connections` (the server's default too).
pub(crate) const MAX_CONNECTIONS: u16 = 64;

/// Errors that end the tap (or keep it from starting).
#[derive(Debug, thiserror::Error)]
pub(crate) enum TapError {
    /// `--upstream` is not an address.
    #[error("--upstream {upstream}: {reason} (expected HOST:PORT, e.g. usarsim-host:3000)")]
    Upstream {
        /// As given.
        upstream: String,
        /// Why.
        reason: String,
    },
    /// The first recording cannot be created.
    #[error("--record: cannot create {path}: {error}")]
    Record {
        /// The file.
        path: PathBuf,
        /// Why (part of the message, so not a `source`).
        error: std::io::Error,
    },
}

/// What the tap does, checked by [`Tap::check`] before it listens.
pub(crate) struct Tap {
    upstream: String,
    record: PathBuf,
    /// The recording of the first connection, created at start (a bad path is an error
    /// then, not when a client comes).
    first: Option<RecordWriter>,
    max_connections: usize,
}

impl Tap {
    /// Checks `upstream` (it must resolve as `HOST:PORT`) and creates the first recording.
    pub(crate) async fn check(
        upstream: String,
        record: PathBuf,
        max_connections: usize,
    ) -> Result<Self, TapError> {
        let bad = |reason: String| TapError::Upstream {
            upstream: upstream.clone(),
            reason,
        };
        let addrs = tokio::net::lookup_host(upstream.as_str())
            .await
            .map_err(|e| bad(e.to_string()))?;
        if addrs.count() == 0 {
            return Err(bad("resolves to no address".into()));
        }
        let first = RecordWriter::create(&record).map_err(|error| TapError::Record {
            path: record.clone(),
            error,
        })?;
        Ok(Self {
            upstream,
            record,
            first: Some(first),
            max_connections,
        })
    }

    /// Accepts clients on `listener` and connects each to the upstream server, until
    /// `shutdown`. Returns the recordings that are incomplete (a file that could not be
    /// created or written), each as `FILE: why`.
    pub(crate) async fn run(
        mut self,
        listener: TcpListener,
        shutdown: CancellationToken,
    ) -> Vec<String> {
        let tracker = TaskTracker::new();
        let incomplete = Incomplete::default();
        let open = Arc::new(AtomicUsize::new(0));
        let (mut refused, mut failed_accepts) = (Repeats::default(), Repeats::default());
        let mut connections = 0;
        loop {
            let accepted = tokio::select! {
                _ = shutdown.cancelled() => break,
                accepted = listener.accept() => accepted,
            };
            let (client, peer) = match accepted {
                Ok(accepted) => accepted,
                Err(error) => {
                    // Out of file descriptors (or another passing failure): wait it out,
                    // the listener's backlog keeps the clients waiting meanwhile.
                    if let Some(n) = failed_accepts.note() {
                        warn!(%error, count = n, "cannot accept a connection; trying again");
                    }
                    tokio::select! {
                        _ = shutdown.cancelled() => break,
                        () = tokio::time::sleep(Duration::from_millis(100)) => continue,
                    }
                }
            };
            if open.load(Ordering::Acquire) >= self.max_connections {
                if let Some(n) = refused.note() {
                    warn!(%peer, limit = self.max_connections, count = n,
                        "connection refused: the limit of connections (--max-connections) is reached");
                }
                drop(client);
                continue;
            }
            open.fetch_add(1, Ordering::AcqRel);
            connections += 1;
            let path = record_path(&self.record, connections);
            let first = self.first.take();
            let upstream = self.upstream.clone();
            let token = shutdown.child_token();
            let open = Arc::clone(&open);
            let incomplete = Arc::clone(&incomplete);
            tracker.spawn(async move {
                info!(%peer, upstream, record = %path.display(), "tapping");
                let recording = Arc::new(Mutex::new(Recording::create(&path, first, incomplete)));
                tokio::select! {
                    _ = token.cancelled() => {}
                    result = tap_one(client, &upstream, &recording) => match result {
                        Ok(()) => info!(%peer, "connection closed"),
                        Err(error) => warn!(%peer, %error, "connection ended"),
                    },
                }
                // Also when stopped: what is buffered is written, or the failure is noted.
                if let Ok(mut r) = recording.lock() {
                    r.with(RecordWriter::flush);
                }
                open.fetch_sub(1, Ordering::AcqRel);
            });
        }
        if refused.count() > 0 {
            warn!(
                refused = refused.count(),
                limit = self.max_connections,
                "connections were refused at the limit"
            );
        }
        tracker.close();
        tracker.wait().await;
        // A session cancelled in the middle of a write has ended by now.
        let mut incomplete = incomplete.lock().map(|l| l.clone()).unwrap_or_default();
        if self.first.is_some() {
            // Never used: an empty recording of its header, flushed now.
            if let Some(mut first) = self.first.take()
                && let Err(error) = first.flush()
            {
                incomplete.insert(0, format!("{}: {error}", self.record.display()));
            }
        }
        incomplete
    }
}

/// The recordings that are incomplete, as `FILE: why`.
type Incomplete = Arc<Mutex<Vec<String>>>;

/// One session's recording: written until the first error, which is reported once (the
/// file is cut back to whole lines) and noted in `incomplete`.
struct Recording {
    file: Option<RecordFile>,
    incomplete: Incomplete,
}

impl Recording {
    fn create(path: &Path, first: Option<RecordWriter>, incomplete: Incomplete) -> Self {
        let file = match first {
            Some(w) => Some(RecordFile::new(w, path)),
            None => match RecordFile::create(path) {
                Ok(file) => Some(file),
                Err(error) => {
                    warn!(file = %path.display(), %error,
                        "cannot create the recording; this connection is forwarded unrecorded");
                    if let Ok(mut list) = incomplete.lock() {
                        list.push(format!("{}: {error}", path.display()));
                    }
                    None
                }
            },
        };
        Self { file, incomplete }
    }

    /// Runs `write` on the writer; on its first error, says so and stops recording.
    fn with(&mut self, write: impl FnOnce(&mut RecordWriter) -> std::io::Result<()>) {
        if let Some(file) = &mut self.file
            && let Err(stopped) = file.with(write)
        {
            warn!(file = %file.path().display(), error = %stopped.error,
                kept_bytes = stopped.kept.as_ref().ok().copied(),
                "cannot write the recording; it ends here (whole lines kept), the rest of this connection is not recorded");
            if let Ok(mut list) = self.incomplete.lock() {
                list.push(format!("{}: {}", file.path().display(), stopped.error));
            }
        }
    }
}

async fn tap_one(
    client: TcpStream,
    upstream: &str,
    recording: &Arc<Mutex<Recording>>,
) -> std::io::Result<()> {
    let server = TcpStream::connect(upstream)
        .await
        .map_err(|e| std::io::Error::new(e.kind(), format!("cannot connect to {upstream}: {e}")))?;
    let _ = (client.set_nodelay(true), server.set_nodelay(true));
    let (mut client_read, client_write) = client.into_split();
    let (server_read, mut server_write) = server.into_split();
    let mut up = Checker::new(Direction::Client, Arc::clone(recording));
    let mut down = Checker::new(Direction::Server, Arc::clone(recording));
    let upward = async {
        let first = first_line_not_http(&mut client_read).await?;
        server_write.write_all(&first).await?;
        up.bytes(&first);
        pump(client_read, server_write, &mut up).await
    };
    let result = tokio::select! {
        r = upward => r,
        r = pump(server_read, client_write, &mut down) => r,
    };
    up.summarise();
    down.summarise();
    result
}

/// Splits one direction's bytes into lines, checks and records them.
struct Checker {
    direction: Direction,
    recording: Arc<Mutex<Recording>>,
    line: Vec<u8>,
    overlong: bool,
    /// Lines that do not parse cleanly.
    unclean: Repeats,
    /// Lines longer than [`MAX_LINE`].
    long: Repeats,
}

impl Checker {
    fn new(direction: Direction, recording: Arc<Mutex<Recording>>) -> Self {
        Self {
            direction,
            recording,
            line: Vec::new(),
            overlong: false,
            unclean: Repeats::default(),
            long: Repeats::default(),
        }
    }

    fn bytes(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            if byte == b'\n' || byte == b'\r' {
                if !self.line.is_empty() && !self.overlong {
                    let line = std::mem::take(&mut self.line);
                    self.observe(&String::from_utf8_lossy(&line));
                    self.line = line;
                }
                self.line.clear();
                self.overlong = false;
            } else if self.line.len() < MAX_LINE {
                self.line.push(byte);
            } else if !self.overlong {
                self.overlong = true;
                self.line.clear();
                if let Some(n) = self.long.note() {
                    warn!(direction = ?self.direction, max = MAX_LINE, count = n,
                        "over-long line forwarded, not recorded");
                }
            }
        }
    }

    /// Records one line and warns when usar-proto cannot read it cleanly.
    fn observe(&mut self, line: &str) {
        let mut time = None;
        let problem = match self.direction {
            Direction::Client => match Command::parse(line) {
                Ok(p) => (!p.deviations.is_empty()).then(|| {
                    let list: Vec<String> = p.deviations.iter().map(ToString::to_string).collect();
                    list.join("; ")
                }),
                Err(e) => Some(e.to_string()),
            },
            Direction::Server => match ServerMessage::parse(line) {
                Ok(p) => {
                    time = p.message.time();
                    None
                }
                Err(e) => Some(e.to_string()),
            },
        };
        if let Some(problem) = problem
            && let Some(n) = self.unclean.note()
        {
            warn!(direction = ?self.direction, line = %Shown(line), problem = %Shown(&problem),
                count = n, "line does not parse cleanly");
        }
        if let Ok(mut r) = self.recording.lock() {
            r.with(|w| {
                if let Some(t) = time {
                    w.set_time(t);
                }
                w.write(self.direction, line)
            });
        }
    }

    /// Says how many warnings were not shown.
    fn summarise(&self) {
        for (repeats, what) in [
            (self.unclean, "lines that do not parse cleanly"),
            (self.long, "over-long lines"),
        ] {
            if repeats.suppressed() > 0 {
                warn!(direction = ?self.direction, count = repeats.count(),
                    not_shown = repeats.suppressed(), "{what} in this connection");
            }
        }
    }
}

/// Forwards bytes from `from` to `to` unchanged, checking and recording each line.
/// Reads the client's bytes up to the end of its first line (or [`MAX_LINE`] bytes, or the
/// end of the stream) and returns them, unless that line looks like HTTP: then an error
/// that says so, and nothing of it is forwarded.
async fn first_line_not_http(from: &mut (impl AsyncReadExt + Unpin)) -> std::io::Result<Vec<u8>> {
    let mut held = Vec::new();
    let mut buffer = [0; 4096];
    loop {
        let end = held.iter().position(|&b| b == b'\n' || b == b'\r');
        if let Some(end) = end
            && usar_proto::http::looks_like_http(&held[..end])
        {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!(
                    "the first line looks like HTTP ({}), as a web page's request would: \
                     closed, nothing of it forwarded",
                    Shown(&String::from_utf8_lossy(&held[..end]))
                ),
            ));
        }
        if end.is_some() || held.len() >= MAX_LINE {
            return Ok(held);
        }
        let n = from.read(&mut buffer).await?;
        if n == 0 {
            return Ok(held);
        }
        held.extend_from_slice(&buffer[..n]);
    }
}

async fn pump(
    mut from: impl AsyncReadExt + Unpin,
    mut to: impl AsyncWriteExt + Unpin,
    checker: &mut Checker,
) -> std::io::Result<()> {
    let mut buffer = vec![0; 16 * 1024];
    loop {
        let n = from.read(&mut buffer).await?;
        if n == 0 {
            to.shutdown().await?;
            return Ok(());
        }
        to.write_all(&buffer[..n]).await?;
        checker.bytes(&buffer[..n]);
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
        let tap = Tap::check(upstream_addr, record.clone(), MAX_CONNECTIONS.into())
            .await
            .unwrap();
        let tap = tokio::spawn(tap.run(front, shutdown.clone()));

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
        assert!(tap.await.unwrap().is_empty(), "every recording is whole");
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

    /// Issue #56: a web page's form POST to the tap's port carried INIT and DRIVE lines in
    /// its body to the USARSim server (which runs them). The tap now closes a connection
    /// whose first line is HTTP before anything of it goes upstream.
    #[tokio::test]
    async fn an_http_request_is_closed_and_nothing_of_it_reaches_the_server() {
        let upstream = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let upstream_addr = upstream.local_addr().unwrap().to_string();
        // A server that greets, then keeps what it receives until the tap closes.
        let server = tokio::spawn(async move {
            let (mut s, _) = upstream.accept().await.unwrap();
            s.write_all(b"NFO {Gametype BotDeathMatch}\r\n")
                .await
                .unwrap();
            let mut got = Vec::new();
            let _ = s.read_to_end(&mut got).await;
            got
        });
        let dir = std::env::temp_dir().join(format!("ucc-tap-http-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let front = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let front_addr = front.local_addr().unwrap();
        let shutdown = CancellationToken::new();
        let tap = Tap::check(upstream_addr, dir.join("s.usarlog"), MAX_CONNECTIONS.into())
            .await
            .unwrap();
        let tap = tokio::spawn(tap.run(front, shutdown.clone()));
        let mut page = tokio::net::TcpStream::connect(front_addr).await.unwrap();
        page.write_all(
            b"POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: text/plain\r\n\r\n\
              INIT {ClassName USARBot.AirRobot} {Location 0,0,-1}\r\nDRIVE {AltitudeVelocity 1}\r\n",
        )
        .await
        .unwrap();
        // The tap closes the page's connection (after the server's greeting, if it came)
        // and the server's; the server got nothing. (Without the check both stay open: the
        // generous deadline turns that into a failure, not a hang.)
        let deadline = std::time::Duration::from_secs(20);
        let mut back = Vec::new();
        let closed = tokio::time::timeout(deadline, page.read_to_end(&mut back)).await;
        assert!(closed.is_ok(), "the page's connection stays open");
        drop(page);
        let got = tokio::time::timeout(deadline, server).await;
        let got = got.expect("the server's connection stays open").unwrap();
        assert!(got.is_empty(), "{}", String::from_utf8_lossy(&got));
        shutdown.cancel();
        tap.await.unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
