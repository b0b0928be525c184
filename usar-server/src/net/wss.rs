//! The Wireless Simulation Server (WSS, TCP 50000; docs/wss.md; the wire reference is
//! side-servers.md §3.1): robots register with `INIT`, ask the signal strength to another
//! robot (`GETSS`), a port that relays to it (`DNS`) and who is behind a relayed connection
//! (`REVERSEDNS`). The obstacle propagation model `S = Pd0 − 10·N·log10(d/d0) − n·A`,
//! connectable while `S ≥ cutoff`. At each evaluation the WSS takes the robots' positions,
//! kicks registered robots the simulator does not have (or whose battery is empty), and
//! breaks (stops the relay ports, closes relayed connections) or resumes each pair's links.
//!
//! Two clocks:
//! * **Wall clock** ([`serve`]: `usar-server wss`, and in-process without lockstep): every
//!   `poll` of wall time the WSS asks a USARSim robot monitor (TCP 7435, ours or a real one)
//!   for positions and wall counts; relayed connections copy bytes as they come, as the
//!   original does.
//! * **Simulated clock** (in-process with lockstep, [`Clock`]): the simulation thread calls
//!   the WSS. After the step that reaches each multiple of `poll` of simulated time it
//!   evaluates the links against the world itself; relayed bytes move only at the world's
//!   current time — just before the world's next step while lockstep clients are in the
//!   barrier, else when a relay socket has news — so bytes a client writes before its
//!   `SYNC` are taken at that barrier's time and delivered if and only if the link held at
//!   the last evaluation, before any client is sent a reading of a later time.

use std::collections::{BTreeMap, HashMap};
use std::io::{Read, Write};
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tokio_util::sync::CancellationToken;
use tracing::{debug, info, warn};

pub use usar_proto::wss::PathLoss;

use super::request::Request;
use super::side::Activity;
use crate::sim::World;

/// The WSS's settings: its obstacle propagation model (defaults as the original's), the
/// monitor it polls and the limits of its control port (docs/limits.md).
#[derive(Debug, Clone)]
pub struct WssConfig {
    /// The robot monitor to ask (USARSim: port 7435).
    pub monitor: SocketAddr,
    /// The signal between two robots and the weakest usable one.
    pub model: PathLoss,
    /// How often positions are polled and links broken or resumed: wall time for
    /// [`serve`], simulated time for a [`Clock`].
    pub poll: Duration,
    /// Control connections served at once; at the limit, the oldest that has not completed
    /// a request (else the slowest sender) is closed to make room.
    pub max_connections: usize,
    /// A control connection that has not completed a request this long after connecting
    /// is closed.
    pub idle_timeout: Duration,
    /// A control connection that has begun a request and not ended it within this time is
    /// closed.
    pub line_timeout: Duration,
}

impl WssConfig {
    /// The defaults of the WSS's obstacle model against the monitor at `monitor`.
    pub fn new(monitor: SocketAddr) -> Self {
        Self {
            monitor,
            model: PathLoss::default(),
            poll: Duration::from_secs(1),
            max_connections: 256,
            idle_timeout: Duration::from_secs(30),
            line_timeout: Duration::from_secs(30),
        }
    }
}

/// The longest control line (bytes); a longer one closes the connection.
const MAX_LINE: usize = 4096;
/// Relayed connections open at once, in all.
const MAX_RELAYED: usize = 256;

/// A number as C++'s default stream prints it (6 significant digits, no trailing zeros).
pub fn stringify(v: f64) -> String {
    if v.is_nan() {
        return "NaN".into();
    }
    if v.is_infinite() {
        return if v > 0.0 { "INF".into() } else { "-INF".into() };
    }
    if v == 0.0 {
        return "0".into();
    }
    let exponent = v.abs().log10().floor() as i32;
    if !(-5..6).contains(&exponent) {
        let s = format!("{v:.5e}");
        let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
        let exp: i32 = exp.parse().unwrap_or(0);
        return format!(
            "{mantissa}e{}{:02}",
            if exp < 0 { '-' } else { '+' },
            exp.abs()
        );
    }
    let decimals = (5 - exponent).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    }
}

#[derive(Debug)]
struct Robot {
    ip: IpAddr,
    ports: Vec<u16>,
    /// Cancelled to kick the robot (closes its control connection).
    kick: CancellationToken,
}

/// A relay port: `from` reaches `to`'s `target` port through `port`.
#[derive(Debug)]
struct Link {
    from: String,
    to: String,
    target: u16,
    port: u16,
    /// Listening (the link holds), or `None` (broken, or not in range yet).
    up: Option<Up>,
}

/// A relay port that listens.
#[derive(Debug)]
enum Up {
    /// Wall clock: cancelled when the link breaks (stops listening, closes the relayed
    /// connections).
    Wall(CancellationToken),
    /// Simulated clock: the listener, accepted from when the WSS takes bytes; dropped when
    /// the link breaks.
    Sim(mio::net::TcpListener),
}

/// A relayed connection on the simulated clock: `a` connected to the relay port of the
/// link on `port`, `b` is the WSS's connection to the target robot.
#[derive(Debug)]
struct Relay {
    port: u16,
    a: mio::net::TcpStream,
    b: mio::net::TcpStream,
    /// `b`'s local port (what `REVERSEDNS` asks about).
    local: u16,
    /// Bytes taken from one side and not yet written to the other (at most [`PENDING`]).
    to_a: Half,
    to_b: Half,
    _permit: OwnedSemaphorePermit,
}

/// One direction of a [`Relay`].
#[derive(Debug, Default)]
struct Half {
    pending: Vec<u8>,
    /// The source has ended its side.
    ended: bool,
    /// The end has been passed on (the destination's writing side shut down).
    shut: bool,
}

/// Bytes waiting in the WSS per direction of a relayed connection; past it the WSS stops
/// reading that side (TCP back-pressure: a flood fills socket buffers, not memory).
const PENDING: usize = 64 * 1024;

/// How long the WSS on the simulated clock waits for a target robot's listener to accept.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(1);

/// A pair's wall count and the two positions it was counted at.
type Walls = (f64, [f64; 3], [f64; 3]);

