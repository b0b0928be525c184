//! The USARSim (UDK Gamebots) text protocol: message model, tolerant parser, byte-exact
//! printer and line codec. (Module overview and example: to be written.)

#[cfg(feature = "codec")]
pub mod codec;
pub mod error;
pub mod format;
pub mod message;
pub mod messages;
pub mod record;

pub use error::ParseError;
pub use message::{Deviation, Group, Message, Pair, Parsed};
pub use messages::*;
