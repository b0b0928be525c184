//! Network layer: accepts TCP connections, runs one session per connection, and owns the
//! thread that drives the simulation. It translates lines to commands and output messages to
//! lines; it never touches rapier types.
//!
//! ```text
//! TCP ─CommandCodec─▶ session ─Request (mpsc, per-client permits)─▶ driver thread: World::command / step
//!  ▲                                                                │
//!  └── write_all ◀── session ◀── bounded per-client queue of Bytes ◀┘ (one chunk per tick)
//! ```

mod driver;
pub mod image;
pub mod monitor;
mod recording;
mod request;
mod session;
mod side;
pub mod truth;
pub mod wss;

pub(crate) use driver::wait_of;

use std::collections::BTreeMap;
use std::net::IpAddr;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{info, warn};

use crate::sim::map::Map;
use crate::sim::robots::RobotCatalog;
use crate::sim::{SimConfig, World};

/// How fast simulated time runs against the wall clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimeScale {
    /// Simulated seconds per wall second (1.0 = real time, as USARSim).
    Factor(f64),
    /// As fast as the CPU allows.
    Max,
}

impl TimeScale {
    /// The slowest accepted factor (a thousandth of real time).
    pub const MIN_FACTOR: f64 = 1e-3;
    /// The fastest accepted factor (faster than any machine steps; use `max` beyond).
    pub const MAX_FACTOR: f64 = 1e6;
}

/// `max` or the factor (`1`, `0.5`, `100`): what [`FromStr`](std::str::FromStr) reads back.
impl std::fmt::Display for TimeScale {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Max => f.write_str("max"),
            Self::Factor(k) => write!(f, "{k}"),
        }
    }
}

impl std::str::FromStr for TimeScale {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s.eq_ignore_ascii_case("max") {
            return Ok(Self::Max);
        }
        match s.parse::<f64>() {
            Ok(k) if (Self::MIN_FACTOR..=Self::MAX_FACTOR).contains(&k) => Ok(Self::Factor(k)),
            _ => Err(format!(
                "invalid time scale '{s}': expected a number from {} to {} or 'max'",
                Self::MIN_FACTOR,
                Self::MAX_FACTOR
            )),
        }
    }
}

