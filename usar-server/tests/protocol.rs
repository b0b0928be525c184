//! The server over real TCP: what a USARSim client sees.

mod common;

use common::{Client, TestServer, distance};
use usar_proto::{Nfo, SenData, ServerMessage, StartPose};

/// The default map's first start pose, asked over the protocol.
async fn first_start(client: &mut Client) -> StartPose {
    client.send("GETSTARTPOSES").await;
    client
        .until(|m| match m {
            ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) => Some(poses[0].clone()),
            _ => None,
        })
        .await
}

#[tokio::test]
async fn greets_with_game_info_and_lists_start_poses() {
    let server = TestServer::start().await;
    let mut c = server.client().await;
    let first = c.raw_line().await.unwrap();
    let level = usar_server::sim::map::Map::default_map().level().to_owned();
    assert_eq!(
        first,
        format!("NFO {{Gametype BotDeathMatch}} {{Level {level}}} {{TimeLimit 20}}\r\n")
    );
    c.send("GETSTARTPOSES").await;
    let (line, msg) = c.message().await;
    let ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) = msg else {
        panic!("expected start poses, got {line}");
    };
    assert!(!poses.is_empty(), "the default map has start poses: {line}");
    assert!(line.starts_with(&format!("NFO {{StartPoses {}}} {{", poses.len())));
    server.stop().await;
}

#[tokio::test]
async fn init_at_location_and_at_start_tag() {
    let server = TestServer::start().await;
    let mut c = server.client().await;
    let start = first_start(&mut c).await;

    c.spawn_at(
        [start.location.x + 1.0, start.location.y, start.location.z],
        0.0,
    )
    .await;
    let (_, p) = c.position().await;
    assert!(
        (p.x - start.location.x - 1.0).abs() < 0.01
            && (p.y - start.location.y).abs() < 0.01
            && (p.z - start.location.z).abs() < 0.01,
        "spawned at {p:?}"
    );

    let mut d = server.client().await;
    d.send(&format!(
        "INIT {{ClassName USARBot.stsAirRobot}} {{Name B}} {{Start {}}}",
        start.name.to_uppercase()
    ))
    .await;
    let (_, q) = d.position().await;
    assert!(
        distance(q, start.location) < 0.01,
        "spawned at {q:?}, start {start:?}"
    );
    server.stop().await;
}

#[tokio::test]
async fn unknown_class_spawns_nothing_and_keeps_the_connection() {
    let server = TestServer::start().await;
    let mut c = server.client().await;
    c.raw_line().await.unwrap();
    c.send("INIT {ClassName USARBot.NoSuchRobot} {Location 0,0,0}")
        .await;
    c.send("FLY {To Moon}").await;
    // Still served: GETSTARTPOSES answers, and nothing else came before it.
    c.send("GETSTARTPOSES").await;
    let (line, _) = c.message().await;
    assert!(line.starts_with("NFO {StartPoses"), "got {line}");
    server.stop().await;
}

/// Drives with `command` from a fresh spawn and returns the rate of change (per simulated
/// second) measured by `probe` over two simulated seconds of motion.
async fn rate_during(
    command: &str,
    window: f64,
    probe: fn(&ServerMessage) -> Option<(f64, f64)>,
) -> f64 {
    let server = TestServer::start().await;
    let mut c = server.client().await;
    let start = first_start(&mut c).await;
    c.spawn_at([start.location.x, start.location.y, start.location.z], 0.0)
        .await;
    c.send(command).await;
    // Skip a little so the command is surely applied, then measure over `window` seconds.
    let (t0, _) = c.until(probe).await;
    let (t1, v1) = c.until(|m| probe(m).filter(|(t, _)| *t >= t0 + 0.25)).await;
    let (t2, v2) = c
        .until(|m| probe(m).filter(|(t, _)| *t >= t1 + window))
        .await;
    server.stop().await;
    (v2 - v1) / (t2 - t1)
}

fn x_position(m: &ServerMessage) -> Option<(f64, f64)> {
    match m {
        ServerMessage::Sen(s) => match &s.data {
            SenData::Position { location, .. } => Some((s.time?.seconds, location.x)),
            _ => None,
        },
        _ => None,
    }
}

