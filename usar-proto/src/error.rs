//! Errors at the crate edge.

/// What kind of problem a [`ParseError`] is, for callers that act on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ParseErrorKind {
    /// The line is empty.
    EmptyLine,
    /// A key the message needs is absent ([`ParseError::key`] names it).
    MissingKey,
    /// A key's value cannot be read ([`ParseError::key`] names it).
    BadValue,
    /// The line's shape is wrong otherwise.
    Malformed,
}

/// A line that could not be read as the message it claims to be.
///
/// The message says what and where, in lower case: `sen imu: missing {Rotation ..}`,
/// `sta: bad number "x" in {Battery ..}`; `kind` and `key` say the same for programs.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct ParseError {
    /// What kind of problem.
    pub kind: ParseErrorKind,
    /// The key concerned, for [`ParseErrorKind::MissingKey`] and [`ParseErrorKind::BadValue`].
    pub key: Option<String>,
    /// What is wrong, lower case.
    pub message: String,
}

impl ParseError {
    /// A [`ParseErrorKind::Malformed`] error with this message.
    pub fn new(message: impl Into<String>) -> Self {
        Self {
            kind: ParseErrorKind::Malformed,
            key: None,
            message: message.into(),
        }
    }

    /// An error of `kind` about `key`.
    pub fn about(kind: ParseErrorKind, key: &str, message: impl Into<String>) -> Self {
        Self {
            kind,
            key: Some(key.to_owned()),
            message: message.into(),
        }
    }
}

/// A value that cannot be printed into a protocol line: it holds a character that would end
/// the line or its group, or start another (a control character such as CR, LF, TAB or NUL,
/// or a brace), so that a name like `UAV1\r\nGETSTARTPOSES` cannot inject a command.
///
/// The message names the command, the key and the character:
/// `INIT {Name ..}: "UAV\r\nX" holds a carriage return (U+000D); values may not hold control characters or braces`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "{command} {{{key} ..}}: {value:?} holds {what}; values may not hold control characters or braces"
)]
pub struct TextError {
    /// The command word (`INIT`).
    pub command: String,
    /// The key (`Name`), or `word` for the command word itself.
    pub key: String,
    /// The value, cut to 80 characters.
    pub value: String,
    /// The character, named (`a carriage return (U+000D)`).
    pub what: String,
}

impl TextError {
    /// Checks one text value: `Err` names its first forbidden character.
    pub fn check(command: &str, key: &str, value: &str) -> Result<(), Self> {
        let Some(c) = value
            .chars()
            .find(|c| c.is_control() || matches!(c, '{' | '}'))
        else {
            return Ok(());
        };
        let what = match c {
            '\r' => "a carriage return (U+000D)".to_owned(),
            '\n' => "a line feed (U+000A)".to_owned(),
            '\t' => "a tab (U+0009)".to_owned(),
            '\0' => "a NUL (U+0000)".to_owned(),
            '{' | '}' => format!("a brace ({c})"),
            c => format!("a control character (U+{:04X})", u32::from(c)),
        };
        let mut shown: String = value.chars().take(80).collect();
        if shown.len() < value.len() {
            shown.push('…');
        }
        Err(Self {
            command: command.to_owned(),
            key: key.to_owned(),
            value: shown,
            what,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::ParseErrorKind;
    use crate::ServerMessage;

    #[test]
    fn callers_can_match_on_the_kind_and_the_key() {
        // `parse` reads such lines in the generic form; `parse_strict` says what is wrong.
        let e = ServerMessage::parse_strict("STA {Battery 1200}").unwrap_err();
        assert_eq!(
            (e.kind, e.key.as_deref()),
            (ParseErrorKind::MissingKey, Some("Time"))
        );
        assert_eq!(e.to_string(), "sta: missing {Time ..}");
        let e = ServerMessage::parse_strict("STA {Time 1.0} {Battery x}").unwrap_err();
        assert_eq!(
            (e.kind, e.key.as_deref()),
            (ParseErrorKind::BadValue, Some("Battery"))
        );
        let e = ServerMessage::parse("   ").unwrap_err();
        assert_eq!((e.kind, e.key), (ParseErrorKind::EmptyLine, None));
    }
}
