//! The simulation driver: the one thread that owns the `World`.
//!
//! Each loop turn it applies the queued requests, steps the world one tick, prints each
//! client's output of that tick into one chunk and offers it to the client's bounded queue.
//! A full queue drops that chunk for that client only (the rule for clients that do not read):
//! the world never waits for a socket.
//!
//! Time: simulated time runs only while the world holds at least one robot (an empty world
//! has nothing to show, and a run that starts from an empty server starts from the same
//! time). At `TimeScale::Factor(k)` tick `n` is due at `anchor + n·dt/k`; when the thread
//! falls more than [`MAX_LAG`] behind (an overloaded machine) it re-anchors instead of
//! bursting to catch up, like tokio's `MissedTickBehavior::Delay`: simulated time then runs
//! slower than requested, but steps are never skipped, so results do not depend on load.
//!
//! Lockstep (docs/lockstep.md): a client that sends `SYNC {Time t}` joins the barrier; the
//! world does not step past `t` until that client syncs again, and the client is answered
//! `SYNC {Time now}` once the world has reached `t`. Clients that never sync are never
//! waited for.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use bytes::{Bytes, BytesMut};
use tokio::sync::{mpsc, oneshot};
use tokio_util::sync::CancellationToken;
use tracing::{debug, trace, warn};
use usar_proto::record::{Direction, RecordWriter};
use usar_proto::{Barrier, Command, Nfo, ServerMessage};

use super::TimeScale;
use crate::sim::{ClientId, World};

/// How far behind schedule the driver may fall before it re-anchors its clock.
const MAX_LAG: Duration = Duration::from_millis(250);

/// Slack when comparing simulated times (ticks are multiples of dt, barriers are decimals).
const TIME_EPSILON: f64 = 1e-6;

/// What sessions ask of the simulation.
#[derive(Debug)]
pub(super) enum Request {
    /// A new connection; the driver answers with its id.
    Connect {
        peer: String,
        queue: mpsc::Sender<Bytes>,
        reply: oneshot::Sender<ClientId>,
    },
    /// A command read from a connection, with its text when recording.
    Command {
        client: ClientId,
        command: Box<Command>,
        line: Option<String>,
    },
    /// A lockstep barrier: `SYNC {Time t}`.
    Sync {
        client: ClientId,
        time: f64,
        line: Option<String>,
    },
    /// A line that was read but could not be understood (recorded only).
    Unreadable { client: ClientId, line: String },
    /// The connection ended.
    Disconnect { client: ClientId },
    /// Wakes the driver so that it notices the shutdown.
    Wake,
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

/// The lockstep reply `SYNC {Time t}`.
fn sync_reply(time: f64) -> ServerMessage {
    ServerMessage::Sync(Barrier::at(time))
}

/// One connected client's outbound side.
struct Client {
    peer: String,
    queue: mpsc::Sender<Bytes>,
    /// Text of this tick not yet handed to the queue.
    pending: BytesMut,
    dropped: u64,
    /// Lockstep target time, once the client has joined the barrier.
    barrier: Option<f64>,
    /// Whether the client has been told that the world reached its barrier.
    answered: bool,
    record: Option<RecordWriter>,
}

impl Client {
    fn push(&mut self, message: &ServerMessage, time: f64) {
        let start = self.pending.len();
        message.write_to(&mut self.pending);
        if let Some(file) = &mut self.record {
            let line = String::from_utf8_lossy(&self.pending[start..]);
            let _ = file.write_at(time, Direction::Server, &line);
        }
        self.pending.extend_from_slice(b"\r\n");
    }

