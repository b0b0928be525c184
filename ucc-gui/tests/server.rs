//! The state server without a browser: the page and its hooks, the security checks, the
//! token, and the hub's answers to bad input.

use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_util::sync::CancellationToken;
use ucc_gui::hub::{Action, Cursor, Hub, Request};
use ucc_gui::{GuiConfig, GuiError, ServerChoice};

/// Sends a raw HTTP/1.1 request; returns the whole response.
async fn http(addr: std::net::SocketAddr, request: &str) -> String {
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    s.write_all(request.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(1), s.read_to_end(&mut out)).await;
    String::from_utf8_lossy(&out).into_owned()
}

async fn start(bind: &str, token: Option<String>) -> (std::net::SocketAddr, CancellationToken) {
    let listener = tokio::net::TcpListener::bind(bind).await.unwrap();
    let addr = listener.local_addr().unwrap();
    let cancel = CancellationToken::new();
    let config = GuiConfig {
        server: ServerChoice::Remote("127.0.0.1:1".into()),
        log_dir: std::env::temp_dir().join("ucc-gui-server-test"),
        token,
        ..GuiConfig::default()
    };
    tokio::spawn(ucc_gui::serve(listener, config, cancel.clone()));
    (addr, cancel)
}

fn get(path: &str, host: &str, extra: &str) -> String {
    format!("GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n{extra}\r\n")
}

#[tokio::test]
async fn the_page_carries_every_hook() {
    let (addr, stop) = start("127.0.0.1:0", None).await;
    let page = http(addr, &get("/", &addr.to_string(), "")).await;
    assert!(page.starts_with("HTTP/1.1 200"), "{page}");
    for id in [
        "server-host",
        "server-port",
        "connect",
        "robot-class",
        "agent-type",
        "start-pose",
        "create-uav",
        "mission-x",
        "mission-y",
        "mission-z",
        "mission-add",
        "mission-list",
        "iterations",
        "start",
        "stop",
        "iteration-counter",
        "uav-position",
        "uav-battery",
        "log",
        "map",
        "scenario-name",
        "scenario-iterations",
        "scenario-seed",
        "scenario-speed",
        "scenario-start",
        "scenario-stop",
        "scenario-metrics",
    ] {
        assert!(
            page.contains(&format!("data-testid=\"{id}\"")),
            "no data-testid {id}"
        );
    }
    assert!(
        !page.contains("http://") && !page.contains("https://"),
        "nothing fetched from elsewhere"
    );
    let js = http(addr, &get("/app.js", &addr.to_string(), "")).await;
    assert!(
        js.starts_with("HTTP/1.1 200") && js.contains("new WebSocket"),
        "{js}"
    );
    stop.cancel();
}

#[tokio::test]
async fn other_hosts_and_origins_are_refused() {
    let (addr, stop) = start("127.0.0.1:0", None).await;
    let host = addr.to_string();
    // DNS rebinding: a page of evil.example resolved to 127.0.0.1.
    let r = http(
        addr,
        &get("/api/state", &format!("evil.example:{}", addr.port()), ""),
    )
    .await;
    assert!(
        r.starts_with("HTTP/1.1 403") && r.contains("is not this server's address"),
        "{r}"
    );
    let upgrade = "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n\
                   Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";
    let r = http(
        addr,
        &format!(
            "GET /ws HTTP/1.1\r\nHost: {host}\r\n{upgrade}Origin: http://evil.example\r\n\r\n"
        ),
    )
    .await;
    assert!(
        r.starts_with("HTTP/1.1 403") && r.contains("(Origin)"),
        "{r}"
    );
    let r = http(
        addr,
        &format!("GET /ws HTTP/1.1\r\nHost: {host}\r\n{upgrade}Origin: http://{host}\r\n\r\n"),
    )
    .await;
    assert!(r.starts_with("HTTP/1.1 101"), "{r}");
    let state = http(addr, &get("/api/state", &host, "")).await;
    assert!(
        state.starts_with("HTTP/1.1 200") && state.contains("\"uavs\":[]"),
        "{state}"
    );
    stop.cancel();
}