fn z_position(m: &ServerMessage) -> Option<(f64, f64)> {
    match m {
        ServerMessage::Sen(s) => match &s.data {
            SenData::Position { location, .. } => Some((s.time?.seconds, location.z)),
            _ => None,
        },
        _ => None,
    }
}

fn yaw(m: &ServerMessage) -> Option<(f64, f64)> {
    match m {
        ServerMessage::Sen(s) => match &s.data {
            SenData::Imu { rotation, .. } => Some((s.time?.seconds, rotation.z)),
            _ => None,
        },
        _ => None,
    }
}

#[tokio::test]
async fn linear_velocity_moves_along_the_heading() {
    let v = rate_during("DRIVE {LinearVelocity 1}", 2.0, x_position).await;
    assert!((v - 1.0).abs() <= 0.05, "moved at {v} m/s");
}

#[tokio::test]
async fn rotational_velocity_is_whole_degrees_per_second() {
    let w = rate_during("DRIVE {RotationalVelocity 45}", 2.0, yaw).await;
    assert!(
        (w.to_degrees() - 45.0).abs() <= 45.0 * 0.05,
        "turned at {} deg/s",
        w.to_degrees()
    );
    let w = rate_during("DRIVE {RotationalVelocity 0.5}", 2.0, yaw).await;
    assert_eq!(w, 0.0, "0.5 deg/s truncates to no rotation");
}

#[tokio::test]
async fn normalized_altitude_velocity_climbs_at_two_metres_per_second() {
    // z is down in the protocol frame: climbing makes z smaller. One second keeps the UAV
    // below the ceiling (the default start has at least 3 m above it).
    let v = rate_during(
        "DRIVE {AltitudeVelocity 100} {Normalized true}",
        1.0,
        z_position,
    )
    .await;
    assert!((v + 2.0).abs() <= 0.1, "climbed at {} m/s", -v);
}

/// The range of sonar `name` in `m`, if `m` is such a reading taken after `since`.
fn sonar_after(m: &ServerMessage, name: &str, since: f64) -> Option<f64> {
    let ServerMessage::Sen(s) = m else {
        return None;
    };
    let SenData::Sonar { readings, .. } = &s.data else {
        return None;
    };
    let r = readings.iter().find(|r| r.name == name)?;
    (s.time?.seconds > since).then_some(r.range)
}

#[tokio::test]
async fn two_robots_see_each_other_in_their_sonars() {
    let server = TestServer::start().await;
    let mut a = server.client().await;
    let start = first_start(&mut a).await;
    let (x, y, z) = (start.location.x, start.location.y, start.location.z);
    a.spawn_at([x, y, z], 0.0).await;
    let mut b = server.client().await;
    b.raw_line().await.unwrap();
    // b 2 m in front of a, facing it.
    b.spawn_at([x + 2.0, y, z], std::f64::consts::PI).await;
    let (since, _) = b.position().await;
    let ra = a.until(|m| sonar_after(m, "Sonar0", since)).await;
    let rb = b.until(|m| sonar_after(m, "Sonar0", since)).await;
    assert!(ra < 2.0 && ra > 1.0, "a's front sonar reads {ra}");
    assert!(rb < 2.0 && rb > 1.0, "b's front sonar reads {rb}");
    let back = a.until(|m| sonar_after(m, "Sonar4", since)).await;
    assert!(back > 2.0, "a's back sonar sees free space: {back}");
    server.stop().await;
}

#[tokio::test]
async fn garbage_from_one_client_leaves_another_undisturbed() {
    let server = TestServer::start().await;
    let mut good = server.client().await;
    let start = first_start(&mut good).await;
    good.spawn_at([start.location.x, start.location.y, start.location.z], 0.0)
        .await;

    let mut bad = server.client().await;
    use tokio::io::AsyncWriteExt;
    let long = vec![b'x'; 200_000];
    bad.writer.write_all(&long).await.unwrap();
    bad.writer
        .write_all(b"\r\n\0\xff\xfe{{{}}}\n")
        .await
        .unwrap();
    bad.writer
        .write_all(b"DRIVE {LinearVelocity")
        .await
        .unwrap();
    drop(bad);

    // The good client's STA keeps coming every 0.1 s of simulated time.
    let mut times = Vec::new();
    while times.len() < 20 {
        let (_, m) = good.message().await;
        if let ServerMessage::Sta(sta) = m {
            times.push(sta.time.seconds);
        }
    }
    for w in times.windows(2) {
        assert!((w[1] - w[0] - 0.1).abs() < 0.011, "STA gap {w:?}");
    }
    server.stop().await;
}

