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
use usar_proto::Command;
use usar_proto::codec::CommandCodec;

use super::driver::Request;

/// Per-connection limits.
#[derive(Debug, Clone, Copy)]
pub(super) struct Limits {
    pub(super) max_line_length: usize,
    pub(super) client_queue: usize,
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

    let mut lines = FramedRead::new(read, CommandCodec::new(limits.max_line_length));
    let reader = async {
        while let Some(item) = lines.next().await {
            match item {
                Ok(Ok(parsed)) => {
                    for deviation in &parsed.deviations {
                        warn!(%peer, %deviation, "tolerated deviation");
                    }
                    if let Command::Other(message) = &parsed.message {
                        warn!(%peer, command = %message.kind, "unknown command ignored");
                    }
                    let command = Request::Command {
                        client,
                        command: parsed.message,
                    };
                    if requests.send(command).await.is_err() {
                        break;
                    }
                }
                Ok(Err(error)) => warn!(%peer, %error, "unreadable line ignored"),
                Err(error) => {
                    debug!(%peer, %error, "read failed");
                    break;
                }
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