/// Everything `run` needs. `Default` is the embedded map and robots at real time.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// The world to fly in.
    pub map: Map,
    /// The robot classes INIT can spawn.
    pub robots: RobotCatalog,
    /// Simulation settings (seed, step).
    pub sim: SimConfig,
    /// Simulated seconds per wall second.
    pub time_scale: TimeScale,
    /// Connections served at once (USARSim: 64; here 256, so that a machine running a
    /// hundred local clients is served). At the limit the oldest connection that has not
    /// sent a complete line is closed to make room; if every one has, the new one is closed
    /// on accept.
    pub max_connections: usize,
    /// Connections from one IP address that have not yet sent a complete line (idle); at the
    /// limit the oldest of them is closed to make room. Connections that have sent a line
    /// are bounded only by `max_connections`: many clients of one machine (loopback) are
    /// served, and silent ones cannot lock their address out (docs/limits.md).
    pub max_connections_per_address: usize,
    /// Connections each side service (image server, USARTruth, robot monitor, WSS control
    /// port) serves at once; at the limit the oldest that has not completed a request (else
    /// the slowest sender) is closed to make room, and if there is none the new one is.
    pub side_connections: usize,
    /// Longest accepted client line in bytes; longer lines are dropped with a warning.
    pub max_line_length: usize,
    /// Chunks of output buffered per client (a tick each; at `TimeScale::Max` several ticks
    /// gathered); when a client does not read and its queue is full, whole ticks of its
    /// output are dropped (counted and logged), never the others' — except at
    /// `TimeScale::Max`, where the world waits instead (see `reader_timeout`).
    pub client_queue: usize,
    /// Bytes of output buffered per client (all its queued chunks together); past it, whole
    /// ticks are dropped (or waited for) by the same rule as a full `client_queue`.
    pub client_buffer: usize,
    /// Requests (lines) of one client the simulation serves per tick; the rest wait for the
    /// next tick, and a client with this many waiting is not read from until they are served
    /// (TCP back-pressure), so no client can hold up the world or grow the server's memory.
    pub requests_per_tick: usize,
    /// A new connection that has not sent one complete line within this time is closed (on
    /// the Gamebots port, USARTruth, the robot monitor and the WSS's control port; an image
    /// client may only read the frame sent on connect).
    pub idle_timeout: Duration,
    /// A connection that has started a line (a request) and not ended it within this time
    /// is closed, on every port (slow senders).
    pub line_timeout: Duration,
    /// Offer lockstep (`SYNC`, docs/lockstep.md) to clients that ask. Off by default: then a
    /// `SYNC` is an unknown command like any other, and no client can hold the world.
    pub lockstep: bool,
    /// Wall-clock time a lockstep client may take to send its next `SYNC` before it is
    /// removed from the barrier (with a warning) and the world goes on without it.
    pub lockstep_timeout: Duration,
    /// Clients in the lockstep barrier at once (the first to send `SYNC`); the `SYNC`s of
    /// others are ignored (logged), so they are never waited for.
    pub lockstep_clients: usize,
    /// While clients outside the barrier are connected, the share of wall time (0 to 1,
    /// measured over 10 s) the barrier may hold the world; past it, the member that held it
    /// longest leaves the barrier for good (warning). 1 (the default of the library, whose
    /// in-process servers serve one program's clients) turns the rule off; the
    /// `usar-server` program, a shared server, uses 0.5.
    pub lockstep_share: f64,
    /// While anyone else is connected, the share of wall time (0 to 1) the world may wait
    /// for members that joined the barrier less than 10 s ago, all of them together: their
    /// first step, and any later step's wait past 25 ms, from a bucket of 0.1 s refilled at
    /// this rate; once it is empty the world does not wait for them until it is full again
    /// (a client that reconnects again and again cannot hold the others, issue #56;
    /// docs/lockstep.md). 1 (the library's default) turns the rule off; the `usar-server`
    /// program uses 0.05.
    pub lockstep_join_share: f64,
    /// At `time_scale: Max` the world waits for its slowest reader instead of dropping
    /// output; a client whose queue has had no room for this long (wall clock) is left
    /// behind: its output is dropped, as at real time, until it reads again.
    pub reader_timeout: Duration,
    /// Record every connection's lines, both directions, into this folder (docs/recording.md).
    pub record: Option<std::path::PathBuf>,
    /// How the image server sends frames (when [`SideListeners::image`] is given).
    pub image: image::ImageConfig,
}

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            map: Map::default_map(),
            robots: RobotCatalog::embedded(),
            sim: SimConfig::default(),
            time_scale: TimeScale::Factor(1.0),
            max_connections: 256,
            max_connections_per_address: 16,
            side_connections: 256,
            max_line_length: 64 * 1024,
            client_queue: 256,
            client_buffer: 4 << 20,
            requests_per_tick: 32,
            idle_timeout: Duration::from_secs(30),
            line_timeout: Duration::from_secs(30),
            lockstep: false,
            lockstep_timeout: Duration::from_secs(10),
            lockstep_clients: usize::MAX,
            lockstep_share: 1.0,
            lockstep_join_share: 1.0,
            reader_timeout: Duration::from_secs(10),
            record: None,
            image: image::ImageConfig::default(),
        }
    }
}

