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
//! and UT2004 sonar readings start at each `Name` key). Unknown words, and lines of a known
//! word that do not fit its typed layout (fields missing, numbers unreadable: real servers
//! print such lines), give [`ServerMessage::Other`], which prints them back byte for byte;
//! unknown sensor types give [`SenData::Other`], CONF parts of unknown layout
//! [`ConfItem::Other`]. Only an empty line is an error.

pub mod command;
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
pub use server::*;
pub use sync::{Barrier, SYNC_WORD};

use crate::error::ParseError;
use crate::format::WireBuf;
use crate::message::{
    Deviation, INLINE_PAIRS, Message, Parsed, Raw, RawPair, groups_of, read_canonical,
};
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
    /// A line that does not fit its word's typed layout reads in the generic form
    /// ([`ServerMessage::Other`]) and prints back exactly; only an empty line fails.
    ///
    /// ```
    /// use usar_proto::{ServerMessage, Sta};
    /// let m = ServerMessage::parse("STA {Time 12.5000} {Battery 1200}").unwrap().message;
    /// let ServerMessage::Sta(Sta { battery, .. }) = m else { panic!() };
    /// assert_eq!(battery, 1200);
    /// ```
    pub fn parse(line: &str) -> Result<Parsed<Self>, ParseError> {
        Self::read(line, false)
    }

    /// Like [`ServerMessage::parse`], but a line of a known word that does not fit its typed
    /// layout is an error saying what and where (for tools that check a server's output).
    pub fn parse_strict(line: &str) -> Result<Parsed<Self>, ParseError> {
        Self::read(line, true)
    }

    fn read(line: &str, strict: bool) -> Result<Parsed<Self>, ParseError> {
        let mut devs = Vec::new();
        // Canonical lines (all the engine prints) are read into the stack.
        let mut inline = [RawPair::default(); INLINE_PAIRS];
        let general;
        let (word, pairs) = match read_canonical(line, &mut inline) {
            Some((word, n)) => (word, &inline[..n]),
            None => {
                general = Raw::parse_general(line, true, &mut devs)?;
                devs.retain(|d| *d == Deviation::GroupedPairs);
                (general.kind, &general.pairs[..])
            }
        };
        let is = |w: &str| word.eq_ignore_ascii_case(w);
        let r = |what| Reader::new(what, pairs);
        let typed: Result<Option<Self>, ParseError> = if is("NFO") {
            Nfo::read(r("nfo")).map(|m| m.map(Self::Nfo))
        } else if is("STA") {
            Sta::read(r("sta")).map(|m| Some(Self::Sta(m)))
        } else if is("SEN") {
            // A reading without its fields prints with a trailing space: only a line with one
            // may be one, so that it prints back exactly.
            Sen::read(r("sen"), line.ends_with(' ')).map(|m| Some(Self::Sen(m)))
        } else if is("CONF") {
            Conf::read(r("conf")).map(|m| m.map(Self::Conf))
        } else if is("GEO") {
            Geo::read(r("geo"), line).map(|m| m.map(Self::Geo))
        } else if is("ASTA") {
            Asta::read(r("asta")).map(|m| Some(Self::Asta(m)))
        } else if is("EFF") {
            Eff::read(r("eff")).map(|m| Some(Self::Eff(m)))
        } else if is("DIE") {
            Die::read(r("die")).map(|m| Some(Self::Die(m)))
        } else if is(SYNC_WORD) {
            Barrier::read(r("sync")).map(|m| Some(Self::Sync(m)))
        } else {
            Ok(None)
        };
        // A line of a known word that does not fit its typed layout (fields missing, a
        // number unreadable) is still a valid line: it reads in the generic form, which
        // prints it back exactly.
        let message = match typed {
            Ok(Some(typed)) => typed,
            Err(error) if strict => return Err(error),
            Ok(None) | Err(_) => {
                let mut generic = Message {
                    kind: word.to_owned(),
                    groups: groups_of(pairs),
                    verbatim: None,
                };
                if generic.to_string() != line {
                    generic.verbatim = Some(line.to_owned());
                }
                Self::Other(generic)
            }
        };
        Ok(Parsed {
            message,
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
