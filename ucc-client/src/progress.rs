//! What a run reports while it flies: [`Progress`] events, handed to an [`Observer`] (the
//! `ucc` program prints them, the browser control center streams them, tests collect them).

use std::fmt;
use std::path::PathBuf;

use crate::agent::{AgentEvent, SpeedCommand};
use crate::geometry::{Coordinates, Num, triple};
use crate::stats::IterationSummary;
use crate::uav::UavState;

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
    /// The readings of one time stamp, complete, and the agent's answer to them: once per
    /// sensor time stamp (every 0.1 simulated s for the stsAirRobot). Not logged.
    State {
        /// 1-based.
        iteration: usize,
        /// Simulated seconds.
        time: f64,
        /// The UAV as the agent saw it.
        uav: Box<UavState>,
        /// The command in force after this step.
        command: Option<SpeedCommand>,
    },
    /// An agent event (mission started or done, log line).
    Agent {
        /// 1-based.
        iteration: usize,
        /// The event.
        event: AgentEvent,
    },
    /// Something the user should know that does not stop the run.
    Warning {
        /// 1-based.
        iteration: usize,
        /// What.
        message: String,
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
    /// The run was stopped during this iteration (its files are written all the same).
    Interrupted {
        /// 1-based.
        iteration: usize,
    },
    /// Files were written.
    Written {
        /// The files.
        files: Vec<PathBuf>,
    },
}

impl Progress {
    /// Whether the event belongs in a log (every event but the per-tick state).
    pub fn is_loggable(&self) -> bool {
        !matches!(self, Self::State { .. })
    }
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
                "[{iteration}] t={}s spawned at {}",
                Num(*time, 2),
                triple(p, 2)
            ),
            Self::State {
                iteration,
                time,
                uav,
                ..
            } => {
                write!(f, "[{iteration}] t={}s", Num(*time, 2))?;
                if let Some(p) = &uav.position {
                    write!(f, " at {}", triple(&p.value, 2))?;
                }
                Ok(())
            }
            Self::Agent { iteration, event } => write!(f, "[{iteration}] {event}"),
            Self::Warning { iteration, message } => write!(f, "[{iteration}] warning: {message}"),
            Self::IterationDone { iteration, summary } => write!(
                f,
                "[{iteration}] iteration done: {} missions in {:.1} simulated s, {:.1} m flown",
                summary.missions_done, summary.duration, summary.distance
            ),
            Self::IterationFailed { iteration, error } => {
                write!(f, "[{iteration}] iteration failed: {error}")
            }
            Self::Interrupted { iteration } => {
                write!(f, "[{iteration}] interrupted: the run was stopped")
            }
            Self::Written { files } => {
                let names: Vec<_> = files.iter().map(|p| p.display().to_string()).collect();
                write!(f, "wrote {}", names.join(", "))
            }
        }
    }
}

/// Receives the [`Progress`] of a run. Any `FnMut(&Progress)` is an observer.
pub trait Observer {
    /// Called for every event, in order, on the runner's task: return quickly.
    fn progress(&mut self, event: &Progress);
}

impl<F: FnMut(&Progress)> Observer for F {
    fn progress(&mut self, event: &Progress) {
        self(event);
    }
}
