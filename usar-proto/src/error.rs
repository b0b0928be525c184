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
