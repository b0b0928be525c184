//! Typed messages: client commands and server messages, each parsed from and printed to the
//! exact wire form.

pub mod command;
pub mod common;
pub mod server;

pub use command::*;
pub use common::*;
pub use server::*;

use crate::error::ParseError;
use crate::message::Parsed;

impl Command {
    /// Parses a client line leniently, as the UDK server would read it.
    pub fn parse(line: &str) -> Result<Parsed<Self>, ParseError> {
        let _ = line;
        todo!()
    }
}

impl ServerMessage {
    /// Parses a server line (any generation's layout).
    pub fn parse(line: &str) -> Result<Parsed<Self>, ParseError> {
        let _ = line;
        todo!()
    }

    /// Appends the exact wire form, without the line terminator.
    pub fn write_to(&self, out: &mut String) {
        let _ = out;
        todo!()
    }
}

impl std::fmt::Display for ServerMessage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut s = String::new();
        self.write_to(&mut s);
        f.write_str(&s)
    }
}

impl Command {
    /// Appends the wire form, without the line terminator.
    pub fn write_to(&self, out: &mut String) {
        let _ = out;
        todo!()
    }
}

impl std::fmt::Display for Command {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut s = String::new();
        self.write_to(&mut s);
        f.write_str(&s)
    }
}
