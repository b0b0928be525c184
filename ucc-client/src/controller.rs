//! The controller: create a UAV, connect, spawn, hand the missions to an agent, fly until
//! every mission is done, and do it again as many times as asked.
//!
//! Each iteration uses a fresh connection (a second INIT on the same connection would leave
//! the old robot in the world): connect, `INIT` at the start pose or tag, wait for the stream,
//! step the agent whenever new sensor data arrives, send its command when it changes,
//! disconnect. Time limits: `stream_timeout` (wall clock) for the stream to start and keep
//! flowing, `mission_timeout` (simulated seconds) for each mission.

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Duration;

use usar_proto::{Command, Init, Nfo, ServerMessage, StartPose};

use crate::agent::{Agent, AgentEvent, MissionRefused, SpeedCommand};
use crate::agents;
use crate::connection::{Connection, ConnectionError};
use crate::geometry::{Coordinates, to_wire};
use crate::mission::{Mission, parse_numbers};
use crate::picture::{MapPicture, PictureError};
use crate::record::{TrajectoryPoint, write_log, write_trajectory};
use crate::uav::UavState;

/// Simulated seconds per lockstep barrier: the rate of the Position and STA streams.
pub const LOCKSTEP_STEP: f64 = 0.1;

/// Where the UAV is spawned.
#[derive(Debug, Clone, PartialEq)]
pub enum Start {
    /// A pose: world frame, metres, z down; rotation roll, pitch, yaw in radians.
    Pose {
        /// x, y, z.
        location: Coordinates,
        /// roll, pitch, yaw.
        rotation: Coordinates,
    },
    /// A PlayerStart of the map, by tag or name.
    Tag(String),
}

impl FromStr for Start {
    type Err = String;

    /// `x,y,z`, `x,y,z,roll,pitch,yaw` (metres, radians) or a PlayerStart tag.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim();
        let looks_numeric = s.starts_with(|c: char| c.is_ascii_digit() || "+-.".contains(c));
        if !looks_numeric {
            if s.is_empty() || s.contains(['{', '}']) {
                return Err(format!("invalid start tag {s:?}"));
            }
            return Ok(Self::Tag(s.to_owned()));
        }
        let n = parse_numbers(s).map_err(|e| format!("invalid start pose {s:?}: {e}"))?;
        let v = |i: usize| n.get(i).copied().unwrap_or(0.0);
        match n.len() {
            3 | 6 => Ok(Self::Pose {
                location: Coordinates::new(v(0), v(1), v(2)),
                rotation: Coordinates::new(v(3), v(4), v(5)),
            }),
            k => Err(format!(
                "invalid start pose {s:?}: {k} numbers, expected x,y,z or x,y,z,roll,pitch,yaw"
            )),
        }
    }
}

impl fmt::Display for Start {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Pose {
                location: l,
                rotation: r,
            } => write!(
                f,
                "{:.2},{:.2},{:.2} (roll {:.2}, pitch {:.2}, yaw {:.2})",
                l.x, l.y, l.z, r.x, r.y, r.z
            ),
            Self::Tag(tag) => write!(f, "start tag {tag}"),
        }
    }
}

/// Everything [`run_missions`] needs.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// `host:port` of the server.
    pub addr: String,
    /// Robot class: `stsAirRobot`, `AirRobot`, or a full `Package.Class`.
    pub robot: String,
    /// The robot's name in the world.
    pub name: String,
    /// A name from the agent registry ([`agents::AGENTS`]).
    pub agent: String,
    /// Where to spawn, every iteration.
    pub start: Start,
    /// The missions, flown in order, every iteration.
    pub missions: Vec<Mission>,
    /// How many times to fly them.
    pub iterations: usize,
    /// Where to write the logs, trajectories and pictures; `None` writes nothing.
    pub log_dir: Option<PathBuf>,
    /// File name prefix of everything written.
    pub prefix: String,
    /// Wall-clock limit for connecting.
    pub connect_timeout: Duration,
    /// Wall-clock limit for the first sensor data after INIT, and for any silence after.
    pub stream_timeout: Duration,
    /// Simulated seconds a single mission may take.
    pub mission_timeout: f64,
    /// Ask the server for lockstep (docs/lockstep.md); without it, run on sensor time.
    pub lockstep: bool,
    /// Record every line of every iteration's connection: this file for the first,
    /// `NAME-2.EXT`, `NAME-3.EXT`, … for the next (docs/recording.md).
    pub record: Option<PathBuf>,
    /// Go on with the next iteration when one fails (a mission timeout, an empty battery, a
    /// spawn that gave no stream); the failure is counted in the [`Summary`]. Failures that
    /// would repeat every time (no server, unwritable files) always end the run.
    pub keep_going: bool,
    /// Which map pictures to draw.
    pub pictures: Pictures,
}

