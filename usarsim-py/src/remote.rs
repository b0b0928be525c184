//! One UAV flown over the protocol: a running usar-server (lockstep via `SYNC`) or a real
//! USARSim (no lockstep: sensor time). A blocking driver of ucc-client's flight core — the
//! same [`Flight`] that `ucc`, the browser control center and the tests drive: the core
//! holds the greeting, the lockstep handshake, the spawn, the barriers and the time limits;
//! this file reads lines (bounded, with a read time-out up to the core's next deadline),
//! writes what the core queued, and pauses at each period for Python's action. Blocking I/O
//! on a std `TcpStream`; the caller releases the GIL around it.

use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, TcpStream, ToSocketAddrs};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use ucc_client::connection::CLOSE_WAIT;
use ucc_client::flight::{Flight, FlightConfig, FlightError, Lockstep, Start};
use ucc_client::lines::BlockingLines;
use ucc_client::uav::UavState;
use ucc_client::{Agent, Coordinates, Mission, MissionRefused, SpeedCommand, Step};
use usar_proto::ServerMessage;
use usar_sim::RobotCatalog;

use crate::core::{Observations, Pose, SimError, first_periods, spawn};

/// How long a connection attempt may take, and the server may stay silent.
const TIMEOUT: Duration = Duration::from_secs(10);
/// How long to wait for the greeting and for the answer to `SYNC {Time 0}` (a real USARSim
/// never answers).
const SYNC_PROBE: Duration = Duration::from_secs(2);
/// Simulated seconds a new connection hovers, at most, for the robot's first Position
/// reading (the slowest stock sensor interval is 0.3 s).
const FIRST_READING: f64 = 2.0;
/// The shortest read time-out: a deadline already past still reads what is waiting.
const MIN_READ: Duration = Duration::from_millis(1);

/// The embedded robot catalog, parsed once.
fn embedded_catalog() -> &'static RobotCatalog {
    static CATALOG: std::sync::OnceLock<RobotCatalog> = std::sync::OnceLock::new();
    CATALOG.get_or_init(RobotCatalog::embedded)
}

fn err(addr: &str, what: impl std::fmt::Display) -> SimError {
    SimError::Invalid(format!("server {addr}: {what}"))
}

/// The agent of the flight: Python's latest action.
struct Python(Arc<Mutex<Option<SpeedCommand>>>);

impl Agent for Python {
    fn name(&self) -> &str {
        "python"
    }
    fn add_mission(&mut self, _: Mission) -> Result<(), MissionRefused> {
        Ok(())
    }
    fn start(&mut self, _: f64) {}
    fn stop(&mut self) {}
    fn step(&mut self, _: &UavState, _: f64) -> Step {
        Step {
            command: *self.0.lock().unwrap_or_else(PoisonError::into_inner),
            ..Step::default()
        }
    }
}

/// The input that ends a period, kept until Python acts: the core steps the agent on it.
#[derive(Debug)]
enum Held {
    /// The lockstep barrier's answer, or (sensor time) the first line of a later time stamp.
    Message(ServerMessage),
    /// Sensor time: the input went quiet after the period's last time stamp.
    Quiet,
}

/// A connection with one UAV.
#[derive(Debug)]
pub(crate) struct Remote {
    addr: String,
    lines: BlockingLines<TcpStream>,
    writer: TcpStream,
    /// The core (in a mutex only so that the Python class may be shared between threads:
    /// `&mut self` reaches it without locking).
    flight: Mutex<Flight>,
    action: Arc<Mutex<Option<SpeedCommand>>>,
    held: Option<Held>,
    /// Sensor time: the time stamp the period ends at.
    due: Option<f64>,
    /// Simulated time of the last barrier (lockstep) or of the last period's readings.
    time: f64,
    period: f64,
    /// The read time-out set on the socket.
    read_timeout: Option<Duration>,
}

/// Ends the stream and waits (at most [`CLOSE_WAIT`]) for the server to end its own, once
/// it has removed the robot, as ucc-client's `Connection::disconnect`: the robot of the next
/// episode's connection then spawns into a world without this one (its sensors on a lone
/// robot's ticks), so episodes are reproducible whatever the two connections' timing.
impl Drop for Remote {
    fn drop(&mut self) {
        if self.writer.shutdown(Shutdown::Write).is_err() {
            return;
        }
        let deadline = Instant::now() + CLOSE_WAIT;
        let mut rest = [0u8; 4096];
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() || self.writer.set_read_timeout(Some(left)).is_err() {
                return;
            }
            if matches!(self.writer.read(&mut rest), Ok(0) | Err(_)) {
                return;
            }
        }
    }
}

