//! One flight, sans I/O: server messages in, commands and progress out. The async
//! [`runner`](crate::runner), the browser control center, the Python package and the unit
//! tests all drive this same loop (in the manner of quinn-proto's core).
//!
//! # Readings of one time stamp, together
//!
//! A server sends one line per sensor, each stamped with its simulated time; the lines of one
//! time stamp come one after another, sensors run at different intervals, and the network may
//! cut the stream anywhere. The flight gathers the readings of the open time stamp (its
//! *frame*) and steps the agent, and records a trajectory row, once the frame is complete:
//!
//! * when a line with a later time stamp arrives (before that line is applied), or
//! * when the server answers a lockstep barrier (`SYNC`): everything up to it was sent, or
//! * when the driver says the input went quiet ([`Flight::end_of_frame`]; without lockstep,
//!   so that the agent does not wait a whole sensor interval for the next time stamp).
//!
//! In lockstep the agent steps only at the barriers (multiples of the lockstep step, shared
//! by every client): a later time stamp between two barriers writes the open frame's row,
//! and the agent steps at the barrier on everything read up to it, labelled with the latest
//! time stamp. So what it sends reaches the world while the world is held, at a tick that
//! does not depend on timing, even when a robot's sensors read between barriers.
//!
//! Lines without a time stamp (INS) belong to the open frame. A trajectory row is written for
//! every frame that has a position reading of its time stamp, with every other reading as of
//! that time stamp. If the input pauses in the middle of a time stamp's lines, the agent has
//! stepped on it already and does not again; the late readings complete its row. In lockstep
//! the rule is exact and the same at any speed.
//!
//! ```
//! use ucc_client::flight::{Flight, FlightConfig};
//! use ucc_client::{Coordinates, Mission, Start, agents};
//! use usar_proto::{Command, ServerMessage};
//!
//! let config = FlightConfig {
//!     start: Start::at(Coordinates::new(0.0, 0.0, -1.0)),
//!     missions: vec![Mission::goto(Coordinates::new(3.0, 0.0, -1.0))],
//!     ..FlightConfig::default()
//! };
//! let mut flight = Flight::new(1, config, agents::create("base").unwrap()).unwrap();
//! flight.spawn();
//! assert!(matches!(flight.poll_command(), Some(Command::Init(_))));
//! let line = |l: &str| ServerMessage::parse(l).unwrap().message;
//! flight.on_message(&line("SEN {Time 0.1000} {Type Position} {Name Position} {Location 0.0000,0.0000,-1.0000}"));
//! flight.end_of_frame();
//! let Some(Command::Drive(drive)) = flight.poll_command() else { panic!() };
//! assert!(drive.linear_velocity.unwrap() > 0.0); // the target is ahead: fly forward
//! ```

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};

use usar_proto::image::ImageRequest;
use usar_proto::{Barrier, Command, Conf, ConfItem, ItemQuery, Nfo, ServerMessage};

use crate::agent::{Agent, AgentEvent, SpeedCommand};
use crate::camera::CameraImage;
use crate::geometry::{Coordinates, Num};
use crate::mission::Mission;
use crate::progress::Progress;
use crate::radio::{Message, Outgoing, Undelivered};
use crate::record::{FlightRecord, TrajectoryPoint};
use crate::uav::{Reading, UavState};

mod config;
mod error;

pub use config::{FlightConfig, Lockstep, Start};
pub use error::FlightError;

/// Without lockstep, the readings of one time stamp are taken as complete when nothing more
/// arrives for this long (a server writes a time stamp's lines together).
pub const QUIET: Duration = Duration::from_millis(3);

/// Where a flight is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Not started: a driver that handles the handshake itself calls
    /// [`Flight::spawn`] directly.
    Connected,
    /// Connected ([`Flight::start`]): waiting for the server's greeting (NFO, for the map
    /// name), at most the handshake time.
    Greeting,
    /// `SYNC {Time 0}` sent: waiting for the server's lockstep answer, at most the
    /// handshake time (a stock USARSim never answers).
    Negotiating,
    /// INIT sent, waiting for the first complete frame with a position.
    Spawning,
    /// The agent flies.
    Flying,
    /// Every mission done; the stop command is queued.
    Done,
    /// Failed: see [`Flight::take_error`].
    Failed,
}

/// Lockstep bookkeeping: the barrier the server last reported.
#[derive(Debug, Clone, Copy)]
struct Barriers {
    step: f64,
    reached: f64,
}

impl Barriers {
    /// The next barrier: the first multiple of `step` after `reached` (times come printed
    /// to 0.1 ms, so one a microsecond short of a multiple is that multiple).
    fn next(&self) -> f64 {
        (((self.reached + 1e-6) / self.step).floor() + 1.0) * self.step
    }
}

/// One iteration's flight.
pub struct Flight {
    iteration: usize,
    config: FlightConfig,
    agent: Box<dyn Agent>,
    uav: UavState,
    phase: Phase,
    error: Option<FlightError>,
    /// When the handshake phase or the spawn times out.
    deadline: Option<Instant>,
    /// When the driver last handed in a message or a time-out (the stream's silence and the
    /// quiet end of a frame count from here).
    heard: Option<Instant>,
    /// The time stamp of the readings gathered and not yet stepped on.
    frame: Option<f64>,
    /// The time stamp the agent last stepped on.
    stepped: Option<f64>,
    lockstep: Option<Barriers>,
    /// Whether any STA or SEN has come since INIT.
    streaming: bool,
    sent: Option<SpeedCommand>,
    /// The running mission's index and start time.
    mission_start: (usize, f64),
    record: FlightRecord,
    commands: VecDeque<Command>,
    progress: VecDeque<Progress>,
    /// The camera: the tile size asked for (`None`: no frames wanted), and once the
    /// camera's CONF came, the rectangle of the image server's frame that is this UAV's.
    camera: Option<CameraWanted>,
    /// Radio messages the agent sent, for the driver.
    outbox: VecDeque<Outgoing>,
    /// Agent steps so far.
    steps: u64,
}

