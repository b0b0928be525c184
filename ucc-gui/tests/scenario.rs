//! Scenarios from the control center without a browser (issue #22): started through the
//! HTTP API, their UAVs appear in the state and their metrics change; bad input is a 4xx
//! with the reason.

use std::time::Duration;

use serde_json::Value;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_util::sync::CancellationToken;
use ucc_gui::hub::{Action, Cursor, Hub, Request};
use ucc_gui::{GuiConfig, ServerChoice};

/// Sends a raw HTTP/1.1 request; returns the status and the body.
async fn http(addr: std::net::SocketAddr, method: &str, path: &str, body: &str) -> (u16, String) {
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    let request = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    );
    s.write_all(request.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(5), s.read_to_end(&mut out)).await;
    let text = String::from_utf8_lossy(&out).into_owned();
    let status = text
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    // Chunked bodies: the JSON is the longest line.
    let body = body
        .lines()
        .max_by_key(|l| l.len())
        .unwrap_or("")
        .to_owned();
    (status, body)
}

async fn start() -> (std::net::SocketAddr, CancellationToken) {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let cancel = CancellationToken::new();
    let config = GuiConfig {
        // Scenarios fly in the process: the server is not asked.
        server: ServerChoice::Remote("127.0.0.1:1".into()),
        log_dir: std::env::temp_dir().join("ucc-gui-scenario-test"),
        token: None,
        ..GuiConfig::default()
    };
    tokio::spawn(ucc_gui::serve(listener, config, cancel.clone()));
    (addr, cancel)
}

async fn state(addr: std::net::SocketAddr) -> Value {
    let (status, body) = http(addr, "GET", "/api/state", "").await;
    assert_eq!(status, 200, "{body}");
    serde_json::from_str(&body).unwrap()
}

fn metric(scenario: &Value, name: &str) -> Option<f64> {
    scenario["metrics"]
        .as_array()?
        .iter()
        .find(|m| m[0] == name)?[1]
        .as_f64()
}

