//! What one flight needs to know: [`FlightConfig`] — the INIT, the start, the missions,
//! the time limits and lockstep; nothing about files, iterations or pictures (those are
//! the runner's [`RunSettings`](crate::RunSettings), which makes one with
//! [`RunSettings::flight`](crate::RunSettings::flight)).

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use usar_proto::Command;

use crate::geometry::{Coordinates, Num};
use crate::mission::{Mission, parse_numbers};

/// What one flight needs to know.
#[derive(Debug, Clone)]
pub struct FlightConfig {
    /// `host:port` of the server, for the messages.
    pub addr: String,
    /// The INIT sent to spawn the robot.
    pub init: Command,
    /// Where the robot is spawned (a tag's location comes from `GETSTARTPOSES`).
    pub start: Start,
    /// The missions, flown in order.
    pub missions: Vec<Mission>,
    /// Simulated seconds a single mission may take.
    pub mission_timeout: f64,
    /// Wall-clock limit for the first sensor data after INIT, and for any silence after.
    pub stream_timeout: Duration,
    /// Wall-clock limit for the server's greeting and for its answer to the lockstep probe
    /// (each at most `stream_timeout`).
    pub handshake_timeout: Duration,
    /// Whether to ask for lockstep.
    pub lockstep: Lockstep,
    /// Simulated seconds per lockstep barrier.
    pub lockstep_step: f64,
    /// The camera tile the agent wants frames of; `None`: no frames.
    pub camera_tile: Option<(u32, u32)>,
    /// Whether the agent may send radio messages.
    pub radio: bool,
    /// Whether a crash or an empty battery ends the flight ([`FlightError::Crashed`],
    /// [`FlightError::BatteryEmpty`]): yes for a run's iteration; a learning environment
    /// flies on and lets its task judge the reading.
    ///
    /// [`FlightError::Crashed`]: super::FlightError::Crashed
    /// [`FlightError::BatteryEmpty`]: super::FlightError::BatteryEmpty
    pub ends_on_crash: bool,
}

impl Default for FlightConfig {
    fn default() -> Self {
        Self {
            addr: "localhost:3000".into(),
            init: Command::Init(usar_proto::Init::default()),
            start: Start::at(Coordinates::zeros()),
            missions: Vec::new(),
            mission_timeout: 120.0,
            stream_timeout: Duration::from_secs(10),
            handshake_timeout: Duration::from_secs(2),
            lockstep: Lockstep::Off,
            lockstep_step: 0.1,
            camera_tile: None,
            radio: false,
            ends_on_crash: true,
        }
    }
}

impl FlightConfig {
    /// The INIT's class name (for the messages).
    pub fn class_name(&self) -> String {
        match &self.init {
            Command::Init(init) => init.class_name.clone(),
            _ => String::new(),
        }
    }
}

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

impl Start {
    /// A pose at `location`, level, heading north.
    pub fn at(location: Coordinates) -> Self {
        Self::Pose {
            location,
            rotation: Coordinates::zeros(),
        }
    }
}

impl FromStr for Start {
    type Err = String;

    /// `x,y,z`, `x,y,z,roll,pitch,yaw` (metres, radians) or a PlayerStart tag.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim();
        // A comma makes it a pose (`nan,0,-1` is a bad pose, not a tag).
        let looks_numeric =
            s.contains(',') || s.starts_with(|c: char| c.is_ascii_digit() || "+-.".contains(c));
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
                "{} (roll {}, pitch {}, yaw {})",
                crate::geometry::triple(l, 2),
                Num(r.x, 2),
                Num(r.y, 2),
                Num(r.z, 2)
            ),
            Self::Tag(tag) => write!(f, "start tag {tag}"),
        }
    }
}

/// Whether to fly in lockstep with the server (docs/lockstep.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Lockstep {
    /// Run on sensor time: the agent answers whatever arrives, as against a stock USARSim.
    /// Results then depend on timing (the machine's load, the network); the run says so in
    /// its log.
    #[default]
    Off,
    /// Lockstep when the server offers it, else sensor time (with a warning in the log).
    IfOffered,
    /// Lockstep or nothing: a server that does not offer it is an error. The same settings
    /// then give the same flight every time.
    Required,
}
