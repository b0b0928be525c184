//! `usarsim._core`: the Rust half of the `usarsim` Python package.
//!
//! * [`PyBatch`] (`usarsim._core.Batch`): N worlds of the usar-server simulation with K UAVs
//!   each, stepped in lockstep in one call (GIL released, worlds spread over the cores).
//! * [`PyRemote`] (`usarsim._core.Remote`): one UAV flown over TCP against a usar-server
//!   (lockstep) or a real USARSim (sensor time).
//!
//! The Gymnasium / PettingZoo classes, rewards and rendering are Python (`python/usarsim`).
//! Every bad argument becomes a `ValueError` naming what and where; nothing panics.

// PyO3's macros expand to `unsafe` blocks, so this crate does not forbid unsafe code the way
// the rest of the workspace does (see Cargo.toml); it writes none itself.

/// mimalloc instead of the C library's allocator, for the extension's own (Rust) memory: a
/// reset drops and builds a few dozen small allocations per world on the worker threads,
/// where glibc's malloc and free took a third of the time (docs/benchmarks-history.md, issue 24).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

mod agents;
mod core;
mod remote;
mod scenario;
mod tasks;

use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3, PyReadwriteArray1,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use std::sync::{Mutex, PoisonError};

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::core::{
    Batch, LASER, Observations, Pose, Reset, Rows, SONARS, Settings, SimError, WorldSim,
};
use crate::remote::Remote;

impl From<SimError> for PyErr {
    fn from(e: SimError) -> Self {
        PyValueError::new_err(e.to_string())
    }
}

/// Rows of a `(n, width)` float array, checked for shape and finiteness.
fn rows<const W: usize>(
    array: &PyReadonlyArray2<'_, f64>,
    n: usize,
    what: &str,
) -> PyResult<Vec<[f64; W]>> {
    let a = array.as_array();
    if a.shape() != [n, W] {
        return Err(PyValueError::new_err(format!(
            "{what}: expected shape ({n}, {W}), got {:?}",
            a.shape()
        )));
    }
    // Read as one row-major slice (a C-contiguous array, what NumPy makes, is not copied):
    // ndarray's row iterators cost some 100 instructions a row, serial, at every step.
    let a = a.as_standard_layout();
    let flat = a.as_slice().unwrap_or_default();
    if let Some(k) = flat.iter().position(|v| !v.is_finite()) {
        let v = flat[k];
        return Err(PyValueError::new_err(format!(
            "{what}: row {}, column {} is not finite ({v})",
            k / W,
            k % W
        )));
    }
    Ok(flat
        .chunks_exact(W)
        .map(|r| std::array::from_fn(|j| r[j]))
        .collect())
}

fn to_dict<'py>(py: Python<'py>, obs: Observations) -> PyResult<Bound<'py, PyDict>> {
    let n = obs.battery.len();
    let dict = PyDict::new(py);
    let put = |name: &str, data: Vec<f64>, width: usize| -> PyResult<()> {
        let array = Array2::from_shape_vec((n, width), data)
            .map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?;
        dict.set_item(name, array.into_pyarray(py))
    };
    put("position", obs.position, 3)?;
    put("velocity", obs.velocity, 3)?;
    put("attitude", obs.attitude, 3)?;
    put("angular_velocity", obs.angular_velocity, 3)?;
    if !obs.no_ranges {
        put("sonar", obs.sonar, SONARS)?;
        put("laser", obs.laser, LASER)?;
    }
    put("battery", obs.battery, 1)?;
    put("time", obs.time, 1)?;
    if obs.with_rotors {
        put("rotor_speeds", obs.rotor_speeds, 4)?;
    }
    dict.set_item("touched", obs.touched.into_pyarray(py))?;
    dict.set_item("crashed", obs.crashed.into_pyarray(py))?;
    Ok(dict)
}

/// The float64 fields of an observation dict and each one's width per UAV.
const FIELDS: [(&str, usize); 9] = [
    ("position", 3),
    ("velocity", 3),
    ("attitude", 3),
    ("angular_velocity", 3),
    ("sonar", SONARS),
    ("laser", LASER),
    ("battery", 1),
    ("time", 1),
    ("rotor_speeds", 4),
];