#[derive(Debug, Default)]
struct State {
    robots: BTreeMap<String, Robot>,
    links: Vec<Link>,
    /// Latest positions from the monitor.
    positions: HashMap<String, [f64; 3]>,
    /// Robots whose radio is off (the monitor's `Radio Off`, a fault; docs/wss.md).
    radio_off: std::collections::HashSet<String>,
    /// Wall clock: robots registered since the poll task last looked (it evaluates them at
    /// once).
    registered: Vec<String>,
    /// Wall counts per unordered pair, with the positions they were counted at.
    walls: HashMap<(String, String), Walls>,
    /// Relayed connections: the WSS's outgoing local port → (from, to).
    outgoing: HashMap<u16, (String, String)>,
    /// Relayed connections on the simulated clock.
    relays: Vec<Relay>,
}

impl State {
    /// Breaks link `i`: stops its relay port and closes its relayed connections.
    fn down(&mut self, i: usize) {
        let link = &mut self.links[i];
        if let Some(Up::Wall(up)) = link.up.take() {
            up.cancel();
        }
        let port = link.port;
        self.close_relays(|r| r.port == port);
    }

    /// Closes the relayed connections (simulated clock) that `which` picks.
    fn close_relays(&mut self, which: impl Fn(&Relay) -> bool) {
        let outgoing = &mut self.outgoing;
        self.relays.retain(|r| {
            let close = which(r);
            if close {
                outgoing.remove(&r.local);
            }
            !close
        });
    }
}

fn pair(a: &str, b: &str) -> (String, String) {
    if a <= b {
        (a.to_owned(), b.to_owned())
    } else {
        (b.to_owned(), a.to_owned())
    }
}

/// The WSS: its state and settings.
struct Wss {
    config: WssConfig,
    /// Where relay ports listen: the control port's address (`--bind`).
    relay_ip: IpAddr,
    state: Mutex<State>,
    relayed: Arc<Semaphore>,
    shutdown: CancellationToken,
    /// The simulated clock's watch over the relay sockets (`None`: wall clock).
    gate: Option<Gate>,
    /// Wall clock: tells the poll task to poll at once (a robot registered)...
    poll_now: tokio::sync::Notify,
    /// ... which counts its polls here, done or failed.
    polled: tokio::sync::watch::Sender<u64>,
}

/// The longest a registration waits for its evaluation (the monitor's answer, or the
/// simulation thread) before `INITREPLY` goes out anyway.
const REFRESH_WAIT: Duration = Duration::from_secs(2);

/// What the WSS on the simulated clock needs to hear from its relay sockets.
struct Gate {
    /// Where relay sockets are registered; the watcher thread wakes the simulation thread
    /// when one has news.
    registry: mio::Registry,
    /// Set by the watcher when it has asked for a take, cleared by each take.
    woken: Arc<AtomicBool>,
    /// The simulation thread's requests: an evaluation at once when a robot registers.
    requests: Sender<Request>,
}

/// The token of every watched relay socket (the watcher only needs to know that one has
/// news).
const NEWS: mio::Token = mio::Token(0);
/// The token of the watcher's stop signal.
const STOP: mio::Token = mio::Token(1);

impl Wss {
    fn new(
        config: WssConfig,
        relay_ip: IpAddr,
        shutdown: CancellationToken,
        gate: Option<Gate>,
    ) -> Self {
        Self {
            config,
            relay_ip,
            state: Mutex::new(State::default()),
            relayed: Arc::new(Semaphore::new(MAX_RELAYED)),
            shutdown,
            gate,
            poll_now: tokio::sync::Notify::new(),
            polled: tokio::sync::watch::Sender::new(0),
        }
    }

    /// Evaluates the links at once (a robot has just registered): so that its `GETSS` and
    /// `DNS` are answered from the positions of now from its `INITREPLY` on, not after the
    /// next poll. On the simulated clock the simulation thread evaluates between two ticks
    /// (at the world's current time); on the wall clock the poll task asks the monitor.
    /// Waits at most [`REFRESH_WAIT`].
    async fn refresh(self: &Arc<Self>, name: &str) {
        match &self.gate {
            Some(gate) => {
                let (done, evaluated) = tokio::sync::oneshot::channel();
                let (wss, name) = (Arc::clone(self), name.to_owned());
                let ask = super::request::Ask(Box::new(move |world: &World| {
                    wss.evaluate(world, Some(&name));
                    let _ = done.send(());
                }));
                if gate.requests.send(Request::Ask(ask)).is_ok() {
                    let _ = tokio::time::timeout(REFRESH_WAIT, evaluated).await;
                }
            }
            None => {
                let mut polled = self.polled.subscribe();
                self.lock().registered.push(name.to_owned());
                self.poll_now.notify_one();
                let _ = tokio::time::timeout(REFRESH_WAIT, polled.changed()).await;
            }
        }
    }
}

/// Serves the WSS on the wall clock on `listener` until `shutdown`, asking the robot
/// monitor `config.monitor` every `config.poll` of wall time. Relay ports listen on the
/// listener's address.
pub async fn serve(listener: TcpListener, config: WssConfig, shutdown: CancellationToken) {
    let relay_ip = match listener.local_addr() {
        Ok(at) => at.ip(),
        Err(error) => {
            warn!(%error, "WSS: the control port has no address; not serving");
            return;
        }
    };
    let wss = Arc::new(Wss::new(config, relay_ip, shutdown, None));
    tokio::spawn(poll(wss.clone()));
    serve_control(listener, wss).await;
}

/// Serves the control connections of `wss` on `listener` until its shutdown.
async fn serve_control(listener: TcpListener, wss: Arc<Wss>) {
    // The side servers' accept loop and limits.
    let tracker = tokio_util::task::TaskTracker::new();
    let limits = super::side::Limits {
        max: wss.config.max_connections,
        idle: Some(wss.config.idle_timeout),
        line: wss.config.line_timeout,
    };
    let shutdown = wss.shutdown.clone();
    super::side::accept(
        "WSS",
        listener,
        limits,
        tracker,
        shutdown,
        move |stream, stop, activity| control(wss.clone(), stream, stop, activity),
    )
    .await;
}

