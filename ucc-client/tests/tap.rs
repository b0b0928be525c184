//! `ucc tap` between a client and a real usar-server.

use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio_util::sync::CancellationToken;

#[tokio::test]
async fn the_tap_forwards_everything_and_records_both_directions() {
    let shutdown = CancellationToken::new();
    let upstream = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let upstream_addr = upstream.local_addr().unwrap().to_string();
    let server = tokio::spawn(usar_server::run(
        upstream,
        usar_server::ServerConfig {
            time_scale: usar_server::TimeScale::Factor(10.0),
            ..usar_server::ServerConfig::default()
        },
        shutdown.clone(),
    ));
    let dir = std::env::temp_dir().join(format!("ucc-tap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let record = dir.join("session.usarlog");
    let front = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let front_addr = front.local_addr().unwrap();
    let tap = tokio::spawn(ucc_client::tap::run(
        front,
        upstream_addr,
        record.clone(),
        shutdown.clone(),
    ));

    let stream = tokio::net::TcpStream::connect(front_addr).await.unwrap();
    let (read, mut write) = stream.into_split();
    let mut lines = BufReader::new(read).lines();
    write
        .write_all(b"INIT {ClassName USARBot.stsAirRobot} {Location 0,0,-1}\r\nNOT A {COMMAND\r\n")
        .await
        .unwrap();
    let mut received = Vec::new();
    while received.len() < 30 {
        received.push(lines.next_line().await.unwrap().unwrap());
    }
    assert!(received[0].starts_with("NFO {Gametype BotDeathMatch}"));
    assert!(received.iter().any(|l| l.starts_with("STA {Time ")));
    drop(write);
    drop(lines);
    // Give the tap a moment to see the close, then stop everything.
    tokio::time::sleep(std::time::Duration::from_millis(200)).await;
    shutdown.cancel();
    tap.await.unwrap().unwrap();
    server.await.unwrap().unwrap();

    let text = std::fs::read_to_string(&record).unwrap();
    let entries: Vec<&str> = text.lines().skip(1).collect();
    assert!(
        entries
            .iter()
            .any(|l| l.ends_with(" C INIT {ClassName USARBot.stsAirRobot} {Location 0,0,-1}")),
        "{text}"
    );
    assert!(
        entries.iter().any(|l| l.ends_with(" C NOT A {COMMAND")),
        "{text}"
    );
    // Every line the client received is in the recording, in order.
    let recorded: Vec<&str> = entries
        .iter()
        .filter_map(|l| l.split_once(" S ").map(|(_, line)| line))
        .collect();
    assert_eq!(&recorded[..received.len()], &received[..]);
    std::fs::remove_dir_all(&dir).unwrap();
}
