//! Why a run or one of its iterations failed: [`RunError`], the runner's error. A flight's
//! own failures ([`FlightError`]) keep their names and messages here.

use std::path::PathBuf;
use std::time::Duration;

use crate::agent::MissionRefused;
use crate::connection::ConnectionError;
use crate::flight::FlightError;
use crate::mission::Mission;
use crate::picture::PictureError;

/// Why a run (or an iteration) failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// Nothing to fly.
    #[error("no missions to fly")]
    NoMissions,
    /// The agent does not handle a mission type.
    #[error(transparent)]
    Refused(#[from] MissionRefused),
    /// Talking to the server failed.
    #[error(transparent)]
    Connection(#[from] ConnectionError),
    /// Lockstep was required and the server does not offer it.
    #[error("{}", FlightError::NoLockstep { addr: addr.clone() })]
    NoLockstep {
        /// `host:port`.
        addr: String,
    },
    /// The configuration's lockstep step is not a positive, finite number of seconds.
    #[error("{}", FlightError::BadLockstepStep { step: *step })]
    BadLockstepStep {
        /// The step given.
        step: f64,
    },
    /// INIT gave no stream.
    #[error("{}", FlightError::SpawnFailed { class: class.clone(), timeout: *timeout })]
    SpawnFailed {
        /// The class asked for.
        class: String,
        /// The limit.
        timeout: Duration,
    },
    /// The robot streams data but nothing tells where it is.
    #[error("{}", FlightError::NoPosition { timeout: *timeout })]
    NoPosition {
        /// The limit.
        timeout: Duration,
    },
    /// The stream stopped.
    #[error("{}", FlightError::StreamStopped { timeout: *timeout })]
    StreamStopped {
        /// The limit.
        timeout: Duration,
    },
    /// The battery ran out.
    #[error("{}", FlightError::BatteryEmpty { time: *time })]
    BatteryEmpty {
        /// Simulated seconds.
        time: f64,
    },
    /// The UAV crashed (its crash sensor fired, docs/quadrotor.md).
    #[error("{}", FlightError::Crashed { time: *time, reason: reason.clone() })]
    Crashed {
        /// Simulated seconds.
        time: f64,
        /// What the UAV state knew then (speed before the impact, tilt, position).
        reason: String,
    },
    /// A mission took too long.
    #[error("{}", FlightError::MissionTimeout {
        number: *number, mission: mission.clone(), seconds: *seconds, hint: hint.clone()
    })]
    MissionTimeout {
        /// 1-based.
        number: usize,
        /// The mission.
        mission: Mission,
        /// The limit.
        seconds: f64,
        /// Empty, or what may explain it (a waypoint far below the UAV: z points down).
        hint: String,
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
    /// Camera frames were asked for and the image server failed.
    #[error("camera frames from the image server at {addr}: {error}")]
    Camera {
        /// `host:port` of the image server.
        addr: String,
        /// Why.
        error: String,
    },
    /// The radio was asked for and the WSS failed.
    #[error("the radio through the WSS at {addr}: {error}")]
    Radio {
        /// `host:port` of the WSS.
        addr: String,
        /// Why.
        error: String,
    },
}

impl From<FlightError> for RunError {
    fn from(error: FlightError) -> Self {
        match error {
            FlightError::Refused(e) => Self::Refused(e),
            FlightError::NoLockstep { addr } => Self::NoLockstep { addr },
            FlightError::BadLockstepStep { step } => Self::BadLockstepStep { step },
            FlightError::SpawnFailed { class, timeout } => Self::SpawnFailed { class, timeout },
            FlightError::NoPosition { timeout } => Self::NoPosition { timeout },
            FlightError::StreamStopped { timeout } => Self::StreamStopped { timeout },
            FlightError::BatteryEmpty { time } => Self::BatteryEmpty { time },
            FlightError::Crashed { time, reason } => Self::Crashed { time, reason },
            FlightError::MissionTimeout {
                number,
                mission,
                seconds,
                hint,
            } => Self::MissionTimeout {
                number,
                mission,
                seconds,
                hint,
            },
        }
    }
}

impl RunError {
    /// Whether the failure would happen again in the next iteration, so that going on is
    /// pointless (no server, a bad configuration, files that cannot be written).
    pub fn is_fatal(&self) -> bool {
        matches!(
            self,
            Self::NoMissions
                | Self::Refused(_)
                | Self::NoLockstep { .. }
                | Self::BadLockstepStep { .. }
                | Self::Connection(
                    ConnectionError::Connect { .. }
                        | ConnectionError::ConnectTimeout { .. }
                        | ConnectionError::Record { .. }
                        | ConnectionError::Unsendable(_)
                )
                | Self::NoStartPoses { .. }
                | Self::Output { .. }
                | Self::Picture(_)
                | Self::Camera { .. }
                | Self::Radio { .. }
        )
    }
}
