//! The log's escaping and rate rules live in usar-proto (`usar_proto::shown`), shared by
//! every program that logs a peer's text.

pub(crate) use usar_proto::shown::{Number, Repeats, Shown};
