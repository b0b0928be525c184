//! Network layer: TCP sessions and the simulation driver. Never touches rapier types.

use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

use crate::sim::SimConfig;

/// How fast simulated time runs against the wall clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimeScale {
    /// Simulated seconds per wall second.
    Factor(f64),
    /// As fast as the CPU allows.
    Max,
}

/// Everything `run` needs; `Default` is the embedded map and robots at real time.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// Simulation settings.
    pub sim: SimConfig,
    /// Simulated seconds per wall second.
    pub time_scale: TimeScale,
    /// Connections accepted at once.
    pub max_connections: usize,
}

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            sim: SimConfig::default(),
            time_scale: TimeScale::Factor(1.0),
            max_connections: 64,
        }
    }
}

/// Errors that end the server.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// The listener failed.
    #[error("listener failed: {0}")]
    Io(#[from] std::io::Error),
}

/// Serves the protocol on an already-bound listener until `shutdown` is cancelled.
pub async fn run(
    listener: TcpListener,
    config: ServerConfig,
    shutdown: CancellationToken,
) -> Result<(), ServerError> {
    let _ = (listener, config);
    shutdown.cancelled().await;
    Ok(())
}