/// The arrays of an observation dict (as `observe()` returns), borrowed writable for Rust to
/// write observations into ([`Windows::rows`]): one per [`FIELDS`] entry (`None` for a field
/// the batch does not observe), then `touched` and `crashed`.
struct Windows<'py> {
    floats: [Option<numpy::PyReadwriteArrayDyn<'py, f64>>; FIELDS.len()],
    flags: [numpy::PyReadwriteArrayDyn<'py, bool>; 2],
}

/// `out[name]`, checked: a writable C-contiguous `T` array of shape `(n, width)` (`(n,)`
/// without a width). `what` names the call in the error.
fn window<'py, T: numpy::Element>(
    out: &Bound<'py, PyDict>,
    name: &str,
    n: usize,
    width: Option<usize>,
    what: &str,
) -> PyResult<numpy::PyReadwriteArrayDyn<'py, T>> {
    let bad = |why: String| PyValueError::new_err(format!("{what}: {name}: {why}"));
    let item = out
        .get_item(name)?
        .ok_or_else(|| bad("missing (pass a dict as observe() returns)".to_string()))?;
    let array = item
        .extract::<numpy::PyReadwriteArrayDyn<'py, T>>()
        .map_err(|e| {
            bad(format!(
                "not a writable {} array: {e}",
                std::any::type_name::<T>()
            ))
        })?;
    let shape = match width {
        Some(w) => vec![n, w],
        None => vec![n],
    };
    if array.shape() != shape.as_slice() {
        return Err(bad(format!(
            "shape {:?}, expected {shape:?}",
            array.shape()
        )));
    }
    // as_slice_mut() takes Fortran order too, which would scatter the rows.
    if !array.is_c_contiguous() {
        return Err(bad("not C-contiguous".to_string()));
    }
    Ok(array)
}

impl<'py> Windows<'py> {
    /// The arrays of `out` for `n` UAVs: every key `observe()` gives (without `sonar` and
    /// `laser` when `state_only`, with `rotor_speeds` when `rotors`), checked by [`window`].
    /// Extra keys are left alone.
    fn of(
        out: &Bound<'py, PyDict>,
        n: usize,
        state_only: bool,
        rotors: bool,
        what: &str,
    ) -> PyResult<Self> {
        let mut floats = [const { None }; FIELDS.len()];
        for (slot, (name, width)) in floats.iter_mut().zip(FIELDS) {
            let observed = match name {
                "sonar" | "laser" => !state_only,
                "rotor_speeds" => rotors,
                _ => true,
            };
            if observed {
                *slot = Some(window(out, name, n, Some(width), what)?);
            }
        }
        let flags = [
            window(out, "touched", n, None, what)?,
            window(out, "crashed", n, None, what)?,
        ];
        Ok(Self { floats, flags })
    }

    /// Their memory as [`Rows`] (the fields left out are empty; [`window`] checked that
    /// every array is C-contiguous).
    fn rows(&mut self) -> Rows<'_> {
        let [
            position,
            velocity,
            attitude,
            angular_velocity,
            sonar,
            laser,
            battery,
            time,
            rotor_speeds,
        ] = self.floats.each_mut().map(|a| {
            a.as_mut()
                .and_then(|a| a.as_slice_mut().ok())
                .unwrap_or_default()
        });
        let [touched, crashed] = self
            .flags
            .each_mut()
            .map(|a| a.as_slice_mut().unwrap_or_default());
        Rows {
            position,
            velocity,
            attitude,
            angular_velocity,
            sonar,
            laser,
            battery,
            time,
            rotor_speeds,
            touched,
            crashed,
        }
    }
}

/// A step's `reset` argument: the worlds' indices, their seeds and their starts.
type StepReset<'py> = (
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    PyReadonlyArray2<'py, f64>,
);

/// N worlds with K UAVs each, stepped together one control period per call.
///
/// `Batch(map, robot, seeds, starts, uavs_per_world=1, period=0.1, noise=None,
/// state_only=False)`: one world per seed; `starts` is a float64 array of shape
/// `(len(seeds) * uavs_per_world, 4)` with x, y, z (metres, z down) and yaw (rad) per UAV,
/// world-major. `state_only`: the robot without sonars and laser (no `sonar`, `laser` keys).
/// `action_mode`: `"velocity"` (DRIVE), `"attitude"`, `"rates"` or `"rotors"` (QUAD;
/// docs/python.md).
#[pyclass(name = "Batch", module = "usarsim._core")]
struct PyBatch {
    /// A mutex only to make the class `Sync` (Python objects may be shared between threads);
    /// every method takes `&mut self`, so it is never contended.
    inner: Mutex<Batch>,
}

