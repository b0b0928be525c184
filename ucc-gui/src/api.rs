//! The HTTP API beside the page: the whole state once, the log as text, a run's files, the
//! scenarios (list, start, stop, state, results).

use std::collections::HashMap;

use axum::extract::{Path, Query, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};

use serde_json::{Value, json};

use crate::App;
use crate::hub::{Cursor, Request, RequestError};

pub(crate) async fn state(State(app): State<App>) -> impl IntoResponse {
    let update = app.shared.lock().update(&mut Cursor::default());
    (
        [(header::CONTENT_TYPE, "application/json")],
        update.to_string(),
    )
}

pub(crate) async fn log_file(
    State(app): State<App>,
    Query(q): Query<HashMap<String, String>>,
) -> Response {
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

pub(crate) async fn file(
    State(app): State<App>,
    Path((uav, index)): Path<(u32, usize)>,
) -> Response {
    let path = {
        let mut hub = app.shared.lock();
        match hub.uav(uav) {
            Ok(u) => u.files.get(index).cloned(),
            Err(e) => return (StatusCode::NOT_FOUND, e.to_string()).into_response(),
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

/// The latest camera frame of a UAV as PNG; asking keeps its run reading frames (for
/// [`CAMERA_IDLE`](crate::hub::CAMERA_IDLE)). 404 with the reason when there is none.
pub(crate) async fn camera(State(app): State<App>, Path(uav): Path<u32>) -> Response {
    let (frame, local) = {
        let mut hub = app.shared.lock();
        let local = hub.image_server.is_some();
        match hub.uav(uav) {
            Ok(u) => (u.camera_frame(), local),
            Err(e) => return (StatusCode::NOT_FOUND, e.to_string()).into_response(),
        }
    };
    let Some(frame) = frame else {
        let why = if local {
            "no camera frame yet (the robot needs a camera, e.g. AirRobot, and must fly)"
        } else {
            "camera frames need the local server (ucc gui --local)"
        };
        return (StatusCode::NOT_FOUND, why).into_response();
    };
    let png = tokio::task::spawn_blocking(move || frame.to_png())
        .await
        .unwrap_or_default();
    (
        [
            (header::CONTENT_TYPE, "image/png"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        png,
    )
        .into_response()
}

/// The embedded scenarios the page offers.
pub(crate) async fn scenarios() -> impl IntoResponse {
    axum::Json(crate::hub::scenario::list())
}

/// A refused request as a 4xx (a 5xx when the server failed) with the reason.
fn refusal(e: &RequestError) -> Response {
    let status = match e {
        RequestError::Field { .. } | RequestError::Malformed(_) => StatusCode::BAD_REQUEST,
        RequestError::NoUav(_) => StatusCode::NOT_FOUND,
        RequestError::State(_) => StatusCode::CONFLICT,
        RequestError::Server(_) => StatusCode::SERVICE_UNAVAILABLE,
    };
    (status, e.to_string()).into_response()
}

/// Applies a request and does what it asks, as the WebSocket does.
async fn apply(app: &App, request: Request) -> Result<(), RequestError> {
    let planned = app.shared.lock().apply(request);
    match planned {
        Ok(action) => crate::socket::act(app, action).await.map(|_| ()),
        Err(e) => Err(e),
    }
}

/// A field of a JSON body as text: a string as it is, a number as written, absent as empty.
fn text_of(body: &Value, key: &'static str) -> Result<String, RequestError> {
    match body.get(key) {
        None | Some(Value::Null) => Ok(String::new()),
        Some(Value::String(s)) => Ok(s.clone()),
        Some(Value::Number(n)) => Ok(n.to_string()),
        Some(other) => Err(RequestError::Malformed(format!(
            "{key}: {other} is neither a string nor a number"
        ))),
    }
}

/// `POST /api/scenario` `{"name": "search", "iterations": 3, "seed": 7, "speed": "max"}`
/// (JSON: a page of another site cannot send it without asking first): starts an embedded
/// scenario; its UAVs' ids, or a 4xx with the reason.
pub(crate) async fn scenario_start(
    State(app): State<App>,
    axum::Json(body): axum::Json<Value>,
) -> Response {
    if let Some(key) = body.as_object().and_then(|o| {
        o.keys()
            .find(|k| !["name", "iterations", "seed", "speed"].contains(&k.as_str()))
    }) {
        return (
            StatusCode::BAD_REQUEST,
            format!("unknown field {key:?} (name, iterations, seed, speed)"),
        )
            .into_response();
    }
    let request = (|| {
        Ok(Request::ScenarioStart {
            name: text_of(&body, "name")?,
            iterations: text_of(&body, "iterations")?,
            seed: text_of(&body, "seed")?,
            speed: text_of(&body, "speed")?,
        })
    })();
    if let Err(e) = match request {
        Ok(request) => apply(&app, request).await,
        Err(e) => Err(e),
    } {
        return refusal(&e);
    }
    let hub = app.shared.lock();
    let Some(s) = &hub.scenario else {
        return (StatusCode::INTERNAL_SERVER_ERROR, "the scenario vanished").into_response();
    };
    axum::Json(json!({"scenario": s.name, "uavs": s.uavs})).into_response()
}

/// `POST /api/scenario/stop` `{}`: stops the scenario's run.
pub(crate) async fn scenario_stop(
    State(app): State<App>,
    axum::Json(_): axum::Json<Value>,
) -> Response {
    match apply(&app, Request::ScenarioStop).await {
        Ok(()) => (StatusCode::OK, "stopping").into_response(),
        Err(e) => refusal(&e),
    }
}

/// `GET /api/scenario`: the scenario's whole state (as a page's first update has it).
pub(crate) async fn scenario_state(State(app): State<App>) -> Response {
    match app
        .shared
        .lock()
        .scenario_json(&mut crate::hub::ScenarioCursor::default())
    {
        Some(s) => axum::Json(s).into_response(),
        None => (StatusCode::NOT_FOUND, "no scenario has been started").into_response(),
    }
}

/// `GET /api/scenario/results.csv`: the rows of the iterations flown, as `results.csv`.
pub(crate) async fn scenario_csv(State(app): State<App>) -> Response {
    match app.shared.lock().scenario_csv() {
        Some(csv) => (
            [
                (header::CONTENT_TYPE, "text/csv; charset=utf-8"),
                (
                    header::CONTENT_DISPOSITION,
                    "attachment; filename=\"results.csv\"",
                ),
            ],
            csv,
        )
            .into_response(),
        None => (StatusCode::NOT_FOUND, "no scenario has been started").into_response(),
    }
}
