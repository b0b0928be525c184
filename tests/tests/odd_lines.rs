//! The client keeps flying when a server prints lines our typed messages do not fit (real
//! UDK servers print some with fields missing): a proxy adds such lines to a real server's
//! stream and the mission is still flown.

use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio_util::sync::CancellationToken;
use ucc_client::{Coordinates, Lockstep, Mission, Progress, RunSettings, Start, agents};
use usar_server::{LocalServer, ServerConfig, TimeScale};

/// Valid lines that do not fit their word's typed layout.
const ODD: &str = "SEN {Time 0.1000} {Type IMU}\r\nSEN {Time 0.1000} {Type Sonar} \r\nGEO {Type Camera} {Name c} {Orientation 0.00,0.00,0.00}{Mount AirRobot}\r\nSTA {Time 0.1000}\r\nSEN {Time 0.1} {Type Position} {Name Position} {Location 1,2}\r\n";

/// Forwards one connection to `server`, adding [`ODD`] after every STA line it relays.
async fn proxy(client: tokio::net::TcpStream, server: String) {
    let upstream = tokio::net::TcpStream::connect(server).await.unwrap();
    let (mut client_read, mut client_write) = client.into_split();
    let (upstream_read, mut upstream_write) = upstream.into_split();
    let up = tokio::spawn(async move {
        let _ = tokio::io::copy(&mut client_read, &mut upstream_write).await;
    });
    let mut lines = BufReader::new(upstream_read);
    let mut line = String::new();
    while lines.read_line(&mut line).await.unwrap_or(0) > 0 {
        let mut out = std::mem::take(&mut line);
        if out.starts_with("STA ") {
            out.push_str(ODD);
        }
        if client_write.write_all(out.as_bytes()).await.is_err() {
            break;
        }
    }
    up.abort();
}

#[tokio::test]
async fn the_client_flies_through_lines_it_cannot_type() {
    let server = LocalServer::start(ServerConfig {
        time_scale: TimeScale::Max,
        lockstep: true,
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let server_addr = server.addr().to_string();
    let front = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let front_addr = front.local_addr().unwrap().to_string();
    let relay = tokio::spawn(async move {
        while let Ok((client, _)) = front.accept().await {
            tokio::spawn(proxy(client, server_addr.clone()));
        }
    });
    let settings = RunSettings {
        addr: front_addr,
        start: Start::at(Coordinates::new(0.0, 0.0, -1.0)),
        missions: vec![Mission::goto(Coordinates::new(3.0, 0.0, -2.0))],
        lockstep: Lockstep::Required,
        ..RunSettings::default()
    };
    let factory = agents::info("base").unwrap().create;
    let (mut progress, cancel) = (|_: &Progress| {}, CancellationToken::new());
    let flight = ucc_client::run(&settings, &factory, &mut progress, &cancel);
    let summary = tokio::time::timeout(Duration::from_secs(120), flight)
        .await
        .expect("the flight ends")
        .unwrap();
    let end = summary.iterations[0].trajectory.last().unwrap().position;
    assert!(
        (end - Coordinates::new(3.0, 0.0, -2.0)).norm() < 0.5,
        "ended at {end:?}"
    );
    relay.abort();
    server.stop().await.unwrap();
}
