//! One TCP connection: reads commands, forwards them to the driver, writes the client's
//! output queue to the socket.

use std::net::SocketAddr;

use bytes::Bytes;
use futures::StreamExt;
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;
use tokio::net::tcp::OwnedWriteHalf;
use tokio::sync::{OwnedSemaphorePermit, mpsc, oneshot};
use tokio_util::codec::FramedRead;
use tokio_util::sync::CancellationToken;
use tracing::{debug, info, warn};
use usar_proto::codec::LineCodec;
use usar_proto::{Command, SYNC_WORD};

use super::driver::Request;
use crate::sim::ClientId;

/// Per-connection limits.
#[derive(Debug, Clone, Copy)]
pub(super) struct Limits {
    pub(super) max_line_length: usize,
    pub(super) client_queue: usize,
    /// Pass the text of client lines to the driver for the recording.
    pub(super) record: bool,
    /// Whether `SYNC` is offered (docs/lockstep.md); if not, it is an unknown command.
    pub(super) lockstep: bool,
}

/// Serves one connection until the client leaves, the socket fails or the server shuts down.
pub(super) async fn serve(
    stream: TcpStream,
    peer: SocketAddr,
    game_info: Bytes,
    requests: mpsc::Sender<Request>,
    limits: Limits,
    shutdown: CancellationToken,
    _permit: OwnedSemaphorePermit,
) {
    let (read, mut write) = stream.into_split();
    // USARSim sends the game info on accept, before the client says anything.
    if let Err(error) = write.write_all(&game_info).await {
        debug!(%peer, %error, "write failed");
        return;
    }
    let (queue, output) = mpsc::channel(limits.client_queue);
    let (reply, id) = oneshot::channel();
    let connect = Request::Connect {
        peer: peer.to_string(),
        queue,
        reply,
    };
    if requests.send(connect).await.is_err() {
        return;
    }
    let Ok(client) = id.await else { return };

    let mut lines = FramedRead::new(read, LineCodec::new(limits.max_line_length));
    let reader = async {
        while let Some(item) = lines.next().await {
            let request = match item {
                Ok(Ok(line)) => read_request(client, line, peer, limits),
                Ok(Err(error)) => {
                    warn!(%peer, %error, "unreadable line ignored");
                    continue;
                }
                Err(error) => {
                    debug!(%peer, %error, "read failed");
                    break;
                }
            };
            if requests.send(request).await.is_err() {
                break;
            }
        }
    };
    let writer = write_output(write, output);
    tokio::select! {
        _ = shutdown.cancelled() => info!(%peer, "closing: server shutting down"),
        () = reader => info!(%peer, "disconnected"),
        result = writer => if let Err(error) = result {
            info!(%peer, %error, "disconnected: write failed");
        },
    }
    let _ = requests.send(Request::Disconnect { client }).await;
}

/// Writes every chunk of the client's queue, one write per chunk.
async fn write_output(
    mut socket: OwnedWriteHalf,
    mut output: mpsc::Receiver<Bytes>,
) -> std::io::Result<()> {
    while let Some(chunk) = output.recv().await {
        socket.write_all(&chunk).await?;
    }
    Ok(())
}

/// Turns one client line into a request for the driver, logging what a stock server would
/// have silently tolerated or ignored.
fn read_request(client: ClientId, line: String, peer: SocketAddr, limits: Limits) -> Request {
    let record = limits.record;
    let parsed = match Command::parse(&line) {
        Ok(parsed) => parsed,
        Err(error) => {
            warn!(%peer, %error, %line, "unreadable line ignored");
            return Request::Unreadable { client, line };
        }
    };
    // The lockstep extension (docs/lockstep.md) is ours: not a deviation, not unknown.
    let sync = match &parsed.message {
        Command::Sync(_) | Command::Other(_) if !limits.lockstep => None,
        Command::Sync(barrier) => Some(Some(barrier.time.seconds)),
        Command::Other(message) if message.kind.eq_ignore_ascii_case(SYNC_WORD) => Some(None),
        _ => None,
    };
    if sync.is_none() {
        for deviation in &parsed.deviations {
            warn!(%peer, %deviation, %line, "tolerated deviation");
        }
    }
    let text = record.then_some(line);
    match sync {
        None => Request::Command {
            client,
            command: Box::new(parsed.message),
            line: text,
        },
        Some(Some(time)) => Request::Sync {
            client,
            time,
            line: text,
        },
        Some(None) => {
            warn!(%peer, "SYNC without a valid {{Time t}} ignored");
            Request::Unreadable {
                client,
                line: text.unwrap_or_default(),
            }
        }
    }
}