/// The WSS on the simulated clock (in-process with lockstep): the simulation thread owns
/// it and calls [`Clock::take`] and [`Clock::stepped`]; its control port is served by
/// [`Clock::serve`].
pub(super) struct Clock {
    wss: Arc<Wss>,
    /// `poll`, simulated seconds.
    poll: f64,
    /// When the next evaluation is due, simulated seconds.
    next: f64,
    stop: mio::Waker,
}

impl Clock {
    /// A WSS with `config`'s model whose evaluations come every `config.poll` of simulated
    /// time, its relay ports on `relay_ip` (the control port's address); a watcher thread
    /// sends `Request::Radio` on `requests` when a relay socket has news.
    pub(super) fn new(
        config: WssConfig,
        relay_ip: IpAddr,
        requests: Sender<Request>,
        shutdown: CancellationToken,
    ) -> std::io::Result<Self> {
        let poll = mio::Poll::new()?;
        let registry = poll.registry().try_clone()?;
        let stop = mio::Waker::new(poll.registry(), STOP)?;
        let woken = Arc::new(AtomicBool::new(false));
        let watched = woken.clone();
        let asks = requests.clone();
        std::thread::Builder::new()
            .name("usar-wss".into())
            .spawn(move || watch(poll, watched, requests))?;
        let seconds = config.poll.as_secs_f64();
        let gate = Gate {
            registry,
            woken,
            requests: asks,
        };
        Ok(Self {
            wss: Arc::new(Wss::new(config, relay_ip, shutdown, Some(gate))),
            poll: seconds,
            next: 0.0,
            stop,
        })
    }

    /// Serves the control port on `listener` (until the shutdown given to [`Clock::new`]).
    pub(super) fn serve(&self, listener: TcpListener) -> impl Future<Output = ()> + use<> {
        serve_control(listener, self.wss.clone())
    }

    /// Takes the connections and bytes waiting at the world's current time.
    pub(super) fn take(&self) {
        self.wss.take();
    }

    /// After each step: evaluates the links if one is due at the world's new time.
    pub(super) fn stepped(&mut self, world: &World) {
        const EPSILON: f64 = 1e-6;
        let time = world.time();
        if time + EPSILON < self.next {
            return;
        }
        self.wss.evaluate(world, None);
        self.next = if self.poll > 0.0 {
            (((time + EPSILON) / self.poll).floor() + 1.0) * self.poll
        } else {
            time
        };
    }
}

impl Drop for Clock {
    fn drop(&mut self) {
        let _ = self.stop.wake();
    }
}

/// The watcher thread: asks the simulation thread for a take whenever a relay socket has
/// news (at most one request waiting at a time), until stopped.
fn watch(mut poll: mio::Poll, woken: Arc<AtomicBool>, requests: Sender<Request>) {
    let mut events = mio::Events::with_capacity(64);
    loop {
        if let Err(error) = poll.poll(&mut events, None) {
            if error.kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            warn!(%error, "WSS: cannot watch the relay sockets");
            return;
        }
        if events.iter().any(|e| e.token() == STOP) {
            return;
        }
        if !woken.swap(true, Ordering::SeqCst) && requests.send(Request::Radio).is_err() {
            return;
        }
    }
}

impl Wss {
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The signal between two registered robots from the latest poll (NaN: unknown).
    fn strength(&self, state: &State, a: &str, b: &str) -> f64 {
        let (Some(pa), Some(pb)) = (state.positions.get(a), state.positions.get(b)) else {
            return f64::NAN;
        };
        if state.radio_off.contains(a) || state.radio_off.contains(b) {
            return f64::NEG_INFINITY;
        }
        let Some((walls, ..)) = state.walls.get(&pair(a, b)) else {
            return f64::NAN;
        };
        self.config.model.strength(*pa, *pb, *walls)
    }

    fn in_range(&self, state: &State, a: &str, b: &str) -> bool {
        self.strength(state, a, b) >= self.config.model.cutoff
    }
}

/// Control requests: lines ended by CR LF only (a bare LF does not end one).
struct Requests<R> {
    read: R,
    buffer: Vec<u8>,
}

impl<R: tokio::io::AsyncRead + Unpin> Requests<R> {
    /// The next request; `Ok(None)` at the end of the stream, `Err` past [`MAX_LINE`] or at
    /// a timeout of `activity` (which is told whether a request is unfinished).
    async fn next(&mut self, activity: &Activity) -> Result<Option<Vec<u8>>, Closing> {
        loop {
            if let Some(at) = self.buffer.windows(2).position(|w| w == b"\r\n") {
                let line = self.buffer[..at].to_vec();
                self.buffer.drain(..at + 2);
                return Ok(Some(line));
            }
            if self.buffer.len() > MAX_LINE {
                return Err(Closing::TooLong);
            }
            let mut chunk = [0u8; 2048];
            let unfinished = !self.buffer.is_empty();
            match activity.read(&mut self.read, &mut chunk, unfinished).await {
                Err(why) => return Err(Closing::TimedOut(why)),
                Ok(Ok(0) | Err(_)) => return Ok(None),
                Ok(Ok(n)) => self.buffer.extend_from_slice(&chunk[..n]),
            }
        }
    }
}

/// Why [`Requests::next`] closes the connection.
enum Closing {
    TooLong,
    TimedOut(super::side::TimedOut),
}

/// One control connection: one reply per request.
async fn control(
    wss: Arc<Wss>,
    stream: TcpStream,
    stop: CancellationToken,
    activity: Arc<Activity>,
) {
    let Ok(peer) = stream.peer_addr() else {
        return;
    };
    let (read, mut write) = stream.into_split();
    let mut requests = Requests {
        read,
        buffer: Vec::new(),
    };
    let mut me: Option<(String, CancellationToken)> = None;
    let never = CancellationToken::new();
    let mut first = true;
    loop {
        let kick = me.as_ref().map_or(never.clone(), |m| m.1.clone());
        let got = tokio::select! {
            _ = stop.cancelled() => break,
            _ = kick.cancelled() => {
                info!(%peer, "WSS: robot kicked (not in the simulation, or its battery is empty)");
                break;
            }
            got = requests.next(&activity) => got,
        };
        let line = match got {
            Ok(Some(line)) => {
                let at = peer.to_string();
                if super::side::refuse_http("WSS", &at, std::mem::take(&mut first), &line) {
                    break;
                }
                activity.completed();
                line
            }
            Ok(None) => break,
            Err(Closing::TooLong) => {
                warn!(%peer, max = MAX_LINE, "WSS: request line too long; closing");
                break;
            }
            Err(Closing::TimedOut(why)) => {
                info!(%peer, "WSS: closing: {why}");
                break;
            }
        };
        let text = String::from_utf8_lossy(&line).into_owned();
        let reply = request(&wss, &mut me, peer.ip(), &text).await;
        if write
            .write_all(format!("{reply}\r\n").as_bytes())
            .await
            .is_err()
        {
            break;
        }
    }
    // A kicked robot was unregistered when it was kicked (its name may be someone else's now).
    if let Some((name, kick)) = me
        && !kick.is_cancelled()
    {
        unregister(&wss, &name);
    }
}