impl Remote {
    /// Connects, asks for lockstep, spawns `robot` at `pose` and hovers until its sensors
    /// have read once (as the in-process world: [`first_periods`]).
    pub(crate) fn connect(
        addr: &str,
        robot: &str,
        pose: Pose,
        period: f64,
    ) -> Result<Self, SimError> {
        if !pose.iter().all(|v| v.is_finite()) {
            return Err(err(addr, format_args!("start not finite: {pose:?}")));
        }
        let target = addr
            .to_socket_addrs()
            .map_err(|e| err(addr, format_args!("bad address (want host:port): {e}")))?
            .next()
            .ok_or_else(|| err(addr, "address resolves to nothing"))?;
        let init = spawn(robot, "UAV", &pose);
        init.check().map_err(|e| err(addr, e))?;
        let stream = TcpStream::connect_timeout(&target, TIMEOUT)
            .map_err(|e| err(addr, format_args!("cannot connect: {e}")))?;
        let _ = stream.set_nodelay(true);
        let writer = stream
            .try_clone()
            .map_err(|e| err(addr, format_args!("{e}")))?;
        let config = FlightConfig {
            addr: addr.to_owned(),
            init,
            start: Start::Pose {
                location: Coordinates::new(pose[0], pose[1], pose[2]),
                rotation: Coordinates::new(0.0, 0.0, pose[3]),
            },
            missions: Vec::new(),
            mission_timeout: f64::INFINITY,
            stream_timeout: TIMEOUT,
            handshake_timeout: SYNC_PROBE,
            lockstep: Lockstep::IfOffered,
            lockstep_step: period,
            camera_tile: None,
            radio: false,
            // A crash is the task's to judge (it ends the episode), not an error.
            ends_on_crash: false,
        };
        let action = Arc::new(Mutex::new(None));
        let flight = Flight::new(1, config, Box::new(Python(Arc::clone(&action))))
            .map_err(|e| err(addr, e))?;
        let mut remote = Self {
            addr: addr.to_owned(),
            lines: BlockingLines::new(stream),
            writer,
            flight: Mutex::new(flight),
            action,
            held: None,
            due: None,
            time: 0.0,
            period,
            read_timeout: None,
        };
        remote.core().start(Instant::now());
        remote.advance()?;
        // Hover until every sensor of the class (as our catalog knows it) has read once, as
        // the in-process world does: the first observation is then as complete (the sonars
        // and the laser read 0.2 s and 0.3 s after the spawn) and taken at the same time.
        let class = embedded_catalog().get(&usar_proto::Init::qualified_class(robot));
        for _ in 1..first_periods(class, period) {
            remote.step([0.0; 4])?;
        }
        // Sensors first speak one interval after the spawn (0.1 s and more): a class we do
        // not know, or periods shorter than that, end before the Position sensor has read.
        // Hover until it has, for at most FIRST_READING of simulated time.
        let mut waited = 0.0;
        while remote.core().uav().position.is_none() && waited < FIRST_READING {
            remote.step([0.0; 4])?;
            waited += period;
        }
        if remote.core().uav().position.is_none() {
            return Err(err(
                addr,
                format_args!("the robot did not spawn at {pose:?} (no Position reading)"),
            ));
        }
        Ok(remote)
    }

    /// Whether the server runs in lockstep with us.
    pub(crate) fn is_lockstep(&self) -> bool {
        self.flight
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .is_lockstep()
    }

    /// Sends the normalized command and waits one period.
    pub(crate) fn step(&mut self, action: [f64; 4]) -> Result<(), SimError> {
        let command = SpeedCommand {
            forward: action[0] * 100.0,
            right: action[1] * 100.0,
            up: action[2] * 100.0,
            yaw: action[3] * 100.0,
        };
        *self.action.lock().unwrap_or_else(PoisonError::into_inner) = Some(command);
        // The held input ends the period: the core steps the agent on it, which sends the
        // action (and, in lockstep, the next barrier).
        match self.held.take() {
            Some(Held::Message(message)) => self.core().handle_message(&message, Instant::now()),
            Some(Held::Quiet) => self.core().end_of_frame(),
            None => {}
        }
        self.advance()
    }

