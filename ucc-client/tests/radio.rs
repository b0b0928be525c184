//! The radio handle against usar-server's WSS (issue 20 item 6).
#![cfg(feature = "local")]

use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio_util::sync::CancellationToken;
use ucc_client::radio::{Radio, RadioError};
use usar_server::sim::Map;
use usar_server::{ServerConfig, SideListeners};

/// Eight thin walls between y = 2 and y = 4.1.
fn walls_map() -> Map {
    let mut text =
        "level = \"Walls\"\n[[box]]\ncenter = [0.0, 0.0, 0.1]\nsize = [60.0, 60.0, 0.2]\n"
            .to_owned();
    for i in 0..8 {
        let y = 2.0 + 0.3 * f64::from(i);
        text.push_str(&format!(
            "[[box]]\ncenter = [0.0, {y}, -1.5]\nsize = [20.0, 0.1, 3.0]\n"
        ));
    }
    Map::from_toml(&text, std::path::Path::new("walls.toml")).unwrap()
}

#[tokio::test]
async fn a_message_reaches_a_uav_in_range_and_fails_behind_walls() {
    let bind = async || TcpListener::bind("127.0.0.1:0").await.unwrap();
    let (main, monitor, wss) = (bind().await, bind().await, bind().await);
    let (gamebots, monitor_at, wss_at) = (
        main.local_addr().unwrap(),
        monitor.local_addr().unwrap(),
        wss.local_addr().unwrap(),
    );
    let shutdown = CancellationToken::new();
    let side = SideListeners {
        image: None,
        truth: None,
        monitor: Some(monitor),
        wss: Some(wss),
    };
    let config = ServerConfig {
        map: walls_map(),
        ..ServerConfig::default()
    };
    tokio::spawn(usar_server::run_with(main, side, config, shutdown.clone()));
    let mut robots = Vec::new();
    for (name, at) in [
        ("Robot1", "0,0,-1"),
        ("Robot2", "3,0,-1"),
        ("Robot3", "0,6,-1"),
    ] {
        let mut s = TcpStream::connect(gamebots).await.unwrap();
        let mut nfo = [0u8; 3];
        s.read_exact(&mut nfo).await.unwrap();
        let init =
            format!("INIT {{ClassName USARBot.AirRobot}} {{Name {name}}} {{Location {at}}}\r\n");
        s.write_all(init.as_bytes()).await.unwrap();
        robots.push(s);
    }
    // Join once the simulation has the robots (the WSS kicks names it does not have).
    let mut monitor_stream = TcpStream::connect(monitor_at).await.unwrap();
    let mut seen = String::new();
    for _ in 0..600 {
        monitor_stream.write_all(b"GETPOS\r\n").await.unwrap();
        let mut buf = [0u8; 4096];
        let n = monitor_stream.read(&mut buf).await.unwrap();
        seen = String::from_utf8_lossy(&buf[..n]).into_owned();
        if seen.contains("{Robots 3}") {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert!(seen.contains("{Robots 3}"), "{seen}");
    let mut one = Radio::join(wss_at, "Robot1").await.unwrap();
    let mut two = Radio::join(wss_at, "Robot2").await.unwrap();
    let _three = Radio::join(wss_at, "Robot3").await.unwrap();
    // The WSS knows positions after its first poll (about a second).
    let mut strength = f64::NAN;
    for _ in 0..200 {
        strength = one.strength("Robot2").await.unwrap();
        if strength.is_finite() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(strength > -93.0, "{strength}");
    one.send("Robot2", b"victim at 3,4").await.unwrap();
    let got = tokio::time::timeout(Duration::from_secs(30), two.recv())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(
        (got.from.as_str(), &got.data[..]),
        ("Robot1", &b"victim at 3,4"[..])
    );
    // Robot3 is behind eight walls.
    let mut result = one.send("Robot3", b"hello").await;
    for _ in 0..200 {
        if !matches!(&result, Err(RadioError::OutOfRange { strength, .. }) if strength.is_nan()) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
        result = one.send("Robot3", b"hello").await;
    }
    match result {
        Err(RadioError::OutOfRange { to, strength }) => {
            assert_eq!(to, "Robot3");
            assert!(strength < -93.0, "{strength}");
        }
        other => panic!("{other:?}"),
    }
    shutdown.cancel();
}

/// A link that breaks between the signal's query and the relay (the WSS re-evaluates links
/// between two requests) fails with the signal the WSS gives then, not the one before:
/// an agent told "out of range at -80 dBm" could not tell why.
#[tokio::test]
async fn a_relay_closed_after_the_signal_query_reports_the_signal_after_it() {
    use tokio::io::{AsyncBufReadExt, BufReader};
    let wss = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let wss_at = wss.local_addr().unwrap();
    // A relay port nobody listens on.
    let closed = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let closed_port = closed.local_addr().unwrap().port();
    drop(closed);
    tokio::spawn(async move {
        let (stream, _) = wss.accept().await.unwrap();
        let (read, mut write) = stream.into_split();
        let mut lines = BufReader::new(read).lines();
        let mut asked = 0;
        while let Ok(Some(line)) = lines.next_line().await {
            let reply = if line.starts_with("INIT") {
                "INITREPLY {Status OK}".to_owned()
            } else if line.starts_with("GETSS") {
                asked += 1;
                let s = if asked == 1 { "-80.00" } else { "-120.00" };
                format!("SS {{Robot Robot2}} {{Strength {s}}}")
            } else {
                format!("DNSREPLY {{Robot Robot2}} {{Port {closed_port}}}")
            };
            write
                .write_all(format!("{reply}\r\n").as_bytes())
                .await
                .unwrap();
        }
    });
    let mut radio = Radio::join(wss_at, "Robot1").await.unwrap();
    match radio.send("Robot2", b"hello").await {
        Err(RadioError::OutOfRange { to, strength }) => {
            assert_eq!(to, "Robot2");
            assert_eq!(strength, -120.0);
        }
        other => panic!("{other:?}"),
    }
}