#[tokio::test]
async fn shutdown_closes_connections_with_eof() {
    let server = TestServer::start().await;
    let mut c = server.client().await;
    c.raw_line().await.unwrap();
    server.stop().await;
    // Drain whatever is left; then EOF.
    while c.raw_line().await.is_some() {}
}

/// The number of decimals of each number in `text` (numbers separated by commas).
fn decimals(text: &str) -> Vec<usize> {
    text.split(',')
        .map(|n| n.split_once('.').map_or(0, |(_, d)| d.len()))
        .collect()
}

#[tokio::test]
async fn every_sensor_reports_at_its_interval_in_its_exact_format() {
    use std::collections::BTreeMap;
    let server = TestServer::start().await;
    let mut c = server.client().await;
    let start = first_start(&mut c).await;
    c.spawn_at([start.location.x, start.location.y, start.location.z], 0.0)
        .await;
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut first_time = None;
    loop {
        let (line, m) = c.message().await;
        // The printer is the exact inverse of the parser: what we sent is canonical.
        assert_eq!(m.to_string(), line, "non-canonical line");
        let (time, key) = match &m {
            ServerMessage::Sta(sta) => {
                assert!(
                    line.starts_with("STA {Time ") && line.contains("} {Battery "),
                    "{line}"
                );
                (sta.time.seconds, "STA".to_owned())
            }
            ServerMessage::Sen(sen) => {
                let t = sen
                    .time
                    .expect("stsAirRobot sensors are time-stamped")
                    .seconds;
                let key = match &sen.data {
                    SenData::Position { name, location } => {
                        assert_eq!(name, "Position");
                        let _ = location;
                        let text = line
                            .split("{Location ")
                            .nth(1)
                            .unwrap()
                            .trim_end_matches('}');
                        assert_eq!(decimals(text), [4, 4, 4], "{line}");
                        "Position".to_owned()
                    }
                    SenData::Velocity { name, .. } => {
                        assert_eq!(name, "Velocity");
                        "Velocity".to_owned()
                    }
                    SenData::Imu { .. } => "IMU".to_owned(),
                    SenData::Sonar { readings, grouped } => {
                        assert!(!grouped && readings.len() == 1, "{line}");
                        let r = &readings[0];
                        assert!((0.1..=5.0).contains(&r.range), "{line}");
                        r.name.clone()
                    }
                    SenData::RangeScanner(scan) => {
                        assert_eq!(scan.ranges.len(), 228, "{line}");
                        assert!(
                            line.contains("{Resolution 0.0184} {FOV 4.1889} {Range "),
                            "{line}"
                        );
                        let text = line.split("{Range ").nth(1).unwrap().trim_end_matches('}');
                        assert!(decimals(text).iter().all(|&d| d == 2), "{line}");
                        scan.name.clone()
                    }
                    other => panic!("unexpected sensor {other:?}"),
                };
                (t, key)
            }
            _ => continue,
        };
        let t0 = *first_time.get_or_insert(time);
        if time >= t0 + 5.0 {
            break;
        }
        *counts.entry(key).or_default() += 1;
    }
    let mut expected: BTreeMap<String, f64> = BTreeMap::new();
    for name in ["STA", "Position", "Velocity", "IMU"] {
        expected.insert(name.into(), 5.0 / 0.1);
    }
    for i in 0..8 {
        expected.insert(format!("Sonar{i}"), 5.0 / 0.2);
    }
    expected.insert("SonarTop".into(), 5.0 / 0.2);
    expected.insert("SonarBottom".into(), 5.0 / 0.2);
    expected.insert("Scanner".into(), 5.0 / 0.3);
    for (name, want) in &expected {
        let got = *counts.get(name).unwrap_or(&0) as f64;
        assert!(
            (got - want).abs() <= want * 0.1,
            "{name}: {got} readings in 5 s, expected {want}"
        );
    }
    assert_eq!(counts.len(), expected.len(), "unexpected parts: {counts:?}");
    server.stop().await;
}