impl PyBatch {
    fn get(&mut self) -> &mut Batch {
        self.inner.get_mut().unwrap_or_else(PoisonError::into_inner)
    }

    /// The arrays of `out` to write this batch's observations into.
    fn windows<'py>(&mut self, out: &Bound<'py, PyDict>, what: &str) -> PyResult<Windows<'py>> {
        let batch = self.get();
        let s = &batch.settings;
        Windows::of(out, batch.len(), s.state_only, s.rotors, what)
    }

    /// `actions` checked (finite, `(len, 4)`) and clipped to -1..=1.
    fn actions(&mut self, actions: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<[f64; 4]>> {
        Ok(rows::<4>(actions, self.get().len(), "action")?
            .into_iter()
            .map(|a| a.map(|v| v.clamp(-1.0, 1.0)))
            .collect())
    }

    /// A step's `reset` argument: `(indices, seeds, starts)` or None.
    fn step_resets(&mut self, reset: Option<StepReset<'_>>) -> PyResult<Resets> {
        match reset {
            Some((indices, seeds, starts)) => self.resets(&indices, &seeds, &starts),
            None => Ok(Resets::none()),
        }
    }

    /// The worlds in `indices` to reset, with their seeds and starts ([`Resets::entries`]).
    fn resets(
        &mut self,
        indices: &Bound<'_, PyAny>,
        seeds: &Bound<'_, PyAny>,
        starts: &PyReadonlyArray2<'_, f64>,
    ) -> PyResult<Resets> {
        let worlds = self.get().worlds.len();
        let indices: Vec<usize> = match indices.extract::<PyReadonlyArray1<'_, i64>>() {
            Ok(a) => a
                .as_array()
                .iter()
                .map(|&i| {
                    usize::try_from(i).map_err(|_| {
                        PyValueError::new_err(format!(
                            "indices: world index {i} out of range (0..{worlds})"
                        ))
                    })
                })
                .collect::<PyResult<_>>()?,
            Err(_) => indices.extract().map_err(|e| {
                PyValueError::new_err(format!("indices: expected world indices: {e}"))
            })?,
        };
        let seeds: Vec<u64> = match seeds.extract::<PyReadonlyArray1<'_, u64>>() {
            Ok(a) => a.as_array().to_vec(),
            Err(_) => seeds
                .extract()
                .map_err(|e| PyValueError::new_err(format!("seeds: expected integers: {e}")))?,
        };
        let per = self.get().uavs_per_world;
        if seeds.len() != indices.len() {
            return Err(PyValueError::new_err(format!(
                "seeds: expected one per reset world ({}), got {}",
                indices.len(),
                seeds.len()
            )));
        }
        let poses = rows::<4>(starts, indices.len() * per, "starts")?;
        let mut at = vec![None; worlds];
        for (j, (&i, seed)) in indices.iter().zip(seeds).enumerate() {
            match at.get_mut(i) {
                Some(slot @ None) => *slot = Some((seed, j * per..(j + 1) * per)),
                Some(Some(_)) => {
                    return Err(PyValueError::new_err(format!(
                        "indices: world {i} listed twice"
                    )));
                }
                None => {
                    return Err(PyValueError::new_err(format!(
                        "indices: world index {i} out of range (0..{worlds})"
                    )));
                }
            }
        }
        Ok(Resets { poses, at })
    }
}

/// The worlds a call resets: their starts in one vector (no allocation per world).
struct Resets {
    poses: Vec<Pose>,
    /// Per world: its seed and its rows of `poses`, or `None` (not reset).
    at: Vec<Option<(u64, std::ops::Range<usize>)>>,
}

impl Resets {
    /// None.
    fn none() -> Self {
        Self {
            poses: Vec::new(),
            at: Vec::new(),
        }
    }

