//! A UAV's radio through a Wireless Simulation Server (docs/wss.md): register a name, ask
//! the signal to another UAV, send it a message — which fails when the pair is out of range
//! — and receive the messages others sent.
//!
//! The names must be the robots' names in the simulation (INIT `{Name ..}`): the WSS kicks
//! registrations of names the simulation does not have. Messages travel as the WSS relays
//! them (TCP through a port of the WSS); on the wire each is the sender's name (a 2-byte
//! big-endian length, then UTF-8) and the data (a 4-byte big-endian length, then the bytes).
//!
//! ```no_run
//! # async fn demo() -> Result<(), ucc_client::radio::RadioError> {
//! use ucc_client::radio::Radio;
//! let mut radio = Radio::join("127.0.0.1:50000".parse().unwrap(), "Robot1").await?;
//! match radio.send("BaseStation", b"victim at 3,4").await {
//!     Ok(()) => {}
//!     Err(ucc_client::radio::RadioError::OutOfRange { strength, .. }) => {
//!         println!("no link ({strength} dBm)");
//!     }
//!     Err(e) => return Err(e),
//! }
//! # Ok(())
//! # }
//! ```

use std::net::SocketAddr;
use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;

/// The weakest usable signal of the WSS's default model, dBm.
pub const CUTOFF: f64 = -93.0;

/// The largest message received (bytes); larger ones are dropped with their connection.
pub const MAX_MESSAGE: usize = 1 << 20;

/// Messages kept until read; more wait in TCP (the sender's write waits).
const INBOX: usize = 256;

/// How long a WSS reply may take.
const REPLY_TIMEOUT: Duration = Duration::from_secs(10);

/// What went wrong with the radio.
#[derive(Debug, thiserror::Error)]
pub enum RadioError {
    /// The WSS could not be reached, or the connection broke.
    #[error("radio: {0}")]
    Io(#[from] std::io::Error),
    /// The WSS answered something else than expected (its reply).
    #[error("radio: the WSS answered {0:?}")]
    Refused(String),
    /// The other UAV is out of range (or behind too many walls) now.
    #[error("radio: {to} is out of range ({strength} dBm, below {CUTOFF})")]
    OutOfRange {
        /// The UAV asked for.
        to: String,
        /// The signal, dBm (NaN when the WSS does not know it yet).
        strength: f64,
    },
    /// A message larger than [`MAX_MESSAGE`].
    #[error("radio: a message of {0} bytes is larger than {MAX_MESSAGE}")]
    TooLarge(usize),
}

/// A message another UAV sent.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Message {
    /// Its sender's name.
    pub from: String,
    /// Its bytes.
    pub data: Vec<u8>,
}

/// A message an agent sends ([`Step::send`](crate::Step::send)): the runner sends it
/// through the UAV's [`Radio`] after the step.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outgoing {
    /// The other UAV's name (its robot name in the simulation).
    pub to: String,
    /// Its bytes.
    pub data: Vec<u8>,
}

/// A message that did not get through, handed back to the agent in the next
/// [`UavState::undelivered`](crate::UavState::undelivered).
#[derive(Debug, Clone, PartialEq)]
pub struct Undelivered {
    /// The message.
    pub message: Outgoing,
    /// The signal to the other UAV when the send failed, dBm (NaN: unknown; the cut-off is
    /// [`CUTOFF`]).
    pub strength: f64,
    /// Why, in words ([`RadioError`]'s message).
    pub reason: String,
}

/// One UAV's registration with a WSS and its listener for others' messages.
#[derive(Debug)]
pub struct Radio {
    name: String,
    wss: SocketAddr,
    read: BufReader<OwnedReadHalf>,
    write: OwnedWriteHalf,
    inbox: mpsc::Receiver<Message>,
}

impl Radio {
    /// Registers `name` with the WSS at `wss` (`INIT`), listening for messages on a free
    /// port of this machine.
    pub async fn join(wss: SocketAddr, name: &str) -> Result<Self, RadioError> {
        // On the address the WSS reaches us at when it is local, else on every interface.
        let listener = match TcpListener::bind((wss.ip(), 0)).await {
            Ok(l) => l,
            Err(_) => TcpListener::bind("0.0.0.0:0").await?,
        };
        let port = listener.local_addr()?.port();
        let (read, write) = TcpStream::connect(wss).await?.into_split();
        let (tx, inbox) = mpsc::channel(INBOX);
        let mut radio = Self {
            name: name.to_owned(),
            wss,
            read: BufReader::new(read),
            write,
            inbox,
        };
        let reply = radio
            .ask(&format!("INIT {{Robot {name}}} {{Port {port}}}"))
            .await?;
        if reply != "INITREPLY {Status OK}" {
            return Err(RadioError::Refused(reply));
        }
        tokio::spawn(receive(listener, tx));
        Ok(radio)
    }

