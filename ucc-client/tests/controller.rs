//! The controller against a server that never spawns the robot. (Flights against the real
//! usar-server are in the workspace's `tests/` crate.)

use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use ucc_client::{Coordinates, Mission, Progress, RunError, RunSettings, Start, agents};

/// Greets with NFO and then reads commands without ever answering, as USARSim does when the
/// INIT names an unknown class.
async fn silent_server(listener: TcpListener) {
    let (socket, _) = listener.accept().await.unwrap();
    let (read, mut write) = socket.into_split();
    write
        .write_all(b"NFO {Gametype BotDeathMatch} {Level TestMap} {TimeLimit 20}\r\n")
        .await
        .unwrap();
    let mut lines = BufReader::new(read).lines();
    while let Ok(Some(_)) = lines.next_line().await {}
}

#[tokio::test]
async fn spawn_failure_is_reported() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    tokio::spawn(silent_server(listener));
    let settings = RunSettings {
        addr,
        start: Start::Tag("Start1".into()),
        missions: vec![Mission::goto(Coordinates::new(2.0, 0.0, -2.0))],
        stream_timeout: Duration::from_secs(2),
        ..RunSettings::default()
    };
    let base = agents::info("base").unwrap().create;
    let cancel = CancellationToken::new();
    let err = ucc_client::run(&settings, &base, &mut |_: &Progress| {}, &cancel)
        .await
        .unwrap_err();
    assert!(matches!(err, RunError::SpawnFailed { .. }), "{err}");
    assert!(err.to_string().contains("USARBot.stsAirRobot"), "{err}");
}