/// Which map pictures a run draws (in the log directory).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pictures {
    /// One per iteration and the overlay of all.
    #[default]
    All,
    /// Only the overlay of all iterations.
    Overlay,
    /// None.
    None,
}

impl FromStr for Pictures {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "all" => Ok(Self::All),
            "overlay" => Ok(Self::Overlay),
            "none" => Ok(Self::None),
            _ => Err(format!("expected all, overlay or none, not {s:?}")),
        }
    }
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            addr: "localhost:3000".into(),
            robot: "stsAirRobot".into(),
            name: "UAV1".into(),
            agent: "base".into(),
            start: Start::Pose {
                location: Coordinates::zeros(),
                rotation: Coordinates::zeros(),
            },
            missions: Vec::new(),
            iterations: 1,
            log_dir: None,
            prefix: "UCCLOG".into(),
            connect_timeout: Duration::from_secs(5),
            stream_timeout: Duration::from_secs(10),
            mission_timeout: 120.0,
            lockstep: false,
            record: None,
            keep_going: false,
            pictures: Pictures::All,
        }
    }
}

impl RunConfig {
    /// The INIT class name: `robot` with `USARBot.` in front unless it names a package.
    pub fn class_name(&self) -> String {
        if self.robot.contains('.') {
            self.robot.clone()
        } else {
            format!("USARBot.{}", self.robot)
        }
    }

    fn init(&self) -> Command {
        let mut init = Init {
            class_name: self.class_name(),
            name: Some(self.name.clone()),
            ..Init::default()
        };
        match &self.start {
            Start::Pose { location, rotation } => {
                init.location = Some(to_wire(location));
                init.rotation = Some(to_wire(rotation));
            }
            Start::Tag(tag) => init.start = Some(tag.clone()),
        }
        Command::Init(init)
    }

    fn file(&self, name: &str) -> Option<PathBuf> {
        self.log_dir
            .as_ref()
            .map(|d| d.join(format!("{}-{name}", self.prefix)))
    }
}

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The agent name is not in the registry.
    #[error("unknown agent {name:?} (known agents: {known})")]
    UnknownAgent {
        /// The name asked for.
        name: String,
        /// The registered names.
        known: String,
    },
    /// Nothing to fly.
    #[error("no missions to fly")]
    NoMissions,
    /// The agent does not handle a mission type.
    #[error(transparent)]
    Refused(#[from] MissionRefused),
    /// Talking to the server failed.
    #[error(transparent)]
    Connection(#[from] ConnectionError),
    /// INIT gave no stream.
    #[error(
        "spawn failed: no data from the server within {timeout:?} after INIT {class} \
         (unknown robot class, bad start pose or tag, or no room there?)"
    )]
    SpawnFailed {
        /// The class asked for.
        class: String,
        /// The limit.
        timeout: Duration,
    },
    /// The robot streams data but never a position.
    #[error(
        "the robot reports no position within {timeout:?}: it needs a Position, GroundTruth \
         or INS sensor"
    )]
    NoPosition {
        /// The limit.
        timeout: Duration,
    },
    /// The stream stopped.
    #[error("the server sent nothing for {timeout:?}")]
    StreamStopped {
        /// The limit.
        timeout: Duration,
    },
    /// The battery ran out.
    #[error("battery empty at t={time:.2}s")]
    BatteryEmpty {
        /// Simulated seconds.
        time: f64,
    },
    /// The UAV crashed (its crash sensor fired, docs/quadrotor.md).
    #[error("crashed at t={time:.2}s: {reason}")]
    Crashed {
        /// Simulated seconds.
        time: f64,
        /// What the UAV state knew then (speed, tilt, position).
        reason: String,
    },
    /// A mission took too long.
    #[error("mission {number} ({mission}) not done after {seconds} simulated seconds")]
    MissionTimeout {
        /// 1-based.
        number: usize,
        /// The mission.
        mission: Mission,
        /// The limit.
        seconds: f64,
    },
    /// A GETSTARTPOSES reply did not come.
    #[error("the server did not answer GETSTARTPOSES within {timeout:?}")]
    NoStartPoses {
        /// The limit.
        timeout: Duration,
    },
    /// A log or trajectory file could not be written.
    #[error("cannot write {path}: {error}")]
    Output {
        /// The file.
        path: PathBuf,
        /// Why (part of the message, so not a `source`).
        error: std::io::Error,
    },
    /// A picture could not be written.
    #[error(transparent)]
    Picture(#[from] PictureError),
}

