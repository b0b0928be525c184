//! `SYNC {Time t}`: the lockstep barrier, a protocol extension of ours (docs/lockstep.md),
//! in both directions. A stock USARSim ignores the command and never sends the reply.
//!
//! * client → server ([`Command::Sync`](super::Command::Sync)): "do not step past `t`";
//! * server → client ([`ServerMessage::Sync`](super::ServerMessage::Sync)): "the world has
//!   reached `t`; every line up to it was sent before this one".

use super::line::Line;
use crate::error::ParseError;
use crate::format::WireBuf;
use crate::primitive::Time;
use crate::value::Reader;
use crate::value::time;

/// The word of the barrier message in both directions.
pub const SYNC_WORD: &str = "SYNC";

/// A lockstep barrier time: `SYNC {Time t}`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Barrier {
    /// Simulated seconds (printed with its decimals, 4 unless read otherwise).
    pub time: Time,
}

impl Barrier {
    /// A barrier at `seconds`, printed with 4 decimals like every UDK time stamp.
    pub const fn at(seconds: f64) -> Self {
        Self {
            time: Time::udk(seconds),
        }
    }

    pub(crate) fn read(r: Reader<'_, '_>) -> Result<Self, ParseError> {
        Ok(Self { time: time(&r)? })
    }

    pub(crate) fn write(&self, out: &mut impl WireBuf) {
        Line::new(out, SYNC_WORD).time(self.time);
    }
}

#[cfg(test)]
mod tests {
    use crate::{Barrier, Command, ServerMessage};

    #[test]
    fn both_directions_round_trip() {
        let reply = crate::messages::testutil::round_trip("SYNC {Time 12.5000}");
        assert_eq!(reply, ServerMessage::Sync(Barrier::at(12.5)));
        assert_eq!(reply.time(), Some(12.5));

        let command = Command::parse("sync {time 0.1}").unwrap().message;
        assert_eq!(command, Command::Sync(Barrier::at(0.1)));
        assert_eq!(command.to_string(), "SYNC {Time 0.1000}");
        assert_eq!(
            Command::parse("SYNC {Time 0.1000}").unwrap().message,
            command
        );
    }

    #[test]
    fn a_sync_without_a_time_is_not_a_barrier() {
        assert!(matches!(
            Command::parse("SYNC {Time soon}").unwrap().message,
            Command::Other(_)
        ));
        assert!(matches!(
            Command::parse("SYNC").unwrap().message,
            Command::Other(_)
        ));
        assert!(ServerMessage::parse_strict("SYNC {Foo 1}").is_err());
        // Still a valid line: the generic form, printed back as it came.
        let m = ServerMessage::parse("SYNC {Foo 1}").unwrap().message;
        assert!(matches!(m, ServerMessage::Other(_)));
        assert_eq!(m.to_string(), "SYNC {Foo 1}");
    }
}
