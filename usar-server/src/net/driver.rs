//! The simulation driver: the one thread that owns the `World`.
//!
//! Each loop turn it applies the queued requests, steps the world one tick, prints each
//! client's output of that tick into one chunk and offers it to the client's bounded queue.
//! At a real-time factor a full queue drops that chunk for that client only (the rule for
//! clients that do not read): the world never waits for a socket.
//!
//! At `TimeScale::Max` nothing is dropped: the world paces itself to its slowest reader. A
//! client's output is gathered over ticks and handed over in chunks of about
//! [`GATHER_BYTES`] (or after [`GATHER_TIME`] of wall time, and always before the driver
//! pauses); when a client's queue has no room, the driver waits until its session has written
//! some. A client that has made no room for `reader_timeout` (wall clock) is left behind: its
//! output is dropped by the real-time rule until its queue has room again, and the world
//! goes on at full speed for the others.
//!
//! Time: simulated time runs only while the world holds at least one robot (an empty world
//! has nothing to show, and a run that starts from an empty server starts from the same
//! time). At `TimeScale::Factor(k)` tick `n` is due at `anchor + n·dt/k`; when the thread
//! falls more than [`MAX_LAG`] behind (an overloaded machine) it re-anchors instead of
//! bursting to catch up, like tokio's `MissedTickBehavior::Delay`: simulated time then runs
//! slower than requested, but steps are never skipped, so results do not depend on load.
//!
//! Fairness: each loop turn serves at most `requests_per_tick` lines of each client (in
//! connection order), so the world steps on time whatever one client sends; lines beyond the
//! budget wait in that client's backlog, which its session keeps short by not reading the
//! socket (TCP back-pressure). A client's output is bounded twice: `client_queue` ticks and
//! `client_buffer` bytes; past either, whole ticks are dropped for that client and counted.
//!
//! Lockstep (docs/lockstep.md, only with `ServerConfig::lockstep`): a client that sends
//! `SYNC {Time t}` joins the barrier; the world does not step past `t` until that client
//! syncs again, and the client is answered `SYNC {Time now}` once the world has reached `t`.
//! Clients that never sync are never waited for, and a client that does not send its next
//! `SYNC` within `lockstep_timeout` (wall clock) of its answer leaves the barrier.

use std::collections::{BTreeMap, VecDeque};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::time::{Duration, Instant};

use bytes::Bytes;
use tokio::sync::{OwnedSemaphorePermit, mpsc};
use tokio_util::sync::CancellationToken;
use tracing::{debug, trace, warn};
use usar_proto::record::Direction;
use usar_proto::{Barrier, Command, Init, ServerMessage};

use super::TimeScale;
use super::recording::Recording;
use super::request::{Line, Request};
use crate::sim::{ClientId, Printed, World};

/// How far behind schedule the driver may fall before it re-anchors its clock.
const MAX_LAG: Duration = Duration::from_millis(250);

/// Slack when comparing simulated times (ticks are multiples of dt, barriers are decimals).
const TIME_EPSILON: f64 = 1e-6;

/// The longest the driver sleeps or waits in one go (it also bounds any computed wait).
const MAX_WAIT: Duration = Duration::from_secs(3600);

/// At `TimeScale::Max`, a client's output is handed to its session once this many bytes
/// have gathered...
const GATHER_BYTES: usize = 32 * 1024;

/// ... or once this much wall time has passed since the last hand-over.
const GATHER_TIME: Duration = Duration::from_millis(1);

/// How long a client's first INIT waits for its place when another robot is there: the
/// robot of a connection that has just closed is removed when its session notices the close,
/// which may come after the next connection's INIT (a client that respawns between runs).
/// The INIT is tried again whenever a robot leaves; the client's later lines wait behind it.
const SPAWN_GRACE: Duration = Duration::from_secs(2);

/// The wall-clock window over which the lockstep barrier's share of the time is measured.
const SHARE_WINDOW: Duration = Duration::from_secs(10);

/// A lockstep member that joined the barrier less than this long ago is *new*: while
/// anyone else is connected, the world waits for new members within a budget, so a client
/// that reconnects again and again, each time a new member, cannot hold the others' world
/// (issue #56). What the budget pays for: the whole wait for a new member's first step (up
/// to its second `SYNC`), and the part of any later step's wait past [`FREE_STEP`] (an
/// agent that thinks a few milliseconds a step never touches it, at any time scale). The
/// budget is a bucket of [`NEW_BURST`] of wall time, refilled at
/// `Settings::lockstep_join_share` seconds per second; once empty, the world does not wait
/// for new members until it is full again.
const PROBATION: Duration = SHARE_WINDOW;

/// The most wall time the world waits for new members in one go (see [`PROBATION`]).
const NEW_BURST: Duration = Duration::from_millis(100);

/// How long a new member's step after its first holds the world before its budget pays.
const FREE_STEP: Duration = Duration::from_millis(25);

