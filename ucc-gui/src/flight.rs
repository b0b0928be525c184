//! The one place that talks to ucc-client's runner: settings for a run, the agent registry,
//! and a run on a thread of its own whose progress events update the [`Hub`].
//!
//! Each run gets its own thread and single-threaded runtime, so that a pause can simply hold
//! the observer (the runner's task waits, and in lockstep the server waits with it).

use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

use serde_json::{Value, json};
use tokio_util::sync::CancellationToken;
use ucc_client::{AgentEvent, Lockstep, Mission, Progress, RunSettings, UavState, agents};

use crate::hub::{Hub, Status, Uav};

/// The hub and the condition a paused flight waits on.
#[derive(Debug)]
pub struct Shared {
    /// The state.
    pub hub: Mutex<Hub>,
    /// Signalled when the pause ends.
    pub resumed: Condvar,
}

impl Shared {
    /// Locks the hub (a poisoned lock is taken over: the state stays usable).
    pub fn lock(&self) -> MutexGuard<'_, Hub> {
        self.hub.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The agent names the page offers.
pub fn agent_names() -> Vec<&'static str> {
    agents::AGENTS.iter().map(|a| a.name).collect()
}

/// An unknown agent name is a message naming the known ones.
pub fn check_agent(name: &str) -> Result<(), String> {
    agents::info(name).map(|_| ()).ok_or_else(|| {
        format!(
            "agent type: unknown agent {name:?} (known agents: {})",
            agents::names()
        )
    })
}

/// Whether the UAV's agent flies this mission type.
pub fn check_mission(agent: &str, mission: &Mission) -> Result<(), String> {
    let info = agents::info(agent).ok_or_else(|| format!("unknown agent {agent:?}"))?;
    (info.create)()
        .add_mission(mission.clone())
        .map_err(|e| e.to_string())
}

/// The settings of a run of `uav`.
pub fn settings(
    uav: &Uav,
    iterations: usize,
    addr: String,
    local: bool,
    log_dir: PathBuf,
    map: Option<ucc_client::picture::MapGeometry>,
) -> RunSettings {
    RunSettings {
        addr,
        robot: uav.robot.clone(),
        name: uav.name.clone(),
        start: uav.start.clone(),
        missions: uav.missions.clone(),
        iterations,
        log_dir: uav.autosave.then_some(log_dir),
        prefix: uav.prefix.clone(),
        // A local server always offers lockstep; a real USARSim never does.
        lockstep: if local {
            Lockstep::Required
        } else {
            Lockstep::IfOffered
        },
        keep_going: true,
        pictures: uav.pictures,
        map,
        ..RunSettings::default()
    }
}

/// The latest state of a UAV, as the live panel shows it.
#[derive(Debug, Clone, Default)]
pub struct Live {
    /// Simulated seconds.
    pub time: f64,
    /// Metres, world frame, z down.
    pub position: Option<[f64; 3]>,
    /// Roll, pitch, yaw, radians.
    pub attitude: Option<[f64; 3]>,
    /// m/s, world frame.
    pub velocity: Option<[f64; 3]>,
    /// Level (1 = full) and remaining seconds.
    pub battery: Option<(f64, i64)>,
    /// Ranges (index 0 rightmost), resolution and field of view (radians).
    pub laser: Option<(Vec<f64>, f64, f64)>,
    /// The horizontal sonars, metres.
    pub sonars: Vec<Option<f64>>,
    /// Free space above and below, metres.
    pub free: (Option<f64>, Option<f64>),
    /// Altitude sensor, metres.
    pub altitude: Option<f64>,
    /// The command in force: forward, right, up, yaw.
    pub command: Option<[f64; 4]>,
    /// Laser hits of this sample in the world frame (x, y).
    pub hits: Vec<[f64; 2]>,
}

impl Live {
    fn of(
        time: f64,
        uav: &UavState,
        command: Option<ucc_client::SpeedCommand>,
        hits: bool,
    ) -> Self {
        let v3 = |c: &ucc_client::Coordinates| [c.x, c.y, c.z];
        let position = uav.position.as_ref().map(|p| v3(&p.value));
        let laser = uav.laser.as_ref().map(|l| l.value.clone());
        let mut live = Self {
            time,
            position,
            attitude: uav.orientation.as_ref().map(|o| v3(&o.value)),
            velocity: uav.velocity.as_ref().map(|v| v3(&v.value)),
            battery: uav
                .battery
                .as_ref()
                .map(|b| (b.value.level, b.value.remaining)),
            laser: laser
                .as_ref()
                .map(|l| (l.ranges.clone(), l.resolution, l.fov)),
            sonars: uav
                .sonars
                .iter()
                .map(|s| s.as_ref().map(|r| r.value))
                .collect(),
            free: (
                uav.free_above.as_ref().map(|r| r.value),
                uav.free_below.as_ref().map(|r| r.value),
            ),
            altitude: uav.altitude.as_ref().map(|r| r.value),
            command: command.map(|c| [c.forward, c.right, c.up, c.yaw]),
            hits: Vec::new(),
        };
        if hits && let (Some(p), Some(l)) = (uav.position.as_ref(), laser) {
            let hits = l.hits(&p.value, uav.yaw());
            live.hits.extend(hits.map(|(_, h)| [h.x, h.y]));
        }
        live
    }

