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

use std::collections::VecDeque;
use std::io::Read;
use std::net::SocketAddr;
use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};

/// The weakest usable signal of the WSS's default model, dBm.
pub const CUTOFF: f64 = -93.0;

/// The largest message received (bytes); larger ones are dropped with their connection.
pub const MAX_MESSAGE: usize = 1 << 20;

/// Messages kept until read; more wait in TCP (the sender's write waits).
const INBOX: usize = 256;

/// Relayed connections read at once; more wait to be accepted.
const RELAYED: usize = 64;

/// How often [`Radio::recv`] looks for a message.
const RECV_POLL: Duration = Duration::from_millis(2);

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
///
/// Messages are taken from the listener's sockets when asked for ([`Radio::try_recv`]),
/// not in the background: a message the WSS delivered before the caller looks is there
/// when it looks. So in lockstep (docs/wss.md), where the WSS delivers at a barrier before
/// the world steps on, a runner that looks before each step of its agent hands each message
/// to the first step after that barrier, whatever the wall-clock timing.
#[derive(Debug)]
pub struct Radio {
    name: String,
    wss: SocketAddr,
    read: BufReader<OwnedReadHalf>,
    write: OwnedWriteHalf,
    /// Non-blocking: the WSS's connections, one message each.
    listener: std::net::TcpListener,
    /// Accepted connections whose message has not all come yet.
    relayed: Vec<Relayed>,
    inbox: VecDeque<Message>,
}

