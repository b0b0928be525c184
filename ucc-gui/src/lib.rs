//! ucc-gui: the UAV Control Center in the browser (`ucc gui`).
//!
//! [`serve`] serves one page (HTML, CSS and JS embedded in the binary: nothing is fetched
//! from the internet) and a WebSocket at `/ws`. The Rust side owns the state ([`hub::Hub`]):
//! the page sends requests (`{"op": "create", ...}`) and renders the updates it gets 20
//! times a second (only what changed: each UAV's state, new trail points, new log lines).
//! Runs go through ucc-client's runner, in [`runs`] (the only module that uses it);
//! scenarios fly in this process through its `Episode`, in [`scenario`]. The
//! guard (`guard.rs`), the WebSocket session (`socket.rs`) and the HTTP API (`api.rs`)
//! each have a module; the state and its requests live in [`hub`].
//!
//! Security (docs/security.md, "The control center page"): a request whose `Host` does not
//! name this server is refused (DNS rebinding), and so is a request from a page of another
//! site (`Origin`, `Sec-Fetch-Site`), WebSocket or not; a non-loopback listener requires a
//! token (`?token=`), printed in the URL at start. A peer that sends slowly, does not read,
//! or whose page stops answering is dropped after [`GuiConfig::page_timeout`] (`listen.rs`).

mod api;
mod guard;
pub mod hub;
mod listen;
pub mod runs;
pub mod scenario;
mod socket;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::Path;
use axum::http::{StatusCode, header};
use axum::middleware;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use ucc_client::Backend;
use usar_server::ServerConfig;

pub use guard::Hosts;
pub use socket::{MAX_MESSAGE, MAX_PAGES, REQUESTS_PER_UPDATE};

use crate::hub::{Hub, Shared};

const INDEX_HTML: &str = include_str!("assets/index.html");

/// The page's files, embedded: `(name, content type, bytes)`. The page's own logic is in ES
/// modules (no bundler); the vendored libraries are pinned, minified, with their licences
/// (`assets/vendor/README.md`).
const ASSETS: &[(&str, &str, &str)] = &[
    ("app.js", "text/javascript", include_str!("assets/app.js")),
    (
        "logic.js",
        "text/javascript",
        include_str!("assets/logic.js"),
    ),
    (
        "map2d.js",
        "text/javascript",
        include_str!("assets/map2d.js"),
    ),
    ("side.js", "text/javascript", include_str!("assets/side.js")),
    (
        "camera.js",
        "text/javascript",
        include_str!("assets/camera.js"),
    ),
    (
        "scenario.js",
        "text/javascript",
        include_str!("assets/scenario.js"),
    ),
    (
        "plots.js",
        "text/javascript",
        include_str!("assets/plots.js"),
    ),
    (
        "view3d.js",
        "text/javascript",
        include_str!("assets/view3d.js"),
    ),
    ("style.css", "text/css", include_str!("assets/style.css")),
    (
        "vendor/three.module.min.js",
        "text/javascript",
        include_str!("assets/vendor/three.module.min.js"),
    ),
    (
        "vendor/uPlot.iife.min.js",
        "text/javascript",
        include_str!("assets/vendor/uPlot.iife.min.js"),
    ),
    (
        "vendor/uPlot.min.css",
        "text/css",
        include_str!("assets/vendor/uPlot.min.css"),
    ),
];

/// The content security policy of the page: everything from this server, nothing inline.
const CSP: &str = "default-src 'self'; connect-src 'self'; img-src 'self' data: blob:; object-src 'none'; base-uri 'none'; frame-ancestors 'none'";

/// The side services of the local server: the image server, for the camera panel.
pub(crate) const CAMERA: ucc_client::backend::Sides = ucc_client::backend::Sides {
    camera: true,
    radio: false,
};

/// How often a page gets an update.
pub const UPDATE_PERIOD: Duration = Duration::from_millis(50);

/// The default of [`GuiConfig::page_timeout`] (`--page-timeout`).
pub const PAGE_TIMEOUT: Duration = Duration::from_secs(30);

/// Which server the UAVs fly on.
#[derive(Debug, Clone)]
pub enum ServerChoice {
    /// A USARSim or usar-server at `host:port`.
    Remote(String),
    /// A usar-server started inside this process with this configuration (lockstep; the
    /// page can change its speed).
    Local(Box<ServerConfig>),
}