/// Loop turns between checks of the shutdown token when no request arrives (a request, such
/// as the `Wake` sent on shutdown, makes the driver check at once).
const SHUTDOWN_CHECK_TURNS: u32 = 256;

/// The driver's fixed settings.
#[derive(Debug, Clone)]
pub(super) struct Settings {
    pub(super) scale: TimeScale,
    pub(super) record_dir: Option<PathBuf>,
    pub(super) requests_per_tick: usize,
    pub(super) client_buffer: usize,
    pub(super) lockstep_timeout: Duration,
    /// Clients in the lockstep barrier at once; later ones' `SYNC`s are ignored.
    pub(super) lockstep_clients: usize,
    /// The share of wall time the barrier may hold the world while clients outside it wait.
    pub(super) lockstep_share: f64,
    /// While anyone else is connected: the rate (seconds per second) at which the budget of
    /// the members that joined less than [`PROBATION`] ago refills (1: no limit).
    pub(super) lockstep_join_share: f64,
    /// At `TimeScale::Max`: how long the world waits for a client whose queue has no room.
    pub(super) reader_timeout: Duration,
}

/// The `NFO` game-info line sent on accept.
pub(super) fn game_info(world: &World) -> Bytes {
    let mut line = world.game_info().to_string();
    line.push_str("\r\n");
    Bytes::from(line)
}

/// The lockstep reply `SYNC {Time t}`.
fn sync_reply(time: f64) -> ServerMessage {
    ServerMessage::Sync(Barrier::at(time))
}

/// A duration of `seconds`, whatever the number (NaN and negatives are 0, huge is capped).
pub(crate) fn wait_of(seconds: f64) -> Duration {
    if seconds > 0.0 {
        Duration::try_from_secs_f64(seconds)
            .unwrap_or(MAX_WAIT)
            .min(MAX_WAIT)
    } else {
        Duration::ZERO
    }
}

/// One connected client's outbound side.
struct Client {
    peer: String,
    queue: mpsc::Sender<Bytes>,
    /// Bytes handed to `queue` and not yet written.
    queued: Arc<AtomicUsize>,
    /// The most bytes `queued` may reach.
    buffer: usize,
    /// Text of this tick not yet handed to the queue.
    pending: Vec<u8>,
    dropped: u64,
    /// At `TimeScale::Max`: made no room within the reader timeout, so not waited for (its
    /// output is dropped) until its queue has room again.
    stalled: bool,
    /// Lines read and not yet served (at most the session's backlog).
    backlog: VecDeque<(Line, OwnedSemaphorePermit)>,
    /// Lockstep target time, once the client has joined the barrier.
    barrier: Option<f64>,
    /// When the client joined the barrier (it is new for [`PROBATION`] after that)...
    joined_at: Option<Instant>,
    /// ... and the `SYNC`s it sent since (1: its first step).
    syncs: u32,
    /// Whether the client has been told that the world reached its barrier.
    answered: bool,
    /// When the world reached the barrier (the lockstep timeout runs from then).
    answered_at: Option<Instant>,
    record: Option<Recording>,
    /// Whether an INIT of this client has spawned a robot.
    spawned: bool,
    /// Wall time the world waited for this client's next `SYNC` in the current window.
    held: Duration,
    /// Whether this client's `SYNC`s are refused (the barrier was full, or it held the
    /// world too long): said once in the log.
    sync_refused: bool,
    /// Left the barrier for holding the world too long: its `SYNC`s are ignored from then on.
    expelled: bool,
    /// A first INIT whose place was taken, tried again when a robot leaves until the
    /// deadline; the client's backlog waits behind it.
    parked: Option<(Init, Instant)>,
}

impl Client {
    fn new(peer: String, queue: mpsc::Sender<Bytes>, queued: Arc<AtomicUsize>) -> Self {
        Self {
            peer,
            queue,
            queued,
            buffer: usize::MAX,
            pending: Vec::new(),
            dropped: 0,
            stalled: false,
            backlog: VecDeque::new(),
            barrier: None,
            joined_at: None,
            syncs: 0,
            answered: false,
            answered_at: None,
            record: None,
            spawned: false,
            parked: None,
            held: Duration::ZERO,
            sync_refused: false,
            expelled: false,
        }
    }

    fn push(&mut self, message: &ServerMessage, time: f64) {
        let start = self.pending.len();
        message.write_to(&mut self.pending);
        if let Some(file) = &mut self.record {
            let line = String::from_utf8_lossy(&self.pending[start..]);
            file.write(time, Direction::Server, &line);
        }
        self.pending.extend_from_slice(b"\r\n");
    }

    /// Appends lines the world printed (each followed by CRLF).
    fn push_printed(&mut self, lines: &[u8], time: f64) {
        self.pending.extend_from_slice(lines);
        if let Some(file) = &mut self.record {
            let lines = lines.strip_suffix(b"\r\n").unwrap_or(lines);
            for line in lines.split(|&b| b == b'\n') {
                let line = line.strip_suffix(b"\r").unwrap_or(line);
                file.write(time, Direction::Server, &String::from_utf8_lossy(line));
            }
        }
    }