#[tokio::test]
async fn beyond_the_loopback_a_token_is_required() {
    let listener = tokio::net::TcpListener::bind("0.0.0.0:0").await.unwrap();
    let config = GuiConfig {
        server: ServerChoice::Remote("127.0.0.1:1".into()),
        log_dir: std::env::temp_dir(),
        token: None,
        ..GuiConfig::default()
    };
    let err = ucc_gui::serve(listener, config, CancellationToken::new())
        .await
        .unwrap_err();
    assert!(matches!(err, GuiError::TokenRequired { .. }), "{err}");

    let (addr, stop) = start("0.0.0.0:0", Some("s3cret".into())).await;
    let target: std::net::SocketAddr = ([127, 0, 0, 1], addr.port()).into();
    let host = target.to_string();
    let r = http(target, &get("/api/state", &host, "")).await;
    assert!(r.starts_with("HTTP/1.1 401"), "{r}");
    let r = http(target, &get("/api/state?token=wrong", &host, "")).await;
    assert!(r.starts_with("HTTP/1.1 401"), "{r}");
    let r = http(target, &get("/api/state?token=s3cret", &host, "")).await;
    assert!(r.starts_with("HTTP/1.1 200"), "{r}");
    assert!(ucc_gui::url(addr, Some("s3cret")).ends_with("/?token=s3cret"));
    stop.cancel();
}

fn hub_with_uav() -> (Hub, u32) {
    let mut hub = Hub::new("127.0.0.1:3000".into(), false, std::env::temp_dir());
    let created = hub.apply(Request::Create {
        robot: "stsAirRobot".into(),
        agent: "base".into(),
        start: "0,0,-1".into(),
        name: String::new(),
    });
    let Ok(Action::Created(id)) = created else {
        panic!("{created:?}")
    };
    (hub, id)
}

fn goto(uav: u32, x: &str, y: &str, z: &str) -> Request {
    Request::AddMission {
        uav,
        kind: "GotoXyz".into(),
        x: x.into(),
        y: y.into(),
        z: z.into(),
        seconds: String::new(),
    }
}