    /// One entry per world, as [`Batch::step`] takes them (empty when none resets).
    fn entries(&self) -> Vec<Option<Reset<'_>>> {
        let poses = &self.poses;
        self.at
            .iter()
            .map(|r| r.as_ref().map(|(seed, rows)| (*seed, &poses[rows.clone()])))
            .collect()
    }
}

#[pymethods]
impl PyBatch {
    #[new]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (map, robot, seeds, starts, uavs_per_world = 1, period = 0.1, noise = None, state_only = false, action_mode = "velocity", camera = None, physics_rate = None, sensor_rates = Vec::new(), robots = None))]
    fn new(
        py: Python<'_>,
        map: &str,
        robot: &str,
        seeds: Vec<u64>,
        starts: PyReadonlyArray2<'_, f64>,
        uavs_per_world: usize,
        period: f64,
        noise: Option<f64>,
        state_only: bool,
        action_mode: &str,
        camera: Option<(u32, u32)>,
        physics_rate: Option<f64>,
        sensor_rates: Vec<(String, f64)>,
        robots: Option<&str>,
    ) -> PyResult<Self> {
        if seeds.is_empty() || uavs_per_world == 0 {
            return Err(PyValueError::new_err(
                "Batch: needs at least one world (seed) and one UAV per world",
            ));
        }
        let mut settings = Settings::with_rates(
            map,
            robot,
            period,
            noise,
            physics_rate,
            &sensor_rates,
            robots,
        )?
        .action_mode(action_mode)?;
        if state_only {
            settings = settings.state_only();
        }
        if let Some((width, height)) = camera {
            settings = settings.camera(width, height)?;
        }
        let poses: Vec<Pose> = rows::<4>(&starts, seeds.len() * uavs_per_world, "starts")?;
        let worlds = py.detach(|| {
            seeds
                .iter()
                .zip(poses.chunks(uavs_per_world))
                .enumerate()
                .map(|(i, (&seed, poses))| {
                    WorldSim::new(&settings, seed, poses)
                        .map_err(|e| SimError::Invalid(format!("world {i}: {e}")))
                })
                .collect::<Result<Vec<_>, _>>()
        })?;
        Ok(Self {
            inner: Mutex::new(Batch {
                settings,
                worlds,
                uavs_per_world,
            }),
        })
    }

    /// Faults (a faults file's text), domain randomisation (a randomisation file's text,
    /// `""` for none) and rotor speeds in the observation (`rotor_speeds` key), for the
    /// worlds made at the next resets; `None` leaves a setting (docs/python.md).
    #[pyo3(signature = (faults = None, randomize = None, rotor_speeds = None))]
    fn configure(
        &mut self,
        faults: Option<&str>,
        randomize: Option<&str>,
        rotor_speeds: Option<bool>,
    ) -> PyResult<()> {
        Ok(self
            .get()
            .settings
            .configure(faults, randomize, rotor_speeds)?)
    }