/// What the flight knows about the camera it was asked to read.
#[derive(Debug, Clone, Copy)]
struct CameraWanted {
    tile: (u32, u32),
    rect: Option<ImageRequest>,
    /// Steps without a camera CONF since it was asked for (a robot without a camera
    /// answers nothing).
    waited: u32,
}

/// Steps after which a camera CONF that has not come means the robot has no camera.
const CONF_STEPS: u32 = 20;

impl std::fmt::Debug for Flight {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Flight")
            .field("iteration", &self.iteration)
            .field("agent", &self.agent.name())
            .field("phase", &self.phase)
            .field("frame", &self.frame)
            .finish_non_exhaustive()
    }
}

impl Flight {
    /// A flight of `config`'s missions with `agent`; a mission the agent refuses is an error.
    pub fn new(
        iteration: usize,
        config: FlightConfig,
        mut agent: Box<dyn Agent>,
    ) -> Result<Self, FlightError> {
        let step = config.lockstep_step;
        if !(step > 0.0 && step.is_finite()) {
            return Err(FlightError::BadLockstepStep { step });
        }
        for mission in &config.missions {
            agent.add_mission(mission.clone())?;
        }
        Ok(Self {
            iteration,
            camera: config.camera_tile.map(|tile| CameraWanted {
                tile,
                rect: None,
                waited: 0,
            }),
            config,
            agent,
            uav: UavState::new(),
            phase: Phase::Connected,
            error: None,
            deadline: None,
            heard: None,
            frame: None,
            stepped: None,
            lockstep: None,
            streaming: false,
            sent: None,
            mission_start: (0, 0.0),
            record: FlightRecord {
                iteration,
                ..FlightRecord::default()
            },
            commands: VecDeque::new(),
            progress: VecDeque::new(),
            outbox: VecDeque::new(),
            steps: 0,
        })
    }

    /// Flies in lockstep from here on: the server reported barrier `reached`; the agent
    /// steps at each barrier, and the next one — the next multiple of `step` simulated
    /// seconds, so that every client with the same step shares its barriers whenever it
    /// joined — is asked for once the agent has answered.
    pub fn set_lockstep(&mut self, step: f64, reached: f64) {
        self.lockstep = Some(Barriers { step, reached });
    }

    /// Whether the flight runs in lockstep.
    pub fn is_lockstep(&self) -> bool {
        self.lockstep.is_some()
    }

    /// The driver connected at `now`: the flight waits for the server's greeting, asks for
    /// lockstep when its configuration says so, then spawns — each step with its deadline
    /// ([`poll_timeout`](Self::poll_timeout)).
    pub fn start(&mut self, now: Instant) {
        self.phase = Phase::Greeting;
        self.heard = Some(now);
        self.deadline = Some(now + self.handshake());
    }

    /// Takes one server message that arrived at `now`.
    pub fn handle_message(&mut self, message: &ServerMessage, now: Instant) {
        self.heard = Some(now);
        match (self.phase, message) {
            (Phase::Greeting, _) => {
                self.on_message(message);
                self.greeted(now);
            }
            (Phase::Negotiating, ServerMessage::Sync(barrier)) => {
                self.set_lockstep(self.config.lockstep_step, barrier.time.seconds);
                self.begin_spawn(now);
            }
            _ => self.on_message(message),
        }
    }

    /// When the driver must call [`handle_timeout`](Self::handle_timeout) if nothing comes
    /// before: the end of the handshake step, the spawn's or the stream's limit, or (without
    /// lockstep, a frame open) the quiet time that ends the frame. `None`: no limit (not
    /// started, or over).
    pub fn poll_timeout(&self) -> Option<Instant> {
        match self.phase {
            Phase::Connected | Phase::Done | Phase::Failed => None,
            Phase::Greeting | Phase::Negotiating => self.deadline,
            Phase::Spawning | Phase::Flying => {
                let stream = self.stream_deadline()?;
                match self.heard {
                    Some(heard) if self.quiet() => Some(stream.min(heard + QUIET)),
                    _ => Some(stream),
                }
            }
        }
    }

    /// Nothing came until `now`: ends the handshake step, closes the quiet frame, or fails
    /// the flight with the time-out ([`FlightError::SpawnFailed`],
    /// [`FlightError::NoPosition`], [`FlightError::StreamStopped`],
    /// [`FlightError::NoLockstep`]). Does nothing before [`poll_timeout`](Self::poll_timeout).
    pub fn handle_timeout(&mut self, now: Instant) {
        if self.poll_timeout().is_none_or(|due| now < due) {
            return;
        }
        match self.phase {
            Phase::Greeting => self.greeted(now),
            Phase::Negotiating if self.config.lockstep == Lockstep::Required => {
                let addr = self.config.addr.clone();
                self.fail(FlightError::NoLockstep { addr });
            }
            Phase::Negotiating => {
                let message =
                    "the server does not offer lockstep; running on sensor time".to_owned();
                self.log(format!("warning: {message}"));
                self.progress.push_back(Progress::Warning {
                    iteration: self.iteration,
                    message,
                });
                self.begin_spawn(now);
            }
            Phase::Spawning | Phase::Flying => {
                if self.quiet() && self.stream_deadline().is_some_and(|d| now < d) {
                    self.heard = Some(now);
                    self.end_of_frame();
                    return;
                }
                let timeout = self.config.stream_timeout;
                let error = match self.phase {
                    Phase::Spawning if self.streaming => FlightError::NoPosition { timeout },
                    Phase::Spawning => FlightError::SpawnFailed {
                        class: self.config.class_name(),
                        timeout,
                    },
                    _ => FlightError::StreamStopped { timeout },
                };
                self.fail(error);
            }
            Phase::Connected | Phase::Done | Phase::Failed => {}
        }
    }

    /// The greeting came or its time is up: ask for lockstep, or spawn.
    fn greeted(&mut self, now: Instant) {
        if self.config.lockstep == Lockstep::Off {
            self.begin_spawn(now);
            return;
        }
        self.commands.push_back(Command::Sync(Barrier::at(0.0)));
        self.phase = Phase::Negotiating;
        self.deadline = Some(now + self.handshake());
    }

