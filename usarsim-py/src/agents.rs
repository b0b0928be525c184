//! Python agents in the control framework: a Python object with `step(state) -> Command`
//! flown by ucc-client's runner (missions, iterations, logs, trajectories, pictures) against a
//! running server or a usar-server started in this process.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use tokio_util::sync::CancellationToken;
use ucc_client::picture::MapGeometry;
use ucc_client::{
    Agent, AgentEvent, Backend, Coordinates, Lockstep, Mission, MissionRefused, Progress,
    RunSettings, SpeedCommand, Start, Step, UavState,
};

use crate::core::{LASER, Observations, SONARS};

/// A speed command: forward, right, up, yaw rate, each in -1..=1 of the robot's maximum;
/// `done=True` marks the current mission as done (for Hover missions, or a custom test).
#[pyclass(name = "Command", module = "usarsim._core", from_py_object)]
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PyCommand {
    #[pyo3(get, set)]
    forward: f64,
    #[pyo3(get, set)]
    right: f64,
    #[pyo3(get, set)]
    up: f64,
    #[pyo3(get, set)]
    yaw: f64,
    #[pyo3(get, set)]
    done: bool,
}

#[pymethods]
impl PyCommand {
    #[new]
    #[pyo3(signature = (forward = 0.0, right = 0.0, up = 0.0, yaw = 0.0, done = false))]
    fn new(forward: f64, right: f64, up: f64, yaw: f64, done: bool) -> PyResult<Self> {
        for (name, v) in [
            ("forward", forward),
            ("right", right),
            ("up", up),
            ("yaw", yaw),
        ] {
            if !v.is_finite() {
                return Err(PyValueError::new_err(format!(
                    "Command: {name} is not finite ({v})"
                )));
            }
        }
        Ok(Self {
            forward,
            right,
            up,
            yaw,
            done,
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "Command(forward={}, right={}, up={}, yaw={}, done={})",
            self.forward,
            self.right,
            self.up,
            self.yaw,
            if self.done { "True" } else { "False" }
        )
    }
}

/// What a Python agent sees each step (world frame, metres, z down; radians).
#[pyclass(name = "State", module = "usarsim._core", get_all)]
#[derive(Debug, Clone)]
pub(crate) struct PyState {
    /// Simulated seconds.
    time: f64,
    position: [f64; 3],
    velocity: [f64; 3],
    attitude: [f64; 3],
    angular_velocity: [f64; 3],
    sonar: Vec<f64>,
    laser: Vec<f64>,
    battery: f64,
    /// 0-based index of the current mission.
    mission: usize,
    /// The current GotoXyz target, or None (Hover mission, or all done).
    target: Option<[f64; 3]>,
}

#[pymethods]
impl PyState {
    fn __repr__(&self) -> String {
        format!(
            "State(time={:.2}, position={:?}, mission={}, target={:?})",
            self.time, self.position, self.mission, self.target
        )
    }
}

/// The first Python exception raised by an agent during a run.
type Failure = Arc<Mutex<Option<PyErr>>>;

/// Adapts a Python agent object to ucc-client's [`Agent`].
struct PythonAgent {
    object: Py<PyAny>,
    missions: Vec<Mission>,
    current: usize,
    started: bool,
    /// Simulated time the current mission started.
    since: f64,
    stopped: bool,
    /// Metres from a GotoXyz target that count as reached.
    reached: f64,
    failure: Failure,
    cancel: CancellationToken,
}

impl PythonAgent {
    fn state(&self, uav: &UavState, time: f64) -> PyState {
        let mut obs = Observations::default();
        obs.push_state(uav, false, time);
        let v3 = |v: &[f64]| [v[0], v[1], v[2]];
        PyState {
            time,
            position: v3(&obs.position),
            velocity: v3(&obs.velocity),
            attitude: v3(&obs.attitude),
            angular_velocity: v3(&obs.angular_velocity),
            sonar: obs.sonar[..SONARS].to_vec(),
            laser: obs.laser[..LASER].to_vec(),
            battery: obs.battery[0],
            mission: self.current,
            target: self
                .missions
                .get(self.current)
                .and_then(Mission::target)
                .map(|t| [t.x, t.y, t.z]),
        }
    }

