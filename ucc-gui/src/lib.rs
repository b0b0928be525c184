//! ucc-gui: the UAV Control Center in the browser (`ucc gui`).
//!
//! [`serve`] serves one page (HTML, CSS and JS embedded in the binary: nothing is fetched
//! from the internet) and a WebSocket at `/ws`. The Rust side owns the state ([`hub::Hub`]):
//! the page sends requests (`{"op": "create", ...}`) and renders the updates it gets 20
//! times a second (each UAV's state, new trail points, new log lines). Runs go through
//! ucc-client's runner, in [`flight`] (the only module that uses it).
//!
//! Security: a loopback listener answers only requests whose `Host` names the loopback
//! (DNS rebinding); the WebSocket refuses an `Origin` other than the page's own; a
//! non-loopback listener requires a token (`?token=`), printed in the URL at start.

pub mod flight;
pub mod hub;

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, Query, Request as HttpRequest, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::json;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use ucc_client::Backend;
use usar_server::ServerConfig;

use crate::flight::Shared;
use crate::hub::{Action, Cursor, Hub, Request};

const INDEX_HTML: &str = include_str!("assets/index.html");
const APP_JS: &str = include_str!("assets/app.js");
const STYLE_CSS: &str = include_str!("assets/style.css");

/// How often a page gets an update.
pub const UPDATE_PERIOD: Duration = Duration::from_millis(50);

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
    server: Option<ucc_client::backend::Server>,
}

#[derive(Clone)]
struct App {
    shared: Arc<Shared>,
    local: Arc<tokio::sync::Mutex<Option<Local>>>,
    token: Option<String>,
    /// Cancelled by Quit.
    shutdown: CancellationToken,
    /// The listener's port, and whether `Host` must name the loopback.
    port: u16,
    loopback_only: bool,
    robots: Vec<String>,
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
    let (server_addr, local, hub_geometry, map_name, robots) = match config.server {
        ServerChoice::Remote(a) => (
            a,
            None,
            None,
            String::new(),
            vec!["stsAirRobot".to_owned(), "AirRobot".to_owned()],
        ),
        ServerChoice::Local(c) => {
            let server = Backend::Local(c.clone()).start().await?;
            let geometry = server.map().cloned();
            let robots = c
                .robots
                .classes()
                .iter()
                .map(|r| r.class.trim_start_matches("USARBot.").to_owned())
                .collect();
            (
                server.addr().to_string(),
                Some(Local {
                    config: *c.clone(),
                    server: Some(server),
                }),
                geometry,
                c.map.level().to_owned(),
                robots,
            )
        }
    };
    let mut hub = Hub::new(server_addr, local.is_some(), config.log_dir);
    hub.geometry = hub_geometry;
    if let Some(l) = &local {
        hub.robot_classes = Some(
            l.config
                .robots
                .classes()
                .iter()
                .map(|r| r.class.clone())
                .collect(),
        );
    }
    hub.map = map_name;
    if let Some(l) = &local {
        hub.speed = l.config.time_scale.to_string();
    }
    let app = App {
        shared: Arc::new(Shared {
            hub: std::sync::Mutex::new(hub),
            resumed: std::sync::Condvar::new(),
        }),
        local: Arc::new(tokio::sync::Mutex::new(local)),
        token: config.token,
        shutdown: shutdown.clone(),
        port: addr.port(),
        loopback_only,
        robots,
    };
    let router = Router::new()
        .route("/", get(index))
        .route(
            "/app.js",
            get(|| async {
                (
                    [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
                    APP_JS,
                )
            }),
        )
        .route(
            "/style.css",
            get(|| async {
                (
                    [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
                    STYLE_CSS,
                )
            }),
        )
        .route("/ws", get(websocket))
        .route("/api/state", get(state))
        .route("/api/log", get(log_file))
        .route("/api/files/{uav}/{index}", get(file))
        .layer(middleware::from_fn_with_state(app.clone(), guard))
        .with_state(app.clone());
    let stop = shutdown.clone();
    let served = axum::serve(listener, router)
        .with_graceful_shutdown(async move { stop.cancelled().await })
        .await;
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
    served?;
    Ok(())
}

/// Refuses requests for another host (DNS rebinding), WebSockets from another origin, and
/// API requests without the token.
async fn guard(State(app): State<App>, request: HttpRequest, next: Next) -> Response {
    let headers = request.headers();
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("");
    if let Err(why) = check_host(host, app.port, app.loopback_only) {
        return (StatusCode::FORBIDDEN, why).into_response();
    }
    let path = request.uri().path();
    if path == "/ws" {
        let origin = headers.get(header::ORIGIN).and_then(|h| h.to_str().ok());
        if origin != Some(format!("http://{host}").as_str()) {
            return (
                StatusCode::FORBIDDEN,
                format!("WebSocket refused: origin {origin:?} is not this page's (http://{host})"),
            )
                .into_response();
        }
    }
    if (path == "/ws" || path.starts_with("/api/"))
        && let Some(token) = &app.token
    {
        let given = request
            .uri()
            .query()
            .unwrap_or("")
            .split('&')
            .find_map(|kv| kv.strip_prefix("token="))
            .unwrap_or("");
        if !same(given.as_bytes(), token.as_bytes()) {
            return (
                StatusCode::UNAUTHORIZED,
                "missing or wrong token: open the URL printed by `ucc gui`",
            )
                .into_response();
        }
    }
    next.run(request).await
}

/// Constant-time comparison.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Whether `host` (the `Host` header) may reach a listener on `port`.
pub fn check_host(host: &str, port: u16, loopback_only: bool) -> Result<(), String> {
    if !loopback_only {
        return Ok(());
    }
    let names = ["127.0.0.1", "localhost", "[::1]"];
    let ok = names
        .iter()
        .any(|n| host == *n || host == format!("{n}:{port}"));
    if ok {
        Ok(())
    } else {
        Err(format!(
            "refused: Host {host:?} is not this machine's loopback (open http://127.0.0.1:{port}/)"
        ))
    }
}

async fn index() -> impl IntoResponse {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (
                header::CONTENT_SECURITY_POLICY,
                "default-src 'self'; connect-src 'self'; img-src 'self' data: blob:",
            ),
        ],
        INDEX_HTML,
    )
}