/// Errors that end the server.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// Accepting connections failed.
    #[error("listener failed: {0}")]
    Io(#[from] std::io::Error),
    /// The simulation thread panicked.
    #[error("simulation thread failed: {0}")]
    Simulation(String),
    /// Some recording files (`ServerConfig::record`) could not be created or written to the
    /// end (a full disk); what was written of them is kept, in whole lines.
    #[error("the recording is incomplete: {} could not be written to the end{}",
        shown_files(.0), if .0.len() > 1 { " (each error was logged)" } else { "" })]
    RecordingIncomplete(Vec<std::path::PathBuf>),
}

/// Up to 5 files by name, then how many more.
fn shown_files(files: &[std::path::PathBuf]) -> String {
    let mut text = files
        .iter()
        .take(5)
        .map(|f| f.display().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    if files.len() > 5 {
        text.push_str(&format!(" and {} more", files.len() - 5));
    }
    text
}

/// The side services' listeners, bound by the caller; `None` leaves a service off.
#[derive(Debug, Default)]
pub struct SideListeners {
    /// The image server (USARSim: TCP 5003; docs/camera.md).
    pub image: Option<TcpListener>,
    /// USARTruth (USARSim: TCP 3989; docs/usartruth.md).
    pub truth: Option<TcpListener>,
    /// The robot monitor a WSS asks for positions and wall counts (USARSim: TCP 7435;
    /// docs/wss.md).
    pub monitor: Option<TcpListener>,
    /// A Wireless Simulation Server (USARSim: TCP 50000; docs/wss.md) that asks this
    /// server's robot monitor (which must be on) with the default propagation model.
    pub wss: Option<TcpListener>,
}

/// Serves the protocol on an already-bound listener until `shutdown` is cancelled; then
/// closes every connection (clients see EOF) and returns. If the simulation thread dies,
/// every connection is closed and the error is returned at once.
pub async fn run(
    listener: TcpListener,
    config: ServerConfig,
    shutdown: CancellationToken,
) -> Result<(), ServerError> {
    run_with(listener, SideListeners::default(), config, shutdown).await
}

/// [`run`] with the side services whose listeners are given (the image server, USARTruth,
/// the WSS and its robot monitor).
pub async fn run_with(
    listener: TcpListener,
    side: SideListeners,
    config: ServerConfig,
    shutdown: CancellationToken,
) -> Result<(), ServerError> {
    // The WSS asks this server's robot monitor, on the loopback when it listens on any address.
    let wss_monitor = match (&side.wss, &side.monitor) {
        (None, _) => None,
        (Some(_), None) => {
            return Err(ServerError::Io(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "the WSS needs the robot monitor (it asks it for positions and walls)",
            )));
        }
        (Some(_), Some(m)) => {
            let at = m.local_addr()?;
            Some(match at.ip() {
                ip if ip.is_unspecified() && ip.is_ipv4() => {
                    std::net::SocketAddr::from(([127, 0, 0, 1], at.port()))
                }
                ip if ip.is_unspecified() => {
                    std::net::SocketAddr::from((std::net::Ipv6Addr::LOCALHOST, at.port()))
                }
                _ => at,
            })
        }
    };
    if let Some(dir) = &config.record {
        std::fs::create_dir_all(dir)?;
    }
    let tiles = config.sim.tiles;
    let world = World::new(config.map, config.robots, config.sim);
    let feed = side.image.as_ref().map(|_| image::Feed::new());
    let game_info = driver::game_info(&world);
    let (requests, inbox) = std::sync::mpsc::channel();
    // With lockstep the WSS runs on the simulated clock (docs/wss.md), called by the
    // simulation thread; without, on the wall clock, asking the robot monitor.
    let wss_config = |monitor| wss::WssConfig {
        max_connections: config.side_connections,
        idle_timeout: config.idle_timeout,
        line_timeout: config.line_timeout,
        ..wss::WssConfig::new(monitor)
    };
    // Relay ports listen where the control port does (`--bind`).
    let relay_ip = match &side.wss {
        Some(listener) => Some(listener.local_addr()?.ip()),
        None => None,
    };
    let radio = match (wss_monitor, relay_ip) {
        (Some(monitor), Some(relay_ip)) if config.lockstep => Some(wss::Clock::new(
            wss_config(monitor),
            relay_ip,
            requests.clone(),
            shutdown.child_token(),
        )?),
        _ => None,
    };
    let (radio_serve, wall_wss) = match &radio {
        Some(clock) => (side.wss.map(|listener| clock.serve(listener)), None),
        None => (None, side.wss),
    };
    let wants_room = Arc::new(AtomicBool::new(false));
    let sim_shutdown = shutdown.child_token();
    // Cancelled by the simulation thread if it unwinds (a bug): the server then stops.
    let sim_died = CancellationToken::new();
    let sim = {
        let token = sim_shutdown.clone();
        let died = sim_died.clone();
        let driver = driver::Driver::new(
            world,
            driver::Settings {
                scale: config.time_scale,
                record_dir: config.record.clone(),
                requests_per_tick: config.requests_per_tick.max(1),
                client_buffer: config.client_buffer.max(1),
                lockstep_timeout: config.lockstep_timeout,
                lockstep_clients: config.lockstep_clients.max(1),
                lockstep_share: config.lockstep_share,
                lockstep_join_share: config.lockstep_join_share,
                reader_timeout: config.reader_timeout,
            },
            wants_room.clone(),
            feed.as_ref()
                .map(|feed| image::Capture::new(feed.clone(), config.image, tiles)),
            radio,
        );
        std::thread::Builder::new()
            .name("usar-sim".into())
            .spawn(move || {
                let _alarm = DeathAlarm(died);
                driver.run(inbox, token)
            })?
    };

    let tracker = TaskTracker::new();
    let side_limits = side::Limits {
        max: config.side_connections,
        idle: Some(config.idle_timeout),
        line: config.line_timeout,
    };
    if let (Some(listener), Some(feed)) = (side.image, feed) {
        tracker.spawn(image::accept(
            listener,
            feed,
            requests.clone(),
            (config.image, side_limits),
            shutdown.child_token(),
            tracker.clone(),
        ));
    }
    if let Some(listener) = side.truth {
        tracker.spawn(truth::serve(
            listener,
            requests.clone(),
            (tracker.clone(), side_limits),
            shutdown.child_token(),
        ));
    }
    if let Some(serve) = radio_serve {
        tracker.spawn(serve);
    }
    if let (Some(listener), Some(monitor)) = (wall_wss, wss_monitor) {
        tracker.spawn(wss::serve(
            listener,
            wss_config(monitor),
            shutdown.child_token(),
        ));
    }
    if let Some(listener) = side.monitor {
        tracker.spawn(monitor::serve(
            listener,
            requests.clone(),
            (tracker.clone(), side_limits),
            shutdown.child_token(),
        ));
    }
    let registry: Arc<Mutex<Registry>> = Arc::default();
    let caps = (
        config.max_connections.max(1),
        config.max_connections_per_address.max(1),
    );
    let limits = session::Limits {
        max_line_length: config.max_line_length,
        client_queue: config.client_queue.max(1),
        backlog: config.requests_per_tick.max(1) * 2,
        idle_timeout: config.idle_timeout,
        line_timeout: config.line_timeout,
        lockstep: config.lockstep,
        record: config.record.is_some(),
    };
    let result = loop {
        tokio::select! {
            _ = shutdown.cancelled() => break Ok(()),
            _ = sim_died.cancelled() => {
                tracing::error!("the simulation thread died; stopping the server");
                break Err(ServerError::Simulation("the simulation thread panicked".into()));
            }
            accepted = listener.accept() => {
                let (stream, peer) = match accepted {
                    Ok(x) => x,
                    Err(e) if is_transient(&e) => {
                        warn!(error = %e, "accept failed");
                        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
                        continue;
                    }
                    Err(e) => break Err(ServerError::Io(e)),
                };
                // At a limit, the oldest connection that has not sent a complete line makes
                // room (closed); only without one is the new connection refused.
                let Some(entry) = Registry::admit(&registry, peer.ip(), caps) else {
                    warn!(%peer, max = config.max_connections,
                        "too many connections, each has sent a line; closing");
                    continue;
                };
                info!(%peer, "connected");
                let _ = stream.set_nodelay(true);
                tracker.spawn(session::serve(
                    stream,
                    peer,
                    game_info.clone(),
                    (requests.clone(), wants_room.clone()),
                    limits,
                    shutdown.child_token(),
                    entry,
                ));
            }
        }
    };
    tracker.close();
    shutdown.cancel();
    tracker.wait().await;
    sim_shutdown.cancel();
    let _ = requests.send(request::Request::Wake);
    drop(requests);
    let joined = tokio::task::spawn_blocking(move || sim.join())
        .await
        .map_err(|e| ServerError::Simulation(e.to_string()))?;
    result?;
    let incomplete =
        joined.map_err(|_| ServerError::Simulation("the simulation thread panicked".into()))?;
    if incomplete.is_empty() {
        Ok(())
    } else {
        Err(ServerError::RecordingIncomplete(incomplete))
    }
}

