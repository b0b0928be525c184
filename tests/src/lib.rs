//! End-to-end tests live in `tests/`; this library is empty.

/// The code of docs/ucc.md (its recipe for an agent of your own), compiled by
/// `cargo test --doc` so that it stays right.
#[cfg(doctest)]
#[doc = include_str!("../../docs/ucc.md")]
pub struct UccDocs;
