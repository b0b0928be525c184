//! Lockstep (docs/lockstep.md): byte-identical runs whatever the time scale.

mod common;

use common::{Client, TestServer};
use usar_proto::{Nfo, SenData, ServerMessage};
use usar_server::sim::WindConfig;
use usar_server::{ServerConfig, TimeScale};

/// Reads until the `SYNC` answer; returns every line read, in order, and the answer's time.
async fn until_sync(c: &mut Client) -> (Vec<String>, f64) {
    let mut lines = Vec::new();
    loop {
        let line = c.raw_line().await.expect("EOF before the SYNC answer");
        lines.push(line.clone());
        if let Some(rest) = line.strip_prefix("SYNC {Time ") {
            let time = rest.trim_end().trim_end_matches('}').parse().unwrap();
            return (lines, time);
        }
    }
}

/// A small closed-loop flight: fly towards x = start + 1.5 while reading Position, in
/// 0.1 s lockstep intervals. Returns every byte the client received.
async fn flight(scale: TimeScale, seed: u64) -> Vec<String> {
    flight_of("USARBot.stsAirRobot", None, scale, seed).await
}

/// [`flight`] with a robot class and a wind.
async fn flight_of(
    class: &str,
    wind: Option<WindConfig>,
    scale: TimeScale,
    seed: u64,
) -> Vec<String> {
    let mut config = ServerConfig {
        time_scale: scale,
        lockstep: true,
        ..ServerConfig::default()
    };
    config.sim.seed = seed;
    config.sim.wind = wind;
    let server = TestServer::with(config).await;
    let mut c = server.client().await;
    let mut seen = vec![c.raw_line().await.unwrap()];
    c.send("GETSTARTPOSES").await;
    let (line, start) = c.message().await;
    seen.push(line);
    let ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) = start else {
        panic!("no start poses")
    };
    let s = poses[0].location;

    c.send("SYNC {Time 0}").await;
    let (lines, t) = until_sync(&mut c).await;
    seen.extend(lines);
    c.send(&format!(
        "INIT {{ClassName {class}}} {{Location {},{},{}}}",
        s.x, s.y, s.z
    ))
    .await;
    let mut time = t;
    for _ in 0..30 {
        time += 0.1;
        c.send(&format!("SYNC {{Time {time:.1}}}")).await;
        let (lines, _) = until_sync(&mut c).await;
        let x = lines.iter().rev().find_map(|l| {
            match ServerMessage::parse(l.trim_end()).ok()?.message {
                ServerMessage::Sen(sen) => match sen.data {
                    SenData::Position { location, .. } => Some(location.x),
                    _ => None,
                },
                _ => None,
            }
        });
        seen.extend(lines);
        if let Some(x) = x {
            let v = (s.x + 1.5 - x).clamp(-1.0, 1.0);
            c.send(&format!("DRIVE {{LinearVelocity {v:.3}}}")).await;
        }
    }
    server.stop().await;
    seen
}

#[tokio::test]
async fn lockstep_runs_are_byte_identical_at_any_time_scale() {
    let fast = flight(TimeScale::Max, 3).await;
    let again = flight(TimeScale::Max, 3).await;
    let paced = flight(TimeScale::Factor(4.0), 3).await;
    assert!(
        fast.len() > 100,
        "the flight produced traffic: {} lines",
        fast.len()
    );
    assert!(
        fast.iter().any(|l| l.contains("{Type Position}")),
        "position readings arrived"
    );
    assert_eq!(fast, again, "two runs differ");
    assert_eq!(fast, paced, "the time scale changed the run");
}

#[tokio::test]
async fn a_quadrotor_in_gusty_wind_is_byte_identical_in_lockstep() {
    let wind = Some(WindConfig {
        velocity: [0.5, 1.5, 0.0],
        gusts: 1.0,
        gust_length: 15.0,
    });
    let quad = "USARBot.stsQuadrotor";
    let fast = flight_of(quad, wind, TimeScale::Max, 9).await;
    let again = flight_of(quad, wind, TimeScale::Max, 9).await;
    let paced = flight_of(quad, wind, TimeScale::Factor(4.0), 9).await;
    let other_seed = flight_of(quad, wind, TimeScale::Max, 10).await;
    assert!(
        fast.iter()
            .any(|l| l.contains("{Type Touch} {Name Crash} {Touch False}"))
    );
    assert_eq!(fast, again, "two runs differ");
    assert_eq!(fast, paced, "the time scale changed the run");
    assert_ne!(fast, other_seed, "the seed drives the gusts");
}

