//! A server inside the calling process, on a free loopback port: what `ucc run --local`,
//! `ucc demo`, the benchmarks and the tests use.

use std::net::SocketAddr;
use std::time::Duration;

use tokio_util::sync::CancellationToken;

use crate::net::{ServerConfig, ServerError, SideListeners, run_with};

/// A usar-server running on a tokio task of the caller's runtime, on `127.0.0.1` and a port
/// the OS chose. Dropping it stops the server (without waiting); [`LocalServer::stop`] waits.
///
/// ```
/// # #[tokio::main(flavor = "current_thread")]
/// # async fn main() -> Result<(), usar_server::ServerError> {
/// let server = usar_server::LocalServer::start(usar_server::ServerConfig::default()).await?;
/// let stream = tokio::net::TcpStream::connect(server.addr()).await?;
/// drop(stream);
/// server.stop().await?;
/// # Ok(())
/// # }
/// ```
#[derive(Debug)]
pub struct LocalServer {
    addr: SocketAddr,
    image: Option<SocketAddr>,
    wss: Option<SocketAddr>,
    shutdown: CancellationToken,
    task: Option<tokio::task::JoinHandle<Result<(), ServerError>>>,
}

impl LocalServer {
    /// Binds a free loopback port and starts serving `config` on it.
    pub async fn start(config: ServerConfig) -> Result<Self, ServerError> {
        Self::start_with(config, LocalSides::default()).await
    }

    /// [`LocalServer::start`] with side services, each on a free loopback port of its own.
    pub async fn start_with(config: ServerConfig, sides: LocalSides) -> Result<Self, ServerError> {
        let bind = async |on: bool| -> Result<_, ServerError> {
            Ok(match on {
                true => Some(tokio::net::TcpListener::bind("127.0.0.1:0").await?),
                false => None,
            })
        };
        let listener = bind(true).await?.expect("bound");
        let addr = listener.local_addr()?;
        let side = SideListeners {
            image: bind(sides.image).await?,
            truth: None,
            monitor: bind(sides.radio).await?,
            wss: bind(sides.radio).await?,
        };
        let at = |l: &Option<tokio::net::TcpListener>| l.as_ref().and_then(|l| l.local_addr().ok());
        let (image, wss) = (at(&side.image), at(&side.wss));
        let shutdown = CancellationToken::new();
        let task = tokio::spawn(run_with(listener, side, config, shutdown.clone()));
        Ok(Self {
            addr,
            image,
            wss,
            shutdown,
            task: Some(task),
        })
    }

    /// The image server's address (with [`LocalSides::image`]).
    pub fn image_addr(&self) -> Option<SocketAddr> {
        self.image
    }

    /// The WSS's address (with [`LocalSides::radio`]).
    pub fn wss_addr(&self) -> Option<SocketAddr> {
        self.wss
    }

    /// The address to connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops the server and waits (up to 5 s) until every connection is closed.
    pub async fn stop(mut self) -> Result<(), ServerError> {
        self.shutdown.cancel();
        let Some(task) = self.task.take() else {
            return Ok(());
        };
        match tokio::time::timeout(Duration::from_secs(5), task).await {
            Ok(Ok(result)) => result,
            Ok(Err(e)) => Err(ServerError::Simulation(format!("server task failed: {e}"))),
            Err(_) => Err(ServerError::Simulation(
                "the server did not stop within 5 s".into(),
            )),
        }
    }
}

/// The side services a [`LocalServer`] runs besides the Gamebots port (none by default).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LocalSides {
    /// The image server (docs/camera.md).
    pub image: bool,
    /// The WSS and its robot monitor (docs/wss.md).
    pub radio: bool,
}

impl Drop for LocalServer {
    fn drop(&mut self) {
        self.shutdown.cancel();
    }
}

impl ServerConfig {
    /// Why `INIT {ClassName class} [{Start tag}]` would not spawn a robot on this server, in
    /// words for a user (naming what exists); `None` when it would. A stock USARSim answers
    /// a bad INIT with silence, so a client of a local server asks here first.
    pub fn spawn_problem(&self, class: &str, start_tag: Option<&str>) -> Option<String> {
        if let Err(unknown) = self.robots.class(class) {
            return Some(unknown.to_string());
        }
        let tag = start_tag?;
        if self.map.find_start(tag).is_some() {
            return None;
        }
        let known: Vec<&str> = self.map.starts().iter().map(|s| s.tag.as_str()).collect();
        Some(format!(
            "map {} has no PlayerStart {tag:?} (its starts: {})",
            self.map.level(),
            if known.is_empty() {
                "none".into()
            } else {
                known.join(", ")
            }
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spawn_problems_name_what_exists() {
        let config = ServerConfig::default();
        assert_eq!(config.spawn_problem("USARBot.stsAirRobot", None), None);
        assert_eq!(config.spawn_problem("usarbot.airrobot", None), None);
        let bad = config.spawn_problem("USARBot.Nope", None).unwrap();
        assert!(bad.contains("USARBot.stsAirRobot"), "{bad}");
        let tag = &config.map.starts()[0].tag;
        assert_eq!(config.spawn_problem("USARBot.AirRobot", Some(tag)), None);
        let bad = config
            .spawn_problem("USARBot.AirRobot", Some("Nowhere"))
            .unwrap();
        assert!(
            bad.contains("no PlayerStart \"Nowhere\"") && bad.contains(tag.as_str()),
            "{bad}"
        );
    }
}
