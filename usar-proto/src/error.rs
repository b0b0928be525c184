//! Errors at the crate edge.

/// A line that could not be read as the message it claims to be.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct ParseError {
    /// What is wrong, lower case.
    pub message: String,
}
