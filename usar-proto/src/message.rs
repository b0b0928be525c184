//! The generic message model: a command word and its ordered brace groups.
//!
//! The parser follows the real server's `MessageParser.uc` (protocol.md §1.3) and accepts the
//! dialects of §10. Typed messages (`crate::messages`) are built on top of it.

use crate::error::ParseError;

/// One protocol line: `KIND {Key Value} {Key Value} ...`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Message {
    /// The command or message word (`INIT`, `SEN`, ...), as written.
    pub kind: String,
    /// The brace groups in order.
    pub groups: Vec<Group>,
}

/// One `{...}` group: usually one key/value pair; UT2004 lines put several in one group
/// (`{Name F1 Range 4.4690}`).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Group {
    /// The pairs in order.
    pub pairs: Vec<Pair>,
}

/// A key and its value text.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Pair {
    /// The key, as written (matched case-insensitively).
    pub key: String,
    /// The value text, trimmed; may contain spaces (`{Location 0, 0, 0}`).
    pub value: String,
}

/// A parsed value together with the tolerated deviations from the canonical form.
#[derive(Debug, Clone, PartialEq)]
pub struct Parsed<T> {
    /// What was read.
    pub message: T,
    /// What the line did that a canonical UDK line would not (for logging).
    pub deviations: Vec<Deviation>,
}

/// A tolerated deviation from the canonical protocol form (protocol.md §10).
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum Deviation {
    /// Placeholder until the parser is complete.
    Other(String),
}

impl Message {
    /// Parses one line (without its terminator) with the real server's tolerance.
    pub fn parse(line: &str) -> Result<Parsed<Self>, ParseError> {
        let _ = line;
        todo!("generic parser")
    }

    /// The value of the first pair whose key equals `key` case-insensitively.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.groups
            .iter()
            .flat_map(|g| g.pairs.iter())
            .find(|p| p.key.eq_ignore_ascii_case(key))
            .map(|p| p.value.as_str())
    }
}

impl std::fmt::Display for Deviation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{self:?}")
    }
}