    /// The parameters each UAV drew at its world's last reset (domain randomisation): one
    /// dict per UAV, world-major (empty without randomisation).
    fn randomized<'py>(&mut self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let mut out = Vec::new();
        for world in &self.get().worlds {
            for drawn in world.randomized() {
                let dict = PyDict::new(py);
                for (k, v) in drawn.0 {
                    dict.set_item(k, v)?;
                }
                out.push(dict);
            }
        }
        Ok(out)
    }

    /// Total number of UAVs (worlds × UAVs per world).
    fn __len__(&mut self) -> usize {
        self.get().len()
    }

    /// Number of worlds.
    #[getter]
    fn worlds(&mut self) -> usize {
        self.get().worlds.len()
    }

    /// The control period, seconds.
    #[getter]
    fn period(&mut self) -> f64 {
        self.get().settings.period
    }

    /// The robot class (`USARBot.stsAirRobot`).
    #[getter]
    fn robot(&mut self) -> String {
        self.get().settings.robot.clone()
    }

    /// Replaces the worlds `indices` by fresh ones, in parallel: world `indices[j]` gets
    /// `seeds[j]` and rows `j*K .. (j+1)*K` of `starts` (shape `(len(indices) * K, 4)`).
    fn reset(
        &mut self,
        py: Python<'_>,
        indices: &Bound<'_, PyAny>,
        seeds: &Bound<'_, PyAny>,
        starts: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<()> {
        let resets = self.resets(indices, seeds, &starts)?;
        let inner = self.get();
        py.detach(|| inner.step(None, &resets.entries(), None, None))?;
        Ok(())
    }

    /// Steps every world one control period. `actions`: float64 `(len, 4)`, each row four
    /// values in -1..=1 (clipped) read as the action mode says. `reset`: None, or `(indices, seeds,
    /// starts)` as in `reset`: those worlds are replaced by fresh ones instead of stepping
    /// (their actions are ignored), in the same parallel pass. `out`: None, or a dict of
    /// arrays as for `observe_into`, into which each world then writes its UAVs'
    /// observations, in the same pass (checked before anything steps).
    #[pyo3(signature = (actions, reset = None, out = None))]
    fn step(
        &mut self,
        py: Python<'_>,
        actions: PyReadonlyArray2<'_, f64>,
        reset: Option<StepReset<'_>>,
        out: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<()> {
        self.get().wake();
        let actions = self.actions(&actions)?;
        let resets = self.step_resets(reset)?;
        let mut windows = match out {
            Some(out) => Some(self.windows(out, "step: out")?),
            None => None,
        };
        let rows = windows.as_mut().map(Windows::rows);
        let inner = self.get();
        py.detach(|| inner.step(Some(&actions), &resets.entries(), rows, None))?;
        Ok(())
    }

    /// `step(actions, reset, out)`, then a task's rewards and observations of every row, as
    /// `task_reward(hover, out's position, attitude, touched, crashed, battery, targets,
    /// count, index, steps, prev, hold_yaw, radius, max_steps, live)` followed by
    /// `task_observe(hover, keys, out, targets, count, index, hold_yaw, lo, hi, obs)` give,
    /// bit for bit — worked out by the stepping threads, each world's rows as soon as they
    /// are written. Returns what `task_reward` returns; `index`, `steps`, `prev` and `obs`
    /// are written in place.
    #[pyo3(signature = (actions, reset, out, obs, hover, keys, targets, count, index, steps, prev, hold_yaw, radius, max_steps, live, lo, hi))]
    #[allow(clippy::too_many_arguments)]
    fn step_task<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyReadonlyArray2<'py, f64>,
        reset: Option<StepReset<'_>>,
        out: &Bound<'_, PyDict>,
        obs: &Bound<'py, PyAny>,
        hover: bool,
        keys: Vec<String>,
        targets: PyReadonlyArray3<'py, f64>,
        count: PyReadonlyArray1<'py, i64>,
        mut index: PyReadwriteArray1<'py, i64>,
        mut steps: PyReadwriteArray1<'py, i64>,
        mut prev: PyReadwriteArray1<'py, f64>,
        hold_yaw: PyReadonlyArray1<'py, f64>,
        radius: f64,
        max_steps: i64,
        live: PyReadonlyArray1<'py, bool>,
        lo: PyReadonlyArray1<'py, f64>,
        hi: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<tasks::Rewards<'py>> {
        self.get().wake();
        let actions = self.actions(&actions)?;
        let resets = self.step_resets(reset)?;
        let mut windows = self.windows(out, "step_task: out")?;
        let rows = windows.rows();
        let lengths = rows.floats().map(<[f64]>::len);
        let arrays = tasks::TaskArrays {
            hover,
            keys: &keys,
            targets: &targets,
            count: &count,
            index: &mut index,
            steps: &mut steps,
            prev: &mut prev,
            hold_yaw: &hold_yaw,
            radius,
            max_steps,
            live: &live,
            lo: &lo,
            hi: &hi,
            obs,
        };
        let inner = self.get();
        let n = inner.len();
        tasks::step_task(py, arrays, n, lengths, |pass, outputs| {
            let resets = resets.entries();
            py.detach(|| inner.step(Some(&actions), &resets, Some(rows), Some((pass, outputs))))
                .map_err(PyErr::from)
        })
    }

    /// Every UAV's observation as a dict of numpy arrays with one row per UAV:
    /// position, velocity, attitude, angular_velocity (n, 3), sonar (n, 10), laser (n, 228),
    /// battery (n, 1), time (n, 1), touched (n,) bool.
    fn observe<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let obs = self.get().observe();
        to_dict(py, obs)
    }

    /// `observe()` written into the arrays of `out` (a dict as `observe()` returns, such as
    /// its first result kept): every key `observe()` gives must be there, a writable
    /// C-contiguous array of the same shape and dtype (float64; bool for touched and
    /// crashed). No array is made: the caller owns the memory and it is overwritten on each
    /// call. Extra keys are left alone.
    fn observe_into(&mut self, out: &Bound<'_, PyDict>) -> PyResult<()> {
        let mut windows = self.windows(out, "observe_into")?;
        self.get().write(windows.rows());
        Ok(())
    }

    /// Every UAV's camera picture (the batch needs `camera=(width, height)`): a dict with
    /// `rgb` uint8 `(n, height, width, 3)` and/or `depth` float32 `(n, height, width, 1)`
    /// (metres, 100 where nothing is nearer), rendered now, worlds in parallel.
    #[pyo3(signature = (rgb = true, depth = true))]
    fn images<'py>(
        &mut self,
        py: Python<'py>,
        rgb: bool,
        depth: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let Some((w, h)) = self.get().settings.camera else {
            return Err(PyValueError::new_err(
                "images: the batch has no camera (Batch(..., camera=(width, height)))",
            ));
        };
        let n = self.get().len();
        let inner = self.get();
        let (r, d) = py.detach(|| inner.images(rgb, depth));
        let shape = |c: usize| [n, h as usize, w as usize, c];
        let out = PyDict::new(py);
        if rgb {
            let a = numpy::ndarray::Array4::from_shape_vec(shape(3), r)
                .map_err(|e| PyValueError::new_err(format!("images: {e}")))?;
            out.set_item("rgb", a.into_pyarray(py))?;
        }
        if depth {
            let a = numpy::ndarray::Array4::from_shape_vec(shape(1), d)
                .map_err(|e| PyValueError::new_err(format!("images: {e}")))?;
            out.set_item("depth", a.into_pyarray(py))?;
        }
        Ok(out)
    }

    /// The radio signal between the UAVs of each world, dBm, float64
    /// `(worlds, uavs_per_world, uavs_per_world)` (the WSS's default model: distance and
    /// walls; 0 on the diagonal; below -93 no link).
    fn signals<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let (worlds, per) = (self.get().worlds.len(), self.get().uavs_per_world);
        let a = numpy::ndarray::Array3::from_shape_vec((worlds, per, per), self.get().signals())
            .map_err(|e| PyValueError::new_err(format!("signals: {e}")))?;
        Ok(a.into_pyarray(py).into_any())
    }

    /// The IMU readings of UAV `uav` of world `index` in the last control period, float64
    /// `(k, 7)`: time (s), acceleration x, y, z (m/s², body frame), body rates x, y, z
    /// (rad/s); as many rows as the IMU read (its rate times the period).
    #[pyo3(signature = (index, uav = 0))]
    fn imu_readings<'py>(
        &mut self,
        py: Python<'py>,
        index: usize,
        uav: usize,
    ) -> PyResult<Bound<'py, PyAny>> {
        let rows = self
            .get()
            .worlds
            .get(index)
            .and_then(|w| w.imu_readings(uav))
            .ok_or_else(|| {
                PyValueError::new_err(format!("world {index}, UAV {uav}: out of range"))
            })?
            .to_vec();
        let flat: Vec<f64> = rows.iter().flatten().copied().collect();
        let a = numpy::ndarray::Array2::from_shape_vec((rows.len(), 7), flat)
            .map_err(|e| PyValueError::new_err(format!("imu_readings: {e}")))?;
        Ok(a.into_pyarray(py).into_any())
    }

    /// Simulated seconds of world `index`.
    fn time(&mut self, index: usize) -> PyResult<f64> {
        self.get()
            .worlds
            .get(index)
            .map(WorldSim::time)
            .ok_or_else(|| PyValueError::new_err(format!("world index {index} out of range")))
    }

    /// The map's player starts: `(tag, x, y, z, yaw)`.
    fn start_poses(&mut self) -> Vec<(String, f64, f64, f64, f64)> {
        self.get()
            .settings
            .map
            .starts()
            .iter()
            .map(|s| {
                let [x, y, z] = s.location;
                (s.tag.clone(), x, y, z, s.rotation[2])
            })
            .collect()
    }

    /// The map from above: `(outline [(x, y), ...], z_min, z_max)` per convex shape.
    fn top_view(&mut self) -> Vec<(Vec<[f64; 2]>, f64, f64)> {
        self.get()
            .settings
            .map
            .footprints()
            .into_iter()
            .map(|s| (s.outline, s.z_min, s.z_max))
            .collect()
    }
}

