//! The HTTP API beside the page: the whole state once, the log as text, a run's files.

use std::collections::HashMap;

use axum::extract::{Path, Query, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};

use crate::App;
use crate::hub::Cursor;

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
