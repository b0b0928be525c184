//! One TCP connection: reads commands, forwards them to the driver, writes the client's
//! output queue to the socket.
//!
//! Bounds: at most `Limits::backlog` of the client's lines wait for the simulation at a time
//! (the session stops reading the socket until the driver has served some, so a flood is
//! held back by TCP, not buffered); a connection that sends no complete line within
//! `idle_timeout` of connecting, or leaves a line unfinished for `line_timeout`, is closed;
//! warnings about what a client sends are escaped and summarised (`shown`).

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

use bytes::Bytes;
use futures::StreamExt;
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;
use tokio::net::tcp::OwnedWriteHalf;
use tokio::sync::{Semaphore, mpsc, oneshot};
use tokio_util::codec::FramedRead;
use tokio_util::sync::CancellationToken;
use tracing::{debug, info, warn};
use usar_proto::codec::LineCodec;
use usar_proto::{Command, SYNC_WORD};

use super::Registered;
use super::request::{Line, Request};
use usar_proto::shown::{Repeats, Shown};

/// Per-connection limits.
#[derive(Debug, Clone, Copy)]
pub(super) struct Limits {
    pub(super) max_line_length: usize,
    pub(super) client_queue: usize,
    /// Lines of this client waiting for the driver at most.
    pub(super) backlog: usize,
    pub(super) idle_timeout: Duration,
    pub(super) line_timeout: Duration,
    /// Whether `SYNC` is served (docs/lockstep.md) or ignored like any unknown command.
    pub(super) lockstep: bool,
    /// Pass the text of client lines to the driver for the recording.
    pub(super) record: bool,
}

/// What one client did that the log summarises.
#[derive(Debug, Default)]
struct Complaints {
    unreadable: Repeats,
    deviations: Repeats,
    sync: Repeats,
}

/// Serves one connection until the client leaves, the socket fails or the server shuts down.
pub(super) async fn serve(
    stream: TcpStream,
    peer: SocketAddr,
    game_info: Bytes,
    (requests, wants_room): (std::sync::mpsc::Sender<Request>, Arc<AtomicBool>),
    limits: Limits,
    shutdown: CancellationToken,
    registered: Registered,
) {
    let (read, mut write) = stream.into_split();
    // USARSim sends the game info on accept, before the client says anything.
    if let Err(error) = write.write_all(&game_info).await {
        debug!(%peer, %error, "write failed");
        return;
    }
    let (queue, output) = mpsc::channel(limits.client_queue);
    let queued = Arc::new(AtomicUsize::new(0));
    let (reply, id) = oneshot::channel();
    let connect = Request::Connect {
        peer: peer.to_string(),
        queue,
        queued: queued.clone(),
        reply,
    };
    if requests.send(connect).is_err() {
        return;
    }
    let Ok(client) = id.await else { return };

    let backlog = Arc::new(Semaphore::new(limits.backlog.max(1)));
    let mut complaints = Complaints::default();
    let mut lines = FramedRead::new(read, LineCodec::new(limits.max_line_length));
    let reader = async {
        let mut first = true;
        loop {
            let wait = if first {
                limits.idle_timeout
            } else {
                limits.line_timeout
            };
            let item = match tokio::time::timeout(wait, lines.next()).await {
                Ok(Some(item)) => item,
                Ok(None) => return Some("disconnected"),
                Err(_) if first => return Some("closing: no complete line in time"),
                // Waiting between lines is fine; a line left half-sent is not.
                Err(_) if lines.read_buffer().is_empty() && !lines.decoder().skipping() => {
                    continue;
                }
                Err(_) => return Some("closing: line not finished in time"),
            };
            if first {
                first = false;
                // A web page's request (docs/security.md): none of its lines is served.
                if let Ok(Ok(line)) = &item
                    && usar_proto::http::looks_like_http(line.as_bytes())
                {
                    warn!(%peer, line = %Shown(line),
                        "closing: the first line is HTTP (a web page's request?), not the \
                         Gamebots protocol; nothing of this connection is served");
                    return None;
                }
                registered.spoke();
            }
            let line = match item {
                Ok(Ok(line)) => read_line(line, peer, limits, &mut complaints),
                Ok(Err(error)) => {
                    if let Some(n) = complaints.unreadable.note() {
                        warn!(%peer, %error, count = n, "unreadable line ignored");
                    }
                    continue;
                }
                Err(error) => {
                    debug!(%peer, %error, "read failed");
                    return Some("disconnected: read failed");
                }
            };
            // Back-pressure: wait until the driver has served enough of this client's lines.
            let Ok(permit) = backlog.clone().acquire_owned().await else {
                return Some("disconnected");
            };
            let request = Request::Line {
                client,
                line,
                permit,
            };
            if requests.send(request).is_err() {
                return Some("closing: simulation stopped");
            }
        }
    };
    // Pinned here rather than moved into the select, so that the socket (its write half is
    // the writer's) closes only after the driver was told: a client that waits for the
    // server's end of the stream before connecting again finds its robot gone.
    let mut writer = std::pin::pin!(write_output(
        write,
        output,
        queued,
        (wants_room, requests.clone())
    ));
    tokio::select! {
        _ = shutdown.cancelled() => info!(%peer, "closing: server shutting down"),
        _ = registered.evicted.cancelled() => warn!(%peer,
            "closing: a connection limit was reached and this was the oldest connection \
             that had not sent a line"),
        why = reader => if let Some(why) = why {
            info!(%peer, "{why}");
        },
        result = &mut writer => if let Err(error) = result {
            info!(%peer, %error, "disconnected: write failed");
        },
    }
    let suppressed = complaints.unreadable.suppressed()
        + complaints.deviations.suppressed()
        + complaints.sync.suppressed();
    if suppressed > 0 {
        warn!(
            %peer,
            unreadable = complaints.unreadable.count(),
            deviations = complaints.deviations.count(),
            sync = complaints.sync.count(),
            suppressed,
            "summary of this client's ignored or tolerated input"
        );
    }
    let _ = requests.send(Request::Disconnect { client });
}

