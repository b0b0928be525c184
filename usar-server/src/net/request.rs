//! What sessions and side servers send the simulation driver (`driver.rs`): the requests
//! the one thread that owns the `World` serves between ticks.

use std::sync::Arc;
use std::sync::atomic::AtomicUsize;

use bytes::Bytes;
use tokio::sync::{OwnedSemaphorePermit, mpsc, oneshot};
use usar_proto::Command;

use crate::sim::{ClientId, World};

/// What sessions ask of the simulation.
#[derive(Debug)]
pub(super) enum Request {
    /// A new connection; the driver answers with its id.
    Connect {
        peer: String,
        queue: mpsc::Sender<Bytes>,
        /// Bytes in `queue` not yet written to the socket (the session subtracts them).
        queued: Arc<AtomicUsize>,
        reply: oneshot::Sender<ClientId>,
    },
    /// A line read from a connection; `permit` is the session's back-pressure token, given
    /// back once the line is served.
    Line {
        client: ClientId,
        line: Line,
        permit: OwnedSemaphorePermit,
    },
    /// The connection ended.
    Disconnect { client: ClientId },
    /// Wakes the driver so that it notices the shutdown.
    Wake,
    /// A question of a side server (USARTruth, the robot monitor): run at once, between
    /// ticks, with the world as it is.
    Ask(Ask),
    /// A relay socket of the WSS on the simulated clock has news: its connections and bytes
    /// are taken at the world's current time.
    Radio,
}

/// A side server's question: a function of the world that sends its own answer.
pub(super) struct Ask(pub(super) Box<dyn FnOnce(&World) + Send>);

impl std::fmt::Debug for Ask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Ask")
    }
}

/// A client line, read.
#[derive(Debug)]
pub(super) enum Line {
    /// A command, with its text when recording.
    Command {
        command: Box<Command>,
        text: Option<String>,
    },
    /// A lockstep barrier: `SYNC {Time t}`.
    Sync { time: f64, text: Option<String> },
    /// A line that was read but could not be understood (recorded only).
    Unreadable { text: String },
    /// Makes the driver panic (tests of what happens when the simulation dies).
    #[cfg(test)]
    Crash,
}