/// A request's type and its `{key value}` blocks (keys case-sensitive; a block of one token
/// is a key with an empty value; blocks of more tokens are ignored).
fn parse(line: &str) -> (&str, Vec<(&str, &str)>) {
    let kind = line.split(' ').next().unwrap_or("");
    let mut blocks = Vec::new();
    let mut rest = &line[kind.len()..];
    while let Some(open) = rest.find('{') {
        let Some(close) = rest[open..].find('}') else {
            break;
        };
        let tokens: Vec<&str> = rest[open + 1..open + close].split_whitespace().collect();
        match tokens[..] {
            [key] => blocks.push((key, "")),
            [key, value] => blocks.push((key, value)),
            _ => {}
        }
        rest = &rest[open + close + 1..];
    }
    (kind, blocks)
}

fn value<'a>(blocks: &[(&str, &'a str)], key: &str) -> Option<&'a str> {
    blocks.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)
}

/// The reply to one request of the robot `me` (once registered).
async fn request(
    wss: &Arc<Wss>,
    me: &mut Option<(String, CancellationToken)>,
    ip: IpAddr,
    line: &str,
) -> String {
    let registering = me.is_none();
    match answer(wss, me, ip, line) {
        // Registered: its links are evaluated before it is told so.
        Answer::Reply(text) if registering && me.is_some() => {
            let name = me.as_ref().map(|m| m.0.clone()).unwrap_or_default();
            wss.refresh(&name).await;
            text
        }
        Answer::Reply(text) => text,
        Answer::Relay {
            other,
            target,
            reachable,
        } => {
            let name = me.as_ref().map(|m| m.0.clone()).unwrap_or_default();
            relay(wss, &name, &other, target, reachable).await
        }
    }
}

/// What a control line needs: a reply, or a new relay port (`DNS`, the only request that
/// needs I/O).
#[derive(Debug)]
enum Answer {
    Reply(String),
    /// A relay port from the robot to `other`'s port `target`; listening at once if
    /// `reachable`.
    Relay {
        other: String,
        target: u16,
        reachable: bool,
    },
}

impl From<String> for Answer {
    fn from(text: String) -> Self {
        Self::Reply(text)
    }
}

impl From<&str> for Answer {
    fn from(text: &str) -> Self {
        Self::Reply(text.to_owned())
    }
}

/// [`request`] without I/O: registers, answers, or says which relay port to open.
fn answer(
    wss: &Wss,
    me: &mut Option<(String, CancellationToken)>,
    ip: IpAddr,
    line: &str,
) -> Answer {
    let (kind, blocks) = parse(line);
    let robot = value(&blocks, "Robot").unwrap_or("");
    let Some((name, _)) = me.as_ref() else {
        if kind != "INIT" {
            return "ERROR {Reason Must.Use.INIT.Method.First}".into();
        }
        let ports: Option<Vec<u16>> = value(&blocks, "Port")
            .unwrap_or("")
            .split(',')
            .map(|p| p.trim().parse().ok())
            .collect();
        let Some(ports) = ports else {
            return "ERROR {Reason Ports.List.Must.Be.Integer}".into();
        };
        if robot.is_empty() {
            return "ERROR {Reason Robot.Name.Must.Not.Be.Empty}".into();
        }
        let mut state = wss.lock();
        if state.robots.contains_key(robot) {
            return "ERROR {Reason Robot.Alread.Exists}".into();
        }
        let kick = CancellationToken::new();
        state.robots.insert(
            robot.to_owned(),
            Robot {
                ip,
                ports,
                kick: kick.clone(),
            },
        );
        info!(robot, %ip, "WSS: robot registered");
        *me = Some((robot.to_owned(), kick));
        return "INITREPLY {Status OK}".into();
    };
    let name = name.clone();
    match kind {
        "GETSS" => {
            if robot.is_empty() {
                return "ERROR {Reason Robot.Name.Must.Not.Be.Empty}".into();
            }
            if robot == name {
                return format!("SS {{Robot {robot}}} {{Strength INF}} {{Error SS.To.Self}}")
                    .into();
            }
            let state = wss.lock();
            if !state.robots.contains_key(robot) {
                return format!(
                    "SS {{Robot {robot}}} {{Strength NaN}} {{Error Robot.Does.Not.Exist}}"
                )
                .into();
            }
            let s = wss.strength(&state, &name, robot);
            if s.is_nan() {
                format!("SS {{Robot {robot}}} {{Strength NaN}} {{Error Model.Returned.NaN}}").into()
            } else if s == f64::NEG_INFINITY {
                format!("SS {{Robot {robot}}} {{Strength -INF}} {{Error Radio.Off}}").into()
            } else if s.is_infinite() || s > 0.0 {
                format!("SS {{Robot {robot}}} {{Strength INF}} {{Error Model.Returned.INF}}").into()
            } else {
                format!("SS {{Robot {robot}}} {{Strength {}}}", stringify(s)).into()
            }
        }
        "DNS" => {
            if robot.is_empty() {
                return "ERROR {Reason Robot.Name.Must.Not.Be.Empty}".into();
            }
            let port = match value(&blocks, "Port").map(str::parse::<u16>) {
                Some(Err(_)) => return "ERROR {Reason Port.Must.Be.Integer}".into(),
                Some(Ok(p)) => Some(p),
                None => None,
            };
            dns(wss, &name, robot, port)
        }
        "REVERSEDNS" => {
            let Some(Ok(port)) = value(&blocks, "Port").map(str::parse::<u16>) else {
                return "ERROR {Reason Port.Must.Be.Integer}".into();
            };
            let state = wss.lock();
            match state.outgoing.get(&port) {
                Some((from, to)) if *to == name => {
                    format!("REVERSEDNSREPLY {{Port {port}}} {{Robot {from}}}").into()
                }
                _ => {
                    format!("REVERSEDNSREPLY {{Port {port}}} {{Error UnknownOrIllegalPort}}").into()
                }
            }
        }
        _ => "ERROR {Reason Method.Unknown.Or.Can.INIT.only.once}".into(),
    }
}