    /// The handshake is over: report the connection and spawn, with the stream's limit.
    fn begin_spawn(&mut self, now: Instant) {
        let addr = self.config.addr.clone();
        self.connected(&addr);
        self.spawn();
        self.deadline = Some(now + self.config.stream_timeout);
    }

    /// The limit of each handshake step.
    fn handshake(&self) -> Duration {
        self.config
            .handshake_timeout
            .min(self.config.stream_timeout)
    }

    /// When the spawn (fixed at INIT) or the stream (from the last input) times out.
    fn stream_deadline(&self) -> Option<Instant> {
        match self.phase {
            Phase::Spawning => self.deadline,
            _ => self.heard.map(|h| h + self.config.stream_timeout),
        }
    }

    /// Whether an open frame is closed by a quiet input (without lockstep).
    fn quiet(&self) -> bool {
        self.frame_open() && !self.is_lockstep()
    }

    /// The time stamp of the readings gathered and not yet stepped on.
    pub fn frame_time(&self) -> Option<f64> {
        self.frame
    }

    /// Reports the connection (the map name comes from the server's NFO, if it came).
    pub fn connected(&mut self, addr: &str) {
        self.record.connected = true;
        self.report(Progress::Connected {
            iteration: self.iteration,
            addr: addr.to_owned(),
            map: self.record.map.clone(),
            lockstep: self.is_lockstep(),
        });
        if self.lockstep.is_none() {
            self.log(
                "running on sensor time: the agent answers whatever arrives, so results \
                 depend on timing (lockstep makes them repeatable)"
                    .into(),
            );
        }
    }

    /// Queues the spawn: `GETSTARTPOSES` first when the start is a tag (its location seeds
    /// dead reckoning for robots without a position sensor), then `INIT`, then the first
    /// barrier in lockstep.
    pub fn spawn(&mut self) {
        match &self.config.start {
            Start::Tag(_) => self.commands.push_back(Command::GetStartPoses),
            Start::Pose { location, .. } => self.record.start = Some(*location),
        }
        self.commands.push_back(self.config.init.clone());
        self.log(format!("sent {}", self.config.init));
        self.phase = Phase::Spawning;
        self.request_barrier();
    }