    /// The JSON of the live panel; the laser and sonars only for the selected UAV.
    pub fn to_json(&self, detail: bool) -> Value {
        let finite = |v: f64| {
            if v.is_finite() {
                Value::from(v)
            } else {
                Value::Null
            }
        };
        let arr = |a: &Option<[f64; 3]>| a.map(|a| a.map(finite));
        let mut v = json!({
            "time": finite(self.time),
            "position": arr(&self.position),
            "attitude": arr(&self.attitude),
            "velocity": arr(&self.velocity),
            "battery": self.battery.map(|b| json!({"level": finite(b.0), "remaining": b.1})),
        });
        if detail {
            v["laser"] = self
                .laser
                .as_ref()
                .map_or(Value::Null, |l| json!({"ranges": l.0.iter().map(|r| finite(*r)).collect::<Vec<_>>(), "resolution": finite(l.1), "fov": finite(l.2)}));
            v["sonars"] = self
                .sonars
                .iter()
                .map(|s| s.map_or(Value::Null, finite))
                .collect();
            v["free_above"] = self.free.0.map_or(Value::Null, finite);
            v["free_below"] = self.free.1.map_or(Value::Null, finite);
            v["altitude"] = self.altitude.map_or(Value::Null, finite);
            v["command"] = self
                .command
                .map_or(Value::Null, |c| c.map(finite).into_iter().collect());
        }
        v
    }
}

/// Starts the run of UAV `id` on a thread of its own; returns its cancellation token (also
/// stored in the UAV).
pub fn spawn_run(
    shared: Arc<Shared>,
    id: u32,
    settings: RunSettings,
    agent: String,
) -> Result<(), String> {
    let info = agents::info(&agent).ok_or_else(|| format!("unknown agent {agent:?}"))?;
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
            let hits = settings.map.is_none();
            let mut observer = |p: &Progress| observe(&shared, id, p, hits);
            let result = runtime.block_on(ucc_client::run(
                &settings,
                &info.create,
                &mut observer,
                &cancel,
            ));
            let mut hub = shared.lock();
            match result {
                Ok(summary) => {
                    if let Ok(u) = hub.uav(id) {
                        u.files.extend(summary.results.clone());
                    }
                    let failed = summary.statistics().failed;
                    let (status, error, line) = if summary.interrupted {
                        (
                            Status::Stopped,
                            None,
                            "run stopped; its files are written".to_owned(),
                        )
                    } else if failed > 0 {
                        let first = summary
                            .iterations
                            .iter()
                            .find_map(|i| i.error())
                            .map(str::to_owned);
                        (
                            Status::Failed,
                            first.clone(),
                            format!(
                                "run ended: {failed} of {} iteration(s) failed",
                                summary.iterations.len()
                            ),
                        )
                    } else {
                        (
                            Status::Done,
                            None,
                            format!("run ended: {} iteration(s) done", summary.iterations.len()),
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
        return Err(format!("cannot start a thread for the run: {e}"));
    }
    Ok(())
}

/// One progress event into the hub; holds the flight while the hub is paused.
fn observe(shared: &Shared, id: u32, progress: &Progress, hits: bool) {
    let mut hub = shared.lock();
    match progress {
        Progress::Connected { iteration, .. } => hub.new_iteration(id, *iteration),
        Progress::State {
            iteration,
            time,
            uav,
            command,
        } => {
            let live = Live::of(*time, uav, *command, hits);
            hub.sample(id, *iteration, live);
        }
        Progress::Agent {
            event: AgentEvent::MissionStarted { index, .. },
            ..
        } => {
            if let Ok(u) = hub.uav(id) {
                u.active = Some(*index);
            }
        }
        Progress::Written { files } => {
            if let Ok(u) = hub.uav(id) {
                u.files.extend(files.iter().cloned());
            }
        }
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
    while hub.paused && !cancel.as_ref().is_some_and(|c| c.is_cancelled()) {
        hub = shared
            .resumed
            .wait_timeout(hub, Duration::from_millis(100))
            .unwrap_or_else(|e| e.into_inner())
            .0;
    }
}

/// Connects to `addr` and hangs up: is a server there?
pub async fn probe(addr: &str) -> Result<(), String> {
    let conn = ucc_client::Connection::connect(addr, Duration::from_secs(3))
        .await
        .map_err(|e| e.to_string())?;
    drop(conn);
    Ok(())
}