    /// This UAV's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    async fn ask(&mut self, request: &str) -> Result<String, RadioError> {
        self.write
            .write_all(format!("{request}\r\n").as_bytes())
            .await?;
        let mut line = String::new();
        let read = tokio::time::timeout(REPLY_TIMEOUT, async {
            let mut limited = (&mut self.read).take(64 * 1024);
            limited.read_line(&mut line).await
        })
        .await
        .map_err(|_| std::io::Error::from(std::io::ErrorKind::TimedOut))??;
        if read == 0 {
            return Err(std::io::Error::from(std::io::ErrorKind::UnexpectedEof).into());
        }
        Ok(line.trim_end().to_owned())
    }

    /// The signal to `to` in dBm (`GETSS`); NaN when the WSS does not know it yet.
    pub async fn strength(&mut self, to: &str) -> Result<f64, RadioError> {
        let reply = self.ask(&format!("GETSS {{Robot {to}}}")).await?;
        let prefix = format!("SS {{Robot {to}}} {{Strength ");
        let value = reply
            .strip_prefix(&prefix)
            .and_then(|r| r.split('}').next())
            .ok_or_else(|| RadioError::Refused(reply.clone()))?;
        Ok(match value {
            "INF" => f64::INFINITY,
            "NaN" => f64::NAN,
            v => v.parse().map_err(|_| RadioError::Refused(reply.clone()))?,
        })
    }

    /// Sends `data` to the UAV `to`; [`RadioError::OutOfRange`] when the link does not hold
    /// now (the signal is below the cut-off, or the WSS refuses the connection).
    pub async fn send(&mut self, to: &str, data: &[u8]) -> Result<(), RadioError> {
        if data.len() > MAX_MESSAGE {
            return Err(RadioError::TooLarge(data.len()));
        }
        let strength = self.strength(to).await?;
        if strength.is_nan() || strength < CUTOFF {
            return Err(RadioError::OutOfRange {
                to: to.to_owned(),
                strength,
            });
        }
        let reply = self.ask(&format!("DNS {{Robot {to}}}")).await?;
        let port: u16 = reply
            .strip_prefix(&format!("DNSREPLY {{Robot {to}}} {{Port "))
            .and_then(|r| r.strip_suffix('}'))
            .and_then(|p| p.parse().ok())
            .ok_or_else(|| RadioError::Refused(reply.clone()))?;
        let mut frame = Vec::with_capacity(6 + self.name.len() + data.len());
        frame.extend_from_slice(&(self.name.len() as u16).to_be_bytes());
        frame.extend_from_slice(self.name.as_bytes());
        frame.extend_from_slice(&(data.len() as u32).to_be_bytes());
        frame.extend_from_slice(data);
        if relay(self.wss, port, &frame).await.is_ok() {
            return Ok(());
        }
        // The WSS closed the relay: the link broke since the signal was asked (the WSS
        // re-evaluates links between two requests), so the error gives the signal now.
        Err(RadioError::OutOfRange {
            to: to.to_owned(),
            strength: self.strength(to).await.unwrap_or(f64::NAN),
        })
    }

    /// The next message received, if any (without waiting).
    pub fn try_recv(&mut self) -> Option<Message> {
        self.inbox.try_recv().ok()
    }

    /// Waits for the next message.
    pub async fn recv(&mut self) -> Option<Message> {
        self.inbox.recv().await
    }
}

/// Writes one framed message through the WSS's relay `port`; delivered once the other side
/// has read it all and closed (the WSS closes our end after the other side's).
async fn relay(wss: SocketAddr, port: u16, frame: &[u8]) -> std::io::Result<()> {
    let mut link = TcpStream::connect((wss.ip(), port)).await?;
    link.write_all(frame).await?;
    link.shutdown().await?;
    let mut rest = Vec::new();
    let _ = tokio::time::timeout(REPLY_TIMEOUT, link.read_to_end(&mut rest)).await;
    Ok(())
}

/// Accepts relayed connections and reads one message from each.
async fn receive(listener: TcpListener, inbox: mpsc::Sender<Message>) {
    // Ends when the radio is dropped (the next connection finds the inbox closed).
    while !inbox.is_closed() {
        let Ok((mut stream, _)) = listener.accept().await else {
            continue;
        };
        let inbox = inbox.clone();
        tokio::spawn(async move {
            if let Ok(message) = read_message(&mut stream).await {
                let _ = inbox.send(message).await;
            }
        });
    }
}

async fn read_message(stream: &mut TcpStream) -> std::io::Result<Message> {
    let bad = || std::io::Error::from(std::io::ErrorKind::InvalidData);
    let mut n = [0u8; 2];
    stream.read_exact(&mut n).await?;
    let mut from = vec![0u8; usize::from(u16::from_be_bytes(n))];
    stream.read_exact(&mut from).await?;
    let mut len = [0u8; 4];
    stream.read_exact(&mut len).await?;
    let len = u32::from_be_bytes(len) as usize;
    if len > MAX_MESSAGE {
        return Err(bad());
    }
    let mut data = vec![0u8; len];
    stream.read_exact(&mut data).await?;
    Ok(Message {
        from: String::from_utf8(from).map_err(|_| bad())?,
        data,
    })
}
