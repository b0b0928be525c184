//! Issue #26 item 11: a client that closes its connection and at once connects again and
//! spawns at the same place must find the place free (the server removes the old robot
//! first), every time — as `ucc run` does between iterations.

mod common;

use common::{Client, TestServer};
use usar_proto::ServerMessage;
use usar_server::{ServerConfig, TimeScale};

/// A server at full speed that offers lockstep, as `ucc run --local` starts.
async fn fast_lockstep_server() -> TestServer {
    TestServer::with(ServerConfig {
        time_scale: TimeScale::Max,
        lockstep: true,
        ..ServerConfig::default()
    })
    .await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_respawn_right_after_closing_always_finds_the_place_free() {
    let server = fast_lockstep_server().await;
    let iterations = 2000;
    let mut failed = 0;
    for _ in 0..iterations {
        let mut client = Client::connect(server.addr).await;
        client.message().await; // NFO
        // INIT, then two requests that are answered in order: GEO only with a robot, the
        // start poses always. A GEO before the start poses: the spawn worked.
        client
            .send("INIT {ClassName USARBot.stsAirRobot} {Name UAV} {Location 0,0,-1}")
            .await;
        client.send("GETGEO {Type Robot}").await;
        client.send("GETSTARTPOSES").await;
        let mut spawned = false;
        loop {
            match client.message().await.1 {
                ServerMessage::Geo(_) => spawned = true,
                ServerMessage::Nfo(_) => break,
                _ => {}
            }
        }
        failed += usize::from(!spawned);
        // Close and go on at once, as a runner does between iterations.
        drop(client);
    }
    server.stop().await;
    assert_eq!(
        failed, 0,
        "{failed} of {iterations} spawns found the place occupied"
    );
}

/// A client that ends its stream and waits for the server to end its own (as ucc-client's
/// `disconnect` does) finds its old robot gone when it spawns again somewhere else: the new
/// robot's sensors are on a lone robot's ticks, its first STA one period after the spawn.
/// (A second robot gets an earlier phase: lockstep iterations of one run then differed.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn after_the_server_closed_its_end_the_old_robot_is_gone() {
    use tokio::io::AsyncWriteExt;
    let server = fast_lockstep_server().await;
    let iterations = 300;
    let mut shifted = Vec::new();
    for i in 0..iterations {
        let mut client = Client::connect(server.addr).await;
        client.message().await; // NFO
        client.send("SYNC {Time 0}").await;
        let now = client
            .until(|m| match m {
                ServerMessage::Sync(b) => Some(b.time.seconds),
                _ => None,
            })
            .await;
        // Each iteration somewhere else: the place is never what keeps the spawn waiting.
        let x = f64::from(i % 2) * 3.0;
        // One write: INIT and the barrier after it reach the server together.
        client
            .send(&format!(
                "INIT {{ClassName USARBot.stsAirRobot}} {{Name UAV}} {{Location {x},0,-1}}\r\n\
                 SYNC {{Time {}}}",
                now + 0.1
            ))
            .await;
        let first = client
            .until(|m| match m {
                ServerMessage::Sta(s) => Some(s.time.seconds),
                _ => None,
            })
            .await;
        if (first - (now + 0.1)).abs() > 1e-6 {
            shifted.push((now, first));
        }
        client.writer.shutdown().await.unwrap();
        while client.raw_line().await.is_some() {}
    }
    server.stop().await;
    assert!(
        shifted.is_empty(),
        "{} of {iterations} robots read off a lone robot's ticks (spawned, first STA): {:?}",
        shifted.len(),
        &shifted[..shifted.len().min(5)]
    );
}
