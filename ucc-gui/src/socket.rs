//! One page's WebSocket session: the hello, then requests in and updates out; and what a
//! request asks to be done outside the hub's lock.
//!
//! Limits (docs/limits.md): a message longer than [`MAX_MESSAGE`] bytes closes the socket
//! (axum refuses it before it is buffered whole); a page may send at most
//! [`REQUESTS_PER_UPDATE`] requests per update period — more wait for the next period, so a
//! flooding page slows only itself, never the runs or the other pages. A page that stops
//! answering (no message, not even the pong to the server's ping, for the page timeout) is
//! dropped, and with it its slot among the [`MAX_PAGES`]: a browser answers pings by itself,
//! a client that does not read (or sends a frame slowly) does not.

use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde_json::{Value, json};

use crate::hub::{Action, Cursor, Request, RequestError};
use crate::{App, UPDATE_PERIOD, runs};

/// The longest WebSocket message a page may send, bytes (a request is well under 1 KiB).
pub const MAX_MESSAGE: usize = 64 * 1024;
/// Requests a page may send per update period; the rest wait for the next one.
pub const REQUESTS_PER_UPDATE: u32 = 200;
/// Pages served at once; more WebSockets are refused (503) until one closes.
pub const MAX_PAGES: usize = 32;

/// Counts an open page; the count goes down when it is dropped.
struct PageSlot(Arc<AtomicUsize>);

impl Drop for PageSlot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

pub(crate) async fn websocket(State(app): State<App>, ws: WebSocketUpgrade) -> Response {
    if app.pages.fetch_add(1, Ordering::SeqCst) >= MAX_PAGES {
        app.pages.fetch_sub(1, Ordering::SeqCst);
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            format!("at most {MAX_PAGES} pages at once: close one"),
        )
            .into_response();
    }
    let slot = PageSlot(app.pages.clone());
    ws.max_message_size(MAX_MESSAGE)
        .max_frame_size(MAX_MESSAGE)
        .on_upgrade(move |socket| async move {
            let _slot = slot;
            page(app, socket).await;
        })
}

/// One page's session: the hello, then requests in and updates out.
async fn page(app: App, mut socket: WebSocket) {
    let hello = {
        let hub = app.shared.lock();
        json!({
            "type": "hello",
            "agents": runs::agent_names(),
            "scenarios": crate::hub::scenario::list(),
            "robots": app.robots,
            "geometry": hub.geometry_json(),
            "map": hub.map,
            "local": hub.local,
            "addr": hub.addr,
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
    let mut budget = REQUESTS_PER_UPDATE;
    // A ping a third of the timeout: a page that answers none of three is gone.
    let mut ping = tokio::time::interval(app.page_timeout / 3);
    ping.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut heard = tokio::time::Instant::now();
    loop {
        tokio::select! {
            biased;
            () = app.shutdown.cancelled() => {
                let _ = socket.send(Message::Close(None)).await;
                return;
            }
            _ = ping.tick() => {
                if heard.elapsed() > app.page_timeout {
                    tracing::info!("ucc gui: a page answered nothing for {:?}: dropped", app.page_timeout);
                    return;
                }
                if socket.send(Message::Ping(Default::default())).await.is_err() {
                    return;
                }
            }
            _ = tick.tick() => {
                budget = REQUESTS_PER_UPDATE;
                let update = app.shared.lock().update(&mut cursor);
                if socket.send(Message::Text(update.to_string().into())).await.is_err() {
                    return;
                }
            }
            message = socket.recv(), if budget > 0 => {
                let text = match message {
                    Some(Ok(Message::Text(t))) => t,
                    Some(Ok(Message::Close(_))) | None | Some(Err(_)) => return,
                    Some(Ok(_)) => {
                        heard = tokio::time::Instant::now();
                        continue;
                    }
                };
                budget -= 1;
                let reply = handle(&app, &mut cursor, text.as_str()).await;
                // The time this request took (a server restarted) is not the page's silence.
                heard = tokio::time::Instant::now();
                if let Some(reply) = reply
                    && socket.send(Message::Text(reply.to_string().into())).await.is_err()
                {
                    return;
                }
            }
        }
    }
}

/// Handles one request; returns the reply for the page (an error, or which UAV was created).
async fn handle(app: &App, cursor: &mut Cursor, text: &str) -> Option<Value> {
    let result = match serde_json::from_str::<Request>(text) {
        Ok(request) => {
            if let Request::Select { uav } = &request {
                cursor.selected = Some(*uav);
            }
            if let Request::View { x0, x1, y0, y1 } = request
                && let Ok(rect) = crate::hub::request::view_rect(x0, x1, y0, y1)
            {
                cursor.view = Some(rect);
            }
            // The lock is released at the end of this statement, before any await.
            let planned = app.shared.lock().apply(request);
            match planned {
                Ok(action) => act(app, action).await,
                Err(e) => Err(e),
            }
        }
        Err(e) => Err(RequestError::Malformed(malformed(&e))),
    };
    match result {
        Ok(Some(id)) => Some(json!({"type": "created", "uav": id})),
        Ok(None) => None,
        Err(e) => Some(json!({"type": "error", "message": e.to_string()})),
    }
}

/// serde's message for bad JSON, without quoting the user's text at length.
fn malformed(e: &serde_json::Error) -> String {
    let text = e.to_string();
    if text.chars().count() <= 200 {
        text
    } else {
        let cut: String = text.chars().take(200).collect();
        format!("{cut}…")
    }
}

/// Does what a request asks outside the hub's lock.
pub(crate) async fn act(app: &App, action: Action) -> Result<Option<u32>, RequestError> {
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
            runs::probe(&addr).await?;
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
            hub.image_server = None;
            hub.robot_classes = None;
            hub.map = String::new();
            hub.log(0, "info", format!("server: {addr}"));
            Ok(None)
        }
        Action::TimeScale(scale) => {
            let mut guard = app.local.lock().await;
            let Some(local) = guard.as_mut() else {
                return Err(RequestError::State("there is no local server".into()));
            };
            if let Some(server) = local.server.take() {
                _ = server.stop().await;
            }
            local.config.time_scale = scale;
            let server = ucc_client::Backend::Local(Box::new(local.config.clone()))
                .start_with(crate::CAMERA)
                .await
                .map_err(|e| {
                    RequestError::Server(format!("cannot restart the local server: {e}"))
                })?;
            let mut hub = app.shared.lock();
            hub.addr = server.addr().to_string();
            hub.image_server = server.image_server();
            hub.time_scale = scale;
            let line = format!("local server at {} runs at time scale {scale}", hub.addr);
            hub.log(0, "info", line);
            local.server = Some(server);
            Ok(None)
        }
        Action::Start(id, settings, agent) => {
            app.shared.resumed.notify_all();
            runs::spawn_run(app.shared.clone(), id, *settings, agent)?;
            Ok(None)
        }
        Action::Scenario(plan) => {
            crate::scenario::spawn(app.shared.clone(), *plan)?;
            Ok(None)
        }
    }
}