    /// Whether the queue takes `len` more bytes now: a free slot, and the bytes within the
    /// buffer (a chunk larger than the whole buffer goes when nothing else is queued).
    fn has_room(&self, len: usize) -> bool {
        let queued = self.queued.load(Ordering::SeqCst);
        (queued == 0 || queued.saturating_add(len) <= self.buffer) && self.queue.capacity() > 0
    }

    /// Hands the pending output to the queue as one chunk. Without room it is dropped and
    /// counted, unless `pace` (`TimeScale::Max`) and the client is not stalled: then it stays
    /// pending and `true` says that the driver should wait for this client.
    fn flush(&mut self, pace: bool) -> bool {
        if self.pending.is_empty() {
            return false;
        }
        let len = self.pending.len();
        if self.has_room(len) {
            self.stalled = false;
            self.queued.fetch_add(len, Ordering::SeqCst);
            // The driver is the only sender and saw a free slot: this fails only when the
            // session is gone, and then its Disconnect request is on the way.
            let chunk = std::mem::replace(&mut self.pending, Vec::with_capacity(len));
            let _ = self.queue.try_send(Bytes::from(chunk));
            return false;
        }
        if pace && !self.stalled && !self.queue.is_closed() {
            return true;
        }
        self.pending.clear();
        self.dropped += 1;
        if self.dropped.is_power_of_two() {
            warn!(peer = %self.peer, dropped_chunks = self.dropped,
                "client is not reading; dropping its output");
        }
        false
    }

    /// Whether the next tick would take the world past this client's barrier.
    fn holds_at(&self, time: f64, dt: f64) -> bool {
        self.barrier.is_some_and(|b| time + dt > b + TIME_EPSILON)
    }

    /// Whether the client joined the barrier less than [`PROBATION`] before `now`.
    fn is_new(&self, now: Instant) -> bool {
        self.joined_at
            .is_some_and(|at| now.saturating_duration_since(at) < PROBATION)
    }

    /// Leaves the barrier (the caller counts it out of `joined`).
    fn leave_barrier(&mut self) {
        self.barrier = None;
        self.answered_at = None;
        self.joined_at = None;
    }
}

/// The driver's state: the world and the clients' outbound sides.
pub(super) struct Driver {
    world: World,
    clients: BTreeMap<ClientId, Client>,
    settings: Settings,
    connections: u64,
    /// Lines in all clients' backlogs (none: nothing to serve, no scan).
    waiting: usize,
    /// Clients that have joined the lockstep barrier (none: no barrier scans).
    joined: usize,
    /// Set by the driver when it waits for a client's queue to have room; a session that
    /// has written output clears it and sends `Request::Wake`.
    wants_room: Arc<AtomicBool>,
    /// When output was last handed to the queues (gathering at `TimeScale::Max`).
    last_flush: Instant,
    /// Recording files that could not be created or written to the end.
    incomplete: Vec<PathBuf>,
    /// Clients with a parked INIT (none: no scans).
    parked: usize,
    /// Start of the current window of the barrier's share, and the time it held the world.
    window: (Instant, Duration),
    /// What is left of new members' budget ([`PROBATION`]), as of `new_refilled`...
    new_tokens: Duration,
    new_refilled: Instant,
    /// ... and, once it ran out, until when new members do not hold the world (their
    /// `SYNC`s are answered when the world reaches their time): when it is full again.
    new_spent_until: Option<Instant>,
    /// The image server's captures (`None`: no image server).
    capture: Option<super::image::Capture>,
    /// The WSS on the simulated clock (`None`: none, or on the wall clock).
    radio: Option<super::wss::Clock>,
    /// A lockstep client was answered at the current time: the radio takes what it wrote
    /// before its next `SYNC` before the world steps on.
    radio_due: bool,
}

impl Driver {
    pub(super) fn new(
        world: World,
        settings: Settings,
        wants_room: Arc<AtomicBool>,
        capture: Option<super::image::Capture>,
        radio: Option<super::wss::Clock>,
    ) -> Self {
        Self {
            world,
            clients: BTreeMap::new(),
            settings,
            connections: 0,
            waiting: 0,
            joined: 0,
            wants_room,
            last_flush: Instant::now(),
            incomplete: Vec::new(),
            parked: 0,
            window: (Instant::now(), Duration::ZERO),
            new_tokens: NEW_BURST,
            new_refilled: Instant::now(),
            new_spent_until: None,
            capture,
            radio,
            radio_due: false,
        }
    }

    /// Runs the world until `shutdown` is cancelled or every request sender is gone; then
    /// writes the recordings out and returns the files that are incomplete (a write error).
    pub(super) fn run(
        mut self,
        inbox: Receiver<Request>,
        shutdown: CancellationToken,
    ) -> Vec<PathBuf> {
        self.run_world(inbox, shutdown);
        let ids: Vec<ClientId> = self.clients.keys().copied().collect();
        for id in ids {
            self.close_record(id);
        }
        self.incomplete
    }

