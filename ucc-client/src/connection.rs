//! A connection to a USARSim server: a reader task that turns every line into a typed
//! [`ServerMessage`], a writer for [`Command`]s, a clean disconnect.

use std::time::Duration;

use tokio::net::TcpStream;
use tokio::net::tcp::OwnedWriteHalf;
use tokio::sync::mpsc;
use tokio_util::task::AbortOnDropHandle;
use usar_proto::{Command, ServerMessage};

use crate::agent::SpeedCommand;
use crate::lines::{LineReader, write_line};

/// Messages buffered between the reader task and the consumer; when full, the reader stops
/// reading and TCP flow control slows the server's writes to this connection.
const CHANNEL_CAPACITY: usize = 1024;

/// Why talking to the server failed.
#[derive(Debug, thiserror::Error)]
pub enum ConnectionError {
    /// Nothing answers at the address.
    #[error("cannot connect to {addr}: {error} (is the server running?)")]
    Connect {
        /// `host:port`.
        addr: String,
        /// Why (part of the message, so not a `source`).
        error: std::io::Error,
    },
    /// The connection attempt took too long.
    #[error("cannot connect to {addr}: no answer within {timeout:?}")]
    ConnectTimeout {
        /// `host:port`.
        addr: String,
        /// The limit.
        timeout: Duration,
    },
    /// The server closed the connection.
    #[error("the server closed the connection")]
    Closed,
    /// Reading from the server failed.
    #[error("connection to the server lost: {0}")]
    Read(std::io::Error),
    /// Sending to the server failed.
    #[error("cannot send to the server: {0}")]
    Write(std::io::Error),
}

/// An open connection.
#[derive(Debug)]
pub struct Connection {
    addr: String,
    messages: mpsc::Receiver<Result<ServerMessage, ConnectionError>>,
    writer: OwnedWriteHalf,
    /// Aborted when the connection is dropped.
    _reader: AbortOnDropHandle<()>,
}

impl Connection {
    /// Connects to `addr` (`host:port`) within `timeout` and starts the reader task.
    pub async fn connect(addr: &str, timeout: Duration) -> Result<Self, ConnectionError> {
        let stream = tokio::time::timeout(timeout, TcpStream::connect(addr))
            .await
            .map_err(|_| ConnectionError::ConnectTimeout {
                addr: addr.to_owned(),
                timeout,
            })?
            .map_err(|error| ConnectionError::Connect {
                addr: addr.to_owned(),
                error,
            })?;
        // Commands are small and latency matters more than packet count.
        let _ = stream.set_nodelay(true);
        let (read, writer) = stream.into_split();
        let (tx, messages) = mpsc::channel(CHANNEL_CAPACITY);
        let reader = tokio::spawn(read_messages(LineReader::new(read), tx));
        tracing::debug!(addr, "connected");
        Ok(Self {
            addr: addr.to_owned(),
            messages,
            writer,
            _reader: AbortOnDropHandle::new(reader),
        })
    }

    /// The address connected to.
    pub fn addr(&self) -> &str {
        &self.addr
    }

    /// The next message from the server; [`ConnectionError::Closed`] once the server closed
    /// the connection.
    pub async fn next_message(&mut self) -> Result<ServerMessage, ConnectionError> {
        self.messages
            .recv()
            .await
            .unwrap_or(Err(ConnectionError::Closed))
    }

    /// Sends one command.
    pub async fn send(&mut self, command: &Command) -> Result<(), ConnectionError> {
        let mut line = String::new();
        command.write_to(&mut line);
        tracing::trace!(%line, "send");
        write_line(&mut self.writer, &line)
            .await
            .map_err(ConnectionError::Write)
    }

    /// Sends a normalized DRIVE: each speed a percentage of the maximum in -100..=100;
    /// `x` forward, `y` right, `z` **climb** (+ = up), `yaw` + = clockwise seen from above.
    pub async fn send_speed_command(
        &mut self,
        x: f64,
        y: f64,
        z: f64,
        yaw: f64,
    ) -> Result<(), ConnectionError> {
        let command = SpeedCommand {
            forward: x,
            right: y,
            up: z,
            yaw,
        };
        self.send(&Command::Drive(command.to_drive())).await
    }

    /// Closes the connection cleanly (the server then removes the robot).
    pub async fn disconnect(mut self) -> Result<(), ConnectionError> {
        use tokio::io::AsyncWriteExt;
        self.writer.shutdown().await.map_err(ConnectionError::Write)
    }
}

async fn read_messages(
    mut lines: LineReader<tokio::net::tcp::OwnedReadHalf>,
    tx: mpsc::Sender<Result<ServerMessage, ConnectionError>>,
) {
    loop {
        let item = match lines.next_line().await {
            Ok(None) => return, // dropping tx tells the consumer: closed
            Err(e) => Err(ConnectionError::Read(e)),
            Ok(Some(line)) if line.trim().is_empty() => continue,
            Ok(Some(line)) => match ServerMessage::parse(&line) {
                Ok(parsed) => {
                    if !parsed.deviations.is_empty() {
                        tracing::trace!(%line, deviations = ?parsed.deviations, "tolerated");
                    }
                    Ok(parsed.message)
                }
                Err(error) => {
                    tracing::warn!(%line, %error, "unreadable server line skipped");
                    continue;
                }
            },
        };
        let stop = item.is_err();
        if tx.send(item).await.is_err() || stop {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn absent_server_is_a_clear_error() {
        // Bind then drop a listener to get a port nobody listens on.
        let port = {
            let l = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
            l.local_addr().unwrap().port()
        };
        let err = Connection::connect(&format!("127.0.0.1:{port}"), Duration::from_secs(5))
            .await
            .unwrap_err();
        let text = err.to_string();
        assert!(text.contains("cannot connect to 127.0.0.1:"), "{text}");
        assert!(text.contains("is the server running?"), "{text}");
    }

    #[tokio::test]
    async fn server_going_away_is_closed() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let server = tokio::spawn(async move {
            let (socket, _) = listener.accept().await.unwrap();
            drop(socket);
        });
        let mut conn = Connection::connect(&addr, Duration::from_secs(5))
            .await
            .unwrap();
        server.await.unwrap();
        assert!(matches!(
            conn.next_message().await,
            Err(ConnectionError::Closed)
        ));
    }

    #[tokio::test]
    #[ignore = "needs usar-proto parser and printer"]
    async fn reads_messages_and_sends_commands() {
        use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let server = tokio::spawn(async move {
            let (mut socket, _) = listener.accept().await.unwrap();
            socket
                .write_all(b"NFO {Gametype BotDeathMatch} {Level Map} {TimeLimit 20}\r\nSTA {Time 1.0000} {Battery 1200}\r\n")
                .await
                .unwrap();
            let mut line = String::new();
            BufReader::new(socket).read_line(&mut line).await.unwrap();
            line
        });
        let mut conn = Connection::connect(&addr, Duration::from_secs(5))
            .await
            .unwrap();
        assert!(matches!(
            conn.next_message().await.unwrap(),
            ServerMessage::Nfo(_)
        ));
        assert!(matches!(
            conn.next_message().await.unwrap(),
            ServerMessage::Sta(_)
        ));
        conn.send_speed_command(50.0, 0.0, 100.0, -10.0)
            .await
            .unwrap();
        let line = server.await.unwrap();
        assert!(line.starts_with("DRIVE {AltitudeVelocity 100"), "{line}");
        assert!(line.ends_with("{Normalized true}\r\n"), "{line}");
    }
}