/// One UAV over TCP: `Remote(server, robot, start, period=0.1)`; `start` is x, y, z, yaw.
#[pyclass(name = "Remote", module = "usarsim._core")]
struct PyRemote {
    inner: Option<Remote>,
    server: String,
}

impl PyRemote {
    fn open(&mut self) -> PyResult<&mut Remote> {
        self.inner.as_mut().ok_or_else(|| {
            PyValueError::new_err(format!("server {}: the connection is closed", self.server))
        })
    }
}

#[pymethods]
impl PyRemote {
    #[new]
    #[pyo3(signature = (server, robot, start, period = 0.1))]
    fn new(
        py: Python<'_>,
        server: &str,
        robot: &str,
        start: [f64; 4],
        period: f64,
    ) -> PyResult<Self> {
        if !(period.is_finite() && period > 0.0) {
            return Err(PyValueError::new_err(format!(
                "period: must be a positive number of seconds, got {period}"
            )));
        }
        let remote = py.detach(|| Remote::connect(server, robot, start, period))?;
        Ok(Self {
            inner: Some(remote),
            server: server.to_string(),
        })
    }

    /// Whether the server steps in lockstep with this client (usar-server: yes).
    #[getter]
    fn lockstep(&mut self) -> bool {
        self.inner.as_ref().is_some_and(Remote::is_lockstep)
    }