    fn flush(&mut self) {
        if self.pending.is_empty() {
            return;
        }
        let chunk = self.pending.split().freeze();
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

    /// Whether the next tick would take the world past this client's barrier.
    fn holds_at(&self, time: f64, dt: f64) -> bool {
        self.barrier.is_some_and(|b| time + dt > b + TIME_EPSILON)
    }
}

/// The driver's state: the world and the clients' outbound sides.
pub(super) struct Driver {
    world: World,
    clients: BTreeMap<ClientId, Client>,
    record_dir: Option<PathBuf>,
    connections: u64,
}

impl Driver {
    pub(super) fn new(world: World, record_dir: Option<PathBuf>) -> Self {
        Self {
            world,
            clients: BTreeMap::new(),
            record_dir,
            connections: 0,
        }
    }

    /// Runs the world until `shutdown` is cancelled or every request sender is gone.
    pub(super) fn run(
        mut self,
        mut inbox: mpsc::Receiver<Request>,
        scale: TimeScale,
        shutdown: CancellationToken,
    ) {
        let mut out = Vec::new();
        let mut anchor = Instant::now();
        let mut ticks_since_anchor: u64 = 0;
        loop {
            // Apply what is queued; wait for requests while the world may not step.
            loop {
                let request = match inbox.try_recv() {
                    Ok(request) => request,
                    Err(mpsc::error::TryRecvError::Empty) if self.may_step() => break,
                    Err(mpsc::error::TryRecvError::Empty) => {
                        self.flush_all();
                        match inbox.blocking_recv() {
                            Some(request) => {
                                // Time stood still: do not burst to catch up afterwards.
                                anchor = Instant::now();
                                ticks_since_anchor = 0;
                                request
                            }
                            None => return,
                        }
                    }
                    Err(mpsc::error::TryRecvError::Disconnected) => return,
                };
                if shutdown.is_cancelled() {
                    return;
                }
                self.handle(request);
            }
            if shutdown.is_cancelled() {
                return;
            }

            self.world.step(&mut out);
            let time = self.world.time();
            for (client, message) in out.drain(..) {
                if let Some(c) = self.clients.get_mut(&client) {
                    c.push(&message, time);
                }
            }
            self.answer_barriers();
            self.flush_all();
            trace!(time, "tick");

            let factor = match scale {
                TimeScale::Max => continue,
                TimeScale::Factor(k) => k,
            };
            ticks_since_anchor += 1;
            let due = anchor
                + Duration::from_secs_f64(ticks_since_anchor as f64 * self.world.dt() / factor);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            } else if now - due > MAX_LAG {
                debug!(
                    lag_ms = (now - due).as_millis() as u64,
                    "simulation behind schedule"
                );
                anchor = now;
                ticks_since_anchor = 0;
            }
        }
    }

    /// The world steps only when it holds a robot and no lockstep client holds it back.
    fn may_step(&self) -> bool {
        let (time, dt) = (self.world.time(), self.world.dt());
        self.world.robot_count() > 0 && !self.clients.values().any(|c| c.holds_at(time, dt))
    }

    fn flush_all(&mut self) {
        for c in self.clients.values_mut() {
            c.flush();
        }
    }

    /// Tells each lockstep client whose barrier the world has reached.
    fn answer_barriers(&mut self) {
        let (time, dt) = (self.world.time(), self.world.dt());
        for c in self.clients.values_mut() {
            if !c.answered && c.holds_at(time, dt) {
                c.answered = true;
                c.push(&sync_reply(time), time);
            }
        }
    }

    fn open_record(&mut self) -> Option<RecordWriter> {
        let dir = self.record_dir.as_ref()?;
        let path = dir.join(format!("connection-{:04}.usarlog", self.connections));
        RecordWriter::create(&path)
            .inspect_err(
                |error| warn!(path = %path.display(), %error, "cannot record this connection"),
            )
            .ok()
    }

    fn record_client_line(&mut self, client: ClientId, line: Option<&str>) {
        let time = self.world.time();
        if let (Some(c), Some(line)) = (self.clients.get_mut(&client), line)
            && let Some(file) = &mut c.record
        {
            let _ = file.write_at(time, Direction::Client, line);
        }
    }

