//! The USARSim (UDK Gamebots) text protocol: message model, tolerant parser, byte-exact
//! printer and line codec.
//!
//! Layout:
//!
//! * [`message`]: the generic model ([`Message`], [`Group`], [`Pair`]) and the tolerant
//!   line parser of protocol.md §1.3/§10, with [`Deviation`]s for logging;
//! * [`messages`]: typed client commands ([`Command`]) and server messages
//!   ([`ServerMessage`]), each read from and printed to its exact wire form;
//! * [`primitive`]: the value types every layer shares ([`Vec3`], [`Time`]);
//! * [`format`]: the engine's number formatters (implicit float, implicit vector,
//!   `FloatString`) writing into any [`format::WireBuf`];
//! * [`codec`] (feature `codec`): the tokio-util line codecs shared by server and client;
//! * [`image`]: the image server's binary requests and frames (port 5003), sans I/O;
//! * [`http`]: whether a connection's first line is HTTP (a web page's request), which
//!   every text port closes;
//! * [`shown`]: a peer's text as a log shows it (escaped, cut) and a counter that
//!   summarises repeated warnings;
//! * [`wss`]: the Wireless Simulation Server's obstacle propagation model ([`wss::PathLoss`]);
//! * [`error`]: the crate-edge errors, [`ParseError`] (reading) and [`TextError`] (a value
//!   that cannot be printed into a line).
//!
//! ```
//! use usar_proto::{SenData, ServerMessage};
//!
//! let line = "SEN {Time 57.1234} {Type Sonar} {Name Sonar0} {Range 2.3456}";
//! let parsed = ServerMessage::parse(line)?;
//! let ServerMessage::Sen(sen) = &parsed.message else { unreachable!() };
//! let SenData::Sonar { readings, .. } = &sen.data else { unreachable!() };
//! assert_eq!(readings[0].range, 2.3456);
//! assert_eq!(parsed.message.to_string(), line);
//! # Ok::<(), usar_proto::ParseError>(())
//! ```

#[cfg(feature = "codec")]
pub mod codec;
pub mod error;
pub mod format;
pub mod http;
pub mod image;
pub mod message;
pub mod messages;
pub mod primitive;
pub mod record;
pub mod shown;
mod value;
pub mod wss;

pub use error::{ParseError, ParseErrorKind, TextError};
pub use message::{Deviation, Group, Message, Pair, Parsed};
pub use messages::*;
pub use primitive::{Time, Vec3};