/// Writes the client's queue to the socket, all chunks waiting at once in one write, and
/// gives their bytes back to the client's budget; wakes the driver if it waits for room
/// (`TimeScale::Max`, the driver's `flush_all`).
async fn write_output(
    mut socket: OwnedWriteHalf,
    mut output: mpsc::Receiver<Bytes>,
    queued: Arc<AtomicUsize>,
    (wants_room, driver): (Arc<AtomicBool>, std::sync::mpsc::Sender<Request>),
) -> std::io::Result<()> {
    let mut chunks = Vec::new();
    let mut joined = Vec::new();
    while output.recv_many(&mut chunks, 64).await > 0 {
        let len = if let [chunk] = &chunks[..] {
            socket.write_all(chunk).await?;
            chunk.len()
        } else {
            joined.clear();
            chunks.iter().for_each(|c| joined.extend_from_slice(c));
            socket.write_all(&joined).await?;
            joined.len()
        };
        chunks.clear();
        queued.fetch_sub(len, Ordering::SeqCst);
        if wants_room.load(Ordering::SeqCst) && wants_room.swap(false, Ordering::SeqCst) {
            let _ = driver.send(Request::Wake);
        }
    }
    Ok(())
}

/// Whether a command is the QUAD extension (docs/quadrotor.md): ours, not unknown; the world
/// applies it.
fn is_quad(command: &Command) -> bool {
    matches!(command, Command::Other(m) if m.kind.eq_ignore_ascii_case("QUAD"))
}

/// Turns one client line into what the driver serves, logging (summarised, escaped) what a
/// stock server would have silently tolerated or ignored.
fn read_line(text: String, peer: SocketAddr, limits: Limits, complaints: &mut Complaints) -> Line {
    let parsed = match Command::parse(&text) {
        Ok(parsed) => parsed,
        Err(error) => {
            if let Some(n) = complaints.unreadable.note() {
                warn!(%peer, %error, line = %Shown(&text), count = n, "unreadable line ignored");
            }
            return Line::Unreadable { text };
        }
    };
    #[cfg(test)]
    if text == "__CRASH_THE_SIMULATION__" {
        return Line::Crash;
    }
    // The lockstep extension (docs/lockstep.md) is ours: not a deviation, not unknown.
    let sync = match &parsed.message {
        Command::Sync(barrier) => {
            Some(Some(barrier.time.seconds).filter(|t| t.is_finite() && *t >= 0.0))
        }
        Command::Other(message) if message.kind.eq_ignore_ascii_case(SYNC_WORD) => Some(None),
        _ => None,
    };
    if sync.is_some() && !limits.lockstep {
        if let Some(n) = complaints.sync.note() {
            warn!(%peer, count = n, "SYNC ignored: lockstep is off (usar-server --lockstep)");
        }
    } else if sync.is_none() && !is_quad(&parsed.message) {
        for deviation in &parsed.deviations {
            if let Some(n) = complaints.deviations.note() {
                let deviation = deviation.to_string();
                warn!(%peer, deviation = %Shown(&deviation), line = %Shown(&text), count = n,
                    "tolerated deviation");
            }
        }
    }
    let text = limits.record.then_some(text);
    match sync {
        Some(Some(time)) if limits.lockstep => Line::Sync { time, text },
        Some(None) if limits.lockstep => {
            if let Some(n) = complaints.sync.note() {
                warn!(%peer, count = n, "SYNC without a valid {{Time t}} ignored");
            }
            Line::Unreadable {
                text: text.unwrap_or_default(),
            }
        }
        _ => Line::Command {
            command: Box::new(parsed.message),
            text,
        },
    }
}
