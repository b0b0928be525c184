//! The control center against a server that offers no lockstep and reports no geometry (as
//! a real USARSim): a page's session over the WebSocket, without a browser.

use std::time::Duration;

use futures::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_util::sync::CancellationToken;
use ucc_gui::{GuiConfig, ServerChoice};
use usar_server::{LocalServer, ServerConfig, TimeScale};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_page_flies_two_iterations_against_a_plain_server() {
    let server = LocalServer::start(ServerConfig {
        time_scale: TimeScale::Factor(10.0),
        lockstep: false,
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let start = ServerConfig::default().map.starts()[0].clone();
    let [ox, oy, _] = start.location;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let log_dir = std::env::temp_dir().join(format!("ucc-gui-remote-{}", addr.port()));
    let shutdown = CancellationToken::new();
    let served = tokio::spawn(ucc_gui::serve(
        listener,
        GuiConfig {
            server: ServerChoice::Remote(server.addr().to_string()),
            log_dir: log_dir.clone(),
            token: None,
            ..GuiConfig::default()
        },
        shutdown.clone(),
    ));

    let mut request = format!("ws://{addr}/ws").into_client_request().unwrap();
    request
        .headers_mut()
        .insert("Origin", format!("http://{addr}").parse().unwrap());
    let (mut ws, _) = tokio_tungstenite::connect_async(request).await.unwrap();
    let mut next = async || -> Value {
        loop {
            let m = tokio::time::timeout(Duration::from_secs(30), ws.next())
                .await
                .expect("an update within 30 s")
                .expect("the socket open")
                .unwrap();
            if let Message::Text(t) = m {
                return serde_json::from_str(t.as_str()).unwrap();
            }
        }
    };
    let hello = next().await;
    assert_eq!(hello["type"], "hello");
    assert_eq!(
        hello["geometry"],
        Value::Null,
        "a plain server reports no geometry"
    );
    assert_eq!(hello["agents"], json!(["base", "avoid", "thesis"]));

    let send = |v: Value| Message::Text(v.to_string().into());
    ws.send(send(
        json!({"op": "create", "robot": "stsAirRobot", "agent": "base", "start": start.tag}),
    ))
    .await
    .unwrap();
    for (x, y) in [(ox + 7.5, oy), (ox + 7.5, oy + 1.5)] {
        // 2.5 m from the north wall
        ws.send(send(json!({"op": "add_mission", "uav": 1, "kind": "GotoXyz", "x": x.to_string(), "y": y.to_string(), "z": "-1.5"})))
            .await
            .unwrap();
    }
    ws.send(send(json!({"op": "start", "uav": 1, "iterations": "2"})))
        .await
        .unwrap();

    // Pause against a server without lockstep (a real USARSim) holds the UAV where it is:
    // zero velocity set-points, not the last command (issue #23, defect 6).
    while position_of_state(&mut ws).await.is_none() {}
    ws.send(send(json!({"op": "pause", "paused": true})))
        .await
        .unwrap();
    for _ in 0..4 {
        position_of_state(&mut ws).await; // the pause takes effect at the flight's next step
    }
    let paused_at = position_of_state(&mut ws).await.unwrap();
    let dist = |a: [f64; 3], b: [f64; 3]| {
        a.iter()
            .zip(b)
            .map(|(p, q)| (p - q).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    // While paused the UAV stays where it is (its state still arrives)...
    let mut held = paused_at;
    let end = tokio::time::Instant::now() + Duration::from_millis(1500);
    while tokio::time::Instant::now() < end {
        if let Some(p) = position_of_state(&mut ws).await {
            held = p;
            assert!(
                dist(p, paused_at) < 0.5,
                "paused at {paused_at:?}, the UAV went on to {p:?}"
            );
        }
    }
    ws.send(send(json!({"op": "pause", "paused": false})))
        .await
        .unwrap();
    // ...and flies on from there on Resume (no jump by what it would have flown meanwhile).
    let mut after = held;
    for _ in 0..40 {
        match position_of_state(&mut ws).await {
            Some(p) if p != held => {
                after = p;
                break;
            }
            _ => {}
        }
    }
    assert!(
        dist(after, held) < 2.0,
        "held at {held:?}, after Resume at {after:?}: the UAV flew on while paused"
    );

    ws.send(send(
        json!({"op": "add_mission", "uav": 1, "kind": "GotoXyz", "x": "1", "y": "NaN", "z": "-1"}),
    ))
    .await
    .unwrap();

    let (mut trail, mut hits, mut past, mut log, mut errors) = (0, 0, 0, Vec::new(), Vec::new());
    let mut last = Value::Null;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(180);
    loop {
        assert!(
            tokio::time::Instant::now() < deadline,
            "the run did not end: {last}"
        );
        let m = tokio::time::timeout(Duration::from_secs(30), ws.next())
            .await
            .unwrap()
            .unwrap()
            .unwrap();
        let Message::Text(t) = m else { continue };
        let v: Value = serde_json::from_str(t.as_str()).unwrap();
        match v["type"].as_str() {
            Some("error") => errors.push(v["message"].as_str().unwrap().to_owned()),
            Some("state") => {
                for l in v["log"].as_array().unwrap() {
                    log.push(l["text"].as_str().unwrap().to_owned());
                }
                let Some(u) = v["uavs"].get(0) else { continue };
                let len = |k: &str| u.get(k).and_then(Value::as_array).map_or(0, Vec::len);
                trail += len("trail");
                hits += len("hits");
                past += len("past");
                // An update carries what changed: merge it into what we know.
                if last.is_null() {
                    last = json!({});
                }
                for (k, v) in u.as_object().unwrap() {
                    last[k] = v.clone();
                }
                // (`info` comes when it changes: until the first one here, the status is not known.)
                let status = last["info"]["status"].as_str();
                if status.is_some_and(|s| !matches!(s, "running" | "stopping" | "idle")) {
                    break;
                }
            }
            _ => {}
        }
    }
    assert_eq!(errors, ["mission y: \"NaN\" is not a finite number"]);
    assert_eq!(last["info"]["status"], "done", "{last}");
    assert_eq!(last["info"]["iteration"], 2);
    assert_eq!(last["info"]["missions"].as_array().unwrap().len(), 2);
    assert!(trail > 20, "{trail} trail points");
    assert!(past >= 1, "the first iteration's trail for the overlay");
    assert!(
        hits > 100,
        "the laser's hits draw the map of a server without geometry: {hits}"
    );
    assert!(
        log.iter().any(
            |l| l == "[2] iteration done: 2 missions in" || l.starts_with("[2] iteration done")
        ),
        "{log:?}"
    );
    assert!(log.iter().any(|l| l.contains("sensor time")) || !log.is_empty());
    let files: Vec<&str> = last["files"]["recent"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    assert!(
        files.contains(&"UAV1-results.csv")
            && files.contains(&"UAV1-02.log")
            && last["files"]["total"].as_u64() >= Some(14),
        "{files:?}"
    );

    // The files are offered for download; Quit ends the control center.
    let index = last["files"]["recent"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["name"] == "UAV1-results.csv")
        .unwrap()["index"]
        .as_u64()
        .unwrap();
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    s.write_all(
        format!("GET /api/files/1/{index} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n")
            .as_bytes(),
    )
    .await
    .unwrap();
    let mut body = String::new();
    s.read_to_string(&mut body).await.unwrap();
    assert!(
        body.starts_with("HTTP/1.1 200") && body.contains("iteration,status"),
        "{body}"
    );
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    s.write_all(
        format!(
            "GET /api/log?uav=1&level=info HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
        )
        .as_bytes(),
    )
    .await
    .unwrap();
    let mut saved = String::new();
    s.read_to_string(&mut saved).await.unwrap();
    assert!(
        saved.contains("attachment") && saved.contains("UAV1 info [2] iteration done"),
        "{saved}"
    );
    ws.send(send(json!({"op": "quit"}))).await.unwrap();
    tokio::time::timeout(Duration::from_secs(20), served)
        .await
        .expect("quit ends serve")
        .unwrap()
        .unwrap();
    server.stop().await.unwrap();
    let _ = std::fs::remove_dir_all(log_dir);
}

/// The position of the first UAV in the next state update.
async fn position_of_state<S, E>(ws: &mut S) -> Option<[f64; 3]>
where
    S: futures::Stream<Item = Result<Message, E>> + Unpin,
    E: std::fmt::Debug,
{
    loop {
        let m = tokio::time::timeout(Duration::from_secs(30), ws.next())
            .await
            .unwrap()
            .unwrap()
            .unwrap();
        let Message::Text(t) = m else { continue };
        let v: Value = serde_json::from_str(t.as_str()).unwrap();
        if v["type"] == "state" {
            let p = v["uavs"][0]["live"]["position"].as_array()?;
            return Some([p[0].as_f64()?, p[1].as_f64()?, p[2].as_f64()?]);
        }
    }
}

/// The server area: a local server's speed changes (the server restarts), Connect refuses an
/// address where nothing answers and switches to one where a server does.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn speed_and_connect() {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let shutdown = CancellationToken::new();
    tokio::spawn(ucc_gui::serve(
        listener,
        GuiConfig {
            server: ServerChoice::Local(Box::default()),
            log_dir: std::env::temp_dir(),
            token: None,
            ..GuiConfig::default()
        },
        shutdown.clone(),
    ));
    let mut request = format!("ws://{addr}/ws").into_client_request().unwrap();
    request
        .headers_mut()
        .insert("Origin", format!("http://{addr}").parse().unwrap());
    let (mut ws, _) = tokio_tungstenite::connect_async(request).await.unwrap();
    let send = |v: Value| Message::Text(v.to_string().into());
    // The next message of a type.
    async fn next_of<S, E>(ws: &mut S, kind: &str) -> Value
    where
        S: futures::Stream<Item = Result<Message, E>> + Unpin,
        E: std::fmt::Debug,
    {
        loop {
            let m = tokio::time::timeout(Duration::from_secs(30), ws.next())
                .await
                .unwrap()
                .unwrap()
                .unwrap();
            let Message::Text(t) = m else { continue };
            let v: Value = serde_json::from_str(t.as_str()).unwrap();
            if v["type"] == kind {
                return v;
            }
        }
    }
    let hello = next_of(&mut ws, "hello").await;
    assert!(hello["geometry"].as_array().is_some_and(|g| !g.is_empty()));
    let first = next_of(&mut ws, "state").await["server"].clone();
    assert_eq!(
        (first["local"].clone(), first["time_scale"].clone()),
        (json!(true), json!("1"))
    );

    ws.send(send(json!({"op": "time_scale", "value": "fast"})))
        .await
        .unwrap();
    let e = next_of(&mut ws, "error").await;
    assert!(
        e["message"].as_str().unwrap().starts_with("time scale: "),
        "{e}"
    );
    ws.send(send(json!({"op": "time_scale", "value": "max"})))
        .await
        .unwrap();
    let mut state = next_of(&mut ws, "state").await;
    for _ in 0..50 {
        if state["server"]["time_scale"] == "max" {
            break;
        }
        state = next_of(&mut ws, "state").await;
    }
    assert_eq!(state["server"]["time_scale"], "max");
    assert_ne!(state["server"]["addr"], first["addr"], "a new local server");

    let nothing = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let dead = nothing.local_addr().unwrap().port();
    drop(nothing);
    ws.send(send(
        json!({"op": "connect", "host": "127.0.0.1", "port": dead.to_string()}),
    ))
    .await
    .unwrap();
    let e = next_of(&mut ws, "error").await;
    assert!(
        e["message"].as_str().unwrap().contains("cannot connect"),
        "{e}"
    );

    let other = LocalServer::start(ServerConfig::default()).await.unwrap();
    let port = other.addr().port().to_string();
    ws.send(send(
        json!({"op": "connect", "host": "127.0.0.1", "port": port}),
    ))
    .await
    .unwrap();
    let mut state = next_of(&mut ws, "state").await;
    for _ in 0..50 {
        if state["server"]["local"] == false {
            break;
        }
        state = next_of(&mut ws, "state").await;
    }
    assert_eq!(state["server"]["addr"], other.addr().to_string());
    assert_eq!(state["server"]["local"], false);
    shutdown.cancel();
    other.stop().await.unwrap();
}
