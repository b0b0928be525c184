//! End to end: a real usar-server, the ucc controller and its agents, in lockstep.

use std::time::Duration;

use tokio_util::sync::CancellationToken;
use ucc_client::agent::AgentEvent;
use ucc_client::{Coordinates, Mission, Progress, RunConfig, Start, run_missions};
use usar_server::sim::map::Map;
use usar_server::{ServerConfig, TimeScale};

/// A server on `map` on a free port, as fast as lockstep allows; cancelled on drop.
struct Server {
    addr: String,
    shutdown: CancellationToken,
    task: tokio::task::JoinHandle<Result<(), usar_server::ServerError>>,
}

impl Server {
    async fn start(map: &str) -> Self {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let shutdown = CancellationToken::new();
        let config = ServerConfig {
            map: Map::embedded(map).unwrap(),
            time_scale: TimeScale::Max,
            lockstep: true,
            ..ServerConfig::default()
        };
        let task = tokio::spawn(usar_server::run(listener, config, shutdown.clone()));
        Self {
            addr,
            shutdown,
            task,
        }
    }

    /// Stops the server and checks it exits cleanly.
    async fn stop(self) {
        self.shutdown.cancel();
        tokio::time::timeout(Duration::from_secs(30), self.task)
            .await
            .expect("the server stops on cancel")
            .unwrap()
            .unwrap();
    }
}

fn pose(x: f64, y: f64, z: f64) -> Start {
    Start::Pose {
        location: Coordinates::new(x, y, z),
        rotation: Coordinates::zeros(),
    }
}

#[tokio::test]
async fn four_waypoints_are_reached_in_order_within_tolerance() {
    let server = Server::start("empty_room").await;
    let waypoints = [
        Coordinates::new(3.0, 0.0, -2.0),
        Coordinates::new(3.0, 3.0, -2.5),
        Coordinates::new(-2.0, 3.0, -1.5),
        Coordinates::new(-2.0, -2.0, -2.0),
    ];
    let config = RunConfig {
        addr: server.addr.clone(),
        start: pose(0.0, 0.0, -1.0),
        missions: waypoints.iter().copied().map(Mission::goto).collect(),
        lockstep: true,
        ..RunConfig::default()
    };
    let mut reached = Vec::new();
    let summary = run_missions(&config, |p| {
        if let Progress::Agent {
            event: AgentEvent::MissionDone {
                index, distance, ..
            },
            ..
        } = p
        {
            reached.push((*index, distance.unwrap()));
        }
    })
    .await
    .unwrap();
    assert_eq!(
        reached.iter().map(|r| r.0).collect::<Vec<_>>(),
        [0, 1, 2, 3],
        "reached in order"
    );
    assert!(
        reached.iter().all(|r| r.1 <= 0.3),
        "within 0.3 m: {reached:?}"
    );
    // Where the trajectory says it was when each waypoint counted as reached.
    let path = &summary.iterations[0].trajectory;
    for w in waypoints {
        let closest = path
            .iter()
            .map(|p| (p.position - w).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(closest <= 0.3, "the path passes {closest:.2} m from {w:?}");
    }
    server.stop().await;
}

/// Distance from point `p` to the segment `a`–`b`, in the horizontal plane.
fn distance_to_segment(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 == 0.0 {
        0.0
    } else {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    };
    let (x, y) = (a.0 + t * dx, a.1 + t * dy);
    ((p.0 - x).powi(2) + (p.1 - y).powi(2)).sqrt()
}

#[tokio::test]
async fn the_avoid_agent_flies_around_a_pillar_without_touching_it() {
    let server = Server::start("arena").await;
    // The arena's pillar of radius 0.3 m at (-5, -4) stands right between start and goal.
    let pillar = (-5.0, -4.0);
    let goal = Coordinates::new(-2.0, -4.0, -1.5);
    let config = RunConfig {
        addr: server.addr.clone(),
        agent: "avoid".into(),
        start: pose(-8.0, -4.0, -1.5),
        missions: vec![Mission::goto(goal)],
        lockstep: true,
        mission_timeout: 60.0,
        ..RunConfig::default()
    };
    let summary = run_missions(&config, |_| {}).await.unwrap();
    let path: Vec<(f64, f64)> = summary.iterations[0]
        .trajectory
        .iter()
        .map(|p| (p.position.x, p.position.y))
        .collect();
    let closest = path
        .windows(2)
        .map(|s| distance_to_segment(pillar, s[0], s[1]))
        .fold(f64::INFINITY, f64::min);
    // The UAV's collision radius is 0.45 m: touching means a centre within 0.75 m.
    assert!(
        closest > 0.75 + 0.05,
        "passed the pillar's axis at {closest:.2} m"
    );
    let end = summary.iterations[0].trajectory.last().unwrap().position;
    assert!((end - goal).norm() <= 0.3, "ended at {end:?}");
    server.stop().await;
}

#[tokio::test]
async fn lockstep_iterations_repeat_exactly() {
    let server = Server::start("empty_room").await;
    let config = RunConfig {
        addr: server.addr.clone(),
        start: pose(0.0, 0.0, -1.0),
        missions: vec![
            Mission::goto(Coordinates::new(2.0, 1.0, -2.0)),
            Mission::goto(Coordinates::new(0.0, 2.0, -1.5)),
        ],
        iterations: 3,
        lockstep: true,
        ..RunConfig::default()
    };
    let summary = run_missions(&config, |_| {}).await.unwrap();
    let paths: Vec<Vec<Coordinates>> = summary
        .iterations
        .iter()
        .map(|i| i.trajectory.iter().map(|p| p.position).collect())
        .collect();
    assert!(
        paths[0].len() > 20,
        "a real flight: {} samples",
        paths[0].len()
    );
    assert_eq!(paths[0], paths[1], "iteration 2 differs from 1");
    assert_eq!(paths[0], paths[2], "iteration 3 differs from 1");
    server.stop().await;
}

#[tokio::test]
async fn a_stock_air_robot_with_a_ground_truth_flies_on_it() {
    // A configuration change, not code: the stock AirRobot plus a GroundTruth part.
    let dir = std::env::temp_dir().join(format!("e2e-airrobot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("robots.toml");
    std::fs::write(
        &file,
        r#"
[[robot]]
class = "USARBot.AirRobot"

[[robot.part]]
type = "IMU"
name = "IMU"

[[robot.part]]
type = "GroundTruth"
name = "GndTruth"
"#,
    )
    .unwrap();
    let robots = usar_server::sim::robots::RobotCatalog::from_file(&file).unwrap();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    let shutdown = CancellationToken::new();
    let task = tokio::spawn(usar_server::run(
        listener,
        ServerConfig {
            robots,
            time_scale: TimeScale::Max,
            lockstep: true,
            ..ServerConfig::default()
        },
        shutdown.clone(),
    ));
    let goal = Coordinates::new(2.0, -1.0, -2.0);
    let config = RunConfig {
        addr,
        robot: "AirRobot".into(),
        start: pose(0.0, 0.0, -1.0),
        missions: vec![Mission::goto(goal)],
        lockstep: true,
        ..RunConfig::default()
    };
    let summary = run_missions(&config, |_| {}).await.unwrap();
    let path = &summary.iterations[0].trajectory;
    assert!(path.len() > 10, "GroundTruth gave the positions");
    assert!((path.last().unwrap().position - goal).norm() <= 0.3);
    // No Velocity sensor: velocity is derived from the positions.
    assert!(
        path.iter()
            .any(|p| p.velocity.is_some_and(|v| v.norm() > 0.5))
    );
    shutdown.cancel();
    task.await.unwrap().unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}