/// A server on the empty room (20 m square, inner wall faces at x, y = ±10, floor z = 0,
/// ceiling z = -5), 10× real time.
async fn empty_room() -> TestServer {
    TestServer::with(usar_server::ServerConfig {
        map: usar_server::sim::map::Map::embedded("empty_room").unwrap(),
        time_scale: usar_server::TimeScale::Factor(10.0),
        ..usar_server::ServerConfig::default()
    })
    .await
}

#[tokio::test]
async fn a_sonar_facing_a_wall_reads_its_distance() {
    let server = empty_room().await;
    let mut c = server.client().await;
    c.raw_line().await.unwrap();
    // Facing north, 3 m from the wall; Sonar0 sits 0.4 m forward of the centre.
    c.spawn_at([7.0, 0.0, -1.0], 0.0).await;
    let (_, range) = c.sonar("Sonar0").await;
    assert!((range - 2.6).abs() <= 0.01, "Sonar0 reads {range}");
    server.stop().await;
}

#[tokio::test]
async fn the_first_laser_beam_looks_right() {
    let server = empty_room().await;
    let mut c = server.client().await;
    c.raw_line().await.unwrap();
    // Facing north, the east wall 2 m to the right, the west wall 18 m to the left.
    c.spawn_at([0.0, 8.0, -1.0], 0.0).await;
    let ranges = c.scan().await;
    // Beam 0 points 120° clockwise from the heading: it meets the east wall after
    // 2 / sin(120°) = 2.309 m. The last beam looks left, where nothing is within 4 m.
    let expected = 2.0 / (2.0945f64).sin();
    assert!(
        (ranges[0] - expected).abs() <= 0.02,
        "beam 0 reads {}",
        ranges[0]
    );
    assert_eq!(*ranges.last().unwrap(), 4.0, "the last beam sees nothing");
    server.stop().await;
}

#[tokio::test]
async fn a_uav_driven_into_a_wall_stops_in_front_of_it() {
    let server = empty_room().await;
    let mut c = server.client().await;
    c.raw_line().await.unwrap();
    c.spawn_at([7.0, 0.0, -1.0], 0.0).await;
    c.send("DRIVE {LinearVelocity 2}").await;
    let (t0, _) = c.position().await;
    // 3 m to the wall at 2 m/s: after 3 s it has long arrived, and stays.
    let (_, p) = c
        .until(|m| match m {
            ServerMessage::Sen(s) => match &s.data {
                SenData::Position { location, .. } if s.time?.seconds >= t0 + 3.0 => {
                    Some((0.0, *location))
                }
                _ => None,
            },
            _ => None,
        })
        .await;
    // The UAV's collision radius is 0.45 m: it stops with its edge at the wall.
    assert!(
        p.x < 10.0 - 0.45 && p.x > 10.0 - 0.5,
        "stopped at x = {}",
        p.x
    );
    assert!(p.y.abs() < 0.01, "drifted sideways to y = {}", p.y);
    server.stop().await;
}

#[tokio::test]
async fn an_empty_battery_leaves_only_sta() {
    let mut robots = usar_server::sim::robots::RobotCatalog::embedded();
    robots.get_mut("USARBot.stsAirRobot").unwrap().battery = Some(2.0);
    let server = TestServer::with(usar_server::ServerConfig {
        robots,
        time_scale: usar_server::TimeScale::Factor(10.0),
        ..usar_server::ServerConfig::default()
    })
    .await;
    let mut c = server.client().await;
    let start = first_start(&mut c).await;
    c.spawn_at([start.location.x, start.location.y, start.location.z], 0.0)
        .await;
    let empty_at = c
        .until(|m| match m {
            ServerMessage::Sta(s) if s.battery == 0 => Some(s.time.seconds),
            _ => None,
        })
        .await;
    assert!((empty_at - 2.0).abs() < 0.15, "battery empty at {empty_at}");
    c.send("GETCONF {Type Robot}").await;
    c.send("DRIVE {LinearVelocity 1}").await;
    let mut stas = 0;
    while stas < 10 {
        let (line, m) = c.message().await;
        match m {
            ServerMessage::Sta(s) => {
                assert_eq!(s.battery, 0, "{line}");
                stas += 1;
            }
            _ => panic!("only STA after the battery is empty, got {line}"),
        }
    }
    server.stop().await;
}