#[tokio::test]
async fn a_client_that_never_syncs_is_never_waited_for() {
    let server = TestServer::with(ServerConfig {
        time_scale: TimeScale::Factor(10.0),
        lockstep: true,
        ..ServerConfig::default()
    })
    .await;
    let mut lockstep = server.client().await;
    lockstep.raw_line().await.unwrap();
    lockstep.send("GETSTARTPOSES").await;
    let (_, start) = lockstep.message().await;
    let ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) = start else {
        panic!("no start poses")
    };
    let s = poses[0].location;
    lockstep.send("SYNC {Time 0}").await;
    until_sync(&mut lockstep).await;

    let mut free = server.client().await;
    free.raw_line().await.unwrap();
    free.send(&format!(
        "INIT {{ClassName USARBot.stsAirRobot}} {{Location {},{},{}}}",
        s.x, s.y, s.z
    ))
    .await;
    // The free client never syncs: the world still reaches the lockstep client's barrier.
    lockstep.send("SYNC {Time 1.0}").await;
    let (_, t) = until_sync(&mut lockstep).await;
    assert!((t - 1.0).abs() < 0.006, "answered at {t}");
    // The free client saw the world run up to the barrier.
    let mut last = 0.0;
    while last < 0.95 {
        last = free
            .until(|m| match m {
                ServerMessage::Sta(s) => Some(s.time.seconds),
                _ => None,
            })
            .await;
    }
    server.stop().await;
}

/// Reads the STA lines of `c` until one reaches `until`; returns its time.
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

/// Lockstep is opt-in: without it a `SYNC` is an unknown command, never answered, and holds
/// nobody (the defect: one `SYNC {Time 0}` froze the world for every client).
#[tokio::test]
async fn without_lockstep_a_sync_holds_nobody() {
    let server = TestServer::start().await;
    let mut c = server.client().await;
    c.raw_line().await.unwrap();
    c.send("SYNC {Time 0}").await;
    c.send("INIT {ClassName USARBot.stsAirRobot} {Location 0,0,-1}")
        .await;
    let mut last = 0.0;
    while last < 0.5 {
        let (_, m) = c.message().await;
        assert!(!matches!(m, ServerMessage::Sync(_)), "SYNC answered");
        if let ServerMessage::Sta(s) = m {
            last = s.time.seconds;
        }
    }
    server.stop().await;
}

#[tokio::test]
async fn a_lockstep_client_that_stops_syncing_leaves_the_barrier() {
    let server = TestServer::with(ServerConfig {
        time_scale: TimeScale::Factor(10.0),
        lockstep: true,
        lockstep_timeout: std::time::Duration::from_millis(300),
        ..ServerConfig::default()
    })
    .await;
    let mut stuck = server.client().await;
    stuck.raw_line().await.unwrap();
    stuck.send("SYNC {Time 0.5}").await;
    let mut free = server.client().await;
    free.raw_line().await.unwrap();
    free.spawn_at([0.0, 0.0, -1.0], 0.0).await;
    // The world reaches the barrier, answers, and waits; the stuck client never syncs
    // again: after the timeout the world goes on without it.
    let (_, t) = until_sync(&mut stuck).await;
    assert!((t - 0.5).abs() < 0.006, "answered at {t}");
    let last = sta_until(&mut free, 2.0).await;
    assert!(last >= 2.0);
    // A later SYNC joins the barrier again.
    stuck.send("SYNC {Time 3.0}").await;
    let (_, t) = until_sync(&mut stuck).await;
    assert!(t >= 2.0, "answered at {t}");
    server.stop().await;
}

