//! Typed messages: client commands and server messages, each parsed from and printed to the
//! exact wire form.
//!
//! * [`command`]: the client commands ([`Command`]); lenient reading (see `value` rules in
//!   [`Command::parse`]), canonical printing with shortest round-trip numbers.
//! * [`server`]: the server message types ([`ServerMessage`]); one file per message word
//!   (`nfo`, `sta`, `sen`, `conf`, `geo`, `actuator` for ASTA/EFF/DIE) holds its reading
//!   and its byte-exact printing, with tests.
//!
//! Server lines are read by key (case-insensitive, first occurrence wins; CONF and GEO parts
//! and UT2004 sonar readings start at each `Name` key). A line of a known word whose keys or
//! numbers cannot be read gives a [`ParseError`] saying what and where; unknown words give
//! [`ServerMessage::Other`], unknown sensor types [`SenData::Other`], CONF parts of unknown
//! layout [`ConfItem::Other`].

pub mod command;
pub mod common;
pub mod server;

mod actuator;
mod conf;
mod geo;
mod line;
mod nfo;
mod sen;
mod sta;
mod sync;

pub use command::*;
pub use common::*;
pub use server::*;
pub use sync::{Barrier, SYNC_WORD};

use crate::error::ParseError;
use crate::format::WireBuf;
use crate::message::{Deviation, Parsed, Raw};
use crate::value::Reader;

/// The words of server → client messages (typed or not): `NFO`, `STA`, `SEN`, `CONF`,
/// `GEO`, `ASTA`, `EFF`, `DIE`, and the older or rarer `MISSTA`, `BSTA`, `RES`.
pub const SERVER_WORDS: [&str; 11] = [
    "NFO", "STA", "SEN", "CONF", "GEO", "ASTA", "EFF", "DIE", "MISSTA", "BSTA", "RES",
];

impl ServerMessage {
    /// Whether a line with this message word comes from a server ([`SERVER_WORDS`],
    /// case-insensitive); every other word is a client command (known or not).
    pub fn is_server_word(word: &str) -> bool {
        SERVER_WORDS.iter().any(|w| w.eq_ignore_ascii_case(word))
    }

    /// Parses a server line (any generation's layout).
    ///
    /// The only deviation reported is [`Deviation::GroupedPairs`] (a UT2004-era layout).
    ///
    /// ```
    /// use usar_proto::{ServerMessage, Sta};
    /// let m = ServerMessage::parse("STA {Time 12.5000} {Battery 1200}").unwrap().message;
    /// let ServerMessage::Sta(Sta { battery, .. }) = m else { panic!() };
    /// assert_eq!(battery, 1200);
    /// ```
    pub fn parse(line: &str) -> Result<Parsed<Self>, ParseError> {
        let mut devs = Vec::new();
        let raw = Raw::parse(line, true, &mut devs)?;
        devs.retain(|d| *d == Deviation::GroupedPairs);
        let word = raw.kind;
        let is = |w: &str| word.eq_ignore_ascii_case(w);
        let r = |what| Reader::new(what, &raw.pairs);
        let typed = if is("NFO") {
            Nfo::read(r("nfo"))?.map(Self::Nfo)
        } else if is("STA") {
            Some(Self::Sta(Sta::read(r("sta"))?))
        } else if is("SEN") {
            Some(Self::Sen(Sen::read(r("sen"))?))
        } else if is("CONF") {
            Conf::read(r("conf"))?.map(Self::Conf)
        } else if is("GEO") {
            Geo::read(r("geo"))?.map(Self::Geo)
        } else if is("ASTA") {
            Some(Self::Asta(Asta::read(r("asta"))?))
        } else if is("EFF") {
            Some(Self::Eff(Eff::read(r("eff"))?))
        } else if is("DIE") {
            Some(Self::Die(Die::read(r("die"))?))
        } else if is(SYNC_WORD) {
            Some(Self::Sync(Barrier::read(r("sync"))?))
        } else {
            None
        };
        Ok(Parsed {
            message: typed.unwrap_or_else(|| Self::Other(raw.to_message())),
            deviations: devs,
        })
    }

    /// Appends the exact wire form, without the line terminator.
    pub fn write_to(&self, out: &mut impl WireBuf) {
        match self {
            Self::Nfo(m) => m.write(out),
            Self::Sta(m) => m.write(out),
            Self::Sen(m) => m.write(out),
            Self::Conf(m) => m.write(out),
            Self::Geo(m) => m.write(out),
            Self::Asta(m) => m.write(out),
            Self::Eff(m) => m.write(out),
            Self::Die(m) => m.write(out),
            Self::Sync(m) => m.write(out),
            Self::Other(m) => m.write_to(out),
        }
    }

    /// Appends the exact wire form and `\r\n`: the way to batch one tick's lines into one
    /// write (`String`, `Vec<u8>` or `bytes::BytesMut`).
    pub fn write_line(&self, out: &mut impl WireBuf) {
        self.write_to(out);
        out.push_text("\r\n");
    }
}

impl std::fmt::Display for ServerMessage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut s = String::new();
        self.write_to(&mut s);
        f.write_str(&s)
    }
}

#[cfg(test)]
pub(crate) mod testutil {
    use super::ServerMessage;

    /// Parses a server line, checks it prints back byte for byte, returns it.
    pub(crate) fn round_trip(line: &str) -> ServerMessage {
        let m = ServerMessage::parse(line)
            .unwrap_or_else(|e| panic!("{line}: {e}"))
            .message;
        assert_eq!(m.to_string(), line, "{m:?}");
        m
    }
}