    /// The UAV's observation (contact is not known remotely: always false).
    pub(crate) fn observe(&self) -> Observations {
        let mut obs = Observations::default();
        let flight = self.flight.lock().unwrap_or_else(PoisonError::into_inner);
        obs.push_state(flight.uav(), false, self.time);
        obs
    }

    fn core(&mut self) -> &mut Flight {
        self.flight
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// Drives the core until the input that ends the period (held for [`step`]), or fails.
    fn advance(&mut self) -> Result<(), SimError> {
        loop {
            self.send_queued()?;
            while self.core().poll_progress().is_some() {}
            if let Some(error) = self.core().take_error() {
                let timed_out = matches!(
                    error,
                    FlightError::SpawnFailed { .. }
                        | FlightError::NoPosition { .. }
                        | FlightError::StreamStopped { .. }
                );
                return Err(if timed_out {
                    err(&self.addr, format_args!("timed out: {error}"))
                } else {
                    err(&self.addr, error)
                });
            }
            let deadline = self.core().poll_timeout();
            let message = self.read(deadline)?;
            let now = Instant::now();
            match message {
                Some(message) if self.ends_period(&message) => {
                    self.held = Some(Held::Message(message));
                    return Ok(());
                }
                Some(message) => self.core().handle_message(&message, now),
                // Sensor time: the frame went quiet (in the core's own words, its quiet
                // time-out); at the period's end Python acts before the agent steps.
                None if self.core().frame_open()
                    && !self.core().is_lockstep()
                    && self.period_over() =>
                {
                    self.held = Some(Held::Quiet);
                    return Ok(());
                }
                None => self.core().handle_timeout(now),
            }
        }
    }

    /// Whether `message` closes the frame that ends the period.
    fn ends_period(&mut self, message: &ServerMessage) -> bool {
        use ucc_client::flight::Phase;
        if !matches!(self.core().phase(), Phase::Spawning | Phase::Flying) {
            return false;
        }
        if self.core().is_lockstep() {
            let ServerMessage::Sync(barrier) = message else {
                return false;
            };
            self.time = barrier.time.seconds;
            return true;
        }
        let later = matches!(
            (message.time(), self.core().frame_time()),
            (Some(t), Some(open)) if t > open + 1e-9
        );
        later && self.period_over()
    }

    /// Sensor time: whether the open frame is at or past the period's end (a fresh
    /// connection waits one period past the first time stamp it sees); then it is the
    /// observation's time.
    fn period_over(&mut self) -> bool {
        let Some(open) = self.core().frame_time() else {
            return false;
        };
        let due = *self.due.get_or_insert(open + self.period);
        if open >= due - 1e-6 && self.core().uav().position.is_some() {
            self.time = open;
            self.due = Some(open + self.period);
            return true;
        }
        false
    }

    /// One message, waiting at most until `deadline` (`None`: the time-out).
    fn read(&mut self, deadline: Option<Instant>) -> Result<Option<ServerMessage>, SimError> {
        let wait = deadline.map_or(TIMEOUT, |d| {
            d.saturating_duration_since(Instant::now()).max(MIN_READ)
        });
        if self.read_timeout != Some(wait) {
            self.lines
                .get_ref()
                .set_read_timeout(Some(wait))
                .map_err(|e| err(&self.addr, e))?;
            self.read_timeout = Some(wait);
        }
        loop {
            match self.lines.next_line() {
                Ok(Some(line)) => {
                    // Unreadable lines are skipped.
                    if let Ok(parsed) = ServerMessage::parse(&line) {
                        return Ok(Some(parsed.message));
                    }
                }
                Ok(None) => return Err(err(&self.addr, "the server closed the connection")),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    return Ok(None);
                }
                Err(e) => return Err(err(&self.addr, format_args!("read failed: {e}"))),
            }
        }
    }

    /// Writes what the core queued, in one write.
    fn send_queued(&mut self) -> Result<(), SimError> {
        let mut out = String::new();
        while let Some(command) = self.core().poll_command() {
            command.write_to(&mut out);
            out.push_str("\r\n");
        }
        if out.is_empty() {
            return Ok(());
        }
        self.writer.write_all(out.as_bytes()).map_err(|e| {
            err(
                &self.addr,
                format_args!("write failed (server closed?): {e}"),
            )
        })
    }
}
