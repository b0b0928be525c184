//! A connection to a USARSim server: a reader that turns every line into a typed
//! [`ServerMessage`] when the caller asks for the next one (no task in between: in lockstep
//! every hand-over between threads is a part of the barrier's round trip), a writer for
//! [`Command`]s, a clean disconnect.
//!
//! Optionally it records every line in both directions (docs/recording.md). Lockstep
//! (docs/lockstep.md) is the flight loop's business ([`crate::flight`]): here a `SYNC` is a
//! command and its answer a message like any other.

use std::path::Path;
use std::time::Duration;

use tokio::net::TcpStream;
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use usar_proto::record::{Direction, RecordFile, RecordWriter};
use usar_proto::shown::{Repeats, Shown};
use usar_proto::{Command, ServerMessage};

use crate::agent::SpeedCommand;
use crate::lines::{LineReader, write_line};

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
    /// A command holds text that would break its line (`usar_proto::Command::check`): a
    /// robot name, class or start tag with a control character or a brace. Nothing was sent.
    #[error("cannot send {0}")]
    Unsendable(#[from] usar_proto::TextError),
    /// The recording file could not be created or written (it is incomplete).
    #[error("cannot record to {path}: {error}")]
    Record {
        /// The file.
        path: String,
        /// Why (part of the message, so not a `source`).
        error: std::io::Error,
    },
}

/// An open connection.
#[derive(Debug)]
pub struct Connection {
    addr: String,
    /// Read only when the caller asks; until then TCP flow control holds the server's
    /// writes (and `LineReader` is cancel-safe: a line half read stays buffered).
    lines: LineReader<OwnedReadHalf>,
    writer: OwnedWriteHalf,
    /// Server lines are recorded when the caller takes them, so that the interleaving with
    /// the caller's commands is the order of cause and effect (and the same in every
    /// lockstep run).
    recorder: Option<Recorder>,
    /// Server lines that could not be read (logged in full 8 times, then at powers of two).
    unreadable: Repeats,
}

/// The recording of a connection: written until the first error, which
/// [`Connection::disconnect`] returns (the file is cut back to whole lines).
#[derive(Debug)]
struct Recorder {
    file: RecordFile,
    error: Option<std::io::Error>,
}

impl Recorder {
    fn write(&mut self, time: Option<f64>, direction: Direction, line: &str) {
        let written = self.file.with(|w| {
            if let Some(time) = time {
                w.set_time(time);
            }
            w.write(direction, line)
        });
        if let Err(stopped) = written {
            self.error = Some(stopped.error);
        }
    }
}

/// How long [`Connection::disconnect`] waits for the server to close its end (a server that
/// never does costs this much per flight, no more).
pub const CLOSE_WAIT: Duration = Duration::from_secs(1);

impl Connection {
    /// Connects to `addr` (`host:port`) within `timeout`.
    pub async fn connect(addr: &str, timeout: Duration) -> Result<Self, ConnectionError> {
        Self::open(addr, timeout, None).await
    }

    /// Like [`Connection::connect`], recording every line in both directions into `path`.
    pub async fn connect_recording(
        addr: &str,
        timeout: Duration,
        path: &Path,
    ) -> Result<Self, ConnectionError> {
        let file = RecordFile::create(path).map_err(|error| ConnectionError::Record {
            path: path.display().to_string(),
            error,
        })?;
        let recorder = Recorder { file, error: None };
        Self::open(addr, timeout, Some(recorder)).await
    }

    async fn open(
        addr: &str,
        timeout: Duration,
        recorder: Option<Recorder>,
    ) -> Result<Self, ConnectionError> {
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
        tracing::debug!(addr, "connected");
        Ok(Self {
            addr: addr.to_owned(),
            lines: LineReader::new(read),
            writer,
            recorder,
            unreadable: Repeats::default(),
        })
    }

    /// The address connected to.
    pub fn addr(&self) -> &str {
        &self.addr
    }

    /// The next message from the server, recorded as it is taken;
    /// [`ConnectionError::Closed`] once the server closed the connection. Lockstep replies
    /// come as [`ServerMessage::Sync`] like any other message.
    pub async fn next_message(&mut self) -> Result<ServerMessage, ConnectionError> {
        loop {
            let line = match self.lines.next_line().await {
                Ok(None) => return Err(ConnectionError::Closed),
                Err(e) => return Err(ConnectionError::Read(e)),
                Ok(Some(line)) if line.trim().is_empty() => continue,
                Ok(Some(line)) => line,
            };
            match ServerMessage::parse(&line) {
                Ok(parsed) => {
                    if !parsed.deviations.is_empty() {
                        tracing::trace!(%line, deviations = ?parsed.deviations, "tolerated");
                    }
                    if let Some(r) = &mut self.recorder {
                        r.write(parsed.message.time(), Direction::Server, &line);
                    }
                    return Ok(parsed.message);
                }
                Err(error) => {
                    if let Some(count) = self.unreadable.note() {
                        tracing::warn!(line = %Shown(&line), %error, count,
                            "unreadable server line skipped");
                    }
                    if let Some(r) = &mut self.recorder {
                        r.write(None, Direction::Server, &line);
                    }
                }
            }
        }
    }

