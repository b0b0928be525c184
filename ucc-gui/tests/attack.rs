//! `ucc gui` under attack (issue #26): WebSocket floods, oversized and malformed JSON,
//! thousands of UAVs, too many pages. The rule of the server's attack suite: a healthy page
//! keeps at least 90 % of its update rate, and memory stays bounded (peak RSS read from
//! /proc, not timed).

use std::time::Duration;

use futures::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_util::sync::CancellationToken;
use ucc_gui::{GuiConfig, ServerChoice};

/// One attack at a time: each measures rates on a shared, small machine.
static ONE_AT_A_TIME: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn start() -> (std::net::SocketAddr, CancellationToken) {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let cancel = CancellationToken::new();
    let config = GuiConfig {
        server: ServerChoice::Remote("127.0.0.1:1".into()),
        log_dir: std::env::temp_dir().join("ucc-gui-attack-test"),
        token: None,
        // The pages of these attacks that do not read must stay until counted (the
        // page timeout has its own test below).
        page_timeout: Duration::from_secs(600),
        ..GuiConfig::default()
    };
    tokio::spawn(ucc_gui::serve(listener, config, cancel.clone()));
    (addr, cancel)
}

async fn page(addr: std::net::SocketAddr) -> Result<Ws, String> {
    let mut request = format!("ws://{addr}/ws").into_client_request().unwrap();
    request
        .headers_mut()
        .insert("Origin", format!("http://{addr}").parse().unwrap());
    tokio_tungstenite::connect_async(request)
        .await
        .map(|(ws, _)| ws)
        .map_err(|e| e.to_string())
}

/// State updates a page receives in `seconds`.
async fn updates_in(ws: &mut Ws, seconds: f64) -> usize {
    let end = tokio::time::Instant::now() + Duration::from_secs_f64(seconds);
    let mut n = 0;
    while let Ok(Some(Ok(m))) = tokio::time::timeout_at(end, ws.next()).await {
        if let Message::Text(t) = m
            && t.as_str().contains("\"type\":\"state\"")
        {
            n += 1;
        }
    }
    n
}

/// The next reply of type `error` or `created`.
async fn reply(ws: &mut Ws) -> Value {
    loop {
        let m = tokio::time::timeout(Duration::from_secs(10), ws.next())
            .await
            .expect("a reply within 10 s")
            .expect("the socket open")
            .unwrap();
        if let Message::Text(t) = m {
            let v: Value = serde_json::from_str(t.as_str()).unwrap();
            if v["type"] == "error" || v["type"] == "created" {
                return v;
            }
        }
    }
}