/// Cancels its token when dropped during a panic (the simulation thread unwinding).
struct DeathAlarm(CancellationToken);

impl Drop for DeathAlarm {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.cancel();
        }
    }
}

/// The connections being served, oldest first: at a limit, the oldest connection that has
/// not sent a complete line is closed to make room for a new one (docs/limits.md).
#[derive(Default)]
struct Registry {
    next: u64,
    live: BTreeMap<u64, Entry>,
}

struct Entry {
    ip: IpAddr,
    /// The client has sent a complete line.
    spoke: bool,
    evicted: CancellationToken,
}

/// A connection's place in the [`Registry`]; its session holds it, and leaves with it.
pub(super) struct Registered {
    registry: Arc<Mutex<Registry>>,
    id: u64,
    /// Cancelled when the connection is closed to make room for a new one.
    pub(super) evicted: CancellationToken,
}

fn lock(registry: &Mutex<Registry>) -> std::sync::MutexGuard<'_, Registry> {
    registry.lock().unwrap_or_else(|e| e.into_inner())
}

impl Registry {
    /// A place for a new connection from `ip` under the limits `(max, max_idle)`: at most
    /// `max` connections in all, at most `max_idle` from one address that have not sent a
    /// complete line. At either limit the oldest connection that has not sent one (from
    /// `ip`, for the second) is closed to make room; `None` when every connection has.
    fn admit(
        registry: &Arc<Mutex<Self>>,
        ip: IpAddr,
        (max, max_idle): (usize, usize),
    ) -> Option<Registered> {
        let mut r = lock(registry);
        let idle_here = r.live.values().filter(|e| e.ip == ip && !e.spoke).count();
        if idle_here >= max_idle {
            r.evict_quiet(Some(ip));
        }
        if r.live.len() >= max && !r.evict_quiet(None) {
            return None;
        }
        let id = r.next;
        r.next += 1;
        let evicted = CancellationToken::new();
        r.live.insert(
            id,
            Entry {
                ip,
                spoke: false,
                evicted: evicted.clone(),
            },
        );
        Some(Registered {
            registry: registry.clone(),
            id,
            evicted,
        })
    }

