//! A USARSim (UDK) stand-in: speaks the Gamebots text protocol and flies simulated
//! quadrotors with rapier3d, headless and as fast as asked.
//!
//! Layout:
//! * [`sim`] — the simulation, the `usar-sim` crate re-exported: synchronous and
//!   deterministic (world, robots, sensors, maps); no tokio, no wall clock.
//! * [`net`] — TCP sessions and the driver thread that owns the world; [`run`] serves the
//!   protocol on a bound listener.
//! * [`replay`] — serves a recording or a real capture to clients.
//! * [`LocalServer`] — a server inside the calling process on a free port.
//!
//! ```no_run
//! # async fn demo() -> Result<(), Box<dyn std::error::Error>> {
//! use tokio::io::{AsyncBufReadExt, BufReader};
//! use tokio_util::sync::CancellationToken;
//!
//! let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
//! let addr = listener.local_addr()?;
//! let shutdown = CancellationToken::new();
//! let server = tokio::spawn(usar_server::run(
//!     listener,
//!     usar_server::ServerConfig::default(),
//!     shutdown.clone(),
//! ));
//! let stream = tokio::net::TcpStream::connect(addr).await?;
//! let mut line = String::new();
//! BufReader::new(stream).read_line(&mut line).await?;
//! assert!(line.starts_with("NFO {Gametype BotDeathMatch}"));
//! shutdown.cancel();
//! server.await??;
//! # Ok(())
//! # }
//! ```

mod args;
mod local;
pub mod logging;
pub mod net;
pub mod replay;

pub use usar_sim as sim;

pub use args::{ArgsError, ServerArgs};
pub use local::{LocalServer, LocalSides};
pub use net::image::ImageConfig;
pub use net::{ServerConfig, ServerError, SideListeners, TimeScale, run, run_with};

/// Cancels `token` on Ctrl-C or SIGTERM, for programs (`usar-server`, `ucc`); call it
/// inside a tokio runtime. The handlers are in place when it returns, so a signal sent
/// once the program has said it is ready is never lost: installed by a spawned task
/// instead, a SIGTERM that came between tokio's handler and the task's listener was
/// swallowed, and the server ran on (a test hung on it).
pub fn cancel_on_signal(token: tokio_util::sync::CancellationToken) {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        if let (Ok(mut interrupt), Ok(mut terminate)) = (
            signal(SignalKind::interrupt()),
            signal(SignalKind::terminate()),
        ) {
            tokio::spawn(async move {
                tokio::select! {
                    _ = interrupt.recv() => {}
                    _ = terminate.recv() => {}
                }
                tracing::info!("signal: stopping");
                token.cancel();
            });
            return;
        }
    }
    tokio::spawn(async move {
        let _ = tokio::signal::ctrl_c().await;
        tracing::info!("signal: stopping");
        token.cancel();
    });
}
