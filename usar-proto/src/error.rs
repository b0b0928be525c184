//! Errors at the crate edge.

/// A line that could not be read as the message it claims to be.
///
/// The message says what and where, in lower case: `sen imu: missing {Rotation ..}`,
/// `sta: bad number "x" in {Battery ..}`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct ParseError {
    /// What is wrong, lower case.
    pub message: String,
}

impl ParseError {
    /// An error with this message.
    pub fn new(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
        }
    }
}