impl RunError {
    /// Whether the failure would happen again in the next iteration, so that going on is
    /// pointless (no server, a bad configuration, files that cannot be written).
    pub fn is_fatal(&self) -> bool {
        matches!(
            self,
            Self::UnknownAgent { .. }
                | Self::NoMissions
                | Self::Refused(_)
                | Self::Connection(
                    ConnectionError::Connect { .. }
                        | ConnectionError::ConnectTimeout { .. }
                        | ConnectionError::Record { .. }
                )
                | Self::NoStartPoses { .. }
                | Self::Output { .. }
                | Self::Picture(_)
        )
    }
}

/// Something a user cares about, reported while running.
#[derive(Debug, Clone, PartialEq)]
pub enum Progress {
    /// Connected to the server.
    Connected {
        /// 1-based.
        iteration: usize,
        /// `host:port`.
        addr: String,
        /// The map, from the server's NFO.
        map: Option<String>,
        /// Whether the run is in lockstep with the server.
        lockstep: bool,
    },
    /// The robot is in the world.
    Spawned {
        /// 1-based.
        iteration: usize,
        /// Simulated seconds.
        time: f64,
        /// Where.
        position: Coordinates,
    },
    /// An agent event (mission started or done, log line).
    Agent {
        /// 1-based.
        iteration: usize,
        /// The event.
        event: AgentEvent,
    },
    /// Every mission of an iteration is done.
    IterationDone {
        /// 1-based.
        iteration: usize,
        /// Its summary.
        summary: IterationSummary,
    },
    /// An iteration failed (and the run goes on, with `keep_going`).
    IterationFailed {
        /// 1-based.
        iteration: usize,
        /// Why.
        error: String,
    },
    /// Files were written.
    Written {
        /// The files.
        files: Vec<PathBuf>,
    },
}

impl fmt::Display for Progress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Connected {
                iteration,
                addr,
                map,
                lockstep,
            } => {
                write!(f, "[{iteration}] connected to {addr}")?;
                map.iter().try_for_each(|m| write!(f, " (map {m})"))?;
                if *lockstep {
                    write!(f, " in lockstep")?;
                }
                Ok(())
            }
            Self::Spawned {
                iteration,
                time,
                position: p,
            } => write!(
                f,
                "[{iteration}] t={time:.2}s spawned at {:.2},{:.2},{:.2}",
                p.x, p.y, p.z
            ),
            Self::Agent { iteration, event } => write!(f, "[{iteration}] {event}"),
            Self::IterationDone { iteration, summary } => write!(
                f,
                "[{iteration}] iteration done: {} missions in {:.1} simulated s, {:.1} m flown",
                summary.missions_done, summary.duration, summary.distance
            ),
            Self::IterationFailed { iteration, error } => {
                write!(f, "[{iteration}] iteration failed: {error}")
            }
            Self::Written { files } => {
                let names: Vec<_> = files.iter().map(|p| p.display().to_string()).collect();
                write!(f, "wrote {}", names.join(", "))
            }
        }
    }
}

/// The result of one iteration.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IterationSummary {
    /// Missions completed.
    pub missions_done: usize,
    /// Simulated seconds from the start to the last mission done.
    pub duration: f64,
    /// Metres flown (along the recorded path).
    pub distance: f64,
    /// The recorded trajectory.
    pub trajectory: Vec<TrajectoryPoint>,
    /// Files written for this iteration.
    pub files: Vec<PathBuf>,
    /// Why the iteration failed (`None`: every mission done).
    pub error: Option<String>,
}

impl IterationSummary {
    /// Simulated seconds from the first to the last trajectory sample.
    pub fn simulated_seconds(&self) -> f64 {
        match (self.trajectory.first(), self.trajectory.last()) {
            (Some(a), Some(b)) => b.time - a.time,
            _ => 0.0,
        }
    }
}