/// What [`serve`] serves.
#[derive(Debug, Clone)]
pub struct GuiConfig {
    /// The server.
    pub server: ServerChoice,
    /// Where runs write their logs, trajectories, pictures and results.
    pub log_dir: PathBuf,
    /// The token every API request must carry; required when listening beyond the loopback.
    pub token: Option<String>,
    /// Host names the page may be reached by besides this server's address and the
    /// loopback's (`--allow-host`): a request naming any other host is refused.
    pub allowed_hosts: Vec<String>,
    /// How long a peer may take to send a request's headers or body, leave a response or
    /// its page's updates unread, or (a page) not answer the server's pings: then its
    /// connection ends, and with it its page's slot (`--page-timeout`, default
    /// [`PAGE_TIMEOUT`]).
    pub page_timeout: Duration,
}

impl Default for GuiConfig {
    /// `ucc gui`'s defaults: a USARSim at `localhost:3000`, files in `ucc-logs`.
    fn default() -> Self {
        Self {
            server: ServerChoice::Remote("localhost:3000".into()),
            log_dir: PathBuf::from("ucc-logs"),
            token: None,
            allowed_hosts: Vec::new(),
            page_timeout: PAGE_TIMEOUT,
        }
    }
}

/// Why the control center could not run.
#[derive(Debug, thiserror::Error)]
pub enum GuiError {
    /// Listening beyond the loopback without a token.
    #[error("listening on {addr}, which is not a loopback address, needs a token")]
    TokenRequired {
        /// The listener's address.
        addr: SocketAddr,
    },
    /// The local server did not start.
    #[error("cannot start {0}")]
    LocalServer(#[from] ucc_client::backend::BackendError),
    /// Serving failed.
    #[error("cannot serve the page: {0}")]
    Io(#[from] std::io::Error),
}

/// The local server and the configuration it was started with.
struct Local {
    config: ServerConfig,
    geometry: ucc_client::picture::MapGeometry,
    server: Option<ucc_client::backend::Server>,
}

#[derive(Clone)]
pub(crate) struct App {
    shared: Arc<Shared>,
    local: Arc<tokio::sync::Mutex<Option<Local>>>,
    token: Option<String>,
    /// Cancelled by Quit.
    shutdown: CancellationToken,
    /// The `Host` values answered.
    hosts: guard::Hosts,
    /// Refused requests, for the log.
    refusals: Arc<std::sync::Mutex<usar_proto::shown::Repeats>>,
    /// [`GuiConfig::page_timeout`].
    page_timeout: Duration,
    robots: Vec<String>,
    /// WebSocket pages open.
    pages: Arc<std::sync::atomic::AtomicUsize>,
}

/// A fresh random token (128 bits, hex).
pub fn new_token() -> String {
    let mut bytes = [0u8; 16];
    if let Ok(mut f) = std::fs::File::open("/dev/urandom") {
        use std::io::Read;
        if f.read_exact(&mut bytes).is_ok() {
            return bytes.iter().map(|b| format!("{b:02x}")).collect();
        }
    }
    // No /dev/urandom: std's randomly keyed hasher, twice.
    use std::hash::{BuildHasher, RandomState};
    let a = RandomState::new().hash_one(std::time::SystemTime::now());
    let b = RandomState::new().hash_one(std::process::id());
    format!("{a:016x}{b:016x}")
}

/// The URL to open for a listener at `addr`.
pub fn url(addr: SocketAddr, token: Option<&str>) -> String {
    let host = if addr.ip().is_unspecified() {
        "127.0.0.1".to_owned()
    } else if addr.is_ipv6() {
        format!("[{}]", addr.ip())
    } else {
        addr.ip().to_string()
    };
    match token {
        Some(t) => format!("http://{host}:{}/?token={t}", addr.port()),
        None => format!("http://{host}:{}/", addr.port()),
    }
}

/// Serves the control center on `listener` until `shutdown` is cancelled; then stops every
/// run (their files are written) and the local server.
pub async fn serve(
    listener: TcpListener,
    config: GuiConfig,
    shutdown: CancellationToken,
) -> Result<(), GuiError> {
    let addr = listener.local_addr()?;
    let loopback_only = addr.ip().is_loopback();
    if !loopback_only && config.token.is_none() {
        return Err(GuiError::TokenRequired { addr });
    }
    let (server_addr, local, robots) = match config.server {
        ServerChoice::Remote(a) => (
            a,
            None,
            vec!["stsAirRobot".to_owned(), "AirRobot".to_owned()],
        ),
        ServerChoice::Local(c) => {
            // The Backend configures it for its one owner, this process: no per-address cap
            // (50 UAVs from one page are 50 connections from 127.0.0.1).
            let config = *c;
            let server = Backend::Local(Box::new(config.clone()))
                .start_with(CAMERA)
                .await?;
            let robots = config
                .robots
                .classes()
                .iter()
                .map(|r| r.class.trim_start_matches("USARBot.").to_owned())
                .collect();
            (
                server.addr().to_string(),
                Some(Local {
                    geometry: ucc_client::picture::MapGeometry::from(&config.map),
                    config,
                    server: Some(server),
                }),
                robots,
            )
        }
    };
    let mut hub = Hub::new(server_addr, local.is_some(), config.log_dir);
    if let Some(l) = &local {
        hub.image_server = l.server.as_ref().and_then(|s| s.image_server());
        hub.camera_classes = l
            .config
            .robots
            .classes()
            .iter()
            .filter(|r| {
                r.parts
                    .iter()
                    .any(|p| p.kind.eq_ignore_ascii_case("Camera"))
            })
            .map(|r| r.class.clone())
            .collect();
        hub.geometry = Some(l.geometry.clone());
        hub.map = l.config.map.level().to_owned();
        hub.time_scale = l.config.time_scale;
        hub.catalog = l.config.robots.clone();
        hub.robot_classes = Some(
            l.config
                .robots
                .classes()
                .iter()
                .map(|r| r.class.clone())
                .collect(),
        );
    }
    let app = App {
        shared: Arc::new(Shared::new(hub)),
        local: Arc::new(tokio::sync::Mutex::new(local)),
        token: config.token,
        shutdown: shutdown.clone(),
        hosts: guard::Hosts {
            listen: addr,
            allowed: config.allowed_hosts,
        },
        refusals: Arc::default(),
        page_timeout: config.page_timeout,
        robots,
        pages: Arc::default(),
    };
    let router = Router::new()
        .route("/", get(index))
        .route("/{*name}", get(asset))
        .route("/ws", get(socket::websocket))
        .route("/api/state", get(api::state))
        .route("/api/log", get(api::log_file))
        .route("/api/files/{uav}/{index}", get(api::file))
        .route("/api/camera/{uav}", get(api::camera))
        .route("/api/scenarios", get(api::scenarios))
        .route(
            "/api/scenario",
            get(api::scenario_state).post(api::scenario_start),
        )
        .route(
            "/api/scenario/stop",
            axum::routing::post(api::scenario_stop),
        )
        .route("/api/scenario/results.csv", get(api::scenario_csv))
        .layer(middleware::from_fn_with_state(app.clone(), guard::guard))
        .with_state(app.clone());
    listen::serve(listener, router, shutdown.clone(), config.page_timeout).await;
    // Stop every run and wait (a little) for their files.
    let cancels: Vec<_> = {
        let mut hub = app.shared.lock();
        hub.paused = false;
        hub.uavs.iter().filter_map(|u| u.cancel.clone()).collect()
    };
    app.shared.resumed.notify_all();
    cancels.iter().for_each(CancellationToken::cancel);
    for _ in 0..100 {
        if !app.shared.lock().busy() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    if let Some(mut l) = app.local.lock().await.take()
        && let Some(server) = l.server.take()
        && let Err(e) = server.stop().await
    {
        tracing::warn!("the local server stopped with an error: {e}");
    }
    Ok(())
}

async fn index() -> impl IntoResponse {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CONTENT_SECURITY_POLICY, CSP),
        ],
        INDEX_HTML,
    )
}

/// One of the page's files, or 404.
async fn asset(Path(name): Path<String>) -> Response {
    match ASSETS.iter().find(|(n, _, _)| *n == name) {
        Some((_, kind, body)) => (
            [
                (header::CONTENT_TYPE, format!("{kind}; charset=utf-8")),
                (header::CACHE_CONTROL, "no-cache".to_owned()),
            ],
            *body,
        )
            .into_response(),
        None => (StatusCode::NOT_FOUND, format!("no file {name:?}")).into_response(),
    }
}