    fn run_world(&mut self, inbox: Receiver<Request>, shutdown: CancellationToken) {
        let pace = self.settings.scale == TimeScale::Max;
        let mut out = Printed::default();
        let mut anchor = Instant::now();
        let mut ticks_since_anchor: u64 = 0;
        let (mut turns, mut heard) = (0u32, false);
        loop {
            // Take what is queued; serve each client's share; wait while the world may not
            // step and nothing is waiting.
            let served = loop {
                loop {
                    match inbox.try_recv() {
                        Ok(request) => {
                            self.take(request);
                            heard = true;
                        }
                        Err(TryRecvError::Empty) => break,
                        Err(TryRecvError::Disconnected) => return,
                    }
                }
                turns = turns.wrapping_add(1);
                if heard || turns.is_multiple_of(SHUTDOWN_CHECK_TURNS) {
                    heard = false;
                    if shutdown.is_cancelled() {
                        return;
                    }
                }
                let served = self.serve_backlogs();
                if self.may_step() {
                    break served;
                }
                // The world stands still (a barrier, no robot): frames asked for now show it
                // as it is.
                if let Some(capture) = &mut self.capture {
                    capture.poll(&self.world, false);
                }
                self.release_stuck_barriers();
                if served > 0 || self.may_step() {
                    continue;
                }
                if !self.flush_all(&inbox, &shutdown) {
                    return;
                }
                let waited = Instant::now();
                let request = match self.next_deadline() {
                    None => inbox.recv().map_err(|_| RecvTimeoutError::Disconnected),
                    Some(deadline) => {
                        inbox.recv_timeout(deadline.saturating_duration_since(Instant::now()))
                    }
                };
                // A share of 1 is the rule off (in-process servers): nothing to count, and no
                // walk over every client per message while the barrier waits.
                if self.joined > 0
                    && (self.settings.lockstep_share < 1.0
                        || self.settings.lockstep_join_share < 1.0)
                {
                    self.note_held(waited.elapsed());
                }
                match request {
                    Ok(request) => {
                        self.take(request);
                        heard = true;
                    }
                    Err(RecvTimeoutError::Timeout) => {}
                    Err(RecvTimeoutError::Disconnected) => return,
                }
                // Time stood still: do not burst to catch up afterwards.
                anchor = Instant::now();
                ticks_since_anchor = 0;
            };

            if let Some(radio) = &self.radio
                && std::mem::take(&mut self.radio_due)
            {
                // What the lockstep clients wrote before their SYNC: taken at this time.
                radio.take();
            }
            self.world.step_printed(&mut out);
            if let Some(capture) = &mut self.capture {
                capture.poll(&self.world, true);
            }
            if let Some(radio) = &mut self.radio {
                radio.stepped(&self.world);
            }
            let time = self.world.time();
            let printed = !out.is_empty();
            for (client, lines) in out.robots() {
                if let Some(c) = self.clients.get_mut(&client) {
                    c.push_printed(lines, time);
                }
            }
            if self.joined > 0 {
                self.answer_barriers();
            }
            if (!pace || ((printed || served > 0) && self.gathered()))
                && !self.flush_all(&inbox, &shutdown)
            {
                return;
            }
            trace!(time, "tick");

            let factor = match self.settings.scale {
                TimeScale::Max => continue,
                TimeScale::Factor(k) => k,
            };
            ticks_since_anchor += 1;
            let offset = wait_of(ticks_since_anchor as f64 * self.world.dt() / factor);
            let due = anchor.checked_add(offset).unwrap_or(anchor);
            let now = Instant::now();
            if due > now {
                std::thread::sleep((due - now).min(MAX_WAIT));
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

    /// At `TimeScale::Max`: whether enough output has gathered (or waited long enough) to be
    /// handed to the sessions.
    fn gathered(&self) -> bool {
        self.last_flush.elapsed() >= GATHER_TIME
            || self
                .clients
                .values()
                .any(|c| c.pending.len() >= GATHER_BYTES)
    }

    /// Files a request: connection changes at once, lines into the client's backlog.
    fn take(&mut self, request: Request) {
        match request {
            Request::Line {
                client,
                line,
                permit,
            } => match self.clients.get_mut(&client) {
                Some(c) => {
                    c.backlog.push_back((line, permit));
                    self.waiting += 1;
                }
                None => drop(permit),
            },
            other => self.handle(other),
        }
    }

    /// Serves up to `requests_per_tick` waiting lines of each client; returns how many.
    fn serve_backlogs(&mut self) -> usize {
        if self.waiting == 0 {
            return 0;
        }
        let ids: Vec<ClientId> = self.clients.keys().copied().collect();
        let mut served = 0;
        for id in ids {
            if self.parked > 0 && self.still_parked(id) {
                continue;
            }
            for _ in 0..self.settings.requests_per_tick {
                if self.parked > 0 && self.still_parked(id) {
                    break;
                }
                let Some((line, permit)) = self
                    .clients
                    .get_mut(&id)
                    .and_then(|c| c.backlog.pop_front())
                else {
                    break;
                };
                self.waiting -= 1;
                self.serve(id, line);
                drop(permit);
                served += 1;
            }
        }
        served
    }

    /// Whether the client's INIT is parked and its deadline not reached (a parked INIT past
    /// its deadline is given up: the spawn failed, as logged when it was first tried).
    fn still_parked(&mut self, id: ClientId) -> bool {
        let Some(c) = self.clients.get_mut(&id) else {
            return false;
        };
        match &c.parked {
            Some((_, deadline)) if Instant::now() < *deadline => true,
            Some(_) => {
                debug!(peer = %c.peer, "INIT gave up waiting for its place");
                c.parked = None;
                self.parked -= 1;
                false
            }
            None => false,
        }
    }

    /// Applies an INIT; `true` if it spawned a robot.
    fn init(&mut self, client: ClientId, init: Init) -> bool {
        let before = self.world.robot_count();
        self.world.command(client, Command::Init(init));
        let spawned = self.world.robot_count() > before;
        if spawned && let Some(c) = self.clients.get_mut(&client) {
            c.spawned = true;
        }
        spawned
    }

    /// Tries the parked INITs again (a robot has left).
    fn retry_parked(&mut self) {
        if self.parked == 0 {
            return;
        }
        let ids: Vec<ClientId> = self.clients.keys().copied().collect();
        for id in ids {
            let Some((init, _)) = self.clients.get(&id).and_then(|c| c.parked.clone()) else {
                continue;
            };
            if self.init(id, init)
                && let Some(c) = self.clients.get_mut(&id)
            {
                c.parked = None;
                self.parked -= 1;
            }
        }
    }

    /// When the driver must look again without a request: a lockstep client runs out of
    /// time, or a parked INIT does.
    fn next_deadline(&self) -> Option<Instant> {
        let parked = (self.parked > 0)
            .then(|| {
                self.clients
                    .values()
                    .filter_map(|c| c.parked.as_ref().map(|p| p.1))
                    .min()
            })
            .flatten();
        [self.barrier_deadline(), parked, self.new_budget_end()]
            .into_iter()
            .flatten()
            .min()
    }

    /// Whether the world waits for this client: it holds the world, and it is not a new
    /// member while the new members' budget is spent.
    fn waits_for(&self, c: &Client, time: f64, dt: f64) -> bool {
        c.holds_at(time, dt)
            && !(self.new_spent_until.is_some() && {
                let now = Instant::now();
                c.is_new(now) && self.new_spent_until.is_some_and(|until| now < until)
            })
    }

    /// The world steps only when it holds a robot and no lockstep client holds it back.
    fn may_step(&self) -> bool {
        let (time, dt) = (self.world.time(), self.world.dt());
        self.world.robot_count() > 0
            && (self.joined == 0 || !self.clients.values().any(|c| self.waits_for(c, time, dt)))
    }

    /// When the earliest lockstep client that holds the world runs out of time.
    fn barrier_deadline(&self) -> Option<Instant> {
        let (time, dt) = (self.world.time(), self.world.dt());
        self.clients
            .values()
            .filter(|c| self.waits_for(c, time, dt))
            .filter_map(|c| c.answered_at)
            .min()
            .map(|at| at.checked_add(self.settings.lockstep_timeout).unwrap_or(at))
    }

    /// Whether, at `now`, the world waits only for new members while someone else (an
    /// established member, or a client outside the barrier) is connected; if so, `each` is
    /// told, for each new member holding it, from when its wait is paid by the budget
    /// (`None`: all of it, its first step; see [`PROBATION`]).
    fn new_holds(&self, now: Instant, mut each: impl FnMut(Option<Instant>)) -> bool {
        let (time, dt) = (self.world.time(), self.world.dt());
        let holding = || self.clients.values().filter(|c| c.holds_at(time, dt));
        if holding().any(|c| !c.is_new(now))
            || holding().next().is_none()
            || self.clients.values().all(|c| c.is_new(now))
        {
            return false;
        }
        for c in holding() {
            each(match c.answered_at {
                Some(at) if c.syncs > 1 => Some(at + FREE_STEP),
                _ => None,
            });
        }
        true
    }

    /// While the world waits only for new members: when their budget runs out.
    fn new_budget_end(&self) -> Option<Instant> {
        if self.joined == 0 || self.settings.lockstep_join_share >= 1.0 {
            return None;
        }
        let now = Instant::now();
        if let Some(until) = self.new_spent_until {
            // The world does not wait for new members until then, so it may step then.
            return (now < until).then_some(until);
        }
        let mut end: Option<Instant> = None;
        let tokens = self.new_tokens;
        self.new_holds(now, |from| {
            let at = from.map_or(now, |from| from.max(now)) + tokens;
            end = Some(end.map_or(at, |end| end.min(at)));
        });
        end
    }

    /// Counts `waited` against the lockstep clients that held the world meanwhile; at the end
    /// of each window, if clients outside the barrier were held for more than the allowed
    /// share of it, the member that held longest leaves the barrier for good (warning).
    /// New members ([`PROBATION`]) have a budget of their own, charged here too.
    fn note_held(&mut self, waited: Duration) {
        let now = Instant::now();
        let share = self.settings.lockstep_join_share;
        if share < 1.0 {
            if self.new_spent_until.is_some_and(|until| now >= until) {
                self.new_spent_until = None;
                (self.new_tokens, self.new_refilled) = (NEW_BURST, now);
            }
            if self.new_spent_until.is_none() {
                let refill = now
                    .saturating_duration_since(self.new_refilled)
                    .mul_f64(share);
                let mut tokens = (self.new_tokens + refill).min(NEW_BURST);
                // The wait that ends now, as far as the budget pays for it.
                let mut charge = Duration::ZERO;
                let paid = self.new_holds(now, |from| {
                    let this = from.map_or(waited, |from| {
                        now.saturating_duration_since(from).min(waited)
                    });
                    charge = charge.max(this);
                });
                if paid {
                    tokens = tokens.saturating_sub(charge);
                    if tokens.is_zero() {
                        let until = now + NEW_BURST.div_f64(share);
                        self.new_spent_until = Some(until);
                        warn!(
                            burst_s = NEW_BURST.as_secs_f64(),
                            max_share = share,
                            "lockstep clients that joined in the last 10 s held the world for \
                             their budget while others are connected; for the next {:.1} s the \
                             world does not wait for them (their SYNCs are answered when it \
                             reaches their time)",
                            (until - now).as_secs_f64()
                        );
                    }
                }
                (self.new_tokens, self.new_refilled) = (tokens, now);
            }
        }
        let (time, dt) = (self.world.time(), self.world.dt());
        let mut holding = false;
        for c in self.clients.values_mut() {
            if c.answered && c.holds_at(time, dt) {
                c.held += waited;
                holding = true;
            }
        }
        if holding {
            self.window.1 += waited;
        }
        let window = now.duration_since(self.window.0);
        if window < SHARE_WINDOW {
            return;
        }
        let share = self.window.1.as_secs_f64() / window.as_secs_f64();
        let others_wait = self.clients.len() > self.joined;
        if others_wait && share > self.settings.lockstep_share {
            let longest = self
                .clients
                .iter()
                .filter(|(_, c)| c.barrier.is_some())
                .max_by_key(|(_, c)| c.held)
                .map(|(id, _)| *id);
            if let Some(c) = longest.and_then(|id| self.clients.get_mut(&id)) {
                warn!(peer = %c.peer, held_s = c.held.as_secs_f64(),
                    window_s = window.as_secs_f64(), max_share = self.settings.lockstep_share,
                    "lockstep client held the world too long while others wait; it leaves the \
                     barrier, and its SYNCs are ignored from now on");
                c.leave_barrier();
                c.expelled = true;
                self.joined -= 1;
            }
        }
        self.window = (now, Duration::ZERO);
        for c in self.clients.values_mut() {
            c.held = Duration::ZERO;
        }
    }

    /// Removes from the barrier every client that has held the world for longer than the
    /// lockstep timeout without sending its next `SYNC`.
    fn release_stuck_barriers(&mut self) {
        let (time, dt) = (self.world.time(), self.world.dt());
        let timeout = self.settings.lockstep_timeout;
        let now = Instant::now();
        for c in self.clients.values_mut() {
            let late = c
                .answered_at
                .is_some_and(|at| now.duration_since(at) >= timeout);
            if late && c.holds_at(time, dt) && c.backlog.is_empty() {
                warn!(peer = %c.peer, barrier = c.barrier, timeout_s = timeout.as_secs_f64(),
                    "lockstep client sent no SYNC in time; it leaves the barrier");
                c.leave_barrier();
                self.joined -= 1;
            }
        }
    }

    /// Hands every client's pending output to its queue. At `TimeScale::Max` this waits
    /// while a client's queue has no room (taking requests meanwhile), for at most
    /// `reader_timeout` per client; a client that made no room by then is stalled (its output
    /// dropped until it has room again). Returns `false` when the driver must stop.
    fn flush_all(&mut self, inbox: &Receiver<Request>, shutdown: &CancellationToken) -> bool {
        let pace = self.settings.scale == TimeScale::Max;
        let mut since = None;
        let mut announced = false;
        loop {
            let mut blocked = false;
            for c in self.clients.values_mut() {
                blocked |= c.flush(pace);
            }
            if !blocked {
                break;
            }
            if !announced {
                // Ask the sessions for a wake-up, then look once more: a session that made
                // room before seeing the request is seen here (both sides use SeqCst).
                self.wants_room.store(true, Ordering::SeqCst);
                announced = true;
                continue;
            }
            let started = *since.get_or_insert_with(Instant::now);
            let deadline = started
                .checked_add(self.settings.reader_timeout)
                .unwrap_or(started);
            match inbox.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
                Ok(request) => {
                    self.take(request);
                    if shutdown.is_cancelled() {
                        return false;
                    }
                }
                Err(RecvTimeoutError::Timeout) => {
                    for c in self.clients.values_mut() {
                        if !c.pending.is_empty() && !c.has_room(c.pending.len()) {
                            warn!(peer = %c.peer,
                                timeout_s = self.settings.reader_timeout.as_secs_f64(),
                                "client read nothing in time; the world goes on without it");
                            c.stalled = true;
                        }
                    }
                }
                Err(RecvTimeoutError::Disconnected) => return false,
            }
            announced = false;
        }
        if pace {
            self.last_flush = Instant::now();
        }
        true
    }

    /// Tells each lockstep client whose barrier the world has reached.
    fn answer_barriers(&mut self) {
        let (time, dt) = (self.world.time(), self.world.dt());
        for c in self.clients.values_mut() {
            if !c.answered && c.holds_at(time, dt) {
                c.answered = true;
                c.answered_at = Some(Instant::now());
                c.push(&sync_reply(time), time);
                self.radio_due = true;
            }
        }
    }

    fn open_record(&mut self) -> Option<Recording> {
        let dir = self.settings.record_dir.as_ref()?;
        let path = dir.join(format!("connection-{:04}.usarlog", self.connections));
        Recording::create(path)
            .inspect_err(|path| self.incomplete.push(path.clone()))
            .ok()
    }

    /// Writes out and closes a client's recording, noting it if it is incomplete.
    fn close_record(&mut self, client: ClientId) {
        if let Some(c) = self.clients.get_mut(&client)
            && let Some(mut file) = c.record.take()
            && !file.flush()
        {
            self.incomplete.push(file.path().to_owned());
        }
    }

    fn record_client_line(&mut self, client: ClientId, line: Option<&str>) {
        let time = self.world.time();
        if let (Some(c), Some(line)) = (self.clients.get_mut(&client), line)
            && let Some(file) = &mut c.record
        {
            file.write(time, Direction::Client, line);
        }
    }

    /// Serves one client line.
    fn serve(&mut self, client: ClientId, line: Line) {
        match line {
            Line::Command { command, text } => {
                self.record_client_line(client, text.as_deref());
                if let Command::Init(init) = *command {
                    let first = self.clients.get(&client).is_some_and(|c| !c.spawned);
                    let others = self.world.robot_count() > 0;
                    if !self.init(client, init.clone())
                        && first
                        && others
                        && let Some(c) = self.clients.get_mut(&client)
                    {
                        debug!(peer = %c.peer, "INIT waits for its place");
                        c.parked = Some((init, Instant::now() + SPAWN_GRACE));
                        self.parked += 1;
                    }
                    return;
                }
                let replies = self.world.command(client, *command);
                let time = self.world.time();
                if let Some(c) = self.clients.get_mut(&client) {
                    for reply in &replies {
                        c.push(reply, time);
                    }
                }
            }
            Line::Sync { time, text } => {
                self.record_client_line(client, text.as_deref());
                let (now, dt) = (self.world.time(), self.world.dt());
                let full = self.joined >= self.settings.lockstep_clients;
                if let Some(c) = self.clients.get_mut(&client) {
                    if c.barrier.is_none() && (c.expelled || full) {
                        if !c.sync_refused {
                            c.sync_refused = true;
                            warn!(peer = %c.peer, expelled = c.expelled,
                                max_clients = self.settings.lockstep_clients,
                                "SYNC ignored: this client may not join the lockstep barrier");
                        }
                        return;
                    }
                    if c.barrier.is_none() {
                        self.joined += 1;
                        c.joined_at = Some(Instant::now());
                        c.syncs = 0;
                    }
                    c.syncs = c.syncs.saturating_add(1);
                    c.barrier = Some(time);
                    c.answered = false;
                    c.answered_at = None;
                    if c.holds_at(now, dt) {
                        c.answered = true;
                        c.answered_at = Some(Instant::now());
                        c.push(&sync_reply(now), now);
                        self.radio_due = true;
                    }
                }
            }
            Line::Unreadable { text } => self.record_client_line(client, Some(&text)),
            #[cfg(test)]
            Line::Crash => panic!("crash requested by a test"),
        }
    }

    fn handle(&mut self, request: Request) {
        match request {
            Request::Connect {
                peer,
                queue,
                queued,
                reply,
            } => {
                self.connections += 1;
                let mut record = self.open_record();
                if let Some(file) = &mut record {
                    let nfo = game_info(&self.world);
                    let text = String::from_utf8_lossy(&nfo);
                    file.write(self.world.time(), Direction::Server, text.trim_end());
                }
                let id = self.world.connect();
                debug!(%peer, client = ?id, "joined the simulation");
                let mut client = Client::new(peer, queue, queued);
                client.buffer = self.settings.client_buffer;
                client.record = record;
                self.clients.insert(id, client);
                // The session may already be gone; then its Disconnect never comes, so undo.
                if reply.send(id).is_err() {
                    self.world.disconnect(id);
                    self.clients.remove(&id);
                }
            }
            Request::Line { client, line, .. } => self.serve(client, line),
            Request::Disconnect { client } => {
                // What the client sent before it left is applied (and recorded) first, as
                // if it had all been served at once.
                while let Some((line, _permit)) = self
                    .clients
                    .get_mut(&client)
                    .and_then(|c| c.backlog.pop_front())
                {
                    self.waiting -= 1;
                    self.serve(client, line);
                }
                self.world.disconnect(client);
                self.close_record(client);
                if let Some(c) = self.clients.remove(&client) {
                    self.joined -= usize::from(c.barrier.is_some());
                    self.parked -= usize::from(c.parked.is_some());
                }
                self.retry_parked();
            }
            Request::Wake => {}
            Request::Ask(ask) => (ask.0)(&self.world),
            // A relay socket has news. While lockstep clients are in the barrier, it is taken
            // just before the world's next step, after every member's next `SYNC`: so what a
            // member writes while the world stands at a barrier reaches the other robot
            // after each agent's last step at that barrier and before its first step past
            // it, whatever the timing (docs/wss.md). Without members, at once.
            Request::Radio if self.joined > 0 => self.radio_due = true,
            Request::Radio => {
                if let Some(radio) = &self.radio {
                    radio.take();
                }
            }
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
        let mut client = Client::new("test".into(), queue, Arc::default());
        for tick in 1..=5 {
            client.push(&sta(f64::from(tick) / 10.0), 0.0);
            client.push(&sta(f64::from(tick) / 10.0 + 0.05), 0.0);
            assert!(!client.flush(false)); // never blocks
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
    fn a_full_byte_buffer_drops_whole_ticks_too() {
        let (queue, mut output) = mpsc::channel(1000);
        let queued = Arc::new(AtomicUsize::new(0));
        let mut client = Client::new("test".into(), queue, queued.clone());
        client.buffer = 100; // bytes: two ticks of 2 × 34 bytes do not fit
        for tick in 1..=5 {
            client.push(&sta(f64::from(tick) / 10.0), 0.0);
            client.push(&sta(f64::from(tick) / 10.0 + 0.05), 0.0);
            assert!(!client.flush(false));
        }
        assert_eq!(client.dropped, 4);
        assert_eq!(queued.load(Ordering::Relaxed), 68);
        // Written: its bytes are given back, and the next tick fits.
        let first = output.try_recv().unwrap();
        queued.fetch_sub(first.len(), Ordering::Relaxed);
        client.push(&sta(0.6), 0.0);
        assert!(!client.flush(false));
        assert_eq!(client.dropped, 4);
        assert!(output.try_recv().unwrap().starts_with(b"STA {Time 0.6000}"));
    }

    #[test]
    fn at_max_speed_a_full_queue_keeps_the_output_until_there_is_room() {
        let (queue, mut output) = mpsc::channel(1);
        let queued = Arc::new(AtomicUsize::new(0));
        let mut client = Client::new("test".into(), queue, queued.clone());
        client.push(&sta(0.1), 0.0);
        assert!(!client.flush(true));
        client.push(&sta(0.2), 0.0);
        assert!(client.flush(true), "no room: the driver must wait");
        assert_eq!(client.dropped, 0);
        // The session writes the first chunk: room again, and the kept tick goes whole.
        let first = output.try_recv().unwrap();
        queued.fetch_sub(first.len(), Ordering::SeqCst);
        client.push(&sta(0.3), 0.0);
        assert!(!client.flush(true));
        let second = output.try_recv().unwrap();
        assert_eq!(
            &second[..],
            b"STA {Time 0.2000} {Battery 1200}\r\nSTA {Time 0.3000} {Battery 1200}\r\n"
        );
        client.push(&sta(0.4), 0.0);
        assert!(!client.flush(true));
        client.push(&sta(0.5), 0.0);
        assert!(client.flush(true));
        // A stalled client (the reader timeout ran out) is not waited for: dropped.
        client.stalled = true;
        assert!(!client.flush(true));
        assert_eq!(client.dropped, 1);
        // Room again: no longer stalled.
        output.try_recv().unwrap();
        queued.store(0, Ordering::SeqCst);
        client.push(&sta(0.6), 0.0);
        assert!(!client.flush(true));
        assert!(!client.stalled);
    }

    #[test]
    fn barriers_hold_the_world_until_the_next_sync() {
        let client = |barrier| Client {
            barrier,
            ..Client::new("test".into(), mpsc::channel(1).0, Arc::default())
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