/// The result of a whole run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Summary {
    /// One entry per iteration flown, completed or failed.
    pub iterations: Vec<IterationSummary>,
    /// The overlay pictures (every iteration's path on one map).
    pub overlay: Vec<PathBuf>,
    /// The results table (`PREFIX-results.csv`), when a log directory is set.
    pub results: Option<PathBuf>,
}

/// Figures over the iterations of a run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Statistics {
    /// Iterations that completed every mission.
    pub completed: usize,
    /// Iterations that failed.
    pub failed: usize,
    /// Mean and standard deviation of the completion time of the completed iterations
    /// (simulated seconds).
    pub duration: (f64, f64),
    /// Mean and standard deviation of their path length (metres).
    pub distance: (f64, f64),
    /// The largest distance between any completed iteration's path and the first one's
    /// (symmetric Hausdorff distance in metres); 0 when every path is the same.
    pub max_deviation: f64,
    /// Simulated seconds flown in all iterations.
    pub simulated_seconds: f64,
}

impl Summary {
    /// The figures of the run.
    pub fn statistics(&self) -> Statistics {
        let done: Vec<&IterationSummary> = self
            .iterations
            .iter()
            .filter(|i| i.error.is_none())
            .collect();
        let first = done.first().map(|i| path_of(i));
        Statistics {
            completed: done.len(),
            failed: self.iterations.len() - done.len(),
            duration: mean_and_spread(done.iter().map(|i| i.duration)),
            distance: mean_and_spread(done.iter().map(|i| i.distance)),
            max_deviation: first.as_ref().map_or(0.0, |first| {
                done.iter()
                    .map(|i| hausdorff(first, &path_of(i)))
                    .fold(0.0, f64::max)
            }),
            simulated_seconds: self.iterations.iter().map(|i| i.simulated_seconds()).sum(),
        }
    }

    /// How far each iteration's path lies from the first completed one's (metres).
    fn deviations(&self) -> Vec<Option<f64>> {
        let first = self
            .iterations
            .iter()
            .find(|i| i.error.is_none())
            .map(path_of);
        self.iterations
            .iter()
            .map(|i| first.as_ref().map(|f| hausdorff(f, &path_of(i))))
            .collect()
    }
}

fn path_of(iteration: &IterationSummary) -> Vec<Coordinates> {
    iteration.trajectory.iter().map(|p| p.position).collect()
}

fn mean_and_spread(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let values: Vec<f64> = values.collect();
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt())
}

/// The symmetric Hausdorff distance between two sampled paths.
fn hausdorff(a: &[Coordinates], b: &[Coordinates]) -> f64 {
    let directed = |from: &[Coordinates], to: &[Coordinates]| {
        from.iter()
            .map(|p| {
                to.iter()
                    .map(|q| (p - q).norm())
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    };
    if a.is_empty() || b.is_empty() {
        return if a.len() == b.len() {
            0.0
        } else {
            f64::INFINITY
        };
    }
    directed(a, b).max(directed(b, a))
}

/// Flies `config.missions` `config.iterations` times; reports progress to `observer`.
///
/// Returns when every iteration completed all its missions, or at the first failure. The log,
/// trajectory and map of an iteration are written even when it fails.
pub async fn run_missions(
    config: &RunConfig,
    mut observer: impl FnMut(&Progress),
) -> Result<Summary, RunError> {
    if config.missions.is_empty() {
        return Err(RunError::NoMissions);
    }
    make_agent(config)?; // refuse a bad agent or mission before connecting
    if let Some(dir) = &config.log_dir {
        std::fs::create_dir_all(dir).map_err(|error| RunError::Output {
            path: dir.clone(),
            error,
        })?;
    }
    let mut summary = Summary::default();
    for iteration in 1..=config.iterations.max(1) {
        let mut flight = Flight::new(iteration);
        let result = flight.fly(config, &mut observer).await;
        if let Err(e) = &result {
            flight.log(format!("error: {e}"));
        }
        let files = flight.write(config)?;
        if !files.is_empty() {
            observer(&Progress::Written {
                files: files.clone(),
            });
        }
        let mut iteration_summary = flight.summary(files);
        match result {
            Ok(()) => observer(&Progress::IterationDone {
                iteration,
                summary: iteration_summary.clone(),
            }),
            Err(e) if !config.keep_going || e.is_fatal() => return Err(e),
            Err(e) => {
                iteration_summary.error = Some(e.to_string());
                observer(&Progress::IterationFailed {
                    iteration,
                    error: e.to_string(),
                });
            }
        }
        summary.iterations.push(iteration_summary);
    }
    if config.pictures != Pictures::None
        && let Some(base) = config.file("overlay")
    {
        let picture = MapPicture {
            title: format!("{} iterations", summary.iterations.len()),
            paths: summary.iterations.iter().map(path_of).collect(),
            waypoints: waypoints(config),
            start: summary
                .iterations
                .iter()
                .find_map(|i| first_position(&i.trajectory)),
        };
        summary.overlay = picture.write(&base)?.to_vec();
        observer(&Progress::Written {
            files: summary.overlay.clone(),
        });
    }
    if let Some(path) = config.file("results.csv") {
        write_results(&path, &summary).map_err(|error| RunError::Output {
            path: path.clone(),
            error,
        })?;
        summary.results = Some(path);
    }
    Ok(summary)
}

/// Writes one line per iteration: its number, status, missions done, completion time,
/// path length, distance of its path from the first one's, and the error.
fn write_results(path: &Path, summary: &Summary) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        out,
        "iteration,status,missions_done,duration_s,distance_m,deviation_m,simulated_s,error"
    )?;
    for (n, (i, deviation)) in summary
        .iterations
        .iter()
        .zip(summary.deviations())
        .enumerate()
    {
        writeln!(
            out,
            "{},{},{},{:.4},{:.4},{},{:.4},{}",
            n + 1,
            if i.error.is_none() { "ok" } else { "failed" },
            i.missions_done,
            i.duration,
            i.distance,
            deviation.map_or(String::new(), |d| format!("{d:.4}")),
            i.simulated_seconds(),
            i.error.as_deref().unwrap_or("").replace([',', '\n'], " "),
        )?;
    }
    out.flush()
}