/// Starting the search scenario through the API makes its UAV appear, fly and cover area;
/// its row of results comes at the end of the iteration.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scenario_started_through_the_api_flies_and_scores() {
    let (addr, stop) = start().await;
    let (status, list) = http(addr, "GET", "/api/scenarios", "").await;
    assert_eq!(status, 200);
    let list: Value = serde_json::from_str(&list).unwrap();
    let names: Vec<&str> = list
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert!(
        names.contains(&"search") && names.contains(&"relay"),
        "{names:?}"
    );

    let (status, body) = http(
        addr,
        "POST",
        "/api/scenario",
        r#"{"name": "search-team", "iterations": 1, "speed": "max"}"#,
    )
    .await;
    assert_eq!(status, 200, "{body}");
    let started: Value = serde_json::from_str(&body).unwrap();
    assert_eq!(started["uavs"].as_array().unwrap().len(), 3, "{started}");

    // Its UAVs are in the state, named, with their team agent, and they move.
    let s = state(addr).await;
    let uavs = s["uavs"].as_array().unwrap();
    assert_eq!(uavs.len(), 3, "{s}");
    assert_eq!(uavs[0]["info"]["name"], "UAV1");
    assert_eq!(uavs[0]["info"]["agent"], "partition-search");
    let mut coverage = 0.0;
    let mut moved = false;
    for _ in 0..600 {
        let s = state(addr).await;
        coverage = metric(&s["scenario"], "coverage_pct").unwrap_or(0.0);
        moved = s["uavs"]
            .as_array()
            .unwrap()
            .iter()
            .all(|u| u["trail"].as_array().is_some_and(|t| t.len() > 5));
        if coverage > 5.0 && moved {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(moved, "the UAVs' trails grow");
    assert!(coverage > 5.0, "coverage rises: {coverage}");
    let s = state(addr).await["scenario"].clone();
    assert_eq!(s["fixed"]["kind"], "search");
    assert!(s["grid_full"].as_str().unwrap().contains('1'), "cells seen");
    assert!(!s["victims"].as_array().unwrap().is_empty());

    // A second start while it runs is refused.
    let (status, body) = http(addr, "POST", "/api/scenario", r#"{"name": "search"}"#).await;
    assert_eq!(status, 409, "{body}");
    assert!(body.contains("is running"), "{body}");

    // Stopped: its UAVs end, the scenario says so.
    let (status, body) = http(addr, "POST", "/api/scenario/stop", "{}").await;
    assert_eq!(status, 200, "{body}");
    let mut ended = Value::Null;
    for _ in 0..100 {
        ended = state(addr).await;
        if ended["scenario"]["status"] == "stopped" {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert_eq!(
        ended["scenario"]["status"], "stopped",
        "{}",
        ended["scenario"]
    );
    assert!(
        ended["uavs"]
            .as_array()
            .unwrap()
            .iter()
            .all(|u| u["info"]["status"] == "stopped")
    );

    // The one-UAV search to its end: its row of results.
    let (status, body) = http(
        addr,
        "POST",
        "/api/scenario",
        r#"{"name": "search", "iterations": "2", "seed": "5", "speed": "max"}"#,
    )
    .await;
    assert_eq!(status, 200, "{body}");
    let mut s = Value::Null;
    for _ in 0..600 {
        s = state(addr).await;
        if s["scenario"]["status"] == "done" {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let sc = &s["scenario"];
    assert_eq!(sc["status"], "done", "{sc}");
    assert_eq!(
        s["uavs"].as_array().unwrap().len(),
        1,
        "the last scenario's UAVs went"
    );
    let rows = sc["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2, "{sc}");
    assert_eq!(rows[0]["seed"], "5");
    assert_eq!(rows[1]["seed"], "6");
    let (status, csv) = http(addr, "GET", "/api/scenario/results.csv", "").await;
    assert_eq!(status, 200);
    assert!(csv.starts_with("iteration,seed,ending,time_s"), "{csv}");
    stop.cancel();
}

/// Bad names, counts, seeds and speeds get a 4xx that names the field.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_scenario_requests_are_refused_with_the_reason() {
    let (addr, stop) = start().await;
    for (body, code, says) in [
        (
            r#"{"name": "nosuch"}"#,
            400,
            "scenario: \"nosuch\" is not an embedded scenario",
        ),
        (
            r#"{"name": "/etc/passwd"}"#,
            400,
            "is not an embedded scenario",
        ),
        (
            r#"{"name": "search", "iterations": 0}"#,
            400,
            "scenario iterations: \"0\" is not a whole number from 1 to 1000",
        ),
        (
            r#"{"name": "search", "iterations": "1e9"}"#,
            400,
            "scenario iterations",
        ),
        (
            r#"{"name": "search", "iterations": 99999999999999999999999}"#,
            400,
            "scenario iterations",
        ),
        (
            r#"{"name": "search", "seed": -1}"#,
            400,
            "scenario seed: \"-1\" is not a whole number",
        ),
        (r#"{"name": "search", "seed": "x"}"#, 400, "scenario seed"),
        (
            r#"{"name": "search", "speed": "warp"}"#,
            400,
            "scenario speed",
        ),
        (r#"{"name": "search", "speed": 0}"#, 400, "scenario speed"),
        (
            r#"{"name": "search", "colour": 1}"#,
            400,
            "unknown field \"colour\"",
        ),
        (r#"{"name": ["search"]}"#, 400, "name:"),
        ("not json", 400, ""),
    ] {
        let (status, text) = http(addr, "POST", "/api/scenario", body).await;
        assert_eq!(status, code, "{body}: {text}");
        assert!(text.contains(says), "{body}: {text}");
    }
    let (status, text) = http(addr, "POST", "/api/scenario/stop", "{}").await;
    assert_eq!(status, 409, "{text}");
    let (status, _) = http(addr, "GET", "/api/scenario", "").await;
    assert_eq!(status, 404);
    assert_eq!(
        state(addr).await["uavs"],
        Value::Array(vec![]),
        "nothing was created"
    );
    stop.cancel();
}

/// The page's updates carry the coverage grid whole once, then only the cells that changed.
#[test]
fn the_grid_is_sent_whole_once_then_as_changes() {
    let mut hub = Hub::new(
        "127.0.0.1:1".into(),
        false,
        std::env::temp_dir().join("ucc-gui-scenario-test"),
    );
    let Ok(Action::Scenario(plan)) = hub.apply(Request::ScenarioStart {
        name: "SEARCH".into(),
        iterations: String::new(),
        seed: String::new(),
        speed: "max".into(),
    }) else {
        panic!("not started");
    };
    let mut episode =
        ucc_client::scenario::engine::Episode::new(plan.prepared.clone(), plan.seed, 1).unwrap();
    hub.scenario_iteration(1, plan.seed, &episode);
    let mut cursor = Cursor::default();
    let first = hub.update(&mut cursor);
    let cells = first["scenario"]["grid_full"].as_str().unwrap().len();
    assert_eq!(cells, 36 * 28, "the search area in 0.5 m cells");
    assert!(first["scenario"]["fixed"]["geometry"].is_array());
    let mut sent = 0;
    for _ in 0..200 {
        episode.step(&[]);
        hub.scenario_sample(&episode, true);
        let u = hub.update(&mut cursor);
        let s = &u["scenario"];
        assert!(s.get("fixed").is_none() && s.get("grid_full").is_none());
        sent += s["grid"].as_array().map_or(0, Vec::len) / 2;
    }
    let seen = hub
        .scenario
        .as_ref()
        .unwrap()
        .levels
        .iter()
        .filter(|&&l| l > 0)
        .count();
    assert!(seen > 50, "{seen} cells seen");
    assert!(
        sent <= seen * ucc_gui::hub::scenario::LEVELS as usize,
        "{sent} changes for {seen} cells"
    );
    assert!(
        hub.update(&mut cursor).get("scenario").is_none(),
        "nothing new: nothing sent"
    );
}

/// The scenario's thread keeps the page's pace: at real time it does not race ahead, a pause
/// holds its world, Resume goes on, and a new speed is taken while it runs.
#[test]
fn the_scenario_keeps_the_pace_and_the_pause() {
    use std::sync::Arc;
    use ucc_gui::hub::Shared;
    let shared = Arc::new(Shared::new(Hub::new(
        "127.0.0.1:1".into(),
        false,
        std::env::temp_dir().join("ucc-gui-scenario-test"),
    )));
    let Ok(Action::Scenario(plan)) = shared.lock().apply(Request::ScenarioStart {
        name: "tracking".into(),
        iterations: "1".into(),
        seed: String::new(),
        speed: "1".into(),
    }) else {
        panic!("not started");
    };
    ucc_gui::scenario::spawn(shared.clone(), *plan).unwrap();
    let time = || shared.lock().scenario.as_ref().unwrap().time;
    std::thread::sleep(Duration::from_millis(1500));
    let t = time();
    assert!(
        t > 0.2 && t < 5.0,
        "real time: {t} simulated s after 1.5 wall s"
    );
    shared
        .lock()
        .apply(Request::Pause { paused: true })
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let held = time();
    std::thread::sleep(Duration::from_millis(700));
    assert_eq!(time(), held, "paused: the world waits");
    shared
        .lock()
        .apply(Request::Pause { paused: false })
        .unwrap();
    shared.resumed.notify_all();
    shared
        .lock()
        .apply(Request::ScenarioSpeed {
            value: "max".into(),
        })
        .unwrap();
    let mut done = false;
    for _ in 0..300 {
        if shared.lock().scenario.as_ref().unwrap().status == ucc_gui::hub::Status::Done {
            done = true;
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(done, "at max speed the 90 s iteration ends: {}", time());
    let hub = shared.lock();
    let s = hub.scenario.as_ref().unwrap();
    assert_eq!(s.rows.len(), 1);
    assert!(
        s.metrics
            .iter()
            .any(|(n, v)| *n == "target_seen_pct" && v.is_some_and(|v| v > 50.0)),
        "{:?}",
        s.metrics
    );
    assert!(
        hub.uavs
            .iter()
            .all(|u| u.status == ucc_gui::hub::Status::Done)
    );
    let csv = hub.scenario_csv().expect("the results");
    assert_eq!(csv.lines().count(), 2, "a header and one row: {csv}");
}

/// Each kind's things reach the page: the relay's link changes, the fire's radius growing,
/// the target's position, the delivery's pads.
#[test]
fn every_kind_sends_its_things() {
    let state = |name: &str, steps: usize| {
        let mut hub = Hub::new(
            "127.0.0.1:1".into(),
            false,
            std::env::temp_dir().join("ucc-gui-scenario-test"),
        );
        let Ok(Action::Scenario(plan)) = hub.apply(Request::ScenarioStart {
            name: name.into(),
            iterations: String::new(),
            seed: String::new(),
            speed: String::new(),
        }) else {
            panic!("{name} not started");
        };
        let mut episode =
            ucc_client::scenario::engine::Episode::new(plan.prepared.clone(), plan.seed, 1)
                .unwrap();
        hub.scenario_iteration(1, plan.seed, &episode);
        for _ in 0..steps {
            episode.step(&[]);
        }
        hub.scenario_sample(&episode, true);
        hub.update(&mut Cursor::default())["scenario"].clone()
    };
    let relay = state("relay", 100);
    assert_eq!(
        relay["fixed"]["endpoints"],
        serde_json::json!([[-50.0, 0.0], [50.0, 0.0]])
    );
    assert_eq!(
        relay["link"][0][1], false,
        "down while the chain forms: {}",
        relay["link"]
    );
    assert_eq!(relay["link_up"], false);
    let fire = state("perimeter", 100);
    let r0 = fire["fixed"]["fire"]["radius"].as_f64().unwrap();
    assert!(fire["fire_radius"].as_f64().unwrap() > r0, "{fire}");
    let tracking = state("tracking", 50);
    assert_eq!(
        tracking["targets"].as_array().unwrap().len(),
        1,
        "{tracking}"
    );
    assert_eq!(tracking["fixed"]["targets"].as_array().unwrap().len(), 1);
    let delivery = state("delivery", 1);
    let pads: Vec<&str> = delivery["fixed"]["pads"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    assert_eq!(pads, ["base", "pickup", "drop-off"]);
}