    /// Closes the oldest connection (from `ip`, if given) that has not sent a complete line,
    /// giving its place back at once; `false` if there is none.
    fn evict_quiet(&mut self, ip: Option<IpAddr>) -> bool {
        let oldest = self
            .live
            .iter()
            .find(|(_, e)| ip.is_none_or(|ip| e.ip == ip) && !e.spoke)
            .map(|(id, _)| *id);
        let Some(entry) = oldest.and_then(|id| self.live.remove(&id)) else {
            return false;
        };
        entry.evicted.cancel();
        true
    }
}

impl Registered {
    /// The client has sent a complete line: it no longer counts against its address's
    /// limit of idle connections, and is not closed to make room.
    pub(super) fn spoke(&self) {
        if let Some(entry) = lock(&self.registry).live.get_mut(&self.id) {
            entry.spoke = true;
        }
    }
}

impl Drop for Registered {
    fn drop(&mut self) {
        lock(&self.registry).live.remove(&self.id);
    }
}

/// Accept errors that concern one connection only (the listener stays usable).
pub(crate) fn is_transient(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::*;
    matches!(
        e.kind(),
        ConnectionAborted | ConnectionReset | Interrupted | WouldBlock
    ) || e.raw_os_error() == Some(24) // EMFILE: too many open files; retry later
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};

    #[test]
    fn a_time_scale_prints_what_it_parses_from() {
        for text in ["max", "1", "0.5", "250", "0.001"] {
            let scale: TimeScale = text.parse().unwrap();
            assert_eq!(scale.to_string(), text);
            assert_eq!(scale.to_string().parse::<TimeScale>(), Ok(scale));
        }
        assert_eq!("MAX".parse::<TimeScale>().unwrap().to_string(), "max");
    }

    #[test]
    fn the_per_address_cap_counts_idle_connections_only() {
        let registry: Arc<Mutex<Registry>> = Arc::default();
        let local = IpAddr::from([127, 0, 0, 1]);
        // 40 active connections of one address (cap of idle ones: 16) are all served.
        let active: Vec<Registered> = (0..40)
            .map(|_| {
                let r = Registry::admit(&registry, local, (64, 16)).expect("served");
                r.spoke();
                r
            })
            .collect();
        assert!(active.iter().all(|r| !r.evicted.is_cancelled()));
        // 16 idle ones, then a 17th: the oldest idle one makes room, no active one.
        let idle: Vec<Registered> = (0..16)
            .map(|_| Registry::admit(&registry, local, (64, 16)).unwrap())
            .collect();
        let newest = Registry::admit(&registry, local, (64, 16)).unwrap();
        assert!(idle[0].evicted.is_cancelled() && !idle[1].evicted.is_cancelled());
        assert!(active.iter().all(|r| !r.evicted.is_cancelled()));
        // At the cap of all connections with every one active, a new one is refused.
        let other = IpAddr::from([127, 0, 0, 2]);
        for r in idle.iter().skip(1) {
            r.spoke();
        }
        newest.spoke();
        assert_eq!(lock(&registry).live.len(), 56);
        let more: Vec<Registered> = (0..8)
            .map(|_| {
                let r = Registry::admit(&registry, other, (64, 16)).unwrap();
                r.spoke();
                r
            })
            .collect();
        assert_eq!(more.len(), 8);
        assert!(Registry::admit(&registry, other, (64, 16)).is_none());
    }

    #[tokio::test]
    async fn the_server_stops_with_an_error_when_the_simulation_dies() {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let shutdown = CancellationToken::new();
        let server = tokio::spawn(run(listener, ServerConfig::default(), shutdown.clone()));
        let stream = tokio::net::TcpStream::connect(addr).await.unwrap();
        let (read, mut write) = stream.into_split();
        let mut read = BufReader::new(read);
        let mut line = String::new();
        read.read_line(&mut line).await.unwrap();
        write
            .write_all(b"__CRASH_THE_SIMULATION__\r\n")
            .await
            .unwrap();
        // Without anyone cancelling: the server ends on its own, with the error.
        let result = tokio::time::timeout(Duration::from_secs(60), server)
            .await
            .expect("the server lingers after its simulation died")
            .unwrap();
        assert!(
            matches!(result, Err(ServerError::Simulation(_))),
            "{result:?}"
        );
        line.clear();
        assert_eq!(
            read.read_line(&mut line).await.unwrap(),
            0,
            "clients see EOF"
        );
    }
}
