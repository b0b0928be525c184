//! Where the flights' server comes from: one that runs elsewhere, or (with the `local`
//! feature) a usar-server inside this process. The one place that starts an in-process
//! server and decides what that implies: lockstep at both ends, the map geometry for the
//! pictures, spawn checks before a flight, and limits for one trusted owner.
//!
//! `ucc run`, `ucc demo`, `ucc gui` and the Python package's `fly` all start here.

use crate::picture::MapGeometry;
use crate::settings::{Lockstep, RunSettings, Start};

/// A server to fly against.
#[derive(Debug, Clone)]
pub enum Backend {
    /// A server at `host:port` (usar-server or a real USARSim): lockstep as the settings ask,
    /// no map geometry (the pictures draw the laser's hits).
    Remote(String),
    /// A usar-server inside this process, on a free loopback port, configured for one
    /// trusted owner: lockstep offered and always used, no per-address connection cap
    /// (a run of many UAVs opens many connections from 127.0.0.1).
    #[cfg(feature = "local")]
    Local(Box<usar_server::ServerConfig>),
}

/// Connections an in-process server accepts in all: two per UAV for the browser's 4096
/// (a UAV may hold two for a moment between iterations); the public server's default is 256,
/// and 16 idle connections per address (docs/limits.md).
#[cfg(feature = "local")]
pub const LOCAL_CONNECTIONS: usize = 8192;

/// A started backend: the address to connect to and what the flights must know about it.
/// Dropping it stops an in-process server (without waiting); [`Server::stop`] waits.
#[derive(Debug)]
pub struct Server {
    addr: String,
    map: Option<MapGeometry>,
    /// An in-process server's image server (whether its raw pixels are B, G, R, its tile
    /// size) and WSS.
    image: Option<(String, bool, (u32, u32))>,
    wss: Option<String>,
    #[cfg(feature = "local")]
    local: Option<(usar_server::LocalServer, Box<usar_server::ServerConfig>)>,
}

/// An in-process server that did not start or stop cleanly.
#[derive(Debug, thiserror::Error)]
#[error("the local server: {0}")]
pub struct BackendError(String);

/// The side services an in-process server runs for the flights (a remote server has what
/// it has).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sides {
    /// The image server, for camera frames (docs/camera.md).
    pub camera: bool,
    /// The WSS and its robot monitor, for the radio (docs/wss.md).
    pub radio: bool,
}

impl Sides {
    /// What `settings` ask for.
    pub fn of(settings: &RunSettings) -> Self {
        Self {
            camera: settings.camera.is_some(),
            radio: settings.radio.is_some(),
        }
    }
}

impl Backend {
    /// Starts the server (a remote one is only named: nothing is connected yet).
    pub async fn start(self) -> Result<Server, BackendError> {
        self.start_with(Sides::default()).await
    }

    /// [`Backend::start`] with the side services `sides` on an in-process server.
    pub async fn start_with(self, sides: Sides) -> Result<Server, BackendError> {
        #[cfg(not(feature = "local"))]
        let _ = sides; // only an in-process server has side services
        match self {
            Self::Remote(addr) => Ok(Server {
                addr,
                map: None,
                image: None,
                wss: None,
                #[cfg(feature = "local")]
                local: None,
            }),
            #[cfg(feature = "local")]
            Self::Local(config) => {
                let config = Box::new(for_one_owner(*config));
                let map = MapGeometry::from(&config.map);
                let local_sides = usar_server::LocalSides {
                    image: sides.camera,
                    radio: sides.radio,
                };
                let local = usar_server::LocalServer::start_with((*config).clone(), local_sides)
                    .await
                    .map_err(|e| BackendError(e.to_string()))?;
                Ok(Server {
                    addr: local.addr().to_string(),
                    map: Some(map),
                    image: local.image_addr().map(|a| {
                        let tiles = config.sim.tiles;
                        (a.to_string(), config.image.bgr, (tiles.width, tiles.height))
                    }),
                    wss: local.wss_addr().map(|a| a.to_string()),
                    local: Some((local, config)),
                })
            }
        }
    }
}

/// `config` as an in-process server runs it: lockstep offered, connections limited only by
/// [`LOCAL_CONNECTIONS`].
#[cfg(feature = "local")]
fn for_one_owner(config: usar_server::ServerConfig) -> usar_server::ServerConfig {
    usar_server::ServerConfig {
        lockstep: true,
        max_connections: LOCAL_CONNECTIONS,
        max_connections_per_address: LOCAL_CONNECTIONS,
        ..config
    }
}

