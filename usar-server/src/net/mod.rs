//! Network layer: accepts TCP connections, runs one session per connection, and owns the
//! thread that drives the simulation. It translates lines to commands and output messages to
//! lines; it never touches rapier types.
//!
//! ```text
//! TCP ─CommandCodec─▶ session ─Request (bounded mpsc)─▶ driver thread: World::command / step
//!  ▲                                                                │
//!  └── write_all ◀── session ◀── bounded per-client queue of Bytes ◀┘ (one chunk per tick)
//! ```

mod driver;
mod session;

use std::sync::Arc;

use tokio::net::TcpListener;
use tokio::sync::{Semaphore, mpsc};
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

impl std::str::FromStr for TimeScale {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s.eq_ignore_ascii_case("max") {
            return Ok(Self::Max);
        }
        match s.parse::<f64>() {
            Ok(k) if k.is_finite() && k > 0.0 => Ok(Self::Factor(k)),
            _ => Err(format!(
                "invalid time scale '{s}': expected a positive number or 'max'"
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
    /// Connections served at once (USARSim: 64); more are closed on accept.
    pub max_connections: usize,
    /// Longest accepted client line in bytes; longer lines are dropped with a warning.
    pub max_line_length: usize,
    /// Ticks of output buffered per client; when a client does not read and its queue is
    /// full, whole ticks of its output are dropped (counted and logged), never the others'.
    pub client_queue: usize,
    /// Record every connection's lines, both directions, into this folder (docs/recording.md).
    pub record: Option<std::path::PathBuf>,
    /// Offer lockstep (`SYNC`, docs/lockstep.md) to clients that ask. Off by default: then a
    /// `SYNC` is an unknown command like any other, and no client can hold the world.
    pub lockstep: bool,
}

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            map: Map::default_map(),
            robots: RobotCatalog::embedded(),
            sim: SimConfig::default(),
            time_scale: TimeScale::Factor(1.0),
            max_connections: 64,
            max_line_length: 64 * 1024,
            client_queue: 256,
            record: None,
            lockstep: false,
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
}

/// Serves the protocol on an already-bound listener until `shutdown` is cancelled; then
/// closes every connection (clients see EOF) and returns.
pub async fn run(
    listener: TcpListener,
    config: ServerConfig,
    shutdown: CancellationToken,
) -> Result<(), ServerError> {
    if let Some(dir) = &config.record {
        std::fs::create_dir_all(dir)?;
    }
    let world = World::new(config.map, config.robots, config.sim);
    let game_info = driver::game_info(&world);
    let (requests, inbox) = mpsc::channel(4096);
    let sim_shutdown = shutdown.child_token();
    let sim = {
        let token = sim_shutdown.clone();
        let scale = config.time_scale;
        let driver = driver::Driver::new(world, config.record.clone());
        std::thread::Builder::new()
            .name("usar-sim".into())
            .spawn(move || driver.run(inbox, scale, token))?
    };

    let tracker = TaskTracker::new();
    let slots = Arc::new(Semaphore::new(config.max_connections));
    let limits = session::Limits {
        max_line_length: config.max_line_length,
        client_queue: config.client_queue.max(1),
        record: config.record.is_some(),
        lockstep: config.lockstep,
    };
    let result = loop {
        tokio::select! {
            _ = shutdown.cancelled() => break Ok(()),
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
                let Ok(permit) = slots.clone().try_acquire_owned() else {
                    warn!(%peer, max = config.max_connections, "too many connections, closing");
                    continue;
                };
                info!(%peer, "connected");
                let _ = stream.set_nodelay(true);
                tracker.spawn(session::serve(
                    stream,
                    peer,
                    game_info.clone(),
                    requests.clone(),
                    limits,
                    shutdown.child_token(),
                    permit,
                ));
            }
        }
    };
    tracker.close();
    shutdown.cancel();
    tracker.wait().await;
    sim_shutdown.cancel();
    let _ = requests.send(driver::Request::Wake).await;
    drop(requests);
    tokio::task::spawn_blocking(move || sim.join())
        .await
        .map_err(|e| ServerError::Simulation(e.to_string()))?
        .map_err(|_| ServerError::Simulation("the simulation thread panicked".into()))?;
    result
}

/// Accept errors that concern one connection only (the listener stays usable).
fn is_transient(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::*;
    matches!(
        e.kind(),
        ConnectionAborted | ConnectionReset | Interrupted | WouldBlock
    ) || e.raw_os_error() == Some(24) // EMFILE: too many open files; retry later
}
