//! Starts runs: the one place that calls ucc-client's runner. A run flies on a thread of its
//! own, and its progress events update the [`Hub`].
//!
//! A pause holds every flight. On the local server (lockstep) the observer simply waits,
//! and the world waits with it. Against another server, which does not wait, the UAV is
//! held where it is: while paused its agent is not asked, and zero velocity set-points are
//! sent instead ([`HoldWhilePaused`]).

use std::sync::Arc;
use std::time::Duration;

use tokio_util::sync::CancellationToken;
use ucc_client::{
    Agent, AgentEvent, Mission, MissionRefused, Progress, RunSettings, SpeedCommand, Step,
    UavState, agents,
};

use crate::hub::{Live, RequestError, Shared, Status};

/// The agent names the page offers.
pub fn agent_names() -> Vec<&'static str> {
    agents::AGENTS.iter().map(|a| a.name).collect()
}

/// An agent that, while the hub is paused, holds the UAV in place (zero velocities) instead
/// of flying on: what a pause means against a server that does not wait (a real USARSim).
struct HoldWhilePaused {
    inner: Box<dyn Agent>,
    shared: Arc<Shared>,
}

impl Agent for HoldWhilePaused {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn add_mission(&mut self, mission: Mission) -> Result<(), MissionRefused> {
        self.inner.add_mission(mission)
    }

    fn start(&mut self, time: f64) {
        self.inner.start(time);
    }

    fn stop(&mut self) {
        self.inner.stop();
    }

    fn step(&mut self, uav: &UavState, time: f64) -> Step {
        if self.shared.lock().paused {
            return Step {
                command: Some(SpeedCommand::STOP),
                ..Step::default()
            };
        }
        self.inner.step(uav, time)
    }
}

/// Starts the run of UAV `id` on a thread of its own; returns its cancellation token (also
/// stored in the UAV).
pub fn spawn_run(
    shared: Arc<Shared>,
    id: u32,
    settings: RunSettings,
    agent: String,
) -> Result<(), RequestError> {
    let info = agents::info(&agent)
        .ok_or_else(|| RequestError::State(format!("unknown agent {agent:?}")))?;
    let cancel = CancellationToken::new();
    {
        let mut hub = shared.lock();
        hub.uav(id)?.cancel = Some(cancel.clone());
        hub.log(
            id,
            "info",
            format!(
                "run: {} iteration(s) of {} mission(s) against {}",
                settings.iterations,
                settings.missions.len(),
                settings.addr
            ),
        );
    }
    let thread_shared = shared.clone();
    let spawned = std::thread::Builder::new()
        .name(format!("ucc-gui-uav{id}"))
        .spawn(move || {
            let shared = thread_shared;
            let runtime = match tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            {
                Ok(rt) => rt,
                Err(e) => {
                    shared.lock().finished(
                        id,
                        Status::Failed,
                        Some(format!("cannot start a runtime: {e}")),
                    );
                    return;
                }
            };
            // A server with geometry is our own, in lockstep: the observer holds it.
            let local = settings.map.is_some();
            let mut observer = |p: &Progress| observe(&shared, id, p, local);
            let create = info.create;
            let agents = || -> Box<dyn Agent> {
                Box::new(HoldWhilePaused {
                    inner: create(),
                    shared: shared.clone(),
                })
            };
            let result =
                runtime.block_on(ucc_client::run(&settings, &agents, &mut observer, &cancel));
            let mut hub = shared.lock();
            match result {
                Ok(summary) => {
                    if let Some(results) = &summary.results {
                        hub.written(id, std::slice::from_ref(results));
                    }
                    let failed = summary.statistics().failed;
                    let (status, error, line) = if summary.interrupted {
                        (
                            Status::Stopped,
                            None,
                            "run stopped; its files are written".to_owned(),
                        )
                    } else if failed > 0 {
                        let first = summary.first_error.clone();
                        (
                            Status::Failed,
                            first.clone(),
                            format!(
                                "run ended: {failed} of {} iteration(s) failed",
                                summary.flown
                            ),
                        )
                    } else {
                        (
                            Status::Done,
                            None,
                            format!("run ended: {} iteration(s) done", summary.flown),
                        )
                    };
                    hub.log(
                        id,
                        if status == Status::Failed {
                            "error"
                        } else {
                            "info"
                        },
                        line,
                    );
                    hub.finished(id, status, error);
                }
                Err(e) => {
                    hub.log(id, "error", format!("run failed: {e}"));
                    hub.finished(id, Status::Failed, Some(e.to_string()));
                }
            }
        });
    if let Err(e) = spawned {
        shared.lock().finished(
            id,
            Status::Failed,
            Some(format!("cannot start a thread: {e}")),
        );
        return Err(RequestError::State(format!(
            "cannot start a thread for the run: {e}"
        )));
    }
    Ok(())
}

/// One progress event into the hub; on the local server, holds the flight while the hub is
/// paused (the world waits in lockstep).
fn observe(shared: &Shared, id: u32, progress: &Progress, local: bool) {
    let mut hub = shared.lock();
    match progress {
        Progress::Connected { iteration, .. } => hub.new_iteration(id, *iteration),
        Progress::State {
            iteration,
            time,
            uav,
            command,
        } => {
            let live = Live::of(*time, uav, *command, !local);
            hub.sample(id, *iteration, live);
            if let Ok(u) = hub.uav(id) {
                u.camera_sample(uav.image.as_ref().map(|i| &i.value));
            }
        }
        Progress::Agent {
            event: AgentEvent::MissionStarted { index, .. },
            ..
        } => hub.mission_started(id, *index),
        Progress::Written { files } => hub.written(id, files),
        _ => {}
    }
    if progress.is_loggable() {
        let level = match progress {
            Progress::Warning { .. } | Progress::Interrupted { .. } => "warn",
            Progress::IterationFailed { .. } => "error",
            _ => "info",
        };
        hub.log(id, level, progress.to_string());
    }
    // A pause holds the runner here (a stop still ends it: the token is checked after).
    let cancel = hub
        .uavs
        .iter()
        .find(|u| u.id == id)
        .and_then(|u| u.cancel.clone());
    while local && hub.paused && !cancel.as_ref().is_some_and(|c| c.is_cancelled()) {
        hub = shared
            .resumed
            .wait_timeout(hub, Duration::from_millis(100))
            .unwrap_or_else(|e| e.into_inner())
            .0;
    }
}

/// Connects to `addr` and hangs up: is a server there?
pub async fn probe(addr: &str) -> Result<(), RequestError> {
    let conn = ucc_client::Connection::connect(addr, Duration::from_secs(3))
        .await
        .map_err(|e| RequestError::Server(e.to_string()))?;
    drop(conn);
    Ok(())
}