async fn websocket(State(app): State<App>, ws: WebSocketUpgrade) -> Response {
    ws.on_upgrade(move |socket| page(app, socket))
}

/// One page's session: the hello, then requests in and updates out.
async fn page(app: App, mut socket: WebSocket) {
    let hello = {
        let hub = app.shared.lock();
        json!({
            "type": "hello",
            "agents": flight::agent_names(),
            "robots": app.robots,
            "geometry": hub.geometry_json(),
            "map": hub.map,
            "local": hub.local,
            "period_ms": UPDATE_PERIOD.as_millis() as u64,
        })
    };
    if socket
        .send(Message::Text(hello.to_string().into()))
        .await
        .is_err()
    {
        return;
    }
    let mut cursor = Cursor::default();
    let mut tick = tokio::time::interval(UPDATE_PERIOD);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            () = app.shutdown.cancelled() => {
                let _ = socket.send(Message::Close(None)).await;
                return;
            }
            message = socket.recv() => {
                let text = match message {
                    Some(Ok(Message::Text(t))) => t,
                    Some(Ok(Message::Close(_))) | None | Some(Err(_)) => return,
                    Some(Ok(_)) => continue,
                };
                let reply = handle(&app, &mut cursor, text.as_str()).await;
                if let Some(reply) = reply
                    && socket.send(Message::Text(reply.to_string().into())).await.is_err()
                {
                    return;
                }
            }
            _ = tick.tick() => {
                let update = app.shared.lock().update(&mut cursor);
                if socket.send(Message::Text(update.to_string().into())).await.is_err() {
                    return;
                }
            }
        }
    }
}

/// Handles one request; returns the reply for the page (an error, or which UAV was created).
async fn handle(app: &App, cursor: &mut Cursor, text: &str) -> Option<serde_json::Value> {
    let request: Request = match serde_json::from_str(text) {
        Ok(r) => r,
        Err(e) => return Some(json!({"type": "error", "message": format!("bad request: {e}")})),
    };
    if let Request::Select { uav } = &request {
        cursor.selected = Some(*uav);
    }
    // The lock is released at the end of this statement, before any await.
    let result = app.shared.lock().apply(request);
    let result = match result {
        Ok(action) => act(app, action).await,
        Err(e) => Err(e),
    };
    match result {
        Ok(Some(id)) => Some(json!({"type": "created", "uav": id})),
        Ok(None) => None,
        Err(message) => Some(json!({"type": "error", "message": message})),
    }
}

