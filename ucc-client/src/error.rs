//! Why a run or one of its iterations failed: [`RunError`], the error of the flight and
//! of the runner that drives it.

use std::path::PathBuf;
use std::time::Duration;

use crate::agent::MissionRefused;
use crate::connection::ConnectionError;
use crate::geometry::Num;
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
    #[error(
        "the server at {addr} does not offer lockstep (a stock USARSim never does; start \
         usar-server with --lockstep)"
    )]
    NoLockstep {
        /// `host:port`.
        addr: String,
    },
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
    /// The robot streams data but nothing tells where it is.
    #[error(
        "the robot reports no position within {timeout:?}: it needs a Position, GroundTruth \
         or INS sensor, or a known start for dead reckoning"
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
    #[error("battery empty at t={}s", Num(*time, 2))]
    BatteryEmpty {
        /// Simulated seconds.
        time: f64,
    },
    /// The UAV crashed (its crash sensor fired, docs/quadrotor.md).
    #[error("crashed at t={}s: {reason}", Num(*time, 2))]
    Crashed {
        /// Simulated seconds.
        time: f64,
        /// What the UAV state knew then (speed before the impact, tilt, position).
        reason: String,
    },
    /// A mission took too long.
    #[error("mission {number} ({mission}) not done after {} simulated seconds{hint}", Num(*seconds, 1))]
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

impl RunError {
    /// Whether the failure would happen again in the next iteration, so that going on is
    /// pointless (no server, a bad configuration, files that cannot be written).
    pub fn is_fatal(&self) -> bool {
        matches!(
            self,
            Self::NoMissions
                | Self::Refused(_)
                | Self::NoLockstep { .. }
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