/// Issue #26 item 5: one client that sends each `SYNC` just before the lockstep timeout
/// held every other client at 0.4 % of its rate. With a share limit it leaves the barrier
/// after one window (10 s of wall time), and the others run at full speed again.
#[tokio::test]
async fn a_client_that_holds_the_world_too_long_leaves_the_barrier() {
    let server = TestServer::with(ServerConfig {
        time_scale: TimeScale::Factor(10.0),
        lockstep: true,
        lockstep_timeout: std::time::Duration::from_secs(1),
        lockstep_share: 0.5,
        ..ServerConfig::default()
    })
    .await;
    let mut hog = server.client().await;
    hog.raw_line().await.unwrap();
    let mut free = server.client().await;
    free.raw_line().await.unwrap();
    free.spawn_at([0.0, 0.0, -1.0], 0.0).await;
    let hogging = tokio::spawn(async move {
        let mut barrier = 0.1;
        let mut answers = 0;
        loop {
            hog.send(&format!("SYNC {{Time {barrier}}}")).await;
            let answered =
                tokio::time::timeout(std::time::Duration::from_secs(3), until_sync(&mut hog)).await;
            if answered.is_err() {
                return answers; // no longer answered: out of the barrier
            }
            answers += 1;
            tokio::time::sleep(std::time::Duration::from_millis(900)).await;
            barrier += 0.1;
        }
    });
    // Held, the world would go 0.1 s per 0.9 s of wall time: 4.4 s in 40 s.
    let started = std::time::Instant::now();
    let last = sta_until(&mut free, 20.0).await;
    assert!(
        started.elapsed() < std::time::Duration::from_secs(40),
        "the hog held the world: {last} s simulated in {:?}",
        started.elapsed()
    );
    let answers = hogging.await.unwrap();
    assert!(
        answers >= 5,
        "the hog was in the barrier first ({answers} answers)"
    );
    server.stop().await;
}

/// `lockstep_clients`: who may join the barrier. With 1, a second client's `SYNC` is
/// ignored: never answered, holding nobody.
#[tokio::test]
async fn only_the_first_lockstep_clients_may_join_the_barrier() {
    let server = TestServer::with(ServerConfig {
        time_scale: TimeScale::Factor(10.0),
        lockstep: true,
        lockstep_clients: 1,
        ..ServerConfig::default()
    })
    .await;
    let mut first = server.client().await;
    first.raw_line().await.unwrap();
    first.send("SYNC {Time 0}").await;
    until_sync(&mut first).await;
    let mut second = server.client().await;
    second.raw_line().await.unwrap();
    second.send("SYNC {Time 0}").await;
    second
        .send("INIT {ClassName USARBot.stsAirRobot} {Location 0,0,-1}")
        .await;
    // The first holds the world at 0 until it syncs again; the second is not answered.
    first.send("SYNC {Time 0.5}").await;
    let (_, t) = until_sync(&mut first).await;
    assert!((t - 0.5).abs() < 0.006, "answered at {t}");
    let mut last = 0.0;
    while last < 0.5 {
        let (_, m) = second.message().await;
        assert!(
            !matches!(m, ServerMessage::Sync(_)),
            "second client answered"
        );
        if let ServerMessage::Sta(s) = m {
            last = s.time.seconds;
        }
    }
    server.stop().await;
}

/// A lockstep server with `faults` recording into `record`.
async fn faulty_server(
    faults: usar_server::sim::faults::FaultPlan,
    record: Option<std::path::PathBuf>,
) -> TestServer {
    let mut config = ServerConfig {
        time_scale: TimeScale::Max,
        lockstep: true,
        record,
        ..ServerConfig::default()
    };
    config.sim.seed = 5;
    config.sim.faults = faults;
    TestServer::with(config).await
}

/// Sends the client lines of a recording in lockstep (each `SYNC` waits for its answer)
/// and returns every line received, without terminators.
async fn resend(c: &mut Client, client_lines: &[String]) -> Vec<String> {
    let mut seen = vec![c.raw_line().await.unwrap()];
    for line in client_lines {
        c.send(line).await;
        if line.starts_with("SYNC") {
            seen.extend(until_sync(c).await.0);
        } else if line.starts_with("GETSTARTPOSES") {
            seen.push(c.raw_line().await.unwrap());
        }
    }
    seen.iter().map(|l| l.trim_end().to_owned()).collect()
}