/// STA times received by `c` until `count` have arrived.
async fn sta_times(c: &mut Client, count: usize) -> Vec<f64> {
    let mut times = Vec::new();
    while times.len() < count {
        if let (_, ServerMessage::Sta(sta)) = c.message().await {
            times.push(sta.time.seconds);
        }
    }
    times
}

#[tokio::test]
async fn a_client_that_never_reads_does_not_slow_the_others() {
    let server = TestServer::with(usar_server::ServerConfig {
        time_scale: usar_server::TimeScale::Factor(50.0),
        // Small enough that the sleeper's output is dropped early, large enough (about half
        // a simulated second) that a reader on a busy machine is never 4 ticks behind.
        client_buffer: 64 * 1024,
        ..usar_server::ServerConfig::default()
    })
    .await;
    let mut sleeper = server.client().await;
    let start = first_start(&mut sleeper).await;
    let (x, y, z) = (start.location.x, start.location.y, start.location.z);
    // Spawns a robot whose stream it never reads; also a silent connection that says nothing.
    sleeper
        .send(&format!(
            "INIT {{ClassName USARBot.stsAirRobot}} {{Location {},{},{}}}",
            x - 2.0,
            y,
            z
        ))
        .await;
    let _silent = server.client().await;
    let mut reader = server.client().await;
    reader.raw_line().await.unwrap();
    reader.spawn_at([x + 2.0, y, z], 0.0).await;
    // 40 simulated seconds (some 5 MB of output): more than the sleeper's queue and socket
    // buffers hold, so its output is being dropped meanwhile.
    let times = sta_times(&mut reader, 400).await;
    for w in times.windows(2) {
        assert!((w[1] - w[0] - 0.1).abs() < 0.011, "STA gap {w:?}");
    }
    server.stop().await;
}

#[tokio::test]
async fn the_default_connection_limit_serves_its_clients_and_refuses_the_next() {
    let server = TestServer::start().await;
    let max = usar_server::ServerConfig::default().max_connections;
    assert_eq!(max, 256, "the documented default (docs/limits.md)");
    let mut clients = Vec::new();
    for i in 0..max {
        // Active connections do not count against the per-address cap (limits.rs).
        let mut c = Client::connect_from(server.addr, 2 + (i % 4) as u8).await;
        assert!(c.raw_line().await.unwrap().starts_with("NFO "));
        // Each has sent a line: none makes room for a newcomer (limits.rs).
        c.send("GETSTARTPOSES").await;
        assert!(c.raw_line().await.unwrap().starts_with("NFO {StartPoses "));
        clients.push(c);
    }
    let mut extra = Client::connect_from(server.addr, 100).await;
    assert_eq!(
        extra.raw_line().await,
        None,
        "the connection past the limit is closed at once"
    );
    // All of them keep being served.
    for c in &mut clients {
        c.send("GETSTARTPOSES").await;
    }
    for c in &mut clients {
        let (line, _) = c.message().await;
        assert!(line.starts_with("NFO {StartPoses "), "{line}");
    }
    // A slot freed is a slot to reuse.
    drop(clients.pop());
    tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    let mut again = Client::connect_from(server.addr, 100).await;
    assert!(again.raw_line().await.unwrap().starts_with("NFO "));
    server.stop().await;
}

