//! The server's limits (docs/limits.md): no client can stop the world or lock others out.

mod common;

use std::time::Duration;

use common::{Client, TestServer};
use tokio::io::AsyncWriteExt;
use usar_proto::ServerMessage;
use usar_server::{ServerConfig, TimeScale};

/// STA times of `c` until one reaches `until`.
async fn sta_until(c: &mut Client, until: f64) -> f64 {
    let mut last = 0.0;
    while last < until {
        last = c
            .until(|m| match m {
                ServerMessage::Sta(s) => Some(s.time.seconds),
                _ => None,
            })
            .await;
    }
    last
}

fn config() -> ServerConfig {
    ServerConfig {
        time_scale: TimeScale::Factor(10.0),
        ..ServerConfig::default()
    }
}

#[tokio::test]
async fn a_flood_of_valid_commands_does_not_stop_the_world() {
    // The attack: a client sending valid commands as fast as it can, never reading,
    // froze simulated time for everyone.
    let server = TestServer::with(config()).await;
    let mut flooder = Client::connect_from(server.addr, 2).await;
    flooder
        .send("INIT {ClassName USARBot.stsAirRobot} {Location 3,3,-1}")
        .await;
    let flood = tokio::spawn(async move {
        let chunk =
            "DRIVE {LinearVelocity 0.1}\r\nGETSTARTPOSES\r\nGETCONF {Type Sonar}\r\n".repeat(500);
        // Ends when the server stops (or the test ends).
        while flooder.writer.write_all(chunk.as_bytes()).await.is_ok() {}
    });
    let mut healthy = server.client().await;
    healthy.raw_line().await.unwrap();
    healthy.spawn_at([0.0, 0.0, -1.0], 0.0).await;
    // Simulated time runs on: 3 s of it reach the healthy client, every STA in turn.
    let mut last = sta_until(&mut healthy, 0.3).await;
    while last < 3.0 {
        let t = sta_until(&mut healthy, last + 0.05).await;
        assert!((t - last - 0.1).abs() < 0.011, "STA gap {last} -> {t}");
        last = t;
    }
    flood.abort();
    server.stop().await;
}

#[tokio::test]
async fn connections_per_address_are_limited() {
    // The per-address cap counts connections that have not sent a line (issue #56: 16 active
    // loopback clients locked every other local client out).
    let server = TestServer::with(ServerConfig {
        max_connections_per_address: 3,
        ..config()
    })
    .await;
    let mut talkers = Vec::new();
    for _ in 0..8 {
        let mut c = Client::connect_from(server.addr, 2).await;
        assert!(c.raw_line().await.unwrap().starts_with("NFO "));
        c.send("GETSTARTPOSES").await;
        assert!(c.raw_line().await.unwrap().starts_with("NFO {StartPoses"));
        talkers.push(c);
    }
    // Eight active clients of one address, then three silent ones: all served.
    let mut silent = Vec::new();
    for _ in 0..3 {
        let mut c = Client::connect_from(server.addr, 2).await;
        assert!(c.raw_line().await.unwrap().starts_with("NFO "));
        silent.push(c);
    }
    // A fourth silent one: the address's oldest silent connection makes room.
    let mut fourth = Client::connect_from(server.addr, 2).await;
    assert!(fourth.raw_line().await.unwrap().starts_with("NFO "));
    assert_eq!(
        silent[0].raw_line().await,
        None,
        "the oldest silent is closed"
    );
    silent.remove(0);
    for c in talkers
        .iter_mut()
        .chain(silent.iter_mut())
        .chain([&mut fourth])
    {
        c.send("GETSTARTPOSES").await;
        assert!(c.raw_line().await.unwrap().starts_with("NFO {StartPoses"));
    }
    // Another address is served.
    let mut other = Client::connect_from(server.addr, 3).await;
    assert!(other.raw_line().await.unwrap().starts_with("NFO "));
    server.stop().await;
}

