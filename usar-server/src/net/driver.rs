//! The simulation driver: the one thread that owns the `World`.
//!
//! Each loop turn it applies the queued requests, steps the world one tick, prints each
//! client's output of that tick into one chunk and offers it to the client's bounded queue.
//! A full queue drops that chunk for that client only (the rule for clients that do not read):
//! the world never waits for a socket.
//!
//! Pacing: at `TimeScale::Factor(k)` tick `n` is due at `anchor + n·dt/k`. When the thread
//! falls more than [`MAX_LAG`] behind (an overloaded machine) it re-anchors instead of
//! bursting to catch up, like tokio's `MissedTickBehavior::Delay`: simulated time then runs
//! slower than requested, but steps are never skipped, so results do not depend on load.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use bytes::Bytes;
use tokio::sync::{mpsc, oneshot};
use tokio_util::sync::CancellationToken;
use tracing::{debug, trace, warn};
use usar_proto::{Command, Nfo, ServerMessage};

use super::TimeScale;
use crate::sim::{ClientId, World};

/// How far behind schedule the driver may fall before it re-anchors its clock.
const MAX_LAG: Duration = Duration::from_millis(250);

/// What sessions ask of the simulation.
#[derive(Debug)]
pub(super) enum Request {
    /// A new connection; the driver answers with its id.
    Connect {
        peer: String,
        queue: mpsc::Sender<Bytes>,
        reply: oneshot::Sender<ClientId>,
    },
    /// A command read from a connection.
    Command { client: ClientId, command: Command },
    /// The connection ended.
    Disconnect { client: ClientId },
}

/// The `NFO` game-info line sent on accept.
pub(super) fn game_info(world: &World) -> Bytes {
    let nfo = ServerMessage::Nfo(Nfo::GameInfo {
        gametype: "BotDeathMatch".into(),
        level: world.level().to_owned(),
        time_limit: world.time_limit(),
    });
    let mut line = nfo.to_string();
    line.push_str("\r\n");
    Bytes::from(line)
}

/// One connected client's outbound side.
struct Client {
    peer: String,
    queue: mpsc::Sender<Bytes>,
    /// Text of this tick not yet handed to the queue.
    pending: String,
    dropped: u64,
}

impl Client {
    fn push(&mut self, message: &ServerMessage) {
        message.write_to(&mut self.pending);
        self.pending.push_str("\r\n");
    }

    fn flush(&mut self) {
        if self.pending.is_empty() {
            return;
        }
        let chunk = Bytes::from(std::mem::take(&mut self.pending));
        match self.queue.try_send(chunk) {
            Ok(()) => {}
            Err(mpsc::error::TrySendError::Full(_)) => {
                self.dropped += 1;
                if self.dropped.is_power_of_two() {
                    warn!(peer = %self.peer, dropped_ticks = self.dropped,
                        "client is not reading; dropping its output");
                }
            }
            // The session is gone; its Disconnect request is on the way.
            Err(mpsc::error::TrySendError::Closed(_)) => {}
        }
    }
}

/// Runs the world until `shutdown` is cancelled or every session and the server are gone.
pub(super) fn drive(
    mut world: World,
    mut inbox: mpsc::Receiver<Request>,
    scale: TimeScale,
    shutdown: CancellationToken,
) {
    let mut clients: BTreeMap<ClientId, Client> = BTreeMap::new();
    let mut out = Vec::new();
    let mut anchor = Instant::now();
    let mut ticks_since_anchor: u64 = 0;
    while !shutdown.is_cancelled() {
        loop {
            match inbox.try_recv() {
                Ok(request) => handle(&mut world, &mut clients, request),
                Err(mpsc::error::TryRecvError::Empty) => break,
                Err(mpsc::error::TryRecvError::Disconnected) => return,
            }
        }
        world.step(&mut out);
        for (client, message) in out.drain(..) {
            if let Some(c) = clients.get_mut(&client) {
                c.push(&message);
            }
        }
        for c in clients.values_mut() {
            c.flush();
        }
        trace!(time = world.time(), "tick");

        // Nothing to simulate for anyone: run at real time rather than spinning the CPU.
        let factor = match scale {
            TimeScale::Max if world.robot_count() > 0 => continue,
            TimeScale::Max => 1.0,
            TimeScale::Factor(k) => k,
        };
        ticks_since_anchor += 1;
        let due = anchor + Duration::from_secs_f64(ticks_since_anchor as f64 * world.dt() / factor);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        } else if now - due > MAX_LAG {
            debug!(lag_ms = (now - due).as_millis() as u64, "simulation behind schedule");
            anchor = now;
            ticks_since_anchor = 0;
        }
    }
}

fn handle(world: &mut World, clients: &mut BTreeMap<ClientId, Client>, request: Request) {
    match request {
        Request::Connect { peer, queue, reply } => {
            let id = world.connect();
            clients.insert(
                id,
                Client {
                    peer,
                    queue,
                    pending: String::new(),
                    dropped: 0,
                },
            );
            // The session may already be gone; then its Disconnect never comes, so undo.
            if reply.send(id).is_err() {
                world.disconnect(id);
                clients.remove(&id);
            }
        }
        Request::Command { client, command } => {
            let replies = world.command(client, command);
            if let Some(c) = clients.get_mut(&client) {
                for reply in &replies {
                    c.push(reply);
                }
            }
        }
        Request::Disconnect { client } => {
            world.disconnect(client);
            clients.remove(&client);
        }
    }
}