/// Asks the server for the map's start poses (`GETSTARTPOSES`) on a connection of its own.
pub async fn start_poses(addr: &str, timeout: Duration) -> Result<Vec<StartPose>, RunError> {
    let mut conn = Connection::connect(addr, timeout).await?;
    conn.send(&Command::GetStartPoses).await?;
    let reply = tokio::time::timeout(timeout, async {
        loop {
            if let ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) = conn.next_message().await? {
                return Ok::<_, ConnectionError>(poses);
            }
        }
    })
    .await
    .map_err(|_| RunError::NoStartPoses { timeout })??;
    conn.disconnect().await?;
    Ok(reply)
}

/// The configured agent with every mission handed over (refusals are errors).
fn make_agent(config: &RunConfig) -> Result<Box<dyn Agent>, RunError> {
    let mut agent = agents::create(&config.agent).ok_or_else(|| RunError::UnknownAgent {
        name: config.agent.clone(),
        known: agents::names(),
    })?;
    for mission in &config.missions {
        agent.add_mission(mission.clone())?;
    }
    Ok(agent)
}

fn waypoints(config: &RunConfig) -> Vec<Coordinates> {
    config.missions.iter().filter_map(Mission::target).collect()
}

fn first_position(trajectory: &[TrajectoryPoint]) -> Option<Coordinates> {
    trajectory.first().map(|p| p.position)
}

/// The record of one iteration, filled while flying.
struct Flight {
    iteration: usize,
    log: Vec<String>,
    trajectory: Vec<TrajectoryPoint>,
    missions_done: usize,
    start_time: Option<f64>,
    end_time: Option<f64>,
    connected: bool,
}

impl Flight {
    fn new(iteration: usize) -> Self {
        Self {
            iteration,
            log: Vec::new(),
            trajectory: Vec::new(),
            missions_done: 0,
            start_time: None,
            end_time: None,
            connected: false,
        }
    }

    fn log(&mut self, line: String) {
        tracing::debug!(iteration = self.iteration, "{line}");
        self.log.push(line);
    }

    fn report(&mut self, observer: &mut impl FnMut(&Progress), progress: Progress) {
        self.log(progress.to_string());
        observer(&progress);
    }