/// Peak resident memory of this process, KiB.
fn peak_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_and_oversized_json_get_answers_not_crashes() {
    let _one = ONE_AT_A_TIME.lock().await;
    let (addr, stop) = start().await;
    let mut ws = page(addr).await.unwrap();
    for bad in [
        "not json",
        "{\"op\":",
        "{\"op\":\"create\"}",
        "{\"op\":\"launch_missiles\"}",
        "{\"op\":\"remove\",\"uav\":-1}",
        "{\"op\":\"remove\",\"uav\":1e300}",
        "[1,2,3]",
        "{\"op\":\"pause\",\"paused\":\"yes\"}",
    ] {
        ws.send(Message::Text(bad.into())).await.unwrap();
        let r = reply(&mut ws).await;
        let m = r["message"].as_str().unwrap();
        assert!(
            m.starts_with("bad request: ") && m.len() < 400,
            "{bad}: {r}"
        );
    }
    // A long name in bad JSON is not echoed back whole.
    let long = format!("{{\"op\":\"{}\"}}", "x".repeat(50_000));
    ws.send(Message::Text(long.into())).await.unwrap();
    let r = reply(&mut ws).await;
    assert!(r["message"].as_str().unwrap().len() < 400, "{r}");

    // Over the size limit: this page is closed; the control center serves the next one.
    let huge = format!(
        "{{\"op\":\"create\",\"robot\":\"stsAirRobot\",\"agent\":\"base\",\"start\":\"0,0,-1\",\"name\":\"{}\"}}",
        "y".repeat(ucc_gui::MAX_MESSAGE + 1)
    );
    let _ = ws.send(Message::Text(huge.into())).await;
    let closed = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            match ws.next().await {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return true,
                Some(Ok(_)) => {}
            }
        }
    })
    .await;
    assert_eq!(closed, Ok(true), "an oversized message closes the socket");
    let mut next = page(addr).await.unwrap();
    assert!(updates_in(&mut next, 0.5).await >= 3);
    stop.cancel();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flooding_page_does_not_slow_a_healthy_one() {
    let _one = ONE_AT_A_TIME.lock().await;
    let (addr, stop) = start().await;
    let mut healthy = page(addr).await.unwrap();
    let baseline = updates_in(&mut healthy, 2.0).await;
    // A flood that slows the healthy page does so every time; a 2-core machine busy with
    // other tests only now and then: under 90 % is measured again, up to three times.
    let mut seen = Vec::new();
    for attempt in 0..3 {
        if attempt > 0 {
            // The updates that waited while the last flood ended are not this attempt's.
            updates_in(&mut healthy, 0.05).await;
        }
        let mut flood = page(addr).await.unwrap();
        let flooding = tokio::spawn(async move {
            let bad = Message::Text("{\"op\":\"select\",\"uav\":12345}".into());
            let garbage = Message::Text("{{{{".into());
            let end = tokio::time::Instant::now() + Duration::from_secs(3);
            let mut sent = 0u64;
            // Sends without reading the replies (the page's own replies back up).
            while tokio::time::Instant::now() < end {
                let m = if sent.is_multiple_of(2) {
                    bad.clone()
                } else {
                    garbage.clone()
                };
                if tokio::time::timeout(Duration::from_millis(200), flood.send(m))
                    .await
                    .is_err()
                {
                    continue; // back-pressure: this page waits, nobody else
                }
                sent += 1;
            }
            sent
        });
        tokio::time::sleep(Duration::from_millis(200)).await;
        let during = updates_in(&mut healthy, 2.0).await;
        let sent = flooding.await.unwrap();
        assert!(sent > 1000, "the flood sent {sent} requests");
        seen.push(during);
        if during * 10 >= baseline * 9 {
            break;
        }
    }
    assert!(
        seen.iter().any(|&during| during * 10 >= baseline * 9),
        "a healthy page got {seen:?} updates in 2 s during each flood, {baseline} before"
    );
    stop.cancel();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thousands_of_uavs_and_pages_stay_bounded() {
    let _one = ONE_AT_A_TIME.lock().await;
    let (addr, stop) = start().await;
    let before = peak_rss_kib();
    let ws = page(addr).await.unwrap();
    let (mut sink, mut stream) = ws.split();
    let reader = tokio::spawn(async move {
        let (mut created, mut refused) = (0usize, Vec::new());
        while let Ok(Some(Ok(m))) =
            tokio::time::timeout(Duration::from_secs(10), stream.next()).await
        {
            if let Message::Text(t) = m {
                let v: Value = serde_json::from_str(t.as_str()).unwrap();
                match v["type"].as_str() {
                    Some("created") => created += 1,
                    Some("error") => refused.push(v["message"].as_str().unwrap().to_owned()),
                    _ => {}
                }
                if created + refused.len() == 5_000 {
                    break;
                }
            }
        }
        (created, refused)
    });
    for i in 0..5_000 {
        let create = json!({"op": "create", "robot": "stsAirRobot", "agent": "base", "start": format!("{},{},-1", i % 100, i / 100), "name": ""});
        sink.send(Message::Text(create.to_string().into()))
            .await
            .unwrap();
    }
    let (created, refused) = reader.await.unwrap();
    assert_eq!(created, 4_096, "{refused:?}");
    assert_eq!(refused.len(), 904);
    assert!(
        refused[0].starts_with("at most 4096 UAVs"),
        "{}",
        refused[0]
    );
    drop(sink);

    // More pages than allowed: the excess is refused, the allowed ones are served.
    let mut pages = Vec::new();
    let mut refused_pages = 0;
    for _ in 0..ucc_gui::MAX_PAGES + 5 {
        match page(addr).await {
            Ok(p) => pages.push(p),
            Err(e) => {
                assert!(e.contains("503"), "{e}");
                refused_pages += 1;
            }
        }
    }
    assert!(refused_pages >= 5, "{refused_pages} pages refused");
    // Every open page receives the whole state of 4096 UAVs, then only what changes.
    for p in pages.iter_mut().take(3) {
        assert!(updates_in(p, 5.0).await >= 5);
    }
    drop(pages);
    let grown = peak_rss_kib().saturating_sub(before);
    println!("peak RSS grew by {} MiB", grown / 1024);
    assert!(grown < 400 * 1024, "peak RSS grew by {} MiB", grown / 1024);
    stop.cancel();
}

/// Issue #56: pages that do not read, and HTTP requests sent slowly, do not hold the
/// control center: with a 2 s page timeout, 40 WebSocket pages that never read (32 take every
/// slot, the rest get 503) and 32 slow-loris connections are dropped, and a new page gets
/// its page and its updates.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pages_that_do_not_read_and_slow_senders_do_not_hold_slots() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let _one = ONE_AT_A_TIME.lock().await;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let stop = CancellationToken::new();
    let config = GuiConfig {
        server: ServerChoice::Remote("127.0.0.1:1".into()),
        log_dir: std::env::temp_dir().join("ucc-gui-attack-test"),
        page_timeout: Duration::from_secs(2),
        ..GuiConfig::default()
    };
    tokio::spawn(ucc_gui::serve(listener, config, stop.clone()));

    // Pages that never read (not even the server's pings).
    let mut silent = Vec::new();
    let mut refused = 0;
    for _ in 0..ucc_gui::MAX_PAGES + 8 {
        match page(addr).await {
            Ok(p) => silent.push(p),
            Err(e) => {
                assert!(e.contains("503"), "{e}");
                refused += 1;
            }
        }
    }
    assert_eq!(silent.len(), ucc_gui::MAX_PAGES, "{refused} refused");
    // Slow-loris: a request's headers a byte every half second, never finished.
    let mut loris = Vec::new();
    for _ in 0..32 {
        loris.push(tokio::spawn(async move {
            let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
            let request = format!("GET / HTTP/1.1\r\nHost: {addr}\r\nX-Slow: ");
            let started = tokio::time::Instant::now();
            for b in request.bytes().chain(std::iter::repeat(b'a')) {
                if s.write_all(&[b]).await.is_err() {
                    break;
                }
                let mut buf = [0u8; 256];
                match tokio::time::timeout(Duration::from_millis(500), s.read(&mut buf)).await {
                    Ok(Ok(0)) | Ok(Err(_)) => break, // closed by the server
                    Ok(Ok(_)) => {}                  // its 408: read on to the close
                    Err(_) => {}                     // still open
                }
                if started.elapsed() > Duration::from_secs(90) {
                    return None;
                }
            }
            Some(started.elapsed())
        }));
    }
    // A new page is served within a generous deadline: its page, its hello, its updates.
    let end = tokio::time::Instant::now() + Duration::from_secs(90);
    let mut honest = loop {
        match page(addr).await {
            Ok(p) => break p,
            Err(e) => {
                assert!(e.contains("503"), "{e}");
                assert!(
                    tokio::time::Instant::now() < end,
                    "no slot freed in 90 s: {e}"
                );
                tokio::time::sleep(Duration::from_millis(250)).await;
            }
        }
    };
    assert!(updates_in(&mut honest, 3.0).await >= 5);
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    s.write_all(format!("GET / HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").as_bytes())
        .await
        .unwrap();
    let mut html = String::new();
    let _ = tokio::time::timeout(Duration::from_secs(10), s.read_to_string(&mut html)).await;
    assert!(
        html.starts_with("HTTP/1.1 200") && html.contains("<html"),
        "{html}"
    );
    // Every slow sender was dropped.
    for l in loris {
        let took = l.await.unwrap();
        assert!(
            took.is_some(),
            "a slow-loris connection still open after 90 s"
        );
    }
    // The honest page, which reads, is still served after several timeouts.
    tokio::time::sleep(Duration::from_secs(5)).await;
    assert!(updates_in(&mut honest, 3.0).await >= 5);
    drop(silent);
    stop.cancel();
}
