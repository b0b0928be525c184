//! A recorded flight served back by `usar-server replay` reads the same in the framework.

use std::time::Duration;

use tokio_util::sync::CancellationToken;
use ucc_client::{
    Connection, Coordinates, Lockstep, Mission, RunSettings, Start, UavState, agents,
};
use usar_server::replay::{self, Pace};
use usar_server::{LocalServer, ServerConfig, TimeScale};

#[tokio::test]
async fn a_recorded_flight_replays_into_the_same_uav_state() {
    let dir = std::env::temp_dir().join(format!("e2e-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let record = dir.join("flight.usarlog");

    // Fly and record, in lockstep against a fresh server.
    let server = LocalServer::start(ServerConfig {
        time_scale: TimeScale::Max,
        lockstep: true,
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let settings = RunSettings {
        addr: server.addr().to_string(),
        start: Start::at(Coordinates::new(0.0, 0.0, -1.0)),
        missions: vec![Mission::goto(Coordinates::new(2.0, 1.0, -2.0))],
        lockstep: Lockstep::Required,
        record: Some(record.clone()),
        ..RunSettings::default()
    };
    let summary = ucc_client::run(
        &settings,
        &agents::info("base").unwrap().create,
        &mut |_: &ucc_client::Progress| {},
        &CancellationToken::new(),
    )
    .await
    .unwrap();
    server.stop().await.unwrap();
    let flown = summary.iterations[0].trajectory.last().unwrap().clone();

    // Serve the recording and read it back with the framework's connection and model.
    let recording = replay::open(&record).unwrap();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    let stop = CancellationToken::new();
    let replayer = tokio::spawn(replay::serve(listener, recording, Pace::Fast, stop.clone()));
    let mut conn = Connection::connect(&addr, Duration::from_secs(5))
        .await
        .unwrap();
    let mut uav = UavState::new();
    while let Ok(message) = conn.next_message().await {
        uav.apply(&message);
    }
    stop.cancel();
    replayer.await.unwrap().unwrap();

    let position = uav.position.expect("positions were replayed");
    assert_eq!(position.time, flown.time);
    assert_eq!(position.value, flown.position);
    std::fs::remove_dir_all(&dir).unwrap();
}
