//! Issue #26 item 11: a client that closes its connection and at once connects again and
//! spawns at the same place must find the place free (the server removes the old robot
//! first), every time — as `ucc run` does between iterations.

mod common;

use common::{Client, TestServer};
use usar_proto::ServerMessage;
use usar_server::{ServerConfig, TimeScale};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_respawn_right_after_closing_always_finds_the_place_free() {
    let server = TestServer::with(ServerConfig {
        time_scale: TimeScale::Max,
        lockstep: true,
        ..ServerConfig::default()
    })
    .await;
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