    fn handle(&mut self, request: Request) {
        match request {
            Request::Connect { peer, queue, reply } => {
                self.connections += 1;
                let mut record = self.open_record();
                if let Some(file) = &mut record {
                    let nfo = game_info(&self.world);
                    let text = String::from_utf8_lossy(&nfo);
                    let _ = file.write_at(self.world.time(), Direction::Server, text.trim_end());
                }
                let id = self.world.connect();
                debug!(%peer, client = ?id, "joined the simulation");
                self.clients.insert(
                    id,
                    Client {
                        peer,
                        queue,
                        pending: BytesMut::new(),
                        dropped: 0,
                        barrier: None,
                        answered: false,
                        record,
                    },
                );
                // The session may already be gone; then its Disconnect never comes, so undo.
                if reply.send(id).is_err() {
                    self.world.disconnect(id);
                    self.clients.remove(&id);
                }
            }
            Request::Command {
                client,
                command,
                line,
            } => {
                self.record_client_line(client, line.as_deref());
                let replies = self.world.command(client, *command);
                let time = self.world.time();
                if let Some(c) = self.clients.get_mut(&client) {
                    for reply in &replies {
                        c.push(reply, time);
                    }
                }
            }
            Request::Sync { client, time, line } => {
                self.record_client_line(client, line.as_deref());
                let (now, dt) = (self.world.time(), self.world.dt());
                if let Some(c) = self.clients.get_mut(&client) {
                    c.barrier = Some(time);
                    c.answered = false;
                    if c.holds_at(now, dt) {
                        c.answered = true;
                        c.push(&sync_reply(now), now);
                    }
                }
            }
            Request::Unreadable { client, line } => self.record_client_line(client, Some(&line)),
            Request::Disconnect { client } => {
                self.world.disconnect(client);
                if let Some(mut c) = self.clients.remove(&client)
                    && let Some(file) = &mut c.record
                {
                    let _ = file.flush();
                }
            }
            Request::Wake => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use usar_proto::{Sta, StaLayout, Time};

    fn sta(t: f64) -> ServerMessage {
        ServerMessage::Sta(Sta {
            time: Time::udk(t),
            battery: 1200,
            vehicle: None,
            layout: StaLayout::Udk,
        })
    }

    #[test]
    fn a_full_queue_drops_whole_ticks_without_waiting() {
        let (queue, mut output) = mpsc::channel(2);
        let mut client = Client {
            peer: "test".into(),
            queue,
            pending: BytesMut::new(),
            dropped: 0,
            barrier: None,
            answered: false,
            record: None,
        };
        for tick in 1..=5 {
            client.push(&sta(f64::from(tick) / 10.0), 0.0);
            client.push(&sta(f64::from(tick) / 10.0 + 0.05), 0.0);
            client.flush(); // never blocks
        }
        assert_eq!(client.dropped, 3);
        // The queue holds the first two ticks, each whole, in one chunk.
        let first = output.try_recv().unwrap();
        assert_eq!(
            &first[..],
            b"STA {Time 0.1000} {Battery 1200}\r\nSTA {Time 0.1500} {Battery 1200}\r\n"
        );
        assert!(output.try_recv().unwrap().starts_with(b"STA {Time 0.2000}"));
        assert!(output.try_recv().is_err());
    }

    #[test]
    fn barriers_hold_the_world_until_the_next_sync() {
        let client = |barrier| Client {
            peer: "test".into(),
            queue: mpsc::channel(1).0,
            pending: BytesMut::new(),
            dropped: 0,
            barrier,
            answered: false,
            record: None,
        };
        let dt = 0.005;
        assert!(
            !client(None).holds_at(5.0, dt),
            "never waited for without SYNC"
        );
        assert!(!client(Some(0.1)).holds_at(0.09, dt));
        assert!(client(Some(0.1)).holds_at(0.1, dt), "stops at the barrier");
        assert!(
            client(Some(0.1)).holds_at(0.0975, dt),
            "no step past the barrier"
        );
    }
}