    async fn fly(
        &mut self,
        config: &RunConfig,
        observer: &mut impl FnMut(&Progress),
    ) -> Result<(), RunError> {
        let iteration = self.iteration;
        let mut conn = match &config.record {
            Some(path) => {
                let path = crate::tap::record_path(path, iteration);
                Connection::connect_recording(&config.addr, config.connect_timeout, &path).await?
            }
            None => Connection::connect(&config.addr, config.connect_timeout).await?,
        };
        self.connected = true;
        let mut uav = UavState::new();

        // The server greets with NFO; take the map name from it if it comes quickly.
        let mut map = None;
        let greeting = Duration::from_secs(2).min(config.stream_timeout);
        if let Ok(message) = tokio::time::timeout(greeting, conn.next_message()).await {
            match message? {
                ServerMessage::Nfo(Nfo::GameInfo { level, .. }) => map = Some(level),
                other => _ = uav.apply(&other),
            }
        }
        if config.lockstep {
            let wait = Duration::from_secs(2).min(config.stream_timeout);
            if !conn.request_lockstep(LOCKSTEP_STEP, wait).await? {
                tracing::warn!("the server does not offer lockstep; running on sensor time");
                self.log("the server does not offer lockstep; running on sensor time".into());
            }
        }
        self.report(
            observer,
            Progress::Connected {
                iteration,
                addr: config.addr.clone(),
                map,
                lockstep: conn.is_lockstep(),
            },
        );

        conn.send(&config.init()).await?;
        self.log(format!(
            "sent INIT {} at {}",
            config.class_name(),
            config.start
        ));
        let position = self.wait_for_position(config, &mut conn, &mut uav).await?;
        let time = uav.time.unwrap_or(0.0);
        self.start_time = Some(time);
        self.report(
            observer,
            Progress::Spawned {
                iteration,
                time,
                position,
            },
        );

        let mut agent = make_agent(config)?;
        agent.start(time);
        let mut sent: Option<SpeedCommand> = None;
        let mut mission_start = (0, time);
        loop {
            let message = tokio::time::timeout(config.stream_timeout, conn.next_message())
                .await
                .map_err(|_| RunError::StreamStopped {
                    timeout: config.stream_timeout,
                })??;
            let fresh = uav.apply(&message);
            let time = uav.time.unwrap_or(0.0);
            if uav.battery_empty() {
                return Err(RunError::BatteryEmpty { time });
            }
            if let Some(crash) = &uav.crash {
                return Err(RunError::Crashed {
                    time: crash.time,
                    reason: crash.value.clone(),
                });
            }
            if !fresh {
                continue;
            }
            self.record(&uav);
            let step = agent.step(&uav, time);
            for event in step.events {
                match &event {
                    AgentEvent::MissionStarted { index, .. } => mission_start = (*index, time),
                    AgentEvent::MissionDone { .. } => {
                        self.missions_done += 1;
                        self.end_time = Some(time);
                    }
                    AgentEvent::Log(_) => {}
                }
                self.report(observer, Progress::Agent { iteration, event });
            }
            if let Some(command) = step.command.filter(|c| sent != Some(*c)) {
                conn.send(&Command::Drive(command.to_drive())).await?;
                sent = Some(command);
            }
            if step.all_done {
                break;
            }
            if time - mission_start.1 > config.mission_timeout {
                return Err(RunError::MissionTimeout {
                    number: mission_start.0 + 1,
                    mission: config.missions[mission_start.0].clone(),
                    seconds: config.mission_timeout,
                });
            }
        }
        agent.stop();
        if sent != Some(SpeedCommand::STOP) {
            conn.send(&Command::Drive(SpeedCommand::STOP.to_drive()))
                .await?;
        }
        conn.disconnect().await?;
        Ok(())
    }

    /// Waits for the first position after INIT.
    async fn wait_for_position(
        &mut self,
        config: &RunConfig,
        conn: &mut Connection,
        uav: &mut UavState,
    ) -> Result<Coordinates, RunError> {
        let timeout = config.stream_timeout;
        let mut streaming = false;
        let deadline = tokio::time::Instant::now() + timeout;
        loop {
            let message = match tokio::time::timeout_at(deadline, conn.next_message()).await {
                Ok(message) => message?,
                Err(_) if streaming => return Err(RunError::NoPosition { timeout }),
                Err(_) => {
                    return Err(RunError::SpawnFailed {
                        class: config.class_name(),
                        timeout,
                    });
                }
            };
            streaming |= matches!(message, ServerMessage::Sta(_) | ServerMessage::Sen(_));
            uav.apply(&message);
            if let Some(position) = &uav.position {
                self.record(uav);
                return Ok(position.value);
            }
        }
    }