impl Radio {
    /// Registers `name` with the WSS at `wss` (`INIT`), listening for messages on a free
    /// port of this machine.
    pub async fn join(wss: SocketAddr, name: &str) -> Result<Self, RadioError> {
        // On the address the WSS reaches us at when it is local, else on every interface.
        let listener = std::net::TcpListener::bind((wss.ip(), 0))
            .or_else(|_| std::net::TcpListener::bind("0.0.0.0:0"))?;
        listener.set_nonblocking(true)?;
        let port = listener.local_addr()?.port();
        let (read, write) = TcpStream::connect(wss).await?.into_split();
        let mut radio = Self {
            name: name.to_owned(),
            wss,
            read: BufReader::new(read),
            write,
            listener,
            relayed: Vec::new(),
            inbox: VecDeque::new(),
        };
        let reply = radio
            .ask(&format!("INIT {{Robot {name}}} {{Port {port}}}"))
            .await?;
        if reply != "INITREPLY {Status OK}" {
            return Err(RadioError::Refused(reply));
        }
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

    /// The next message received, if any, without waiting: takes every message that has
    /// come in full by now (in the order the WSS connected), then hands out the oldest.
    pub fn try_recv(&mut self) -> Option<Message> {
        self.take();
        self.inbox.pop_front()
    }

    /// Waits for the next message (looking every 2 ms).
    pub async fn recv(&mut self) -> Option<Message> {
        loop {
            if let Some(message) = self.try_recv() {
                return Some(message);
            }
            tokio::time::sleep(RECV_POLL).await;
        }
    }

    /// Accepts the WSS's new connections and reads what has come on each, without waiting.
    fn take(&mut self) {
        while self.relayed.len() < RELAYED {
            match self.listener.accept() {
                Ok((stream, _)) => {
                    if stream.set_nonblocking(true).is_ok() {
                        self.relayed.push(Relayed {
                            stream,
                            bytes: Vec::new(),
                        });
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(_) => break, // none waiting (or an error: looked at again next time)
            }
        }
        let inbox = &mut self.inbox;
        self.relayed.retain_mut(|relayed| {
            if inbox.len() >= INBOX {
                return true; // read later; meanwhile the rest waits in TCP
            }
            match relayed.read() {
                Arrival::Done(message) => {
                    inbox.push_back(message);
                    false
                }
                Arrival::Waiting => true,
                Arrival::Broken => false,
            }
        });
    }
}

/// One connection from the WSS and the bytes of its message read so far.
#[derive(Debug)]
struct Relayed {
    stream: std::net::TcpStream,
    bytes: Vec<u8>,
}

/// Where a relayed connection's message is.
enum Arrival {
    Done(Message),
    /// Not all here yet.
    Waiting,
    /// Closed before the end, too large, or not a message: dropped.
    Broken,
}

impl Relayed {
    /// Reads what has come (without waiting) and the message if it is complete.
    fn read(&mut self) -> Arrival {
        let mut chunk = [0u8; 16 * 1024];
        let closed = loop {
            match self.stream.read(&mut chunk) {
                Ok(0) => break true,
                Ok(n) => {
                    self.bytes.extend_from_slice(&chunk[..n]);
                    if self.bytes.len() > 6 + usize::from(u16::MAX) + MAX_MESSAGE {
                        return Arrival::Broken;
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break false,
                Err(_) => break true,
            }
        };
        match frame(&self.bytes) {
            Some(Ok(message)) => Arrival::Done(message),
            Some(Err(())) => Arrival::Broken,
            None if closed => Arrival::Broken,
            None => Arrival::Waiting,
        }
    }
}

/// The message framed at the start of `bytes`: the sender's name (a 2-byte big-endian
/// length, then UTF-8), the data (a 4-byte big-endian length, then the bytes). `None`: not
/// all here yet; `Err`: not a message (or larger than [`MAX_MESSAGE`]).
fn frame(bytes: &[u8]) -> Option<Result<Message, ()>> {
    let name = usize::from(u16::from_be_bytes(bytes.get(..2)?.try_into().ok()?));
    let len = bytes.get(2 + name..6 + name)?;
    let len = u32::from_be_bytes(len.try_into().ok()?) as usize;
    if len > MAX_MESSAGE {
        return Some(Err(()));
    }
    let data = bytes.get(6 + name..6 + name + len)?;
    Some(
        String::from_utf8(bytes[2..2 + name].to_vec())
            .map(|from| Message {
                from,
                data: data.to_vec(),
            })
            .map_err(|_| ()),
    )
}

/// Writes one framed message through the WSS's relay `port`. It is delivered once the WSS
/// has relayed it and the other side has read it and closed, which is not waited for (in
/// lockstep that comes only after this client's next `SYNC`): the connection is kept open
/// in the background until the WSS closes it.
async fn relay(wss: SocketAddr, port: u16, frame: &[u8]) -> std::io::Result<()> {
    let mut link = TcpStream::connect((wss.ip(), port)).await?;
    // Written at once, not held back for the WSS's acknowledgement (docs/wss.md, lockstep).
    link.set_nodelay(true)?;
    link.write_all(frame).await?;
    link.shutdown().await?;
    tokio::spawn(async move {
        let mut rest = Vec::new();
        let _ = tokio::time::timeout(REPLY_TIMEOUT, link.read_to_end(&mut rest)).await;
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn framed(from: &[u8], data: &[u8]) -> Vec<u8> {
        let mut bytes = (from.len() as u16).to_be_bytes().to_vec();
        bytes.extend_from_slice(from);
        bytes.extend_from_slice(&(data.len() as u32).to_be_bytes());
        bytes.extend_from_slice(data);
        bytes
    }

    #[test]
    fn a_message_is_taken_once_all_of_it_has_come() {
        let bytes = framed(b"Robot2", b"victim at 3,4");
        for cut in 0..bytes.len() {
            assert!(frame(&bytes[..cut]).is_none(), "{cut} bytes");
        }
        let message = frame(&bytes).unwrap().unwrap();
        assert_eq!(message.from, "Robot2");
        assert_eq!(message.data, b"victim at 3,4");
        // What follows the message (nothing should) is not part of it.
        let mut more = bytes.clone();
        more.extend_from_slice(b"junk");
        assert_eq!(frame(&more).unwrap().unwrap(), message);
    }

    #[test]
    fn an_oversized_or_misnamed_message_is_refused() {
        let mut huge = framed(b"R", b"");
        huge[3..7].copy_from_slice(&(MAX_MESSAGE as u32 + 1).to_be_bytes());
        assert!(frame(&huge).unwrap().is_err());
        assert!(frame(&framed(&[0xff, 0xfe], b"x")).unwrap().is_err());
    }
}
