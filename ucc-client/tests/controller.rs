//! The controller against a scripted kinematic server speaking the real wire lines.

use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;
use ucc_client::{Coordinates, Mission, Progress, RunConfig, RunError, Start, run_missions};
use usar_proto::Command;

/// Serves `connections` clients, one after the other: NFO, then after INIT a UAV that obeys
/// normalized DRIVE commands (2 m/s, 100 deg/s), streaming STA, Position and IMU every 0.1 s
/// of simulated time (as fast as possible). With `spawn: false` it never answers INIT.
async fn fake_server(listener: TcpListener, connections: usize, spawn: bool) {
    for _ in 0..connections {
        let (socket, _) = listener.accept().await.unwrap();
        let (read, mut write) = socket.into_split();
        let mut lines = BufReader::new(read).lines();
        write
            .write_all(b"NFO {Gametype BotDeathMatch} {Level TestMap} {TimeLimit 20}\r\n")
            .await
            .unwrap();
        let (mut p, mut yaw, mut t) = (Coordinates::new(0.0, 0.0, -1.0), 0.0f64, 10.0);
        let mut drive = [0.0; 4]; // forward, right, up, yaw (percent)
        let mut spawned = false;
        loop {
            let line = if spawned {
                tokio::time::timeout(Duration::from_millis(1), lines.next_line()).await
            } else {
                Ok(lines.next_line().await)
            };
            match line {
                Ok(Ok(None)) | Ok(Err(_)) => break,
                Ok(Ok(Some(line))) => match Command::parse(&line).unwrap().message {
                    Command::Init(_) => spawned = spawn,
                    Command::Drive(d) => {
                        drive = [
                            d.linear_velocity.unwrap_or(drive[0]),
                            d.lateral_velocity.unwrap_or(drive[1]),
                            d.altitude_velocity.unwrap_or(drive[2]),
                            d.rotational_velocity.unwrap_or(drive[3]),
                        ]
                    }
                    _ => {}
                },
                Err(_) => {}
            }
            if !spawned {
                continue;
            }
            let dt = 0.1;
            yaw += (drive[3] as i64 as f64).to_radians() * dt;
            let (s, c) = yaw.sin_cos();
            let (f, r) = (drive[0] * 0.02, drive[1] * 0.02);
            p += Coordinates::new(f * c - r * s, f * s + r * c, -drive[2] * 0.02) * dt;
            t += dt;
            let out = format!(
                "STA {{Time {t:.4}}} {{Battery 1200}}\r\n\
                 SEN {{Time {t:.4}}} {{Type Position}} {{Name Position}} {{Location {:.4},{:.4},{:.4}}}\r\n\
                 SEN {{Time {t:.4}}} {{Type IMU}} {{Name IMU}} {{XYZAcceleration 0.0000,0.0000,0.0000}} {{AngularVel 0.0000,0.0000,0.0000}} {{AngularAccel 0.0000,0.0000,0.0000}} {{Rotation 0.0000,0.0000,{yaw:.4}}}\r\n",
                p.x, p.y, p.z
            );
            if write.write_all(out.as_bytes()).await.is_err() {
                break;
            }
        }
    }
}

fn config(addr: String, dir: Option<std::path::PathBuf>) -> RunConfig {
    RunConfig {
        addr,
        start: Start::Tag("Start1".into()),
        missions: vec![
            Mission::goto(Coordinates::new(2.0, 0.0, -2.0)),
            Mission::goto(Coordinates::new(2.0, -2.0, -2.0)),
        ],
        iterations: 2,
        log_dir: dir,
        stream_timeout: Duration::from_secs(2),
        ..RunConfig::default()
    }
}

#[tokio::test]
#[ignore = "needs usar-proto parser and printer"]
async fn flies_two_iterations_and_writes_files() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    tokio::spawn(fake_server(listener, 2, true));
    let dir = std::env::temp_dir().join(format!("ucc-controller-{}", std::process::id()));
    let mut lines = Vec::new();
    let summary = run_missions(&config(addr, Some(dir.clone())), |p: &Progress| {
        lines.push(p.to_string())
    })
    .await
    .unwrap();
    assert_eq!(summary.iterations.len(), 2);
    for it in &summary.iterations {
        assert_eq!(it.missions_done, 2);
        assert!(it.distance > 4.0 && it.distance < 8.0, "{}", it.distance);
        for f in &it.files {
            assert!(std::fs::metadata(f).unwrap().len() > 0, "{f:?}");
        }
    }
    assert!(
        lines.iter().any(|l| l.contains("map TestMap")),
        "{lines:#?}"
    );
    assert!(
        lines.iter().any(|l| l.contains("mission 2 done")),
        "{lines:#?}"
    );
    assert_eq!(summary.overlay.len(), 2);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[tokio::test]
#[ignore = "needs usar-proto parser and printer"]
async fn spawn_failure_is_reported() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    tokio::spawn(fake_server(listener, 1, false));
    let err = run_missions(&config(addr, None), |_| {}).await.unwrap_err();
    assert!(matches!(err, RunError::SpawnFailed { .. }), "{err}");
    assert!(err.to_string().contains("USARBot.stsAirRobot"), "{err}");
}