#[tokio::test]
async fn a_faulty_run_is_reproduced_from_its_recording_alone() {
    let dir = std::env::temp_dir().join(format!("usar-faulty-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let plan = usar_server::sim::faults::FaultPlan::from_toml(
        "[[fault]]\ntime = 1.0\nrobot = 1\nline = \"FAULT {Motor 2} {Thrust 0.6}\"\n\
         [[random]]\nprobability = 0.5\nrobot = 1\nline = \"FAULT {Sensor Position} {Mode Drift} {Rate 0.3}\"\n",
    )
    .unwrap();
    // The run: a lockstep flight with the faults, recorded by the server.
    let server = faulty_server(plan, Some(dir.clone())).await;
    let mut c = server.client().await;
    let mut lines = vec!["SYNC {Time 0}".to_string()];
    lines.push("INIT {ClassName USARBot.stsQuadrotor} {Location 0,0,-2}".into());
    for k in 1..=40 {
        if k == 5 {
            lines.push("DRIVE {LinearVelocity 1}".into());
        }
        lines.push(format!("SYNC {{Time {:.1}}}", f64::from(k) * 0.1));
    }
    let seen = resend(&mut c, &lines).await;
    drop(c);
    server.stop().await;
    assert!(
        seen.iter().filter(|l| l.starts_with("FAULT {Time")).count() == 2,
        "the server told of both faults: {:?}",
        seen.iter()
            .filter(|l| l.starts_with("FAULT"))
            .collect::<Vec<_>>()
    );
    let file = dir.join("connection-0001.usarlog");
    let text = std::fs::read_to_string(&file).unwrap();
    let (mut client_lines, mut server_lines) = (Vec::new(), Vec::new());
    for line in text.lines() {
        if let Some(e) = usar_proto::record::parse_entry(line).unwrap() {
            match e.direction {
                usar_proto::record::Direction::Client => client_lines.push(e.text.to_owned()),
                usar_proto::record::Direction::Server => server_lines.push(e.text.to_owned()),
            }
        }
    }
    assert_eq!(
        server_lines, seen,
        "the recording holds what the client saw"
    );
    // Again from the recording alone: its FAULT lines are the faults (`--faults REC`), its
    // client lines the commands.
    let plan = usar_server::sim::faults::FaultPlan::from_file(&file).unwrap();
    let server = faulty_server(plan, None).await;
    let mut c = server.client().await;
    let again = resend(&mut c, &client_lines).await;
    server.stop().await;
    assert_eq!(again, server_lines, "the same bytes");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue #56's rule for new members (`lockstep_join_share`) does not touch a well-behaved
/// agent: one that joins next to an established member and thinks 5 ms a step, at full
/// speed (where waiting for the agents is nearly all the wall time), is answered at the
/// time of every barrier it asks for: the world always waits for it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_new_member_that_thinks_a_few_milliseconds_a_step_keeps_its_lockstep() {
    let server = TestServer::with(ServerConfig {
        time_scale: TimeScale::Max,
        lockstep: true,
        lockstep_join_share: 0.05,
        ..ServerConfig::default()
    })
    .await;
    // The established member: syncs one step ahead as soon as it is answered, from the
    // start, for the whole test.
    let mut old = server.client().await;
    old.raw_line().await.unwrap();
    old.spawn_at([0.0, 0.0, -1.0], 0.0).await;
    let stop = tokio_util::sync::CancellationToken::new();
    let established = {
        let stop = stop.clone();
        tokio::spawn(async move {
            let mut barrier = 0.05;
            while !stop.is_cancelled() {
                old.send(&format!("SYNC {{Time {barrier:.2}}}")).await;
                let (_, t) = until_sync(&mut old).await;
                barrier = t + 0.05;
            }
        })
    };
    // New members are new for 10 s.
    tokio::time::sleep(std::time::Duration::from_millis(10_500)).await;
    let mut new = server.client().await;
    new.raw_line().await.unwrap();
    new.spawn_at([3.0, 0.0, -1.0], 0.0).await;
    new.send("SYNC {Time 0}").await;
    let (_, mut t) = until_sync(&mut new).await;
    let mut late = Vec::new();
    for _ in 0..200 {
        tokio::time::sleep(std::time::Duration::from_millis(5)).await;
        // The barrier asked for is the one on the wire (answer times are multiples of the
        // 5 ms tick, so three decimals are exact; two would round half a tick away).
        let asked = format!("{:.3}", t + 0.05);
        new.send(&format!("SYNC {{Time {asked}}}")).await;
        (_, t) = until_sync(&mut new).await;
        let barrier: f64 = asked.parse().unwrap();
        if (t - barrier).abs() > 1e-6 {
            late.push((barrier, t));
        }
    }
    stop.cancel();
    established.await.unwrap();
    assert!(
        late.is_empty(),
        "{} of 200 answers past their barrier (barrier, answer): {:?}",
        late.len(),
        &late[..late.len().min(5)]
    );
    server.stop().await;
}