/// Does what a request asks outside the hub's lock.
async fn act(app: &App, action: Action) -> Result<Option<u32>, String> {
    match action {
        Action::None => Ok(None),
        Action::Created(id) => Ok(Some(id)),
        Action::Quit => {
            app.shared
                .lock()
                .log(0, "info", "quit: the control center stops".into());
            app.shutdown.cancel();
            Ok(None)
        }
        Action::Connect(addr) => {
            flight::probe(&addr).await?;
            let mut local = app.local.lock().await;
            if let Some(mut l) = local.take()
                && let Some(server) = l.server.take()
            {
                _ = server.stop().await;
            }
            let mut hub = app.shared.lock();
            hub.addr = addr.clone();
            hub.local = false;
            hub.geometry = None;
            hub.robot_classes = None;
            hub.map = String::new();
            hub.log(0, "info", format!("server: {addr}"));
            Ok(None)
        }
        Action::Speed(value) => {
            let scale: usar_server::TimeScale = value.parse().map_err(|e| format!("speed: {e}"))?;
            let mut guard = app.local.lock().await;
            let Some(local) = guard.as_mut() else {
                return Err("there is no local server".into());
            };
            if let Some(server) = local.server.take() {
                _ = server.stop().await;
            }
            local.config.time_scale = scale;
            let server = Backend::Local(Box::new(local.config.clone()))
                .start()
                .await
                .map_err(|e| format!("cannot restart the local server: {e}"))?;
            let mut hub = app.shared.lock();
            hub.addr = server.addr().to_string();
            hub.speed = value.clone();
            let line = format!("local server at {} runs at speed {value}", hub.addr);
            hub.log(0, "info", line);
            local.server = Some(server);
            Ok(None)
        }
        Action::Start(id, settings, agent) => {
            app.shared.resumed.notify_all();
            flight::spawn_run(app.shared.clone(), id, *settings, agent)?;
            Ok(None)
        }
    }
}

async fn state(State(app): State<App>) -> impl IntoResponse {
    let update = app.shared.lock().update(&mut Cursor::default());
    (
        [(header::CONTENT_TYPE, "application/json")],
        update.to_string(),
    )
}

async fn log_file(State(app): State<App>, Query(q): Query<HashMap<String, String>>) -> Response {
    let uav = match q.get("uav").map(|s| s.as_str()) {
        None | Some("") | Some("all") => None,
        Some(s) => match s.parse() {
            Ok(id) => Some(id),
            Err(_) => {
                return (
                    StatusCode::BAD_REQUEST,
                    format!("uav: {s:?} is not a UAV id"),
                )
                    .into_response();
            }
        },
    };
    let level = q.get("level").map_or("", |s| s.as_str());
    if !["", "info", "warn", "error"].contains(&level) {
        return (
            StatusCode::BAD_REQUEST,
            format!("level: {level:?} (info, warn or error)"),
        )
            .into_response();
    }
    let text = app.shared.lock().log_text(uav, level);
    (
        [
            (header::CONTENT_TYPE, "text/plain; charset=utf-8".to_owned()),
            (
                header::CONTENT_DISPOSITION,
                "attachment; filename=\"ucc-gui.log\"".to_owned(),
            ),
        ],
        text,
    )
        .into_response()
}

async fn file(
    State(app): State<App>,
    Path((uav, index)): Path<(u32, usize)>,
    _headers: HeaderMap,
) -> Response {
    let path = {
        let mut hub = app.shared.lock();
        match hub.uav(uav) {
            Ok(u) => u.files.get(index).cloned(),
            Err(e) => return (StatusCode::NOT_FOUND, e).into_response(),
        }
    };
    let Some(path) = path else {
        return (
            StatusCode::NOT_FOUND,
            format!("UAV {uav} has no file {index}"),
        )
            .into_response();
    };
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) => {
            return (
                StatusCode::NOT_FOUND,
                format!("cannot read {}: {e}", path.display()),
            )
                .into_response();
        }
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let kind = match path.extension().and_then(|e| e.to_str()) {
        Some("png") => "image/png",
        Some("svg") => "image/svg+xml",
        Some("csv") => "text/csv",
        _ => "text/plain; charset=utf-8",
    };
    (
        [
            (header::CONTENT_TYPE, kind.to_owned()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{}\"", name.replace('"', "")),
            ),
        ],
        bytes,
    )
        .into_response()
}