    /// Takes one server message.
    pub fn on_message(&mut self, message: &ServerMessage) {
        if matches!(self.phase, Phase::Done | Phase::Failed) {
            return;
        }
        if let (Some(time), Some(open)) = (message.time(), self.frame)
            && time > open + 1e-9
        {
            if self.is_lockstep() {
                self.record_frame(open);
            } else {
                self.close_frame();
            }
        }
        match message {
            ServerMessage::Nfo(Nfo::GameInfo { level, .. }) => {
                self.record.map = Some(level.clone())
            }
            ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) => {
                if let Start::Tag(tag) = &self.config.start
                    && let Some(pose) = poses.iter().find(|p| p.name.eq_ignore_ascii_case(tag))
                {
                    let l = pose.location;
                    self.record.start = Some(Coordinates::new(l.x, l.y, l.z));
                }
            }
            ServerMessage::Conf(Conf::Items { items, .. }) => self.on_camera_conf(items),
            ServerMessage::Sync(Barrier { time }) => {
                if let Some(lockstep) = &mut self.lockstep {
                    lockstep.reached = time.seconds;
                    self.close_frame();
                    self.request_barrier();
                }
                return;
            }
            _ => {}
        }
        self.streaming |= matches!(message, ServerMessage::Sta(_) | ServerMessage::Sen(_));
        if self.uav.apply(message) && matches!(self.phase, Phase::Spawning | Phase::Flying) {
            self.frame = Some(self.uav.time.unwrap_or(0.0));
        }
        if let ServerMessage::Other(m) = message {
            self.notice(&m.kind);
        }
        if !self.config.ends_on_crash {
            return;
        }
        if self.uav.battery_empty() && self.phase == Phase::Flying {
            let time = self.uav.time.unwrap_or(0.0);
            self.fail(FlightError::BatteryEmpty { time });
        }
        if let Some(crash) = &self.uav.crash
            && self.phase == Phase::Flying
        {
            let error = FlightError::Crashed {
                time: crash.time,
                reason: crash.value.clone(),
            };
            self.fail(error);
        }
    }

    /// Ends the open frame now: the driver saw the input go quiet (see the module docs).
    /// Does nothing when no readings are pending.
    pub fn end_of_frame(&mut self) {
        self.close_frame();
    }

    /// Whether readings are gathered that the agent has not seen yet.
    pub fn frame_open(&self) -> bool {
        self.frame.is_some()
    }

    /// The next command to send, in order.
    pub fn poll_command(&mut self) -> Option<Command> {
        self.commands.pop_front()
    }

    /// The next progress event, in order.
    pub fn poll_progress(&mut self) -> Option<Progress> {
        self.progress.pop_front()
    }

    /// Where the flight is.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Whether any STA or SEN line came since the spawn.
    pub fn is_streaming(&self) -> bool {
        self.streaming
    }

    /// Whether the flight is over (done or failed).
    pub fn is_over(&self) -> bool {
        matches!(self.phase, Phase::Done | Phase::Failed)
    }

    /// The failure, once (the flight stays [`Phase::Failed`]).
    pub fn take_error(&mut self) -> Option<FlightError> {
        self.error.take()
    }

    /// Ends the flight with `error`. The driver reports it ([`run`](crate::run) as the
    /// log's last line).
    pub fn fail(&mut self, error: FlightError) {
        if self.is_over() {
            return;
        }
        if self.phase == Phase::Flying {
            self.agent.stop();
        }
        self.phase = Phase::Failed;
        self.error = Some(error);
    }

    /// The rectangle of the image server's frame that shows this UAV's camera, once its
    /// CONF came (the flight asks for it after the spawn when the settings want frames).
    pub fn camera_request(&self) -> Option<ImageRequest> {
        self.camera.and_then(|c| c.rect)
    }

    /// A camera frame arrived: the agent sees it from its next step on. A frame of another
    /// size than the tile (the whole frame a legacy image server sends first) is ignored;
    /// returns whether it was taken.
    pub fn on_image(&mut self, image: Arc<CameraImage>) -> bool {
        let Some(camera) = &self.camera else {
            return false;
        };
        if (image.width, image.height) != camera.tile {
            return false;
        }
        let time = self.uav.time.unwrap_or(0.0);
        self.uav.image = Some(Reading { value: image, time });
        true
    }

    /// A radio message arrived: the agent sees it at its next step.
    pub fn on_radio(&mut self, message: Message) {
        self.uav
            .signal
            .entry(message.from.clone())
            .or_insert(f64::NAN);
        self.uav.inbox.push(message);
    }

    /// A message the agent sent did not get through: the agent sees it at its next step.
    pub fn on_undelivered(&mut self, undelivered: Undelivered) {
        self.log(format!(
            "radio: message to {} not delivered: {}",
            undelivered.message.to, undelivered.reason
        ));
        self.uav
            .signal
            .insert(undelivered.message.to.clone(), undelivered.strength);
        self.uav.undelivered.push(undelivered);
    }

    /// The radio signal to `to` (dBm) as the WSS reports it now.
    pub fn set_signal(&mut self, to: &str, strength: f64) {
        self.uav.signal.insert(to.to_owned(), strength);
    }

    /// The next radio message the agent sent, in order.
    pub fn poll_radio(&mut self) -> Option<Outgoing> {
        self.outbox.pop_front()
    }

    /// How many times the agent has stepped.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The UAV as last seen.
    pub fn uav(&self) -> &UavState {
        &self.uav
    }

    /// What the flight recorded so far.
    pub fn record(&self) -> &FlightRecord {
        &self.record
    }

    /// Adds a line to the flight's log.
    pub fn log(&mut self, line: String) {
        tracing::debug!(iteration = self.iteration, "{line}");
        self.record.log.push(line);
    }

    /// The record, for writing the iteration's files.
    pub fn into_record(self) -> FlightRecord {
        self.record
    }

    /// A fault the server applied, or the parameters it drew: logged (as a warning: the
    /// browser shows it too), counted and kept for the results.
    fn notice(&mut self, kind: &str) {
        let message = if kind.eq_ignore_ascii_case("FAULT")
            && let Some(f) = self.uav.faults.last()
        {
            self.record.faults += 1;
            format!(
                "fault at t={}s: {}",
                crate::geometry::Num(f.time, 2),
                f.value
            )
        } else if kind.eq_ignore_ascii_case("RANDOMIZED")
            && let Some(r) = &self.uav.randomized
        {
            self.record.randomized = Some(r.value.clone());
            format!("randomized: {}", r.value)
        } else {
            return;
        };
        self.report(Progress::Warning {
            iteration: self.iteration,
            message,
        });
    }

    fn report(&mut self, progress: Progress) {
        if progress.is_loggable() {
            self.log(progress.to_string());
        }
        self.progress.push_back(progress);
    }

    fn request_barrier(&mut self) {
        if let Some(l) = self.lockstep
            && !self.is_over()
        {
            self.commands
                .push_back(Command::Sync(Barrier::at(l.next())));
        }
    }

    /// The readings of the open frame are complete: spawn, record, step the agent.
    fn close_frame(&mut self) {
        let Some(time) = self.frame.take() else {
            return;
        };
        match self.phase {
            Phase::Spawning => {
                let seeded = self
                    .record
                    .start
                    .is_some_and(|s| self.uav.seed_position(s, time));
                let Some(position) = self.uav.position.as_ref().map(|p| p.value) else {
                    return; // streaming, but nothing tells where the robot is yet
                };
                if seeded {
                    self.log(
                        "no position sensor: position by dead reckoning from the start, the \
                         commanded velocities and the heading (and altitude when reported)"
                            .into(),
                    );
                }
                self.phase = Phase::Flying;
                self.record.start_time = Some(time);
                self.mission_start = (0, time);
                self.report(Progress::Spawned {
                    iteration: self.iteration,
                    time,
                    position,
                });
                if self.camera.is_some() {
                    self.commands.push_back(Command::GetConf(ItemQuery {
                        kind: "Camera".into(),
                        name: None,
                    }));
                }
                self.agent.start(time);
                self.fly(time);
            }
            Phase::Flying => self.fly(time),
            _ => {}
        }
    }

    /// In lockstep, a later time stamp completes the open frame's trajectory row, but the
    /// agent steps only at the barrier, on the readings gathered up to it: while the world
    /// runs between barriers nothing the agent would send could reach it at a tick that does
    /// not depend on timing.
    fn record_frame(&mut self, time: f64) {
        if self.phase == Phase::Flying && self.stepped.is_none_or(|last| time > last + 1e-9) {
            self.uav.dead_reckon(time);
            self.record_point(time);
        }
    }

    fn fly(&mut self, time: f64) {
        self.uav.dead_reckon(time);
        if self.stepped.is_some_and(|last| time <= last + 1e-9) {
            // Late lines of a time stamp already stepped on (the input paused mid-frame):
            // the row of that time stamp gets them; the agent sees them at the next one.
            if let Some(point) = TrajectoryPoint::of(&self.uav, time)
                && let Some(last) = self.record.trajectory.last_mut()
                && (last.time - time).abs() < 1e-9
            {
                *last = point;
            }
            return;
        }
        self.stepped = Some(time);
        self.record_point(time);
        let step = self.agent.step(&self.uav, time);
        self.steps += 1;
        self.uav.inbox.clear();
        self.uav.undelivered.clear();
        self.camera_waited();
        if !step.send.is_empty() {
            if self.config.radio {
                for message in &step.send {
                    self.uav
                        .signal
                        .entry(message.to.clone())
                        .or_insert(f64::NAN);
                }
                self.outbox.extend(step.send);
            } else {
                self.log(format!(
                    "radio: {} message(s) not sent: the run has no radio (RunSettings::radio, \
                     ucc run --radio)",
                    step.send.len()
                ));
            }
        }
        for event in step.events {
            match &event {
                AgentEvent::MissionStarted { index, .. } => self.mission_start = (*index, time),
                AgentEvent::MissionDone { index, .. } => {
                    self.record.missions_done += 1;
                    self.record.end_time = Some(time);
                    // The next mission's time starts now, whether or not it is announced.
                    self.mission_start = (index + 1, time);
                }
                AgentEvent::Log(_) => {}
            }
            self.report(Progress::Agent {
                iteration: self.iteration,
                event,
            });
        }
        if let Some(command) = step.command.map(SpeedCommand::clamped)
            && self.sent != Some(command)
        {
            self.send_speed(command, time);
        }
        self.report(Progress::State {
            iteration: self.iteration,
            time,
            uav: Box::new(self.uav.clone()),
            command: self.sent,
        });
        if step.all_done {
            self.count_unreported(time);
            self.agent.stop();
            if self.sent != Some(SpeedCommand::STOP) {
                self.send_speed(SpeedCommand::STOP, time);
            }
            self.phase = Phase::Done;
            return;
        }
        let (index, since) = self.mission_start;
        if time - since > self.config.mission_timeout {
            let mission = self
                .config
                .missions
                .get(index)
                .cloned()
                .unwrap_or(Mission::Hover { seconds: 0.0 });
            let hint = below_hint(&mission, self.uav.position.as_ref().map(|p| p.value));
            self.fail(FlightError::MissionTimeout {
                number: index + 1,
                mission,
                seconds: self.config.mission_timeout,
                hint,
            });
        }
    }

    /// The camera's CONF: its tile's top-left pixel in the image server's frame.
    fn on_camera_conf(&mut self, items: &[ConfItem]) {
        let Some(camera) = &mut self.camera else {
            return;
        };
        let found = items.iter().find_map(|item| match item {
            ConfItem::Camera {
                name,
                texture_offset_x,
                texture_offset_y,
                ..
            } => Some((name.clone(), *texture_offset_x, *texture_offset_y)),
            _ => None,
        });
        let Some((name, x, y)) = found else {
            return;
        };
        let (width, height) = camera.tile;
        camera.rect = Some(ImageRequest::Rect {
            x: u32::try_from(x).unwrap_or(0),
            y: u32::try_from(y).unwrap_or(0),
            width,
            height,
        });
        self.log(format!(
            "camera {name}: its {width}x{height} tile of the image server's frame is at {x},{y}"
        ));
    }

    /// Counts the steps without a camera CONF; says once that the robot has no camera.
    fn camera_waited(&mut self) {
        let Some(camera) = &mut self.camera else {
            return;
        };
        if camera.rect.is_some() || camera.waited > CONF_STEPS {
            return;
        }
        camera.waited += 1;
        if camera.waited > CONF_STEPS {
            let message = "frames asked for, but the robot has no camera (GETCONF {Type \
                           Camera} answered nothing): the agent gets no images"
                .to_owned();
            self.report(Progress::Warning {
                iteration: self.iteration,
                message,
            });
        }
    }

    /// The agent says every mission is done but reported fewer `MissionDone`s: the runner
    /// counts the missions itself (the statistics would say 0 missions in 0 s otherwise) and
    /// warns, naming the events the agent should send.
    fn count_unreported(&mut self, time: f64) {
        let (reported, total) = (self.record.missions_done, self.config.missions.len());
        if reported >= total {
            return;
        }
        self.record.missions_done = total;
        self.record.end_time = Some(time);
        let message = format!(
            "agent {} says all done after reporting {reported} of {total} mission(s) done; \
             counted all {total} done at t={time:.2}s (an agent reports \
             AgentEvent::MissionStarted and AgentEvent::MissionDone for each mission)",
            self.agent.name()
        );
        self.report(Progress::Warning {
            iteration: self.iteration,
            message,
        });
    }

    fn send_speed(&mut self, command: SpeedCommand, time: f64) {
        self.commands.push_back(Command::Drive(command.to_drive()));
        self.uav.set_command(command, time);
        self.sent = Some(command);
    }

    /// A trajectory row when the frame has a position of its own time stamp.
    fn record_point(&mut self, time: f64) {
        if let Some(point) = TrajectoryPoint::of(&self.uav, time)
            && self.record.trajectory.last().is_none_or(|l| l.time < time)
        {
            self.record.trajectory.push(point);
        }
        if let Some(laser) = &self.uav.laser
            && laser.time == time
            && let Some(position) = &self.uav.position
        {
            self.record
                .add_laser_hits(&position.value, self.uav.yaw(), &laser.value);
        }
    }
}