#[test]
fn bad_input_gets_a_clear_message() {
    let (mut hub, id) = hub_with_uav();
    let err = |hub: &mut Hub, r: Request| hub.apply(r).unwrap_err().to_string();
    assert_eq!(
        err(&mut hub, goto(id, "NaN", "0", "-2")),
        "mission x: \"NaN\" is not a finite number"
    );
    assert_eq!(
        err(&mut hub, goto(id, "1", "", "-2")),
        "mission y: empty (a number in metres)"
    );
    assert_eq!(
        err(&mut hub, goto(id, "1", "2", "inf")),
        "mission z: \"inf\" is not a finite number"
    );
    assert_eq!(
        err(&mut hub, goto(99, "1", "2", "3")),
        "there is no UAV 99 (it was removed?)"
    );
    let e = err(
        &mut hub,
        Request::Create {
            robot: "stsAirRobot".into(),
            agent: "nope".into(),
            start: "0,0,0".into(),
            name: String::new(),
        },
    );
    assert_eq!(
        e,
        "agent type: unknown agent \"nope\" (known agents: base, avoid, thesis)"
    );
    let e = err(
        &mut hub,
        Request::Create {
            robot: "stsAirRobot".into(),
            agent: "base".into(),
            start: "1,2".into(),
            name: String::new(),
        },
    );
    assert!(
        e.starts_with("start pose: ") && e.contains("2 numbers"),
        "{e}"
    );
    let e = err(
        &mut hub,
        Request::Start {
            uav: id,
            iterations: "3".into(),
        },
    );
    assert_eq!(e, "UAV1 has no missions: add a waypoint first");
    hub.apply(goto(id, "1", "2", "-2")).unwrap();
    let e = err(
        &mut hub,
        Request::Start {
            uav: id,
            iterations: "0".into(),
        },
    );
    assert!(e.starts_with("iterations: \"0\""), "{e}");
    let e = err(
        &mut hub,
        Request::Connect {
            host: "h".into(),
            port: "99999".into(),
        },
    );
    assert!(e.starts_with("server port: "), "{e}");
    let e = err(&mut hub, Request::TimeScale { value: "2".into() });
    assert!(e.contains("only a local server"), "{e}");
    hub.robot_classes = Some(vec![
        "USARBot.stsAirRobot".into(),
        "USARBot.AirRobot".into(),
    ]);
    let e = err(
        &mut hub,
        Request::Create {
            robot: "Tank".into(),
            agent: "base".into(),
            start: "0,0,0".into(),
            name: String::new(),
        },
    );
    assert_eq!(
        e,
        "robot class: \"Tank\" is unknown to this server (it has: stsAirRobot, AirRobot)"
    );
    assert!(
        hub.apply(Request::Create {
            robot: "airrobot".into(),
            agent: "base".into(),
            start: "0,0,-1".into(),
            name: String::new()
        })
        .is_ok()
    );
    let bad: Result<Request, _> = serde_json::from_str(r#"{"op":"launch_missiles"}"#);
    assert!(bad.is_err());
}

#[test]
fn updates_carry_only_what_is_new() {
    let (mut hub, id) = hub_with_uav();
    hub.apply(goto(id, "1", "2", "-2")).unwrap();
    let Ok(Action::Start(uav, settings, agent)) = hub.apply(Request::Start {
        uav: id,
        iterations: "2".into(),
    }) else {
        panic!()
    };
    assert_eq!((uav, settings.iterations, agent.as_str()), (id, 2, "base"));
    assert_eq!(settings.missions.len(), 1);
    let mut cursor = Cursor::default();
    hub.new_iteration(id, 1);
    for i in 0..5 {
        let live = ucc_gui::hub::Live {
            time: i as f64 * 0.1,
            position: Some([i as f64, 0.0, -1.0]),
            ..Default::default()
        };
        hub.sample(id, 1, live);
    }
    hub.log(id, "info", "hello".into());
    let u = hub.update(&mut cursor);
    assert_eq!(u["uavs"][0]["trail"].as_array().unwrap().len(), 5);
    assert_eq!(u["uavs"][0]["info"]["status"], "running");
    assert_eq!(u["uavs"][0]["live"]["position"][0], 4.0);
    assert_eq!(u["log"][0]["text"], "hello");
    let live = ucc_gui::hub::Live {
        time: 1.0,
        position: Some([9.0, 0.0, -1.0]),
        ..Default::default()
    };
    hub.sample(id, 1, live);
    let u = hub.update(&mut cursor);
    assert_eq!(u["uavs"][0]["trail"], serde_json::json!([[9.0, 0.0, -1.0]]));
    assert!(
        u["uavs"][0].get("info").is_none(),
        "what did not change is not sent again"
    );
    assert_eq!(u["log"].as_array().unwrap().len(), 0);
    // The next iteration: the trail goes to the overlay, once.
    hub.new_iteration(id, 2);
    let u = hub.update(&mut cursor);
    assert_eq!(u["uavs"][0]["past"].as_array().unwrap().len(), 1);
    assert_eq!(u["uavs"][0]["trail_reset"], true);
    assert_eq!(u["uavs"][0]["info"]["iteration"], 2);
    let u = hub.update(&mut cursor);
    assert_eq!(
        u["uavs"],
        serde_json::json!([]),
        "nothing new, nothing sent"
    );
    // A new run starts a new overlay.
    hub.finished(id, ucc_gui::hub::Status::Done, None);
    hub.apply(Request::Start {
        uav: id,
        iterations: "1".into(),
    })
    .unwrap();
    let u = hub.update(&mut cursor);
    assert_eq!(u["uavs"][0]["past_reset"], true);
    assert!(u["uavs"][0].get("past").is_none());
    let u = hub.update(&mut cursor);
    assert_eq!(u["uavs"], serde_json::json!([]));
    // A stop is refused nowhere, a second start while flying is.
    assert!(
        hub.apply(Request::Start {
            uav: id,
            iterations: "1".into()
        })
        .unwrap_err()
        .to_string()
        .contains("already flying")
    );
    assert_eq!(hub.log_text(Some(id), "warn"), "");
    assert_eq!(hub.log_text(Some(id), ""), "UAV1 info hello\n");
    assert!(
        ucc_gui::UPDATE_PERIOD <= Duration::from_millis(100),
        "at least 10 updates a second"
    );
}

/// A POST to the scenario API with these extra headers; the response.
async fn post(addr: std::net::SocketAddr, host: &str, extra: &str) -> String {
    let body = r#"{"name": "search", "iterations": 1, "speed": "max"}"#;
    http(
        addr,
        &format!(
            "POST /api/scenario HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\
             Content-Type: application/json\r\nContent-Length: {}\r\n{extra}\r\n{body}",
            body.len()
        ),
    )
    .await
}

/// Issue #56: a page of another site cannot drive the control center — no cross-site POST,
/// no cross-site WebSocket, no rebound host name — and each refusal is in the log; the same
/// requests from the page itself (or from no page: curl) are served.
#[tokio::test]
async fn cross_site_requests_and_rebound_hosts_are_refused_and_logged() {
    let (addr, stop) = start("127.0.0.1:0", None).await;
    let host = addr.to_string();
    let evil = "Origin: http://evil.example\r\n";
    let r = post(addr, &host, evil).await;
    assert!(
        r.starts_with("HTTP/1.1 403") && r.contains("POST /api/scenario refused"),
        "{r}"
    );
    assert!(r.contains("\"http://evil.example\" (Origin)"), "{r}");
    let r = post(addr, &host, "Sec-Fetch-Site: cross-site\r\n").await;
    assert!(
        r.starts_with("HTTP/1.1 403") && r.contains("cross-site"),
        "{r}"
    );
    // Another port of this machine is another site too.
    let r = post(addr, &host, "Origin: http://127.0.0.1:1\r\n").await;
    assert!(r.starts_with("HTTP/1.1 403"), "{r}");
    // DNS rebinding: evil.example resolved to 127.0.0.1, the page's own origin.
    let rebound = format!("evil.example:{}", addr.port());
    let r = post(addr, &rebound, &format!("Origin: http://{rebound}\r\n")).await;
    assert!(
        r.starts_with("HTTP/1.1 403") && r.contains("is not this server's address"),
        "{r}"
    );
    let upgrade = "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n\
                   Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";
    let ws = |host: &str, origin: &str| {
        format!("GET /ws HTTP/1.1\r\nHost: {host}\r\n{upgrade}Origin: {origin}\r\n\r\n")
    };
    let r = http(addr, &ws(&rebound, &format!("http://{rebound}"))).await;
    assert!(r.starts_with("HTTP/1.1 403"), "{r}");
    let r = http(addr, &ws(&host, "http://evil.example")).await;
    assert!(r.starts_with("HTTP/1.1 403"), "{r}");
    // Nothing was started; the refusals are in the page's log.
    let state = http(addr, &get("/api/state", &host, "")).await;
    assert!(state.contains("\"uavs\":[]"), "{state}");
    assert!(
        state.contains("POST /api/scenario refused")
            && state.contains("evil.example")
            && state.contains("is not this server's address"),
        "{state}"
    );
    // The same requests from the page itself, by each of the loopback's names, and from curl.
    for name in ["127.0.0.1", "localhost", "[::1]"] {
        let h = format!("{name}:{}", addr.port());
        let r = http(addr, &ws(&h, &format!("http://{h}"))).await;
        assert!(r.starts_with("HTTP/1.1 101"), "{name}: {r}");
    }
    let r = post(
        addr,
        &host,
        &format!("Origin: http://{host}\r\nSec-Fetch-Site: same-origin\r\n"),
    )
    .await;
    assert!(r.starts_with("HTTP/1.1 200"), "{r}");
    let r = http(
        addr,
        "POST /api/scenario/stop HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\
         Content-Type: application/json\r\nContent-Length: 2\r\n\r\n{}"
            .replace("localhost", &host)
            .as_str(),
    )
    .await;
    assert!(
        !r.starts_with("HTTP/1.1 403") && r.starts_with("HTTP/1.1 "),
        "a request without Origin is served: {r}"
    );
    stop.cancel();

    // A name the user allowed.
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let cancel = CancellationToken::new();
    let config = GuiConfig {
        log_dir: std::env::temp_dir().join("ucc-gui-server-test"),
        allowed_hosts: vec!["gui.lab".into()],
        ..GuiConfig::default()
    };
    tokio::spawn(ucc_gui::serve(listener, config, cancel.clone()));
    let allowed = format!("gui.lab:{}", addr.port());
    let r = http(addr, &ws(&allowed, &format!("http://{allowed}"))).await;
    assert!(r.starts_with("HTTP/1.1 101"), "{r}");
    let r = http(addr, &get("/api/state", "other.lab", "")).await;
    assert!(
        r.starts_with("HTTP/1.1 403") && r.contains("--allow-host"),
        "{r}"
    );
    cancel.cancel();
}