    /// Adds the latest position to the trajectory when it is new.
    fn record(&mut self, uav: &UavState) {
        if let Some(point) = TrajectoryPoint::of(uav)
            && self
                .trajectory
                .last()
                .is_none_or(|last| last.time < point.time)
        {
            self.trajectory.push(point);
        }
    }

    fn summary(&self, files: Vec<PathBuf>) -> IterationSummary {
        let distance = self
            .trajectory
            .windows(2)
            .map(|w| (w[1].position - w[0].position).norm())
            .sum();
        IterationSummary {
            missions_done: self.missions_done,
            duration: match (self.start_time, self.end_time) {
                (Some(s), Some(e)) => e - s,
                _ => 0.0,
            },
            distance,
            trajectory: self.trajectory.clone(),
            files,
            error: None,
        }
    }

    /// Writes the log, the trajectory and the map of this iteration (when a log directory is
    /// set); returns the files written.
    fn write(&self, config: &RunConfig) -> Result<Vec<PathBuf>, RunError> {
        if !self.connected {
            return Ok(Vec::new()); // nothing happened worth a file
        }
        let name = |suffix: &str| config.file(&format!("{:02}{suffix}", self.iteration));
        let (Some(log), Some(csv), Some(map)) =
            (name(".log"), name("-trajectory.csv"), name("-map"))
        else {
            return Ok(Vec::new());
        };
        let output = |path: &Path| {
            let path = path.to_owned();
            move |error| RunError::Output { path, error }
        };
        write_log(&log, &self.log).map_err(output(&log))?;
        write_trajectory(&csv, &self.trajectory).map_err(output(&csv))?;
        if config.pictures != Pictures::All {
            return Ok(vec![log, csv]);
        }
        let picture = MapPicture {
            title: format!("{} — iteration {}", config.prefix, self.iteration),
            paths: vec![self.trajectory.iter().map(|p| p.position).collect()],
            waypoints: waypoints(config),
            start: first_position(&self.trajectory),
        };
        let mut files = vec![log, csv];
        files.extend(picture.write(&map)?);
        Ok(files)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn start_parsing() {
        assert_eq!(
            "1,2,-3".parse::<Start>().unwrap(),
            Start::Pose {
                location: Coordinates::new(1.0, 2.0, -3.0),
                rotation: Coordinates::zeros()
            }
        );
        assert_eq!(
            "1,2,-3,0,0,1.57".parse::<Start>().unwrap(),
            Start::Pose {
                location: Coordinates::new(1.0, 2.0, -3.0),
                rotation: Coordinates::new(0.0, 0.0, 1.57)
            }
        );
        assert_eq!(
            "PlayerStart_1".parse::<Start>().unwrap(),
            Start::Tag("PlayerStart_1".into())
        );
        assert!("1,2".parse::<Start>().unwrap_err().contains("2 numbers"));
        assert!("1,a,2".parse::<Start>().is_err());
        assert!("".parse::<Start>().is_err());
    }

    #[test]
    fn class_names() {
        let mut config = RunConfig::default();
        assert_eq!(config.class_name(), "USARBot.stsAirRobot");
        config.robot = "MyPkg.Drone".into();
        assert_eq!(config.class_name(), "MyPkg.Drone");
    }

    #[tokio::test]
    async fn refuses_before_connecting() {
        let mut config = RunConfig {
            addr: "127.0.0.1:1".into(),
            ..RunConfig::default()
        };
        assert!(matches!(
            run_missions(&config, |_| {}).await,
            Err(RunError::NoMissions)
        ));
        config.missions = vec![Mission::Hover { seconds: 1.0 }];
        config.agent = "avoid".into();
        let err = run_missions(&config, |_| {}).await.unwrap_err();
        assert!(matches!(err, RunError::Refused(_)), "{err}");
        config.agent = "nope".into();
        let err = run_missions(&config, |_| {}).await.unwrap_err();
        assert_eq!(
            err.to_string(),
            "unknown agent \"nope\" (known agents: base, avoid)"
        );
    }

    #[tokio::test]
    async fn no_server() {
        let port = {
            let l = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
            l.local_addr().unwrap().port()
        };
        let config = RunConfig {
            addr: format!("127.0.0.1:{port}"),
            missions: vec![Mission::goto(Coordinates::zeros())],
            ..RunConfig::default()
        };
        let err = run_missions(&config, |_| {}).await.unwrap_err();
        assert!(
            matches!(err, RunError::Connection(ConnectionError::Connect { .. })),
            "{err}"
        );
    }
}
