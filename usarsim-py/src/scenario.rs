//! `usarsim._core.Scenario`: a scenario of `ucc scenario` (docs/scenarios.md) stepped one
//! period at a time from Python. The UAVs named in `controlled` fly the actions given to
//! `step`; the others fly their scenario agents. The Python environments (`_scenario.py`)
//! build their observations and rewards on it.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use numpy::IntoPyArray;
use numpy::ndarray::Array2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use ucc_client::SpeedCommand;
use ucc_client::agents::team;
use ucc_client::scenario::engine::{Ending, Episode};
use ucc_client::scenario::{Prepared, Scenario};
use usar_sim::RobotCatalog;

fn invalid(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A scenario: `Scenario(name_or_file, seed=None, controlled=(), threads=1)`.
#[pyclass(name = "Scenario", module = "usarsim._core")]
pub(crate) struct PyScenario {
    prepared: Arc<Prepared>,
    controlled: Vec<usize>,
    threads: usize,
    /// Behind a lock: a Python class must be `Sync`, the world is only `Send`.
    episode: Mutex<Option<Episode>>,
}

impl PyScenario {
    fn episode(&self) -> MutexGuard<'_, Option<Episode>> {
        self.episode.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

#[pymethods]
impl PyScenario {
    #[new]
    #[pyo3(signature = (scenario, controlled = Vec::new(), threads = 1))]
    fn new(scenario: &str, controlled: Vec<usize>, threads: usize) -> PyResult<Self> {
        let s = Scenario::lookup(scenario).map_err(invalid)?;
        let prepared = Prepared::new(s, RobotCatalog::embedded()).map_err(invalid)?;
        let n = prepared.scenario.uav_count();
        if let Some(&bad) = controlled.iter().find(|&&i| i >= n) {
            return Err(invalid(format!(
                "controlled: UAV index {bad} out of range: the scenario has {n} UAV(s), 0..{}",
                n - 1
            )));
        }
        let mut sorted = controlled.clone();
        sorted.sort_unstable();
        sorted.dedup();
        if sorted.len() != controlled.len() {
            return Err(invalid(format!(
                "controlled: an index is given twice: {controlled:?}"
            )));
        }
        if !(1..=64).contains(&threads) {
            return Err(invalid(format!("threads: must be 1..=64, got {threads}")));
        }
        Ok(Self {
            prepared: Arc::new(prepared),
            controlled,
            threads,
            episode: Mutex::new(None),
        })
    }

    /// The scenario's name.
    #[getter]
    fn name(&self) -> String {
        self.prepared.scenario.name.clone()
    }

    /// `search`, `relay`, `tracking` or `delivery`.
    #[getter]
    fn kind(&self) -> &'static str {
        self.prepared.scenario.kind.name()
    }

    /// UAVs in all.
    #[getter]
    fn uav_count(&self) -> usize {
        self.prepared.scenario.uav_count()
    }

    /// The scenario's own seed (iterations start there).
    #[getter]
    fn default_seed(&self) -> u64 {
        self.prepared.scenario.seed
    }

    /// Simulated seconds an episode lasts at most.
    #[getter]
    fn time_limit(&self) -> f64 {
        self.prepared.scenario.time_limit
    }

    /// Seconds between two steps.
    #[getter]
    fn period(&self) -> f64 {
        self.prepared.scenario.period
    }

    /// The UAVs that fly `step`'s actions.
    #[getter]
    fn controlled(&self) -> Vec<usize> {
        self.controlled.clone()
    }

    /// Starts an episode with `seed` (the world, the drawn victims, the agents).
    fn reset(&mut self, py: Python<'_>, seed: u64) -> PyResult<()> {
        let prepared = Arc::clone(&self.prepared);
        let threads = self.threads;
        let episode = py
            .detach(|| Episode::new(prepared, seed, threads))
            .map_err(invalid)?;
        *self.episode() = Some(episode);
        Ok(())
    }

    /// Steps one period: row k of `actions` (forward, right, up, yaw in -1..=1) is the
    /// command of `controlled[k]`. Returns whether the episode has ended.
    fn step(&mut self, py: Python<'_>, actions: Vec<[f64; 4]>) -> PyResult<bool> {
        let mut guard = self.episode();
        let Some(episode) = guard.as_mut() else {
            return Err(invalid("step before reset: call reset(seed) first"));
        };
        if actions.len() != self.controlled.len() {
            return Err(invalid(format!(
                "actions: expected {} row(s) (one per controlled UAV), got {}",
                self.controlled.len(),
                actions.len()
            )));
        }
        let mut overrides = vec![None; episode.uav_count()];
        for (row, (&i, a)) in self.controlled.iter().zip(&actions).enumerate() {
            if let Some(j) = a.iter().position(|v| !v.is_finite()) {
                return Err(invalid(format!(
                    "actions: row {row}, component {j} is not finite ({})",
                    a[j]
                )));
            }
            overrides[i] = Some(SpeedCommand {
                forward: 100.0 * a[0].clamp(-1.0, 1.0),
                right: 100.0 * a[1].clamp(-1.0, 1.0),
                up: 100.0 * a[2].clamp(-1.0, 1.0),
                yaw: 100.0 * a[3].clamp(-1.0, 1.0),
            });
        }
        Ok(py.detach(|| episode.step(&overrides)).is_some())
    }

    /// Whether the episode ended before its time limit (every agent done).
    fn done(&self) -> bool {
        self.episode().as_ref().and_then(Episode::ending) == Some(Ending::Done)
    }

    /// Simulated seconds.
    fn time(&self) -> f64 {
        self.episode().as_ref().map_or(0.0, Episode::time)
    }

    /// Every UAV's readings: `position` (n, 3), `velocity` (n, 3), `yaw` (n,), `battery`
    /// (n,) fraction left, `crashed` (n,), `carrying` (n,), `charging` (n,); the board:
    /// `found` (k, 3) victims found, `targets` (m, 4) last sighting x, y, z and its age in
    /// seconds (NaN: never seen), `fire_radius` (NaN until sensed); `time`.
    fn observe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let guard = self.episode();
        let Some(e) = guard.as_ref() else {
            return Err(invalid("observe before reset: call reset(seed) first"));
        };
        let n = e.uav_count();
        let mut position = Array2::<f64>::zeros((n, 3));
        let mut velocity = Array2::<f64>::zeros((n, 3));
        let mut yaw = Vec::with_capacity(n);
        let mut battery = Vec::with_capacity(n);
        let mut crashed = Vec::with_capacity(n);
        for i in 0..n {
            let s = e.state(i).expect("index within count");
            if let Some(p) = team::position(s) {
                for k in 0..3 {
                    position[[i, k]] = p[k];
                }
            }
            if let Some(v) = &s.velocity {
                velocity[[i, 0]] = v.value.x;
                velocity[[i, 1]] = v.value.y;
                velocity[[i, 2]] = v.value.z;
            }
            yaw.push(s.yaw());
            battery.push(team::battery_level(s));
            crashed.push(e.crashed(i));
        }
        let board = e.board();
        let mut found = Array2::<f64>::zeros((board.found.len(), 3));
        for (i, p) in board.found.iter().enumerate() {
            for k in 0..3 {
                found[[i, k]] = p[k];
            }
        }
        let mut targets = Array2::<f64>::from_elem((board.targets.len(), 4), f64::NAN);
        for (j, t) in board.targets.iter().enumerate() {
            if let Some((p, t)) = t {
                for k in 0..3 {
                    targets[[j, k]] = p[k];
                }
                targets[[j, 3]] = e.time() - t;
            }
        }
        let d = PyDict::new(py);
        d.set_item("position", position.into_pyarray(py))?;
        d.set_item("velocity", velocity.into_pyarray(py))?;
        d.set_item("yaw", yaw.into_pyarray(py))?;
        d.set_item("battery", battery.into_pyarray(py))?;
        d.set_item("crashed", crashed.into_pyarray(py))?;
        d.set_item("carrying", board.carrying.clone().into_pyarray(py))?;
        d.set_item("charging", board.charging.clone().into_pyarray(py))?;
        d.set_item("found", found.into_pyarray(py))?;
        d.set_item("targets", targets.into_pyarray(py))?;
        d.set_item("fire_radius", board.fire_radius.unwrap_or(f64::NAN))?;
        d.set_item("link_up", e.link_up().unwrap_or(false))?;
        d.set_item("time", e.time())?;
        Ok(d)
    }

    /// The figures so far (docs/scenarios.md): name -> value (None: not measured).
    fn metrics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let guard = self.episode();
        let Some(e) = guard.as_ref() else {
            return Err(invalid("metrics before reset: call reset(seed) first"));
        };
        let d = PyDict::new(py);
        for (name, value) in e.metrics().values {
            d.set_item(name, value)?;
        }
        Ok(d)
    }

    /// What the scenario tells UAV `i` (its brief): `altitude`, `footprint`, `speed`,
    /// `start`, `spot` (its landing spot), and, when the scenario has them, `base`,
    /// `area` ((2, 2): min, max), `endpoints` ((2, 3)), `chain`, `slot` (its chain point or
    /// None for a spare), `fire_center`, `fire_radius` (at the start), `targets` (their
    /// starts), `pickup`, `dropoff`.
    fn brief<'py>(&self, py: Python<'py>, i: usize) -> PyResult<Bound<'py, PyDict>> {
        let guard = self.episode();
        let Some(e) = guard.as_ref() else {
            return Err(invalid("brief before reset: call reset(seed) first"));
        };
        let Some(b) = e.brief(i) else {
            return Err(invalid(format!(
                "brief: UAV index {i} out of range 0..{}",
                e.uav_count()
            )));
        };
        let d = PyDict::new(py);
        d.set_item("altitude", b.altitude)?;
        d.set_item("footprint", b.footprint)?;
        d.set_item("speed", b.speed)?;
        d.set_item("start", b.start.to_vec())?;
        d.set_item("spot", b.spot.to_vec())?;
        if let Some(base) = &b.base {
            d.set_item("base", base.location.to_vec())?;
        }
        if let Some(s) = &b.search {
            d.set_item("area", vec![s.area[0].to_vec(), s.area[1].to_vec()])?;
        }
        if let Some(r) = &b.relay {
            d.set_item(
                "endpoints",
                vec![r.endpoints[0].to_vec(), r.endpoints[1].to_vec()],
            )?;
            d.set_item("chain", r.chain)?;
            let slot = (b.rank() < r.chain).then(|| {
                team::relay::slot_point(
                    r.endpoints[0],
                    r.endpoints[1],
                    r.chain,
                    b.rank(),
                    -b.altitude,
                )
                .to_vec()
            });
            d.set_item("slot", slot)?;
        }
        if let Some(f) = &b.fire {
            d.set_item("fire_center", f.center.to_vec())?;
            d.set_item("fire_radius", f.radius)?;
        }
        if !b.targets.is_empty() {
            d.set_item(
                "targets",
                b.targets.iter().map(|t| t.to_vec()).collect::<Vec<_>>(),
            )?;
        }
        if let Some(job) = &b.delivery {
            d.set_item("pickup", job.pickup.location.to_vec())?;
            d.set_item("dropoff", job.dropoff.location.to_vec())?;
        }
        Ok(d)
    }

    /// The episode's log lines so far.
    fn log(&self) -> Vec<String> {
        self.episode()
            .as_ref()
            .map_or_else(Vec::new, |e| e.log().to_vec())
    }
}

/// The embedded scenarios' names.
#[pyfunction]
pub(crate) fn scenarios() -> Vec<&'static str> {
    ucc_client::scenario::spec::EMBEDDED
        .iter()
        .map(|(n, _)| *n)
        .collect()
}
