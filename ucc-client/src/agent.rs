//! The [`Agent`] trait: a control algorithm that flies missions.
//!
//! Agents do no I/O and read no clock: the runner hands them the [`UavState`] and the
//! simulated time, they answer with a [`Step`] (a speed command, log lines, mission events,
//! radio messages). Camera frames and radio messages reach them in the [`UavState`].
//! So they behave the same at any simulation speed and are unit-tested with synthetic states.

use std::fmt;

use crate::mission::Mission;
pub use crate::speed::SpeedCommand;
use crate::uav::UavState;

/// Something an agent reports besides its command.
#[derive(Debug, Clone, PartialEq)]
pub enum AgentEvent {
    /// A line for the log.
    Log(String),
    /// A mission was started.
    MissionStarted {
        /// 0-based index in the agent's mission list.
        index: usize,
        /// The mission.
        mission: Mission,
        /// Simulated seconds.
        time: f64,
    },
    /// A mission was completed.
    MissionDone {
        /// 0-based index in the agent's mission list.
        index: usize,
        /// The mission.
        mission: Mission,
        /// Simulated seconds.
        time: f64,
        /// For GotoXyz, the distance to the target when it counted as reached (metres).
        distance: Option<f64>,
    },
}

impl fmt::Display for AgentEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Log(line) => f.write_str(line),
            Self::MissionStarted {
                index,
                mission,
                time,
            } => write!(f, "t={time:.2}s mission {} started: {mission}", index + 1),
            Self::MissionDone {
                index,
                mission,
                time,
                distance,
            } => {
                write!(f, "t={time:.2}s mission {} done: {mission}", index + 1)?;
                if let Some(d) = distance {
                    write!(f, " (reached at {d:.2} m)")?;
                }
                Ok(())
            }
        }
    }
}

/// What an agent answers to one step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Step {
    /// The speed command to send; `None` keeps the previous one.
    pub command: Option<SpeedCommand>,
    /// What happened during this step.
    pub events: Vec<AgentEvent>,
    /// Every mission is done.
    pub all_done: bool,
    /// Radio messages to send to other UAVs (with
    /// [`RunSettings::radio`](crate::RunSettings::radio); ignored, with a log line,
    /// without). One that does not get through comes back in the next step's
    /// [`UavState::undelivered`].
    pub send: Vec<crate::radio::Outgoing>,
}

/// Why an agent refused a mission.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("agent {agent} cannot fly a {kind} mission: {reason}")]
pub struct MissionRefused {
    /// The agent's name.
    pub agent: String,
    /// The mission type.
    pub kind: &'static str,
    /// Why.
    pub reason: String,
}

/// A control algorithm. Implementations are pure: state and time in, command and log out.
pub trait Agent: Send {
    /// A short name for logs (the registry's name for the built-in agents).
    fn name(&self) -> &str;

    /// Appends a mission, or refuses a type it does not handle.
    fn add_mission(&mut self, mission: Mission) -> Result<(), MissionRefused>;

    /// Starts flying the missions at simulated time `time`.
    fn start(&mut self, time: f64);

    /// Stops: later steps return [`SpeedCommand::STOP`].
    fn stop(&mut self);

    /// Called whenever new sensor data has arrived, with the simulated time.
    fn step(&mut self, uav: &UavState, time: f64) -> Step;
}

/// Makes a fresh agent for every iteration: what the runner takes instead of an agent
/// name, so that any agent flies (one from another crate, a Python one). Any
/// `Fn() -> Box<dyn Agent>` is a factory.
///
/// ```
/// use ucc_client::{Agent, AgentFactory, agents};
/// let factory = || agents::create("avoid").unwrap();
/// assert_eq!(factory.create().name(), "avoid");
/// ```
pub trait AgentFactory: Send + Sync {
    /// A new agent with no missions.
    fn create(&self) -> Box<dyn Agent>;
}

impl<F: Fn() -> Box<dyn Agent> + Send + Sync> AgentFactory for F {
    fn create(&self) -> Box<dyn Agent> {
        self()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drive_is_normalized_and_clamped() {
        let d = SpeedCommand {
            forward: 150.0,
            right: -20.0,
            up: f64::NAN,
            yaw: -300.0,
        }
        .to_drive();
        assert_eq!(d.linear_velocity, Some(100.0));
        assert_eq!(d.lateral_velocity, Some(-20.0));
        assert_eq!(d.altitude_velocity, Some(0.0));
        assert_eq!(d.rotational_velocity, Some(-100.0));
        assert_eq!(d.normalized, Some(true));
    }
}