/// `DNS`: the relay port from `me` to `other`'s `port` (its first port without one).
fn dns(wss: &Wss, me: &str, other: &str, port: Option<u16>) -> Answer {
    let (target, existing, reachable) = {
        let state = wss.lock();
        let Some(robot) = state.robots.get(other).filter(|_| other != me) else {
            return format!("DNSREPLY {{Robot {other}}} {{Port -1}} {{Error NoSuchRobot}}").into();
        };
        let target = match port {
            None => robot.ports.first().copied(),
            Some(p) => robot.ports.contains(&p).then_some(p),
        };
        let Some(target) = target else {
            return format!(
                "DNSREPLY {{Robot {other}}} {{Port -1}} {{Error RobotDoesNotListenOnThisPort}}"
            )
            .into();
        };
        let existing = state
            .links
            .iter()
            .find(|l| l.from == me && l.to == other && l.target == target)
            .map(|l| l.port);
        (target, existing, wss.in_range(&state, me, other))
    };
    if let Some(port) = existing {
        return format!("DNSREPLY {{Robot {other}}} {{Port {port}}}").into();
    }
    Answer::Relay {
        other: other.to_owned(),
        target,
        reachable,
    }
}

/// Opens a relay port from `me` to `other`'s port `target` and answers the `DNS`.
async fn relay(wss: &Arc<Wss>, me: &str, other: &str, target: u16, reachable: bool) -> String {
    if wss.gate.is_some() {
        return wss.relay_now(me, other, target);
    }
    // A port of our own for this pair: bound now (and kept for the pair), listening only
    // while the pair is in range.
    let listener = match TcpListener::bind((wss.bind_ip(), 0)).await {
        Ok(l) => l,
        Err(error) => {
            warn!(%error, "WSS: cannot open a relay port");
            return "ERROR {Reason Could.Not.Allocate.Port}".into();
        }
    };
    let Ok(local) = listener.local_addr() else {
        return "ERROR {Reason Could.Not.Allocate.Port}".into();
    };
    let mut link = Link {
        from: me.to_owned(),
        to: other.to_owned(),
        target,
        port: local.port(),
        up: None,
    };
    if reachable {
        link.up = Some(Up::Wall(start_relay(wss, listener, me, other, target)));
    } else {
        drop(listener);
    }
    wss.lock().links.push(link);
    format!("DNSREPLY {{Robot {other}}} {{Port {}}}", local.port())
}

impl Wss {
    /// Where relay ports listen: where the control port does (`--bind`; docs/security.md).
    fn bind_ip(&self) -> IpAddr {
        self.relay_ip
    }

    /// [`relay`] on the simulated clock: the port listens at once if the pair is in range
    /// by the last evaluation.
    fn relay_now(&self, me: &str, other: &str, target: u16) -> String {
        let listener = match std::net::TcpListener::bind((self.bind_ip(), 0)) {
            Ok(l) => l,
            Err(error) => {
                warn!(%error, "WSS: cannot open a relay port");
                return "ERROR {Reason Could.Not.Allocate.Port}".into();
            }
        };
        let Ok(port) = listener.local_addr().map(|a| a.port()) else {
            return "ERROR {Reason Could.Not.Allocate.Port}".into();
        };
        let mut state = self.lock();
        let up = if self.in_range(&state, me, other) {
            match self.listen(listener) {
                Ok(up) => Some(up),
                Err(error) => {
                    warn!(%error, "WSS: cannot open a relay port");
                    return "ERROR {Reason Could.Not.Allocate.Port}".into();
                }
            }
        } else {
            None
        };
        state.links.push(Link {
            from: me.to_owned(),
            to: other.to_owned(),
            target,
            port,
            up,
        });
        format!("DNSREPLY {{Robot {other}}} {{Port {port}}}")
    }

    /// A relay port on the simulated clock, watched.
    fn listen(&self, listener: std::net::TcpListener) -> std::io::Result<Up> {
        listener.set_nonblocking(true)?;
        let mut listener = mio::net::TcpListener::from_std(listener);
        if let Some(gate) = &self.gate {
            gate.registry
                .register(&mut listener, NEWS, mio::Interest::READABLE)?;
        }
        Ok(Up::Sim(listener))
    }

    /// Simulated clock: accepts the connections waiting on the relay ports of the links
    /// that hold and moves the bytes waiting on relayed connections, at the world's current
    /// time.
    fn take(&self) {
        let Some(gate) = &self.gate else {
            return;
        };
        // Cleared first: news that comes after this point asks for another take.
        gate.woken.store(false, Ordering::SeqCst);
        let mut guard = self.lock();
        let state = &mut *guard;
        let mut accepted = Vec::new();
        for link in &state.links {
            let Some(Up::Sim(listener)) = &link.up else {
                continue;
            };
            loop {
                match listener.accept() {
                    Ok((client, _)) => accepted.push((link.port, client)),
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    // Nothing more waits (or a transient error: the next take tries again).
                    Err(_) => break,
                }
            }
        }
        for (port, client) in accepted {
            self.bridge(state, port, client);
        }
        let mut closed = Vec::new();
        for (i, relay) in state.relays.iter_mut().enumerate() {
            let alive = pump(&relay.a, &relay.b, &mut relay.to_b)
                && pump(&relay.b, &relay.a, &mut relay.to_a);
            let done = relay.to_a.shut && relay.to_b.shut;
            if !alive || done {
                closed.push(i);
            }
        }
        for i in closed.into_iter().rev() {
            let relay = state.relays.remove(i);
            state.outgoing.remove(&relay.local);
        }
    }