#[tokio::test]
async fn at_a_limit_the_oldest_connection_without_a_line_makes_room() {
    // Issue #26 item 6: 16 silent connections locked a new client of their address out for
    // the 30 s idle timeout.
    let server = TestServer::with(ServerConfig {
        max_connections_per_address: 3,
        max_connections: 6,
        ..config()
    })
    .await;
    let mut talker = Client::connect_from(server.addr, 2).await;
    assert!(talker.raw_line().await.unwrap().starts_with("NFO "));
    talker.send("GETSTARTPOSES").await;
    assert!(
        talker
            .raw_line()
            .await
            .unwrap()
            .starts_with("NFO {StartPoses")
    );
    let mut silent = Vec::new();
    for _ in 0..3 {
        let mut c = Client::connect_from(server.addr, 2).await;
        assert!(c.raw_line().await.unwrap().starts_with("NFO "));
        silent.push(c);
    }
    // The address is at its limit of silent connections: the newcomer is served, the oldest
    // silent one closed.
    let mut newcomer = Client::connect_from(server.addr, 2).await;
    assert!(newcomer.raw_line().await.unwrap().starts_with("NFO "));
    assert_eq!(
        silent[0].raw_line().await,
        None,
        "the oldest silent is closed"
    );
    silent.remove(0);
    // The others stay; every kept client speaks.
    for c in silent.iter_mut().chain([&mut talker, &mut newcomer]) {
        c.send("GETSTARTPOSES").await;
        assert!(c.raw_line().await.unwrap().starts_with("NFO {StartPoses"));
    }
    // The server's limit (6) works the same way, across addresses.
    let mut quiet = Client::connect_from(server.addr, 3).await;
    assert!(quiet.raw_line().await.unwrap().starts_with("NFO "));
    let mut other = Client::connect_from(server.addr, 4).await;
    assert!(other.raw_line().await.unwrap().starts_with("NFO "));
    let mut fifth = Client::connect_from(server.addr, 5).await;
    assert!(fifth.raw_line().await.unwrap().starts_with("NFO "));
    assert_eq!(quiet.raw_line().await, None, "the oldest silent is closed");
    for c in [&mut other, &mut fifth] {
        c.send("GETSTARTPOSES").await;
        assert!(c.raw_line().await.unwrap().starts_with("NFO {StartPoses"));
    }
    // All six have spoken: the next is refused.
    let mut sixth = Client::connect_from(server.addr, 6).await;
    assert_eq!(sixth.raw_line().await, None, "refused: everyone has spoken");
    server.stop().await;
}

#[tokio::test]
async fn silent_and_half_sent_connections_are_closed_but_quiet_clients_stay() {
    // The attack: 63 idle connections locked every new client out.
    let server = TestServer::with(ServerConfig {
        idle_timeout: Duration::from_millis(300),
        line_timeout: Duration::from_millis(300),
        ..config()
    })
    .await;
    let mut silent = server.client().await;
    let mut half = server.client().await;
    let mut quiet = server.client().await;
    for c in [&mut silent, &mut half, &mut quiet] {
        assert!(c.raw_line().await.unwrap().starts_with("NFO "));
    }
    quiet.send("GETSTARTPOSES").await;
    let (line, _) = quiet.message().await;
    assert!(line.starts_with("NFO {StartPoses"));
    // Slowloris: a line started, one byte now and then, never ended.
    half.send("GETSTARTPOSES").await;
    half.message().await;
    let drip = tokio::spawn(async move {
        for b in b"GETCONF {Type Sonar".iter().cycle().take(40) {
            if half.writer.write_all(&[*b]).await.is_err() {
                break;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        half
    });
    // The same with a line past the length limit, which the server skips as it arrives.
    let mut long = server.client().await;
    long.raw_line().await.unwrap();
    long.send("GETSTARTPOSES").await;
    long.message().await;
    let endless = tokio::spawn(async move {
        let chunk = vec![b'A'; 16 * 1024];
        for _ in 0..40 {
            if long.writer.write_all(&chunk).await.is_err() {
                break;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        long
    });
    assert_eq!(silent.raw_line().await, None, "no line at all: closed");
    let mut half = drip.await.unwrap();
    assert_eq!(half.raw_line().await, None, "a line never ended: closed");
    let mut long = endless.await.unwrap();
    assert_eq!(
        long.raw_line().await,
        None,
        "an over-long line never ended: closed"
    );
    // A client that said something and then only listens is kept.
    tokio::time::sleep(Duration::from_millis(700)).await;
    quiet.send("GETSTARTPOSES").await;
    let (line, _) = quiet.message().await;
    assert!(line.starts_with("NFO {StartPoses"));
    server.stop().await;
}

#[tokio::test]
async fn one_robot_per_connection_however_many_inits() {
    // The attack: 20,000 INITs on one connection made 20,000 moving robots.
    let server = TestServer::with(config()).await;
    let mut c = server.client().await;
    c.raw_line().await.unwrap();
    for i in 0..200 {
        c.send(&format!(
            "INIT {{ClassName USARBot.AirRobot}} {{Location {},0,-1}}",
            f64::from(i % 9) - 4.0
        ))
        .await;
    }
    c.send("GETGEO {Type Robot}").await;
    // The GEO answer comes once the INITs are served; the ASTA lines of one AirRobot run at
    // 10 Hz, so two seconds show at most ~20 of them from one robot, ~4000 from 200.
    let mut asta = 0;
    let mut last = 0.0;
    while last < 2.0 {
        let (_, m) = c.message().await;
        match m {
            ServerMessage::Asta(_) => asta += 1,
            ServerMessage::Sta(s) => last = s.time.seconds,
            _ => {}
        }
    }
    assert!(asta <= 25, "{asta} ASTA lines in 2 s: more than one robot");
    server.stop().await;
}