/// What may explain a waypoint that was never reached: one far below where the UAV got to
/// (z points down, so a sign slip puts a waypoint under the floor), said with the rule.
fn below_hint(mission: &Mission, position: Option<Coordinates>) -> String {
    match (mission.target(), position) {
        (Some(target), Some(at)) if target.z - at.z > 0.5 => format!(
            "; the waypoint is {} m below where the UAV stopped (z points down: z = 1 is 1 m \
             below z = 0) — is it under the floor?",
            Num(target.z - at.z, 1)
        ),
        _ => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::agent::Step;
    use crate::agents;
    use crate::settings::RunSettings;

    fn line(text: &str) -> ServerMessage {
        ServerMessage::parse(text).unwrap().message
    }

    fn position(t: f64, x: f64) -> ServerMessage {
        line(&format!(
            "SEN {{Time {t:.4}}} {{Type Position}} {{Name Position}} {{Location {x:.4},0.0000,-1.0000}}"
        ))
    }

    fn velocity(t: f64, vx: f64) -> ServerMessage {
        line(&format!(
            "SEN {{Time {t:.4}}} {{Type Velocity}} {{Name Velocity}} {{AbsoluteVelocity {vx:.4},0.0000,-0.6324}} {{RelativeVelocity {vx:.4},0.0000,-0.6324}}"
        ))
    }

    /// The time of a step, and of the position and velocity the agent saw then.
    type Seen = (f64, Option<f64>, Option<f64>);

    /// Records what it is shown.
    struct Witness(std::sync::Arc<std::sync::Mutex<Vec<Seen>>>);

    impl Agent for Witness {
        fn name(&self) -> &str {
            "witness"
        }
        fn add_mission(&mut self, _: Mission) -> Result<(), crate::MissionRefused> {
            Ok(())
        }
        fn start(&mut self, _: f64) {}
        fn stop(&mut self) {}
        fn step(&mut self, uav: &UavState, time: f64) -> Step {
            let seen = (
                time,
                uav.position.as_ref().map(|p| p.time),
                uav.velocity.as_ref().map(|v| v.time),
            );
            self.0.lock().unwrap().push(seen);
            Step::default()
        }
    }

    fn flight(agent: Box<dyn Agent>) -> Flight {
        let settings = RunSettings {
            missions: vec![Mission::goto(Coordinates::new(5.0, 0.0, -1.0))],
            ..RunSettings::default()
        };
        let mut f = Flight::new(1, settings.flight(), agent).unwrap();
        f.spawn();
        f
    }

    /// The defect: the row for t=0.3 carried the Velocity sent at t=0.2, because the loop
    /// stepped on the Position line before the Velocity line of the same time stamp.
    #[test]
    fn a_frame_holds_the_readings_of_one_time_stamp() {
        let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let mut f = flight(Box::new(Witness(seen.clone())));
        for (t, x, vx) in [(0.1, 0.0, 0.0), (0.2, 0.1, 2.0), (0.3, 0.3, 1.5)] {
            f.on_message(&position(t, x));
            f.on_message(&velocity(t, vx));
        }
        f.end_of_frame();
        let rows: Vec<(f64, f64)> = f
            .record()
            .trajectory
            .iter()
            .map(|p| (p.time, p.velocity.unwrap().x))
            .collect();
        assert_eq!(rows, [(0.1, 0.0), (0.2, 2.0), (0.3, 1.5)]);
        let seen = seen.lock().unwrap();
        assert_eq!(seen.len(), 3, "one step per time stamp: {seen:?}");
        for (t, p, v) in seen.iter() {
            assert_eq!((Some(*t), Some(*t)), (*p, *v), "the agent saw mixed stamps");
        }
    }

    /// Without lockstep the input may pause in the middle of a time stamp's lines: the agent
    /// steps once for it all the same, and its row ends up with every reading.
    #[test]
    fn a_time_stamp_split_by_a_pause_is_stepped_on_once() {
        let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let mut f = flight(Box::new(Witness(seen.clone())));
        f.on_message(&position(0.1, 0.0));
        f.on_message(&velocity(0.1, 0.0));
        f.end_of_frame();
        f.on_message(&position(0.2, 0.1));
        f.end_of_frame(); // the pause
        f.on_message(&velocity(0.2, 2.0));
        f.end_of_frame();
        f.on_message(&position(0.3, 0.3));
        f.end_of_frame();
        let times: Vec<f64> = seen.lock().unwrap().iter().map(|s| s.0).collect();
        assert_eq!(times, [0.1, 0.2, 0.3]);
        let row = &f.record().trajectory[1];
        assert_eq!((row.time, row.velocity.unwrap().x), (0.2, 2.0));
    }

    #[test]
    fn a_lockstep_barrier_closes_the_frame_and_asks_for_the_next() {
        let mut f = flight(agents::create("base").unwrap());
        f.set_lockstep(0.1, 0.0);
        // set_lockstep after spawn: the first barrier is asked now.
        f.request_barrier();
        let mut commands = Vec::new();
        while let Some(c) = f.poll_command() {
            commands.push(c.to_string());
        }
        assert_eq!(commands.last().unwrap(), "SYNC {Time 0.1000}");
        f.on_message(&position(0.1, 0.0));
        assert!(f.frame_open());
        f.on_message(&line("SYNC {Time 0.1000}"));
        assert!(!f.frame_open());
        let commands: Vec<String> = std::iter::from_fn(|| f.poll_command())
            .map(|c| c.to_string())
            .collect();
        assert!(commands[0].starts_with("DRIVE "), "{commands:?}");
        assert_eq!(commands.last().unwrap(), "SYNC {Time 0.2000}");
        assert_eq!(f.phase(), Phase::Flying);
    }

    /// The defect: in lockstep, a robot whose sensors read between barriers (a second robot
    /// reads on ticks of its own) stepped its agent at each later time stamp while the world
    /// ran on toward the barrier, so its commands and radio messages reached the world at a
    /// tick that depended on timing. Now such time stamps only write their rows, and the
    /// agent steps once at each barrier, on the latest readings.
    #[test]
    fn in_lockstep_the_agent_steps_only_at_the_barriers() {
        let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let mut f = flight(Box::new(Witness(seen.clone())));
        f.set_lockstep(0.1, 0.0);
        f.request_barrier();
        commands(&mut f);
        f.on_message(&position(0.05, 0.0));
        f.on_message(&velocity(0.05, 0.0));
        f.on_message(&line("SYNC {Time 0.1000}"));
        f.on_message(&position(0.15, 0.1));
        f.on_message(&velocity(0.15, 1.0));
        f.on_message(&position(0.18, 0.2));
        assert_eq!(seen.lock().unwrap().len(), 1, "stepped between barriers");
        assert_eq!(commands(&mut f), ["SYNC {Time 0.2000}"]);
        f.on_message(&line("SYNC {Time 0.2000}"));
        let seen = seen.lock().unwrap().clone();
        assert_eq!(
            seen,
            [
                (0.05, Some(0.05), Some(0.05)),
                (0.18, Some(0.18), Some(0.15))
            ]
        );
        let rows: Vec<f64> = f.record().trajectory.iter().map(|r| r.time).collect();
        assert_eq!(
            rows,
            [0.05, 0.15, 0.18],
            "a row per time stamp all the same"
        );
        assert_eq!(commands(&mut f), ["SYNC {Time 0.3000}"]);
    }

    /// The defect: a client that joined the lockstep at 0.005 s asked for barriers 0.105,
    /// 0.205, … — never those of a client that joined at 0 — so two UAVs held the world twice
    /// per step, and each stepped while the other's barrier held the world.
    #[test]
    fn lockstep_barriers_are_multiples_of_the_step_whenever_the_client_joined() {
        let mut f = flight(agents::create("base").unwrap());
        commands(&mut f);
        for (reached, next) in [(0.005, "0.1000"), (0.1, "0.2000"), (0.3, "0.4000")] {
            f.set_lockstep(0.1, reached);
            f.request_barrier();
            assert_eq!(
                commands(&mut f),
                [format!("SYNC {{Time {next}}}")],
                "{reached}"
            );
        }
    }

    /// A step of 0, below or NaN would ask for barriers at `NaN` (or never past the last).
    #[test]
    fn a_lockstep_step_that_is_not_a_positive_number_is_refused() {
        for step in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            let config = FlightConfig {
                lockstep_step: step,
                ..FlightConfig::default()
            };
            let Err(e) = Flight::new(1, config, agents::create("base").unwrap()) else {
                panic!("step {step} accepted");
            };
            let text = e.to_string();
            assert!(text.contains(&format!("lockstep step {step} s")), "{text}");
            assert!(text.contains("positive and finite"), "{text}");
        }
    }

    #[test]
    fn a_robot_without_a_position_sensor_flies_on_dead_reckoning() {
        let settings = RunSettings {
            robot: "AirRobot".into(),
            start: Start::at(Coordinates::new(1.0, 2.0, -1.0)),
            missions: vec![Mission::goto(Coordinates::new(9.0, 2.0, -1.0))],
            ..RunSettings::default()
        };
        let mut f = Flight::new(1, settings.flight(), agents::create("base").unwrap()).unwrap();
        f.spawn();
        let imu = |t: f64| {
            line(&format!(
                "SEN {{Time {t:.4}}} {{Type IMU}} {{Name IMU}} {{XYZAcceleration 0.0000,0.0000,0.0000}} {{AngularVel 0.0000,0.0000,0.0000}} {{AngularAccel 0.0000,0.0000,0.0000}} {{Rotation 0.0000,0.0000,0.0000}}"
            ))
        };
        let altitude = |t: f64| {
            line(&format!(
                "SEN {{Time {t:.4}}} {{Type AltitudeSensor}} {{Name GPS}} {{relativeAltitude 0.0000}} {{absoluteAltitude 111.0000}}"
            ))
        };
        for i in 1..=30 {
            let t = f64::from(i) * 0.1;
            f.on_message(&line(&format!("STA {{Time {t:.4}}} {{Battery 99999}}")));
            f.on_message(&imu(t));
            f.on_message(&altitude(t));
            f.end_of_frame();
        }
        assert_eq!(f.phase(), Phase::Flying);
        let p = f.uav().position.clone().unwrap();
        assert!((p.value.y - 2.0).abs() < 1e-9 && p.value.z == -1.0, "{p:?}");
        assert!(p.value.x > 2.0, "moved north by dead reckoning: {p:?}");
        assert!(f.record().log.iter().any(|l| l.contains("dead reckoning")));
    }

    fn commands(f: &mut Flight) -> Vec<String> {
        std::iter::from_fn(|| f.poll_command())
            .map(|c| c.to_string())
            .collect()
    }

    /// A flight of one hover with the base agent, not started.
    fn handshake_flight(lockstep: Lockstep) -> Flight {
        let config = RunSettings {
            missions: vec![Mission::Hover { seconds: 1.0 }],
            lockstep,
            ..RunSettings::default()
        }
        .flight();
        Flight::new(1, config, agents::create("base").unwrap()).unwrap()
    }

    /// The greeting and the lockstep handshake are phases of the core, each with its
    /// deadline: a driver sleeps until `poll_timeout` and hands in the time-out.
    #[test]
    fn the_handshake_runs_on_poll_timeout_and_handle_timeout() {
        let t0 = Instant::now();
        let mut f = handshake_flight(Lockstep::IfOffered);
        assert_eq!(f.poll_timeout(), None, "not started");
        f.start(t0);
        assert_eq!(f.phase(), Phase::Greeting);
        assert_eq!(f.poll_timeout(), Some(t0 + Duration::from_secs(2)));
        f.handle_timeout(t0 + Duration::from_secs(1)); // early: nothing happens
        assert_eq!(f.phase(), Phase::Greeting);
        let t1 = t0 + Duration::from_millis(5);
        f.handle_message(
            &line("NFO {Gametype BotDeathMatch} {Level UAVmap} {TimeLimit 0}"),
            t1,
        );
        assert_eq!(f.record().map.as_deref(), Some("UAVmap"));
        assert_eq!(f.phase(), Phase::Negotiating);
        assert_eq!(commands(&mut f), ["SYNC {Time 0.0000}"]);
        // A server that never answers (a stock USARSim): sensor time, with a warning.
        let t2 = t1 + Duration::from_secs(2);
        assert_eq!(f.poll_timeout(), Some(t2));
        f.handle_timeout(t2);
        assert_eq!(f.phase(), Phase::Spawning);
        assert!(!f.is_lockstep());
        assert!(commands(&mut f)[0].starts_with("INIT {ClassName USARBot.stsAirRobot}"));
        let events: Vec<String> = std::iter::from_fn(|| f.poll_progress())
            .map(|p| p.to_string())
            .collect();
        assert!(
            events.iter().any(|e| e.contains("does not offer lockstep")),
            "{events:?}"
        );
        // No data within the stream limit after INIT: the spawn failed.
        let t3 = t2 + Duration::from_secs(10);
        assert_eq!(f.poll_timeout(), Some(t3));
        f.handle_timeout(t3);
        assert_eq!(f.phase(), Phase::Failed);
        assert!(matches!(
            f.take_error(),
            Some(FlightError::SpawnFailed { .. })
        ));
        assert_eq!(f.poll_timeout(), None);
    }

    #[test]
    fn a_lockstep_answer_ends_the_handshake_and_the_first_barrier_follows_init() {
        let t0 = Instant::now();
        let mut f = handshake_flight(Lockstep::Required);
        f.start(t0);
        f.handle_timeout(t0 + Duration::from_secs(2)); // no greeting
        assert_eq!(commands(&mut f), ["SYNC {Time 0.0000}"]);
        f.handle_message(&line("SYNC {Time 4.2000}"), t0 + Duration::from_secs(3));
        assert!(f.is_lockstep());
        let sent = commands(&mut f);
        assert!(sent[0].starts_with("INIT "), "{sent:?}");
        assert_eq!(sent.last().unwrap(), "SYNC {Time 4.3000}");
        // In lockstep no quiet time ends a frame: only the stream's limit.
        f.handle_message(&position(4.3, 0.0), t0 + Duration::from_secs(4));
        assert_eq!(
            f.poll_timeout(),
            Some(t0 + Duration::from_secs(3) + Duration::from_secs(10))
        );
    }

    #[test]
    fn required_lockstep_without_an_answer_fails_and_without_lockstep_a_quiet_frame_closes() {
        let t0 = Instant::now();
        let mut f = handshake_flight(Lockstep::Required);
        f.start(t0);
        f.handle_timeout(t0 + Duration::from_secs(2));
        f.handle_timeout(t0 + Duration::from_secs(4));
        assert!(matches!(
            f.take_error(),
            Some(FlightError::NoLockstep { .. })
        ));
        assert!(!f.record().connected);

        let mut f = handshake_flight(Lockstep::Off);
        f.start(t0);
        f.handle_message(
            &line("NFO {Gametype BotDeathMatch} {Level UAVmap} {TimeLimit 0}"),
            t0,
        );
        assert_eq!(f.phase(), Phase::Spawning, "no lockstep asked");
        let t1 = t0 + Duration::from_millis(1);
        f.handle_message(&position(0.1, 0.0), t1);
        assert_eq!(f.poll_timeout(), Some(t1 + QUIET));
        f.handle_timeout(t1 + QUIET);
        assert_eq!(f.phase(), Phase::Flying, "the quiet frame closed: spawned");
    }

    /// Says hello to `Robot2` at every step and notes what it is shown.
    struct Sender(std::sync::Arc<std::sync::Mutex<Vec<UavState>>>);

    impl Agent for Sender {
        fn name(&self) -> &str {
            "sender"
        }
        fn add_mission(&mut self, _: Mission) -> Result<(), crate::MissionRefused> {
            Ok(())
        }
        fn start(&mut self, _: f64) {}
        fn stop(&mut self) {}
        fn step(&mut self, uav: &UavState, _: f64) -> Step {
            self.0.lock().unwrap().push(uav.clone());
            Step {
                send: vec![Outgoing {
                    to: "Robot2".into(),
                    data: b"hello".to_vec(),
                }],
                ..Step::default()
            }
        }
    }

    #[test]
    fn frames_and_radio_reach_the_agent_through_the_flight() {
        let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let settings = RunSettings {
            missions: vec![Mission::Hover { seconds: 5.0 }],
            camera: Some(crate::CameraSettings::default()),
            radio: Some(crate::RadioSettings::default()),
            ..RunSettings::default()
        };
        let mut f = Flight::new(1, settings.flight(), Box::new(Sender(seen.clone()))).unwrap();
        f.spawn();
        f.on_message(&position(0.1, 0.0));
        f.end_of_frame();
        // After the spawn the flight asks for the camera's CONF; its tile becomes the request.
        let commands: Vec<String> = std::iter::from_fn(|| f.poll_command())
            .map(|c| c.to_string())
            .collect();
        assert!(
            commands.iter().any(|c| c == "GETCONF {Type Camera}"),
            "{commands:?}"
        );
        assert_eq!(f.camera_request(), None);
        f.on_message(&line(
            "CONF {Type Camera} {Name cams}{TextureOffsetX 320}{TextureOffsetY 0}{TextureResolutionX 320}{TextureResolutionY 240}{CameraDefFov 80.0000}{CameraMinFov 20.0000}{CameraMaxFov 120.0000}{CameraFov 80.0000}",
        ));
        assert_eq!(
            f.camera_request(),
            Some(ImageRequest::Rect {
                x: 320,
                y: 0,
                width: 320,
                height: 240
            })
        );
        // The whole frame a legacy server sends first is not the UAV's tile.
        let image = |width, height, index| {
            Arc::new(CameraImage {
                width,
                height,
                rgb: vec![0; 3 * (width * height) as usize],
                index,
            })
        };
        assert!(!f.on_image(image(640, 480, 0)));
        assert!(f.on_image(image(320, 240, 1)));
        f.on_radio(Message {
            from: "Robot2".into(),
            data: b"hi".to_vec(),
        });
        let sent = f.poll_radio().expect("the first step's message");
        f.on_undelivered(Undelivered {
            message: sent,
            strength: -120.0,
            reason: "out of range".into(),
        });
        f.on_message(&position(0.2, 0.0));
        f.end_of_frame();
        f.on_message(&position(0.3, 0.0));
        f.end_of_frame();
        let seen = seen.lock().unwrap();
        let second = &seen[1];
        assert_eq!(second.image.as_ref().unwrap().value.index, 1);
        assert_eq!(second.inbox.len(), 1);
        assert_eq!(second.undelivered[0].strength, -120.0);
        assert_eq!(second.signal["Robot2"], -120.0);
        // Shown once: the next step's inbox and failures are empty; the image stays.
        assert!(seen[2].inbox.is_empty() && seen[2].undelivered.is_empty());
        assert!(seen[2].image.is_some());
        assert!(f.record().log.iter().any(|l| l.contains("not delivered")));
    }

    #[test]
    fn a_send_without_the_radio_is_dropped_with_a_log_line() {
        let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let mut f = flight(Box::new(Sender(seen)));
        f.on_message(&position(0.1, 0.0));
        f.end_of_frame();
        assert!(f.poll_radio().is_none());
        assert!(
            f.record()
                .log
                .iter()
                .any(|l| l.contains("the run has no radio"))
        );
    }
}