    /// Sends one normalized command (forward, right, up, yaw in -1..=1) and waits a period.
    fn step(&mut self, py: Python<'_>, action: [f64; 4]) -> PyResult<()> {
        if let Some(j) = action.iter().position(|v| !v.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "action: component {j} is not finite ({})",
                action[j]
            )));
        }
        let action = action.map(|v| v.clamp(-1.0, 1.0));
        let remote = self.open()?;
        let result = py.detach(|| remote.step(action));
        if result.is_err() {
            self.inner = None;
        }
        Ok(result?)
    }

    /// The observation, as `Batch.observe` with one row.
    fn observe<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let obs = self.open()?.observe();
        to_dict(py, obs)
    }

    /// Closes the connection and waits (at most a second) until the server has removed the
    /// robot.
    fn close(&mut self, py: Python<'_>) {
        let inner = self.inner.take();
        py.detach(|| drop(inner));
    }
}

/// The INIT class name for a robot name: `stsAirRobot` -> `USARBot.stsAirRobot`; a name
/// with a package stays as it is (`usar_proto::Init::qualified_class`).
#[pyfunction]
fn qualified_class(robot: &str) -> String {
    usar_proto::Init::qualified_class(robot)
}

/// The Rust core of the `usarsim` package.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyBatch>()?;
    m.add_class::<PyRemote>()?;
    m.add_class::<scenario::PyScenario>()?;
    m.add_function(wrap_pyfunction!(scenario::scenarios, m)?)?;
    m.add_class::<agents::PyCommand>()?;
    m.add_class::<agents::PyState>()?;
    m.add_function(wrap_pyfunction!(agents::fly, m)?)?;
    m.add_function(wrap_pyfunction!(qualified_class, m)?)?;
    m.add_function(wrap_pyfunction!(tasks::stream_draws, m)?)?;
    m.add_function(wrap_pyfunction!(tasks::task_reward, m)?)?;
    m.add_function(wrap_pyfunction!(tasks::task_observe, m)?)?;
    m.add_function(wrap_pyfunction!(tasks::stream_sample, m)?)?;
    m.add_function(wrap_pyfunction!(tasks::hover_spawns, m)?)?;
    m.add("LASER_BEAMS", LASER)?;
    m.add("SONARS", SONARS)?;
    Ok(())
}