#[tokio::test]
async fn a_quadrotor_obeys_quad_rotor_commands_and_reports_its_crash() {
    let server = empty_room().await;
    let mut c = server.client().await;
    c.raw_line().await.unwrap();
    c.send("INIT {ClassName USARBot.stsQuadrotor} {Location 0,0,-2}")
        .await;
    let (_, hover) = c.position().await;
    // All four rotors well below hover speed: it sinks, lands hard on the floor, crashes.
    c.send("QUAD {Rotors 300,300,300,300}").await;
    let crash_time = c
        .until(|m| match m {
            ServerMessage::Sen(s) => match &s.data {
                SenData::Touch { name, touch: true } if name == "Crash" => {
                    Some(s.time.unwrap().seconds)
                }
                _ => None,
            },
            _ => None,
        })
        .await;
    let (t, p) = c.position().await;
    assert!(
        t >= crash_time && p.z > hover.z + 1.8,
        "on the floor: {p:?}"
    );
    // Nothing was answered to QUAD: only STA and SEN lines arrived.
    c.send("QUAD {Rotors 700,700,700,700}").await;
    for _ in 0..40 {
        let (line, _) = c.message().await;
        assert!(
            line.starts_with("STA ") || line.starts_with("SEN "),
            "{line}"
        );
    }
    server.stop().await;
}

/// STA times among the next `lines` raw lines of `c` (read without parsing the others).
async fn sta_times_raw(c: &mut Client, lines: usize) -> Vec<f64> {
    let mut times = Vec::new();
    for _ in 0..lines {
        let line = c.raw_line().await.expect("unexpected EOF");
        if let Some(rest) = line.strip_prefix("STA {Time ") {
            let end = rest.find('}').unwrap();
            times.push(rest[..end].parse().unwrap());
        }
    }
    times
}

fn assert_no_sta_missing(times: &[f64]) {
    for w in times.windows(2) {
        assert!((w[1] - w[0] - 0.1).abs() < 0.011, "STA gap {w:?}");
    }
}

#[tokio::test]
async fn at_max_speed_a_slow_reader_misses_nothing() {
    let server = TestServer::with(usar_server::ServerConfig {
        time_scale: usar_server::TimeScale::Max,
        // About a simulated second and a half: dropped at once if the world did not wait.
        client_buffer: 16 * 1024,
        ..usar_server::ServerConfig::default()
    })
    .await;
    let mut reader = server.client().await;
    reader.raw_line().await.unwrap();
    reader.spawn_at([0.0, 0.0, -1.0], 0.0).await;
    let mut times = Vec::new();
    // 30 simulated seconds (about 2800 lines), read in pauses of 2 ms every 100 lines.
    for _ in 0..28 {
        times.extend(sta_times_raw(&mut reader, 100).await);
        tokio::time::sleep(std::time::Duration::from_millis(2)).await;
    }
    assert!(times.len() > 250, "{} STA", times.len());
    assert_no_sta_missing(&times);
    server.stop().await;
}

#[tokio::test]
async fn at_max_speed_a_client_that_stops_reading_holds_the_world_only_for_the_reader_timeout() {
    let timeout = std::time::Duration::from_millis(400);
    let server = TestServer::with(usar_server::ServerConfig {
        time_scale: usar_server::TimeScale::Max,
        client_buffer: 16 * 1024,
        reader_timeout: timeout,
        ..usar_server::ServerConfig::default()
    })
    .await;
    let began = std::time::Instant::now();
    let mut sleeper = server.client().await;
    sleeper.raw_line().await.unwrap();
    sleeper.spawn_at([-2.0, 0.0, -1.0], 0.0).await;
    let mut reader = server.client().await;
    reader.raw_line().await.unwrap();
    reader.spawn_at([2.0, 0.0, -1.0], 0.0).await;
    // 1000 simulated seconds (some 11 MB to each client): far more than the sleeper's queue
    // and socket buffers hold. The world waits for the sleeper, then goes on without it,
    // and the reader still gets every line.
    let times = sta_times_raw(&mut reader, 93_000).await;
    assert!(times.len() > 9000, "{} STA", times.len());
    assert_no_sta_missing(&times);
    assert!(
        began.elapsed() >= timeout,
        "the world did not wait for the sleeper: {:?}",
        began.elapsed()
    );
    server.stop().await;
}