    /// Bridges a connection accepted on the relay port `port` to the link's target robot
    /// (the link holds: its port listens only then).
    fn bridge(&self, state: &mut State, port: u16, client: mio::net::TcpStream) {
        let Some(link) = state.links.iter().find(|l| l.port == port) else {
            return;
        };
        let Some(robot) = state.robots.get(&link.to) else {
            return;
        };
        let Ok(permit) = self.relayed.clone().try_acquire_owned() else {
            warn!(
                max = MAX_RELAYED,
                "WSS: too many relayed connections; dropped"
            );
            return;
        };
        let target = SocketAddr::new(robot.ip, link.target);
        // The target's listener accepts at once on its own machine; waiting for it here
        // makes the connection part of this moment of the simulation.
        let out = match std::net::TcpStream::connect_timeout(&target, CONNECT_TIMEOUT) {
            Ok(out) => out,
            Err(error) => {
                debug!(%target, %error, "WSS: cannot reach the target robot");
                return;
            }
        };
        let local = out.local_addr().map(|a| a.port()).unwrap_or(0);
        if out.set_nonblocking(true).is_err() {
            return;
        }
        let (mut a, mut b) = (client, mio::net::TcpStream::from_std(out));
        let _ = (a.set_nodelay(true), b.set_nodelay(true));
        if let Some(gate) = &self.gate {
            let both = mio::Interest::READABLE | mio::Interest::WRITABLE;
            if gate.registry.register(&mut a, NEWS, both).is_err()
                || gate.registry.register(&mut b, NEWS, both).is_err()
            {
                return;
            }
        }
        state
            .outgoing
            .insert(local, (link.from.clone(), link.to.clone()));
        state.relays.push(Relay {
            port,
            a,
            b,
            local,
            to_a: Half::default(),
            to_b: Half::default(),
            _permit: permit,
        });
    }

    /// Simulated clock: positions and wall counts from the world; kicks; breaks and
    /// resumes.
    fn evaluate(&self, world: &World, only: Option<&str>) {
        let found: Vec<Found> = world
            .robots_truth()
            .into_iter()
            .map(|r| (r.name, r.location, r.battery_empty, r.radio_off))
            .collect();
        let (names, stale) = self.observe(&found, only);
        let counted = stale
            .into_iter()
            .map(|(key, pa, pb)| {
                (
                    key,
                    Some(f64::from(world.obstacles_between(pa, pb))),
                    pa,
                    pb,
                )
            })
            .collect();
        for (from, to, port, _) in self.judge(&names, counted) {
            // Listening again on the same port.
            let up = std::net::TcpListener::bind((self.bind_ip(), port))
                .and_then(|listener| self.listen(listener));
            match up {
                Ok(up) => {
                    let mut state = self.lock();
                    if let Some(link) = state
                        .links
                        .iter_mut()
                        .find(|l| l.port == port && l.up.is_none())
                    {
                        info!(%from, %to, port, "WSS: link resumed");
                        link.up = Some(up);
                    }
                }
                Err(error) => {
                    warn!(%from, %to, port, %error, "WSS: cannot listen again on the relay port")
                }
            }
        }
    }
}

/// One direction of a relayed connection: reads what `from` has (while fewer than
/// [`PENDING`] bytes wait) and writes what `to` takes; once `from` has ended and all is
/// written, shuts `to`'s writing side. `false` on an error (the connection is closed).
fn pump(from: &mio::net::TcpStream, to: &mio::net::TcpStream, half: &mut Half) -> bool {
    use std::io::ErrorKind::{Interrupted, WouldBlock};
    let mut chunk = [0u8; 16 * 1024];
    while !half.ended && half.pending.len() < PENDING {
        let room = (PENDING - half.pending.len()).min(chunk.len());
        match (&mut &*from).read(&mut chunk[..room]) {
            Ok(0) => half.ended = true,
            Ok(n) => half.pending.extend_from_slice(&chunk[..n]),
            Err(e) if e.kind() == WouldBlock => break,
            Err(e) if e.kind() == Interrupted => {}
            Err(_) => return false,
        }
    }
    while !half.pending.is_empty() {
        match (&mut &*to).write(&half.pending) {
            Ok(0) => return false,
            Ok(n) => {
                half.pending.drain(..n);
            }
            Err(e) if e.kind() == WouldBlock => break,
            Err(e) if e.kind() == Interrupted => {}
            Err(_) => return false,
        }
    }
    if half.ended && half.pending.is_empty() && !half.shut {
        let _ = to.shutdown(std::net::Shutdown::Write);
        half.shut = true;
    }
    true
}

/// Accepts on a relay port until the returned token is cancelled (the link broke): each
/// connection is bridged to the target robot while the pair stays in range.
fn start_relay(
    wss: &Arc<Wss>,
    listener: TcpListener,
    from: &str,
    to: &str,
    port: u16,
) -> CancellationToken {
    let up = wss.shutdown.child_token();
    let (wss, stop, from, to) = (wss.clone(), up.clone(), from.to_owned(), to.to_owned());
    tokio::spawn(async move {
        loop {
            let (client, peer) = tokio::select! {
                _ = stop.cancelled() => return,
                accepted = listener.accept() => match accepted {
                    Ok(x) => x,
                    Err(_) => continue,
                },
            };
            let target = {
                let state = wss.lock();
                let Some(robot) = state.robots.get(&to) else {
                    continue;
                };
                if !wss.in_range(&state, &from, &to) {
                    debug!(%peer, "WSS: out of range, connection dropped");
                    continue;
                }
                SocketAddr::new(robot.ip, port)
            };
            let Ok(permit) = wss.relayed.clone().try_acquire_owned() else {
                warn!(
                    max = MAX_RELAYED,
                    "WSS: too many relayed connections; dropped"
                );
                continue;
            };
            let (wss, stop, from, to) = (wss.clone(), stop.clone(), from.clone(), to.clone());
            tokio::spawn(async move {
                let Ok(out) = TcpStream::connect(target).await else {
                    return;
                };
                let local = out.local_addr().map(|a| a.port()).unwrap_or(0);
                wss.lock().outgoing.insert(local, (from, to));
                let mut client = client;
                let mut out = out;
                // Bounded: bytes are read only as fast as the other side takes them.
                tokio::select! {
                    _ = stop.cancelled() => {}
                    _ = tokio::io::copy_bidirectional(&mut client, &mut out) => {}
                }
                wss.lock().outgoing.remove(&local);
                drop(permit);
            });
        }
    });
    up
}