    /// Sends one command; refuses one whose text would break the line
    /// ([`ConnectionError::Unsendable`]).
    pub async fn send(&mut self, command: &Command) -> Result<(), ConnectionError> {
        command.check()?;
        let mut line = String::new();
        command.write_to(&mut line);
        self.send_line(&line).await
    }

    /// Sends commands in one write (a DRIVE and the next `SYNC` reach the server together);
    /// sends none if one of them would break its line ([`ConnectionError::Unsendable`]).
    pub async fn send_all(&mut self, commands: &[Command]) -> Result<(), ConnectionError> {
        use tokio::io::AsyncWriteExt;
        commands.iter().try_for_each(Command::check)?;
        let mut text = String::new();
        for command in commands {
            let start = text.len();
            command.write_to(&mut text);
            tracing::trace!(line = %&text[start..], "send");
            if let Some(r) = &mut self.recorder {
                r.write(None, Direction::Client, &text[start..]);
            }
            text.push_str("\r\n");
        }
        self.writer
            .write_all(text.as_bytes())
            .await
            .map_err(ConnectionError::Write)
    }

    async fn send_line(&mut self, line: &str) -> Result<(), ConnectionError> {
        tracing::trace!(%line, "send");
        if let Some(r) = &mut self.recorder {
            r.write(None, Direction::Client, line);
        }
        write_line(&mut self.writer, line)
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

    /// Closes the connection cleanly: ends the stream, then waits (at most [`CLOSE_WAIT`])
    /// for the server to end its own, which it does once it has removed the robot. So the
    /// next connection's robot spawns into a world without this one — its place free and its
    /// sensors on the ticks a lone robot gets, whatever the two connections' timing. A
    /// recording that could not be written whole is [`ConnectionError::Record`], naming the
    /// file.
    pub async fn disconnect(mut self) -> Result<(), ConnectionError> {
        use tokio::io::AsyncWriteExt;
        if let Some(r) = &mut self.recorder {
            let flushed = r.file.with(RecordWriter::flush).map_err(|s| s.error);
            if let Some(error) = r.error.take().or(flushed.err()) {
                return Err(ConnectionError::Record {
                    path: r.file.path().display().to_string(),
                    error,
                });
            }
        }
        self.writer
            .shutdown()
            .await
            .map_err(ConnectionError::Write)?;
        // What the server still sends is dropped unrecorded: the flight is over.
        let drained = async { while let Ok(Some(_)) = self.lines.next_line().await {} };
        let _ = tokio::time::timeout(CLOSE_WAIT, drained).await;
        Ok(())
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

    /// The defect: `disconnect` returned as soon as it had ended its stream, so the next
    /// flight's INIT could reach the server before the old robot was removed (a sensor phase
    /// of two robots: lockstep iterations that differed under load).
    #[tokio::test]
    async fn disconnect_returns_once_the_server_has_closed_its_end() {
        use std::sync::atomic::{AtomicBool, Ordering};
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let removed = std::sync::Arc::new(AtomicBool::new(false));
        let server = tokio::spawn({
            let removed = removed.clone();
            async move {
                let (mut socket, _) = listener.accept().await.unwrap();
                let mut rest = Vec::new();
                socket.read_to_end(&mut rest).await.unwrap();
                // The robot's removal takes a while; the stream goes on until it is done.
                for _ in 0..20 {
                    let _ = socket.write_all(b"STA {Time 1.0000}\r\n").await;
                    tokio::time::sleep(Duration::from_millis(10)).await;
                }
                removed.store(true, Ordering::SeqCst);
            }
        });
        let conn = Connection::connect(&addr, Duration::from_secs(5))
            .await
            .unwrap();
        conn.disconnect().await.unwrap();
        assert!(
            removed.load(Ordering::SeqCst),
            "returned before the server closed"
        );
        server.await.unwrap();
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
    async fn a_command_that_would_inject_a_line_is_not_sent() {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let server = tokio::spawn(async move {
            let (mut socket, _) = listener.accept().await.unwrap();
            let mut received = String::new();
            socket.read_to_string(&mut received).await.unwrap();
            socket.shutdown().await.unwrap();
            received
        });
        let mut conn = Connection::connect(&addr, Duration::from_secs(5))
            .await
            .unwrap();
        let init = |name: &str| {
            Command::Init(usar_proto::Init {
                class_name: "USARBot.stsAirRobot".into(),
                name: Some(name.into()),
                ..usar_proto::Init::default()
            })
        };
        for bad in ["UAV1\r\nGETSTARTPOSES", "UAV\t1", "UAV\u{0}1"] {
            let error = conn.send(&init(bad)).await.unwrap_err();
            assert!(matches!(error, ConnectionError::Unsendable(_)), "{error}");
            let error = conn
                .send_all(&[Command::GetStartPoses, init(bad)])
                .await
                .unwrap_err();
            assert!(
                error.to_string().starts_with("cannot send INIT {Name ..}"),
                "{error}"
            );
        }
        conn.send(&init("UAV1")).await.unwrap();
        conn.disconnect().await.unwrap();
        assert_eq!(
            server.await.unwrap(),
            "INIT {ClassName USARBot.stsAirRobot} {Name UAV1}\r\n"
        );
    }

    #[tokio::test]
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