    fn fail(&self, error: PyErr) -> Step {
        let mut slot = self.failure.lock().unwrap_or_else(PoisonError::into_inner);
        slot.get_or_insert(error);
        self.cancel.cancel();
        Step {
            command: Some(SpeedCommand::STOP),
            ..Step::default()
        }
    }
}

impl Agent for PythonAgent {
    fn name(&self) -> &str {
        "python"
    }

    fn add_mission(&mut self, mission: Mission) -> Result<(), MissionRefused> {
        self.missions.push(mission);
        Ok(())
    }

    fn start(&mut self, _time: f64) {}

    fn stop(&mut self) {
        self.stopped = true;
    }

    fn step(&mut self, uav: &UavState, time: f64) -> Step {
        let mut step = Step::default();
        if self.stopped || uav.position.is_none() {
            step.command = Some(SpeedCommand::STOP);
            return step;
        }
        let Some(mission) = self.missions.get(self.current).cloned() else {
            step.all_done = true;
            step.command = Some(SpeedCommand::STOP);
            return step;
        };
        if !self.started {
            self.started = true;
            self.since = time;
            step.events.push(AgentEvent::MissionStarted {
                index: self.current,
                mission: mission.clone(),
                time,
            });
        }
        let state = self.state(uav, time);
        let answer = Python::attach(|py| -> PyResult<PyCommand> {
            // Ctrl-C: the runner runs on the calling (main) thread, so signals are seen here.
            py.check_signals()?;
            let result = self.object.call_method1(py, "step", (state.clone(),))?;
            result.extract::<PyCommand>(py).map_err(|_| {
                PyValueError::new_err(format!(
                    "agent.step at t={time:.2}: must return usarsim.Command, got {}",
                    result
                        .bind(py)
                        .get_type()
                        .name()
                        .map_or("?".into(), |n| n.to_string())
                ))
            })
        });
        let command = match answer {
            Ok(c) => c,
            Err(e) => return self.fail(e),
        };
        step.command = Some(
            SpeedCommand {
                forward: command.forward * 100.0,
                right: command.right * 100.0,
                up: command.up * 100.0,
                yaw: command.yaw * 100.0,
            }
            .clamped(),
        );
        let distance = mission.target().and_then(|t| {
            let p = uav.position.as_ref()?.value;
            Some((t - p).norm())
        });
        let hovered = match mission {
            Mission::Hover { seconds } => time - self.since >= seconds,
            Mission::GotoXyz { .. } => false,
        };
        if command.done || hovered || distance.is_some_and(|d| d < self.reached) {
            step.events.push(AgentEvent::MissionDone {
                index: self.current,
                mission,
                time,
                distance,
            });
            self.current += 1;
            self.started = false;
            step.all_done = self.current == self.missions.len();
            if step.all_done {
                step.command = Some(SpeedCommand::STOP);
            }
        }
        step
    }
}

/// Flies `agent_class` (called with no arguments once per iteration) through `missions`.
#[pyfunction]
#[pyo3(signature = (agent_class, missions, *, server = None, start = (0.0, 0.0, -1.0), iterations = 1, log_dir = None, map = "empty_room", robot = "stsAirRobot", reached = 0.3, mission_timeout = 120.0, lockstep = true, quiet = true))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fly<'py>(
    py: Python<'py>,
    agent_class: Py<PyAny>,
    missions: Vec<Bound<'py, PyAny>>,
    server: Option<String>,
    start: (f64, f64, f64),
    iterations: usize,
    log_dir: Option<PathBuf>,
    map: &str,
    robot: &str,
    reached: f64,
    mission_timeout: f64,
    lockstep: bool,
    quiet: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let missions = missions
        .iter()
        .enumerate()
        .map(|(i, m)| mission(m).map_err(|e| PyValueError::new_err(format!("missions[{i}]: {e}"))))
        .collect::<PyResult<Vec<_>>>()?;
    if missions.is_empty() {
        return Err(PyValueError::new_err("missions: at least one mission"));
    }
    if !(reached.is_finite() && reached > 0.0) {
        return Err(PyValueError::new_err(format!(
            "reached: must be a positive number of metres, got {reached}"
        )));
    }
    let map =
        std::sync::Arc::unwrap_or_clone(crate::core::Settings::new(map, robot, 0.1, None)?.map);
    let failure: Failure = Arc::default();
    let cancel = CancellationToken::new();
    let factory = {
        let (failure, cancel) = (failure.clone(), cancel.clone());
        move || -> Box<dyn Agent> {
            let object = Python::attach(|py| agent_class.call0(py));
            let object = object.unwrap_or_else(|e| {
                failure
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .get_or_insert(e);
                cancel.cancel();
                Python::attach(|py| py.None())
            });
            Box::new(PythonAgent {
                object,
                missions: Vec::new(),
                current: 0,
                started: false,
                since: 0.0,
                stopped: false,
                reached,
                failure: failure.clone(),
                cancel: cancel.clone(),
            })
        }
    };
    let settings = RunSettings {
        robot: robot.to_string(),
        start: Start::at(Coordinates::new(start.0, start.1, start.2)),
        missions,
        iterations: iterations.max(1),
        log_dir,
        prefix: "python".into(),
        mission_timeout,
        lockstep: if lockstep {
            Lockstep::IfOffered
        } else {
            Lockstep::Off
        },
        map: Some(MapGeometry::from(&map)),
        // `fly` returns every iteration, trajectory included.
        kept_iterations: usize::MAX,
        ..RunSettings::default()
    };
    let backend = match server {
        Some(addr) => Backend::Remote(addr),
        None => Backend::Local(Box::new(usar_server::ServerConfig {
            map,
            time_scale: usar_server::TimeScale::Max,
            ..usar_server::ServerConfig::default()
        })),
    };
    let result = py.detach(|| run(settings, backend, &factory, &cancel, quiet));
    if let Some(e) = failure
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .take()
    {
        return Err(e);
    }
    let summary = result.map_err(PyValueError::new_err)?;
    let out = PyDict::new(py);
    let rows = summary
        .iterations
        .iter()
        .map(|it| {
            let row = PyDict::new(py);
            row.set_item("status", it.status.word())?;
            row.set_item("error", it.error())?;
            row.set_item("missions_done", it.missions_done)?;
            row.set_item("duration", it.duration)?;
            row.set_item("distance", it.distance)?;
            row.set_item(
                "trajectory",
                it.trajectory
                    .iter()
                    .map(|p| (p.time, p.position.x, p.position.y, p.position.z))
                    .collect::<Vec<_>>(),
            )?;
            row.set_item("files", it.files.clone())?;
            Ok(row)
        })
        .collect::<PyResult<Vec<_>>>()?;
    out.set_item("iterations", rows)?;
    out.set_item("overlay", summary.overlay.clone())?;
    out.set_item("results", summary.results.clone())?;
    let stats = summary.statistics();
    out.set_item("completed", stats.completed)?;
    out.set_item("failed", stats.failed)?;
    Ok(out)
}