impl Server {
    /// `host:port` to connect to.
    pub fn addr(&self) -> &str {
        &self.addr
    }

    /// An in-process server's image server (with [`Sides::camera`]), `host:port`.
    pub fn image_server(&self) -> Option<String> {
        self.image.as_ref().map(|(addr, ..)| addr.clone())
    }

    /// Whether this is a server inside this process.
    pub fn is_local(&self) -> bool {
        self.map.is_some()
    }

    /// The map's walls and obstacles, when this process knows them (an in-process server).
    pub fn map(&self) -> Option<&MapGeometry> {
        self.map.as_ref()
    }

    /// The lockstep a flight uses here when the user asked for `wanted`: always
    /// [`Lockstep::Required`] on an in-process server (the same flight every time), as
    /// asked elsewhere.
    pub fn lockstep(&self, wanted: Lockstep) -> Lockstep {
        if self.is_local() {
            Lockstep::Required
        } else {
            wanted
        }
    }

    /// `settings` pointed at this server: its address, its lockstep ([`Server::lockstep`]
    /// of the settings' own), when known its map geometry, and an in-process server's
    /// image server and WSS for the camera and the radio.
    pub fn settings(&self, settings: RunSettings) -> RunSettings {
        let mut camera = settings.camera;
        if let (Some(camera), Some((image, bgr, tile))) = (&mut camera, &self.image) {
            camera.server = image.clone();
            camera.bgr = *bgr;
            camera.tile = *tile;
        }
        let mut radio = settings.radio;
        if let (Some(radio), Some(wss)) = (&mut radio, &self.wss) {
            radio.wss = wss.clone();
        }
        RunSettings {
            addr: self.addr.clone(),
            lockstep: self.lockstep(settings.lockstep),
            map: self.map.clone().or(settings.map),
            camera,
            radio,
            ..settings
        }
    }

    /// Why a robot of `class` (`Package.Class`) at `start` would not spawn here, in words
    /// naming what exists; `None` when it would, or when this process cannot know (a
    /// remote server, which answers a bad INIT with silence).
    pub fn spawn_problem(&self, class: &str, start: &Start) -> Option<String> {
        #[cfg(feature = "local")]
        if let Some((_, config)) = &self.local {
            let tag = match start {
                Start::Tag(tag) => Some(tag.as_str()),
                Start::Pose { .. } => None,
            };
            return config.spawn_problem(class, tag);
        }
        let _ = (class, start);
        None
    }

    /// Stops an in-process server and waits until every connection is closed.
    pub async fn stop(self) -> Result<(), BackendError> {
        #[cfg(feature = "local")]
        if let Some((local, _)) = self.local {
            return local.stop().await.map_err(|e| BackendError(e.to_string()));
        }
        Ok(())
    }
}

#[cfg(all(test, feature = "local"))]
mod tests {
    use super::*;

    #[tokio::test]
    async fn a_local_server_takes_more_connections_than_the_public_limit() {
        let server = Backend::Local(Box::default()).start().await.unwrap();
        assert!(server.is_local() && server.map().is_some());
        assert_eq!(server.lockstep(Lockstep::Off), Lockstep::Required);
        // The public server closes the 17th connection from one address at once.
        let mut streams = Vec::new();
        for _ in 0..20 {
            streams.push(tokio::net::TcpStream::connect(server.addr()).await.unwrap());
        }
        for stream in &mut streams {
            let mut reader = tokio::io::BufReader::new(stream);
            let mut line = String::new();
            tokio::io::AsyncBufReadExt::read_line(&mut reader, &mut line)
                .await
                .unwrap();
            assert!(line.starts_with("NFO"), "{line:?}");
        }
        server.stop().await.unwrap();
    }

    #[tokio::test]
    async fn a_remote_server_keeps_the_lockstep_asked_for() {
        let server = Backend::Remote("example.invalid:3000".into())
            .start()
            .await
            .unwrap();
        assert!(!server.is_local() && server.map().is_none());
        assert_eq!(server.lockstep(Lockstep::IfOffered), Lockstep::IfOffered);
        assert_eq!(
            server.spawn_problem("USARBot.Nope", &Start::Tag("x".into())),
            None
        );
    }
}
