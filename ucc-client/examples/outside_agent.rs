//! An agent written outside the library, flown by the library's runner with the same
//! missions, iterations, logs, trajectories, pictures and statistics as the built-in ones.
//!
//! It only uses ucc-client's public API: define a type, implement [`Agent`], hand a factory
//! to [`ucc_client::run`]. Run it against a server of its own (in lockstep, as fast as the
//! CPU allows) or against any USARSim host:
//!
//! ```sh
//! cargo run -p ucc-client --example outside_agent                      # local server
//! cargo run -p ucc-client --example outside_agent -- localhost:3000    # a running one
//! ```
//!
//! The files go to `./outside-agent-output/`; the exit code is 0 only when every iteration
//! completed and wrote its files.

use std::process::ExitCode;

use tokio_util::sync::CancellationToken;
use ucc_client::geometry::world_to_heading;
use ucc_client::{
    Agent, AgentEvent, Coordinates, Lockstep, Mission, MissionRefused, Progress, RunSettings,
    SpeedCommand, Start, Step, UavState,
};

/// Flies straight at each waypoint without turning: the error in the world frame, turned
/// into the heading frame, drives forward/right/up proportionally (a strafing controller,
/// unlike the built-in agents, which turn towards the target first).
#[derive(Default)]
struct Strafer {
    missions: Vec<Mission>,
    current: usize,
    started: bool,
    stopped: bool,
}

/// Metres from a waypoint that count as reached.
const REACHED: f64 = 0.25;
/// Percent of full speed per metre of error.
const GAIN: f64 = 60.0;

impl Agent for Strafer {
    fn name(&self) -> &str {
        "strafer"
    }

    fn add_mission(&mut self, mission: Mission) -> Result<(), MissionRefused> {
        match mission {
            Mission::GotoXyz { .. } => {
                self.missions.push(mission);
                Ok(())
            }
            Mission::Hover { .. } => Err(MissionRefused {
                agent: "strafer".into(),
                kind: mission.kind(),
                reason: "it only flies to points".into(),
            }),
        }
    }

    fn start(&mut self, _time: f64) {}

    fn stop(&mut self) {
        self.stopped = true;
    }

    fn step(&mut self, uav: &UavState, time: f64) -> Step {
        let mut step = Step::default();
        let (Some(position), false) = (&uav.position, self.stopped) else {
            step.command = Some(SpeedCommand::STOP);
            return step;
        };
        let Some(target) = self.missions.get(self.current).and_then(Mission::target) else {
            step.all_done = true;
            step.command = Some(SpeedCommand::STOP);
            return step;
        };
        if !self.started {
            self.started = true;
            step.events.push(AgentEvent::MissionStarted {
                index: self.current,
                mission: self.missions[self.current].clone(),
                time,
            });
        }
        let error = target - position.value;
        if error.norm() < REACHED {
            step.events.push(AgentEvent::MissionDone {
                index: self.current,
                mission: self.missions[self.current].clone(),
                time,
                distance: Some(error.norm()),
            });
            self.current += 1;
            self.started = false;
            step.all_done = self.current == self.missions.len();
            step.command = Some(SpeedCommand::STOP);
            return step;
        }
        let local = world_to_heading(&error, uav.yaw());
        step.command = Some(
            SpeedCommand {
                forward: local.x * GAIN,
                right: local.y * GAIN,
                up: -local.z * GAIN,
                yaw: 0.0,
            }
            .clamped(),
        );
        step
    }
}

#[tokio::main]
async fn main() -> ExitCode {
    match fly(std::env::args().nth(1)).await {
        Ok(code) => code,
        Err(e) => {
            eprintln!("outside_agent: {e}");
            ExitCode::FAILURE
        }
    }
}

async fn fly(addr: Option<String>) -> Result<ExitCode, Box<dyn std::error::Error>> {
    // Without an address: a usar-server of our own, in lockstep.
    let local = match addr {
        Some(_) => None,
        None => Some(
            usar_server::LocalServer::start(usar_server::ServerConfig {
                time_scale: usar_server::TimeScale::Max,
                lockstep: true,
                ..usar_server::ServerConfig::default()
            })
            .await?,
        ),
    };
    let addr = match (&local, addr) {
        (Some(server), _) => server.addr().to_string(),
        (None, addr) => addr.unwrap_or_default(),
    };
    let settings = RunSettings {
        addr,
        start: Start::at(Coordinates::new(0.0, 0.0, -1.0)),
        missions: [
            (3.0, 0.0, -2.0),
            (3.0, 3.0, -2.5),
            (0.0, 3.0, -1.5),
            (0.0, 0.0, -1.0),
        ]
        .into_iter()
        .map(|(x, y, z)| Mission::goto(Coordinates::new(x, y, z)))
        .collect(),
        iterations: 2,
        log_dir: Some("outside-agent-output".into()),
        prefix: "strafer".into(),
        lockstep: if local.is_some() {
            Lockstep::Required
        } else {
            Lockstep::IfOffered
        },
        ..RunSettings::default()
    };
    let factory = || Box::new(Strafer::default()) as Box<dyn Agent>;
    let mut print = |p: &Progress| {
        if p.is_loggable() && !matches!(p, Progress::Written { .. }) {
            println!("{p}");
        }
    };
    let summary =
        ucc_client::run(&settings, &factory, &mut print, &CancellationToken::new()).await?;
    if let Some(server) = local {
        server.stop().await?;
    }
    let stats = summary.statistics();
    println!(
        "{} of {} iterations done, {:.1} m flown on average; files in outside-agent-output/",
        stats.completed,
        summary.iterations.len(),
        stats.distance.0
    );
    // Each iteration: log, trajectory, map (SVG, PNG), plots (SVG, PNG); then the overlay.
    let written = summary.iterations.iter().all(|i| i.files.len() == 6)
        && summary.overlay.len() == 2
        && summary.results.is_some();
    Ok(if stats.completed == settings.iterations && written {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