/// A mission from Python: `(x, y, z)` is GotoXyz, `{"hover": seconds}` is Hover.
fn mission(m: &Bound<'_, PyAny>) -> Result<Mission, String> {
    if let Ok((x, y, z)) = m.extract::<(f64, f64, f64)>() {
        if ![x, y, z].iter().all(|v| v.is_finite()) {
            return Err(format!("target not finite: ({x}, {y}, {z})"));
        }
        return Ok(Mission::goto(Coordinates::new(x, y, z)));
    }
    if let Ok(d) = m.cast::<PyDict>()
        && let Ok(Some(v)) = d.get_item("hover")
        && let Ok(seconds) = v.extract::<f64>()
    {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(format!("hover seconds must be >= 0, got {seconds}"));
        }
        return Ok(Mission::Hover { seconds });
    }
    Err("expected (x, y, z) or {\"hover\": seconds}".into())
}

fn run(
    settings: RunSettings,
    backend: Backend,
    factory: &dyn ucc_client::AgentFactory,
    cancel: &CancellationToken,
    quiet: bool,
) -> Result<ucc_client::Summary, String> {
    // On the calling thread, so that agents run on Python's main thread (signals, and
    // libraries that insist on the main thread).
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| format!("cannot start the runtime: {e}"))?;
    runtime.block_on(async {
        let server = backend.start().await.map_err(|e| e.to_string())?;
        let asked = settings.lockstep;
        let mut settings = server.settings(settings);
        if asked == Lockstep::Off {
            // `lockstep=False`: on sensor time even against our own server.
            settings.lockstep = Lockstep::Off;
        }
        let mut print = |p: &Progress| {
            if !quiet && p.is_loggable() {
                println!("{p}");
            }
        };
        let result = ucc_client::run(&settings, factory, &mut print, cancel).await;
        let _ = server.stop().await;
        result.map_err(|e| format!("server {}: {e}", settings.addr))
    })
}