/// Removes a robot and every link from or to it.
fn unregister(wss: &Wss, name: &str) {
    let mut state = wss.lock();
    state.robots.remove(name);
    while let Some(i) = state
        .links
        .iter()
        .position(|l| l.from == name || l.to == name)
    {
        state.down(i);
        state.links.remove(i);
    }
    state.walls.retain(|(a, b), _| a != name && b != name);
    info!(robot = name, "WSS: robot unregistered");
}

/// Every `poll`: positions and wall counts from the monitor; kicks; breaks and resumes.
async fn poll(wss: Arc<Wss>) {
    let mut monitor: Option<BufReader<TcpStream>> = None;
    let mut ticker = tokio::time::interval(wss.config.poll);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        // A tick evaluates every robot (and kicks); a registration only the robots that
        // registered since (their places and walls now).
        let only = tokio::select! {
            _ = wss.shutdown.cancelled() => return,
            _ = ticker.tick() => None,
            _ = wss.poll_now.notified() => Some(std::mem::take(&mut wss.lock().registered)),
        };
        if monitor.is_none() {
            match TcpStream::connect(wss.config.monitor).await {
                Ok(s) => monitor = Some(BufReader::new(s)),
                Err(error) => {
                    warn!(monitor = %wss.config.monitor, %error, "WSS: cannot reach the robot monitor");
                }
            }
        }
        if let Some(m) = monitor.as_mut() {
            let names = match &only {
                None => vec![None],
                Some(names) => names.iter().map(|n| Some(n.as_str())).collect(),
            };
            for name in names {
                if update(&wss, m, name).await.is_err() {
                    warn!(monitor = %wss.config.monitor, "WSS: the robot monitor stopped answering");
                    monitor = None;
                    break;
                }
            }
        }
        wss.polled.send_modify(|n| *n += 1);
    }
}

/// One request to the monitor and its reply line (without CR LF).
async fn ask(m: &mut BufReader<TcpStream>, request: &str) -> Result<String, ()> {
    m.get_mut()
        .write_all(format!("{request}\r\n").as_bytes())
        .await
        .map_err(|_| ())?;
    let mut line = String::new();
    let read = tokio::time::timeout(Duration::from_secs(10), async {
        let mut limited = (&mut *m).take(1 << 20);
        limited.read_line(&mut line).await
    })
    .await;
    match read {
        Ok(Ok(n)) if n > 0 => Ok(line.trim_end().to_owned()),
        _ => Err(()),
    }
}

/// `POSITIONS {Robots n} {Name R Location x,y,z BatteryEmpty False [Radio Off]} ...` → name,
/// place, battery empty, radio off (our monitor's extension for a radio fault).
fn positions(line: &str) -> Vec<Found> {
    let mut out = Vec::new();
    for block in line.split('{').skip(1) {
        let tokens: Vec<&str> = block
            .trim_end_matches(['}', ' '])
            .split_whitespace()
            .collect();
        let radio_off = matches!(tokens[..], [.., "Radio", off] if off.eq_ignore_ascii_case("Off"));
        if let ["Name", name, "Location", at, "BatteryEmpty", empty, ..] = tokens[..] {
            let p: Vec<f64> = at.split(',').filter_map(|x| x.parse().ok()).collect();
            if let [x, y, z] = p[..] {
                out.push((
                    name.to_owned(),
                    [x, y, z],
                    empty.eq_ignore_ascii_case("True"),
                    radio_off,
                ));
            }
        }
    }
    out
}

/// `NUMOBS ... {ObstCount n}` → n, whole.
fn obstacle_count(line: &str) -> Option<f64> {
    line.rsplit("{ObstCount ")
        .next()
        .and_then(|v| v.trim_end_matches('}').trim().parse::<f64>().ok())
        .map(f64::trunc)
}

/// The control protocol without sockets (the fuzz target's door: fuzz/fuzz_targets/wss.rs):
/// a WSS that read the robot monitor's `GETPOS` reply `positions` (every pair of robots
/// `walls` walls apart, the monitor's `GETOBS` reply read by the same rule as from a real
/// one) answers `lines`, each sent on the control connection numbered by its first
/// element; a `DNS` that would open a relay port answers port 0. Returns the replies.
#[doc(hidden)]
pub fn answer_offline(positions_reply: &str, walls: &str, lines: &[(usize, &str)]) -> Vec<String> {
    let wss = Wss::new(
        WssConfig::new(SocketAddr::from(([127, 0, 0, 1], 7435))),
        IpAddr::from([127, 0, 0, 1]),
        CancellationToken::new(),
        None,
    );
    {
        let mut state = wss.lock();
        state.positions = positions(positions_reply)
            .into_iter()
            .filter(|p| !p.2)
            .map(|p| (p.0, p.1))
            .collect();
        if let Some(n) = obstacle_count(walls).filter(|n| *n >= 0.0) {
            let found: Vec<(String, [f64; 3])> = state
                .positions
                .iter()
                .map(|(k, v)| (k.clone(), *v))
                .collect();
            for (a, pa) in &found {
                for (b, pb) in &found {
                    state.walls.insert(pair(a, b), (n, *pa, *pb));
                }
            }
        }
    }
    let mut connections: Vec<Option<(String, CancellationToken)>> = Vec::new();
    let ip = IpAddr::from([127, 0, 0, 1]);
    lines
        .iter()
        .map(|&(c, line)| {
            if c >= connections.len() {
                connections.resize_with(c + 1, || None);
            }
            match answer(&wss, &mut connections[c], ip, line) {
                Answer::Reply(text) => text,
                Answer::Relay { other, .. } => format!("DNSREPLY {{Robot {other}}} {{Port 0}}"),
            }
        })
        .collect()
}

/// A robot as the simulator reports it: name, place, battery empty, radio off.
type Found = (String, [f64; 3], bool, bool);

/// A pair whose wall count is to be refreshed, and the two positions.
type Stale = ((String, String), [f64; 3], [f64; 3]);

/// A pair's wall count (`None` or negative: unknown) and the two positions it was counted at.
type Counted = ((String, String), Option<f64>, [f64; 3], [f64; 3]);

