//! Why a flight failed: [`FlightError`], the core's own error (the runner turns it into a
//! [`RunError`](crate::RunError) of the same name).

use std::time::Duration;

use crate::agent::MissionRefused;
use crate::geometry::Num;
use crate::mission::Mission;

/// Why a flight ended before its missions were done.
#[derive(Debug, thiserror::Error)]
pub enum FlightError {
    /// The agent does not handle a mission type.
    #[error(transparent)]
    Refused(#[from] MissionRefused),
    /// Lockstep was required and the server does not offer it.
    #[error(
        "the server at {addr} does not offer lockstep (a stock USARSim never does; start \
         usar-server with --lockstep)"
    )]
    NoLockstep {
        /// `host:port`.
        addr: String,
    },
    /// The configuration's lockstep step is not a positive, finite number of seconds.
    #[error(
        "lockstep step {step} s: the simulated seconds between barriers must be positive and \
         finite (FlightConfig::lockstep_step)"
    )]
    BadLockstepStep {
        /// The step given.
        step: f64,
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
}