impl Wss {
    /// Takes the simulator's robots: kicks registered robots it does not have (or whose
    /// battery is empty); returns the registered robots it has and the pairs whose wall
    /// count is missing or was counted more than 1 m (squared) away.
    fn observe(&self, found: &[Found], only: Option<&str>) -> (Vec<String>, Vec<Stale>) {
        let mut state = self.lock();
        match only {
            None => {
                state.positions = found
                    .iter()
                    .filter(|f| !f.2)
                    .map(|f| (f.0.clone(), f.1))
                    .collect();
                state.radio_off = found.iter().filter(|f| f.3).map(|f| f.0.clone()).collect();
            }
            // A robot that has just registered: its own place only; the others' stay as the
            // last evaluation saw them.
            Some(name) => {
                if let Some(f) = found.iter().find(|f| f.0 == name && !f.2) {
                    state.positions.insert(f.0.clone(), f.1);
                    if f.3 {
                        state.radio_off.insert(f.0.clone());
                    }
                }
            }
        }
        let (names, kicked): (Vec<String>, Vec<String>) = state
            .robots
            .keys()
            .cloned()
            .partition(|name| state.positions.contains_key(name));
        drop(state);
        // Kicks come at the evaluations only, not at a registration: a robot may register
        // just before the simulation has it.
        for name in kicked.iter().filter(|_| only.is_none()) {
            warn!(robot = %name, "WSS: no such robot in the simulation (or its battery is empty); kicked");
            // Unregistered now (its links break, others are told it does not exist); its
            // control connection closes when its task sees the cancel.
            if let Some(r) = self.lock().robots.get(name) {
                r.kick.cancel();
            }
            unregister(self, name);
        }
        let state = self.lock();
        let mut stale = Vec::new();
        for (i, a) in names.iter().enumerate() {
            for b in &names[i + 1..] {
                let key = pair(a, b);
                let (pa, pb) = (state.positions[&key.0], state.positions[&key.1]);
                let moved = |p: [f64; 3], q: [f64; 3]| {
                    (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2) > 1.0
                };
                match state.walls.get(&key) {
                    Some((_, ca, cb)) if !moved(*ca, pa) && !moved(*cb, pb) => {}
                    _ => stale.push((key, pa, pb)),
                }
            }
        }
        (names, stale)
    }

    /// Stores the wall counts (`None`, or negative: unknown) and breaks the links that no
    /// longer hold; returns the broken links that hold again (from, to, port, target), for
    /// the caller to listen on their ports again.
    fn judge(&self, names: &[String], counted: Vec<Counted>) -> Vec<(String, String, u16, u16)> {
        let mut state = self.lock();
        for (key, count, pa, pb) in counted {
            match count {
                Some(n) if n >= 0.0 => {
                    state.walls.insert(key, (n, pa, pb));
                }
                _ => {
                    state.walls.remove(&key);
                }
            }
        }
        let verdicts: Vec<bool> = state
            .links
            .iter()
            .map(|l| {
                names.contains(&l.from)
                    && names.contains(&l.to)
                    && self.in_range(&state, &l.from, &l.to)
            })
            .collect();
        let mut resume = Vec::new();
        for (i, ok) in verdicts.into_iter().enumerate() {
            let link = &state.links[i];
            match (link.up.is_some(), ok) {
                (true, false) => {
                    info!(from = %link.from, to = %link.to, "WSS: link broken");
                    state.down(i);
                }
                (false, true) => {
                    resume.push((link.from.clone(), link.to.clone(), link.port, link.target))
                }
                _ => {}
            }
        }
        resume
    }
}

/// Wall clock: one evaluation, asking the robot monitor `m`.
async fn update(
    wss: &Arc<Wss>,
    m: &mut BufReader<TcpStream>,
    only: Option<&str>,
) -> Result<(), ()> {
    let reply = ask(m, "GETPOS").await?;
    let (names, stale) = wss.observe(&positions(&reply), only);
    let mut counted = Vec::new();
    for ((a, b), pa, pb) in stale {
        let reply = ask(m, &format!("GETOBS {{From {a}}} {{To {b}}}")).await?;
        counted.push(((a, b), obstacle_count(&reply), pa, pb));
    }
    for (from, to, port, target) in wss.judge(&names, counted) {
        // Listening again on the same port.
        match TcpListener::bind((wss.bind_ip(), port)).await {
            Ok(listener) => {
                let up = start_relay(wss, listener, &from, &to, target);
                let mut state = wss.lock();
                match state
                    .links
                    .iter_mut()
                    .find(|l| l.port == port && l.up.is_none())
                {
                    Some(link) => {
                        info!(%from, %to, port, "WSS: link resumed");
                        link.up = Some(Up::Wall(up));
                    }
                    None => up.cancel(),
                }
            }
            Err(error) => {
                warn!(%from, %to, port, %error, "WSS: cannot listen again on the relay port")
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_print_as_cpp_streams_do() {
        assert_eq!(stringify(-63.24123456), "-63.2412");
        assert_eq!(stringify(-49.67), "-49.67");
        assert_eq!(stringify(0.0), "0");
        assert_eq!(stringify(-100.0), "-100");
        assert_eq!(stringify(-123456.7), "-123457");
    }

    #[test]
    fn requests_parse_as_the_wss_grammar() {
        assert_eq!(
            parse("INIT {Robot R1} {Port 8001,8002}"),
            ("INIT", vec![("Robot", "R1"), ("Port", "8001,8002")])
        );
        assert_eq!(
            parse("GETSS {robot x} {A B C}"),
            ("GETSS", vec![("robot", "x")])
        );
        assert_eq!(
            positions(
                "POSITIONS {Robots 2} {Name A Location 1.0000,2.0000,-1.0000 BatteryEmpty False} {Name B Location 0,0,0 BatteryEmpty True}"
            ),
            vec![
                ("A".to_owned(), [1.0, 2.0, -1.0], false, false),
                ("B".to_owned(), [0.0; 3], true, false)
            ]
        );
        assert_eq!(
            positions("POSITIONS {Robots 1} {Name A Location 1,2,3 BatteryEmpty False Radio Off}"),
            vec![("A".to_owned(), [1.0, 2.0, 3.0], false, true)]
        );
    }
}
