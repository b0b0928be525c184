//! The tasks' per-step arithmetic over every row in one call each: the rewards
//! (`usarsim._task.Tasks.reward`), the observations (`Tasks.observe`), and a reset's random
//! places — Waypoints' waypoints and `start="random"` (`MapInfo.sample_rows`), Hover's spawns
//! (`Tasks.new_starts`) — drawn from each row's stream. Each gives what its Python definition
//! kept in `_task.py` / `_maps.py` gives, bit for bit (the same operations in the same order,
//! in float64; the tests compare them), without the NumPy passes and temporaries: at 1024
//! rows the NumPy rewards and observations took 0.5–0.6 ms of a step, during which the
//! stepping threads wait, and the Python sampling loop 0.3–0.45 s per 1024 Waypoints resets.

use numpy::ndarray::{Array2, Array3, ArrayView1, ArrayView2};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2,
    PyReadonlyArray3, PyReadwriteArray1, PyReadwriteArray2, PyReadwriteArray3,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The streams' increment (`usarsim._task._GOLDEN`).
const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;
/// 2⁻⁵³: a draw's top 53 bits times this is a uniform double in [0, 1).
const UNIT: f64 = 1.0 / 9_007_199_254_740_992.0;

/// The rows' random streams (`usarsim._task.Streams`): each row's key and the draws its
/// stream has made.
struct Streams<'a> {
    keys: &'a [u64],
    drawn: &'a mut [u64],
}

impl<'a> Streams<'a> {
    fn of(
        keys: &'a PyReadonlyArray1<'_, u64>,
        drawn: &'a mut PyReadwriteArray1<'_, u64>,
        what: &str,
    ) -> PyResult<Self> {
        let contiguous = |_| bad(format!("{what}: keys and draw counts must be contiguous"));
        let (keys, drawn) = (
            keys.as_slice().map_err(contiguous)?,
            drawn.as_slice_mut().map_err(contiguous)?,
        );
        if drawn.len() != keys.len() {
            return Err(bad(format!(
                "{what}: {} keys but {} draw counts",
                keys.len(),
                drawn.len()
            )));
        }
        Ok(Self { keys, drawn })
    }

    /// Each of `rows` checked, with the draws its stream had made: all read before any count
    /// moves (a row listed twice draws the same twice, as NumPy's `drawn[rows] += k` counts it
    /// once).
    fn starts(&self, rows: &ArrayView1<'_, i64>, what: &str) -> PyResult<Vec<(usize, u64)>> {
        let n = self.keys.len();
        // A plain loop: collecting the checked rows into a `PyResult<Vec<_>>` cost some 60
        // instructions a row (12 µs for 1024 rows).
        let mut starts = Vec::with_capacity(rows.len());
        for &r in rows {
            match usize::try_from(r) {
                Ok(r) if r < n => starts.push((r, self.drawn[r])),
                _ => return Err(bad(format!("{what}: row {r} is not in 0..{n}"))),
            }
        }
        Ok(starts)
    }

    /// SplitMix64's state for row `r` after `made` draws: the next draws continue from it.
    fn state(&self, r: usize, made: u64) -> u64 {
        self.keys[r].wrapping_add(made.wrapping_mul(GOLDEN))
    }
}

/// A uniform double in [0, 1): the next draw's top 53 bits times 2⁻⁵³ (`Streams.doubles`).
fn uniform(state: &mut u64) -> f64 {
    (usar_sim::splitmix(state) >> 11) as f64 * UNIT
}

/// `usarsim._task.Streams.draw`: `k` 64-bit draws from the stream of each of `rows`, shape
/// `(len(rows), k)`: SplitMix64 from `keys[row] + drawn[row] * golden` (the `drawn[row]`
/// draws made so far), the golden-ratio increment once per draw; then `drawn[row] += k` (once
/// per row, as NumPy's `drawn[rows] += k` does when a row repeats). What the NumPy expression
/// gives, bit for bit, without its dozen temporary arrays (a vector env's autoreset draws for
/// every resetting row).
#[pyfunction]
pub(crate) fn stream_draws<'py>(
    py: Python<'py>,
    keys: PyReadonlyArray1<'py, u64>,
    mut drawn: PyReadwriteArray1<'py, u64>,
    rows: PyReadonlyArray1<'py, i64>,
    k: usize,
) -> PyResult<Bound<'py, PyArray2<u64>>> {
    let streams = Streams::of(&keys, &mut drawn, "stream_draws")?;
    let starts = streams.starts(&rows.as_array(), "stream_draws")?;
    let mut out = vec![0u64; starts.len() * k];
    if k > 0 {
        for (row, &(r, made)) in out.chunks_exact_mut(k).zip(&starts) {
            let mut state = streams.state(r, made);
            row.iter_mut()
                .for_each(|v| *v = usar_sim::splitmix(&mut state));
            streams.drawn[r] = made.wrapping_add(k as u64);
        }
    }
    let rows = starts.len();
    Ok(Array2::from_shape_vec((rows, k), out)
        .map_err(|e| bad(format!("stream_draws: {e}")))?
        .into_pyarray(py))
}

/// Reward per waypoint reached (`_task.WAYPOINT_BONUS`).
const WAYPOINT_BONUS: f64 = 10.0;
/// Reward per period with a touch (`_task.TOUCH_PENALTY`).
const TOUCH_PENALTY: f64 = 1.0;
/// Reward of a crash (`_task.CRASH_PENALTY`).
const CRASH_PENALTY: f64 = 100.0;

fn bad(what: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(what.to_string())
}

/// `_task._wrap` of one angle: `(x + pi) % (2 pi) - pi` as `fmod` plus 2 pi on a negative
/// remainder gives it.
fn wrap(x: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let shifted = x + PI;
    // fmod without the call where it is exact arithmetic: a value in (-2 pi, 2 pi) is its
    // own remainder, and one in [2 pi, 4 pi) less 2 pi is exact (Sterbenz).
    let mut out = if shifted > -TAU && shifted < TAU {
        shifted
    } else if (TAU..2.0 * TAU).contains(&shifted) {
        shifted - TAU
    } else {
        shifted % TAU
    };
    if out < 0.0 {
        out += TAU;
    }
    out - PI
}

/// `_task._lengths` of one row: the squares summed left to right, as `np.add.reduce` does
/// over three values.
fn length(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `np.clip` of one float64: NaN stays NaN, and the bounds are compared as NumPy does
/// (`max(x, lo)` is `lo` unless `x > lo`, so -0 clipped at 0 is +0).
fn clip(x: f64, lo: f64, hi: f64) -> f64 {
    // `lo >= x` is false for a NaN x, as `x > lo` is true just when `lo >= x` is false
    // otherwise: the same as `if x.is_nan() || x > lo { x } else { lo }`, without a branch.
    let x = if lo >= x { lo } else { x };
    if hi <= x { hi } else { x }
}

/// The rows' targets and how many each has, shared by both calls: C-ordered values, `slots`
/// targets of three a row.
#[derive(Clone, Copy)]
struct Targets<'a> {
    targets: &'a [f64],
    slots: usize,
    count: &'a [i64],
}

impl<'a> Targets<'a> {
    /// The targets `(n, slots, 3)` and counts `(n,)` of `n` rows, checked with every row's
    /// target `index`.
    fn of(
        targets: &'a PyReadonlyArray3<'_, f64>,
        count: &'a PyReadonlyArray1<'_, i64>,
        n: usize,
        index: &[i64],
    ) -> PyResult<Self> {
        let (rows, slots, three) = targets.as_array().dim();
        if rows != n || three != 3 || count.len() != n || index.len() != n {
            return Err(bad(format!(
                "tasks: targets {:?}, count {}, index {} for {n} rows",
                targets.shape(),
                count.len(),
                index.len()
            )));
        }
        let t = Self {
            targets: targets
                .as_slice()
                .map_err(|_| bad("tasks: targets: not C-contiguous"))?,
            slots,
            count: count
                .as_slice()
                .map_err(|_| bad("tasks: count: not contiguous"))?,
        };
        for (i, (&c, &k)) in t.count.iter().zip(index).enumerate() {
            if c < 1 || c as usize > slots || k < 0 {
                return Err(bad(format!(
                    "tasks: row {i}: {c} waypoints of {slots} slots, index {k}"
                )));
            }
        }
        Ok(t)
    }

    /// `Tasks._vector` of row `i`: its current target minus its position `p` (the row's
    /// three values).
    #[inline(always)]
    fn vector(&self, i: usize, p: &[f64], index: i64) -> [f64; 3] {
        let j = index.min(self.count[i] - 1) as usize;
        let at = (i * self.slots + j) * 3;
        let t = &self.targets[at..at + 3];
        [t[0] - p[0], t[1] - p[1], t[2] - p[2]]
    }
}

/// The values of a contiguous array of `n` rows of `width`, named in the error.
fn slice2<'a>(
    a: &'a PyReadonlyArray2<'_, f64>,
    n: usize,
    width: usize,
    name: &str,
) -> PyResult<&'a [f64]> {
    contiguous(&rows2(a, n, width, name)?, name)
}

/// The values of a contiguous array of `n` values, named in the error.
fn slice1<'a, T: numpy::Element>(
    a: &'a PyReadonlyArray1<'_, T>,
    n: usize,
    name: &str,
) -> PyResult<&'a [T]> {
    rows1(a, n, name)?;
    a.as_slice()
        .map_err(|_| bad(format!("tasks: {name}: not contiguous")))
}

fn rows2<'a>(
    a: &'a PyReadonlyArray2<'_, f64>,
    n: usize,
    width: usize,
    name: &str,
) -> PyResult<ArrayView2<'a, f64>> {
    let v = a.as_array();
    if v.dim() != (n, width) {
        return Err(bad(format!(
            "tasks: {name}: shape {:?}, expected ({n}, {width})",
            v.shape()
        )));
    }
    Ok(v)
}

fn rows1<'a, T: numpy::Element>(
    a: &'a PyReadonlyArray1<'_, T>,
    n: usize,
    name: &str,
) -> PyResult<ArrayView1<'a, T>> {
    let v = a.as_array();
    if v.len() != n {
        return Err(bad(format!(
            "tasks: {name}: {} rows, expected {n}",
            v.len()
        )));
    }
    Ok(v)
}

/// The values of a C-ordered array, row after row.
fn contiguous<'a>(a: &ArrayView2<'a, f64>, name: &str) -> PyResult<&'a [f64]> {
    a.to_slice()
        .ok_or_else(|| bad(format!("tasks: raw {name:?}: not C-contiguous")))
}

/// The task state a reward updates (`index`, `steps`, `prev`), checked: contiguous, `n` rows.
type TaskState<'a> = (&'a mut [i64], &'a mut [i64], &'a mut [f64]);

fn task_state<'a>(
    index: &'a mut PyReadwriteArray1<'_, i64>,
    steps: &'a mut PyReadwriteArray1<'_, i64>,
    prev: &'a mut PyReadwriteArray1<'_, f64>,
    n: usize,
) -> PyResult<TaskState<'a>> {
    let (Ok(index), Ok(steps), Ok(prev)) = (
        index.as_slice_mut(),
        steps.as_slice_mut(),
        prev.as_slice_mut(),
    ) else {
        return Err(bad("tasks: index, steps and prev: not contiguous"));
    };
    if index.len() != n || steps.len() != n || prev.len() != n {
        return Err(bad(format!("tasks: index, steps and prev need {n} rows")));
    }
    Ok((index, steps, prev))
}

pub(crate) type Rewards<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
);

/// `Tasks.reward`'s arithmetic: returns (reward, terminated, truncated, touched, crashed,
/// reached) and updates `index`, `steps` and `prev` in place (see `Tasks.reward`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub(crate) fn task_reward<'py>(
    py: Python<'py>,
    hover: bool,
    position: PyReadonlyArray2<'py, f64>,
    attitude: PyReadonlyArray2<'py, f64>,
    touched: PyReadonlyArray1<'py, bool>,
    crashed: PyReadonlyArray1<'py, bool>,
    battery: PyReadonlyArray2<'py, f64>,
    targets: PyReadonlyArray3<'py, f64>,
    count: PyReadonlyArray1<'py, i64>,
    mut index: PyReadwriteArray1<'py, i64>,
    mut steps: PyReadwriteArray1<'py, i64>,
    mut prev: PyReadwriteArray1<'py, f64>,
    hold_yaw: PyReadonlyArray1<'py, f64>,
    radius: f64,
    max_steps: i64,
    live: PyReadonlyArray1<'py, bool>,
) -> PyResult<Rewards<'py>> {
    let n = position.as_array().nrows();
    let position = slice2(&position, n, 3, "position")?;
    let attitude = slice2(&attitude, n, 3, "attitude")?;
    let battery = slice2(&battery, n, 1, "battery")?;
    let (touched, crashed) = (
        slice1(&touched, n, "touched")?,
        slice1(&crashed, n, "crashed")?,
    );
    let (hold_yaw, live) = (slice1(&hold_yaw, n, "hold_yaw")?, slice1(&live, n, "live")?);
    let (index, steps, prev) = task_state(&mut index, &mut steps, &mut prev, n)?;
    let r = Reward {
        hover,
        targets: Targets::of(&targets, &count, n, index)?,
        hold_yaw,
        live,
        radius,
        max_steps,
    };
    let mut out = RewardRows::new(n);
    {
        let mut rows = out.rows(index, steps, prev);
        for i in 0..n {
            let raw = RawRow::at(i, position, attitude, touched, crashed, battery);
            r.row(i, i, &raw, &mut rows);
        }
    }
    Ok(out.into_arrays(py))
}

/// What a task's reward of a row reads besides the row's raw observation (`Tasks.reward`).
struct Reward<'a> {
    hover: bool,
    targets: Targets<'a>,
    hold_yaw: &'a [f64],
    /// Rows not reset in this step (every row's).
    live: &'a [bool],
    radius: f64,
    max_steps: i64,
}

/// The raw values of one row a reward reads.
struct RawRow<'a> {
    position: &'a [f64],
    yaw: f64,
    touched: bool,
    crashed: bool,
    battery: f64,
}

impl<'a> RawRow<'a> {
    /// Row `j` of the raw arrays (C order: three values a row for `position` and
    /// `attitude`, one for the others).
    #[inline(always)]
    fn at(
        j: usize,
        position: &'a [f64],
        attitude: &[f64],
        touched: &[bool],
        crashed: &[bool],
        battery: &[f64],
    ) -> Self {
        Self {
            position: &position[3 * j..3 * j + 3],
            yaw: attitude[3 * j + 2],
            touched: touched[j],
            crashed: crashed[j],
            battery: battery[j],
        }
    }
}

/// Some rows' reward outputs, and the task state a reward updates (`index`, `steps`,
/// `prev`), all indexed from the same first row.
pub(crate) struct RewardOut<'a> {
    index: &'a mut [i64],
    steps: &'a mut [i64],
    prev: &'a mut [f64],
    reward: &'a mut [f64],
    terminated: &'a mut [bool],
    truncated: &'a mut [bool],
    touched: &'a mut [bool],
    crashed: &'a mut [bool],
    reached: &'a mut [bool],
}

impl Reward<'_> {
    /// Row `i`'s reward (`j`: its index in `out`) from its raw values: what the loop of
    /// `Tasks._reward_numpy` gives for the row, bit for bit.
    #[inline(always)]
    fn row(&self, i: usize, j: usize, raw: &RawRow<'_>, out: &mut RewardOut<'_>) {
        let live = self.live[i];
        out.steps[j] += i64::from(live);
        let touch = if raw.touched { TOUCH_PENALTY } else { 0.0 };
        let k = out.index[j];
        let t = &self.targets;
        let mut dist = length(t.vector(i, raw.position, k));
        let mut reached = false;
        let (mut r, mut end, next) = if self.hover {
            let yaw = wrap(raw.yaw - self.hold_yaw[i]).abs();
            (-dist - 0.2 * yaw - touch, false, k)
        } else {
            let r = out.prev[j] - dist - touch;
            reached = dist < self.radius && live;
            let next = k + i64::from(reached);
            let r = r + if reached { WAYPOINT_BONUS } else { 0.0 };
            dist = length(t.vector(i, raw.position, next));
            (r, next >= t.count[i], next)
        };
        out.prev[j] = dist;
        r -= if raw.crashed { CRASH_PENALTY } else { 0.0 };
        end = (end || raw.crashed) && live;
        out.truncated[j] = live && !end && (out.steps[j] >= self.max_steps || raw.battery <= 0.0);
        out.terminated[j] = end;
        out.reward[j] = if live { r } else { 0.0 };
        out.index[j] = next;
        out.reached[j] = reached;
        out.touched[j] = raw.touched && live;
        out.crashed[j] = raw.crashed && live;
    }
}

/// The reward arrays of `n` rows, filled through [`RewardRows::rows`].
pub(crate) struct RewardRows {
    reward: Vec<f64>,
    flags: [Vec<bool>; 5],
}

impl RewardRows {
    pub(crate) fn new(n: usize) -> Self {
        Self {
            reward: vec![0.0; n],
            flags: std::array::from_fn(|_| vec![false; n]),
        }
    }

    /// Every row's outputs, with the task state a reward updates.
    pub(crate) fn rows<'a>(
        &'a mut self,
        index: &'a mut [i64],
        steps: &'a mut [i64],
        prev: &'a mut [f64],
    ) -> RewardOut<'a> {
        let [terminated, truncated, touched, crashed, reached] =
            self.flags.each_mut().map(Vec::as_mut_slice);
        RewardOut {
            index,
            steps,
            prev,
            reward: &mut self.reward,
            terminated,
            truncated,
            touched,
            crashed,
            reached,
        }
    }

    /// (reward, terminated, truncated, touched, crashed, reached) for Python.
    pub(crate) fn into_arrays(self, py: Python<'_>) -> Rewards<'_> {
        let [terminated, truncated, touched, crashed, reached] = self.flags;
        (
            self.reward.into_pyarray(py),
            terminated.into_pyarray(py),
            truncated.into_pyarray(py),
            touched.into_pyarray(py),
            crashed.into_pyarray(py),
            reached.into_pyarray(py),
        )
    }
}

impl<'a> RewardOut<'a> {
    /// Cut into `n` pieces of `per` rows each (the last one shorter).
    fn split(self, per: usize, n: usize) -> Vec<Self> {
        let mut index = self.index.chunks_mut(per);
        let mut steps = self.steps.chunks_mut(per);
        let mut prev = self.prev.chunks_mut(per);
        let mut reward = self.reward.chunks_mut(per);
        let mut terminated = self.terminated.chunks_mut(per);
        let mut truncated = self.truncated.chunks_mut(per);
        let mut touched = self.touched.chunks_mut(per);
        let mut crashed = self.crashed.chunks_mut(per);
        let mut reached = self.reached.chunks_mut(per);
        (0..n)
            .map(|_| RewardOut {
                index: index.next().unwrap_or_default(),
                steps: steps.next().unwrap_or_default(),
                prev: prev.next().unwrap_or_default(),
                reward: reward.next().unwrap_or_default(),
                terminated: terminated.next().unwrap_or_default(),
                truncated: truncated.next().unwrap_or_default(),
                touched: touched.next().unwrap_or_default(),
                crashed: crashed.next().unwrap_or_default(),
                reached: reached.next().unwrap_or_default(),
            })
            .collect()
    }
}

/// Where the columns of one observation key come from.
#[derive(Clone, Copy)]
enum Source {
    /// Raw array `k` (C order), as it is.
    Raw(usize),
    /// The raw attitude (C order), wrapped.
    Attitude,
    /// The vector to the current target.
    Waypoint,
    /// Hover: the yaw to hold minus the yaw, wrapped; Waypoints: 0.
    YawError,
}

/// A task's observation of a row (`Tasks.observe`): each key's columns, in order, from raw
/// arrays (C order, rows of their width) — `raws[position]` and `raws[attitude]` among them.
struct Observe<'a> {
    hover: bool,
    sources: Vec<(Source, usize)>,
    position: usize,
    attitude: usize,
    targets: Targets<'a>,
    hold_yaw: &'a [f64],
    /// One bound per column.
    lo: &'a [f64],
    hi: &'a [f64],
}

impl<'a> Observe<'a> {
    /// The observation of `keys` (`raw(key)`: the index of the key's raw array and its
    /// width, `None` when there is none), checked against the bounds.
    #[allow(clippy::too_many_arguments)]
    fn of(
        hover: bool,
        keys: &[String],
        mut raw: impl FnMut(&str) -> PyResult<(usize, usize)>,
        targets: Targets<'a>,
        hold_yaw: &'a [f64],
        lo: &'a [f64],
        hi: &'a [f64],
    ) -> PyResult<Self> {
        let (position, _) = raw("position")?;
        let (attitude, _) = raw("attitude")?;
        let sources = keys
            .iter()
            .map(|k| match k.as_str() {
                "attitude" => Ok((Source::Attitude, 3)),
                "waypoint" => Ok((Source::Waypoint, 3)),
                "yaw_error" => Ok((Source::YawError, 1)),
                k => raw(k).map(|(a, w)| (Source::Raw(a), w)),
            })
            .collect::<PyResult<Vec<_>>>()?;
        let columns = sources.iter().map(|(_, w)| w).sum::<usize>();
        if lo.len() != columns || hi.len() != columns {
            return Err(bad(format!(
                "tasks: {} low and {} high bounds for {columns} columns",
                lo.len(),
                hi.len()
            )));
        }
        Ok(Self {
            hover,
            sources,
            position,
            attitude,
            targets,
            hold_yaw,
            lo,
            hi,
        })
    }

    fn columns(&self) -> usize {
        self.lo.len()
    }

    /// Row `i`'s values, every column clipped, in `buf`: row `j` of `raws` (C order, rows
    /// of each array's width), its target `index`.
    #[inline(always)]
    fn fill(&self, raws: &[&[f64]], i: usize, j: usize, index: i64, buf: &mut [f64]) {
        let mut at = 0;
        for &(s, w) in &self.sources {
            let b = &mut buf[at..at + w];
            match s {
                Source::Raw(a) => b.copy_from_slice(&raws[a][j * w..(j + 1) * w]),
                Source::Attitude => b
                    .iter_mut()
                    .zip(&raws[self.attitude][3 * j..3 * j + 3])
                    .for_each(|(b, v)| *b = wrap(*v)),
                Source::Waypoint => {
                    let p = &raws[self.position][3 * j..3 * j + 3];
                    b.copy_from_slice(&self.targets.vector(i, p, index));
                }
                Source::YawError if self.hover => {
                    b[0] = wrap(self.hold_yaw[i] - raws[self.attitude][3 * j + 2]);
                }
                Source::YawError => b[0] = 0.0,
            }
            at += w;
        }
        for ((b, lo), hi) in buf.iter_mut().zip(self.lo).zip(self.hi) {
            *b = clip(*b, *lo, *hi);
        }
    }

    /// [`Observe::fill`] written as float32 into row `j` of `dests` (each a C-ordered
    /// array of its width: one of every column, or one per key).
    #[inline(always)]
    fn write(
        &self,
        raws: &[&[f64]],
        i: usize,
        j: usize,
        index: i64,
        buf: &mut [f64],
        dests: &mut [(&mut [f32], usize)],
    ) {
        self.fill(raws, i, j, index, buf);
        let mut at = 0;
        for (dest, w) in dests {
            let w = *w;
            dest[j * w..(j + 1) * w]
                .iter_mut()
                .zip(&buf[at..at + w])
                .for_each(|(d, v)| *d = *v as f32);
            at += w;
        }
    }
}

/// The observation's output arrays `out`, checked (writable, C-contiguous, `n` rows): one
/// float32 `(n, columns)` array (flat: `true`) or a dict of one `(n, width)` array per key,
/// each with its width.
#[allow(clippy::type_complexity)]
fn obs_arrays<'py>(
    out: &Bound<'py, PyAny>,
    keys: &[String],
    o: &Observe<'_>,
    n: usize,
) -> PyResult<(Vec<(PyReadwriteArray2<'py, f32>, usize)>, bool)> {
    let mut arrays = Vec::with_capacity(keys.len());
    let flat = if let Ok(flat) = out.extract::<PyReadwriteArray2<'py, f32>>() {
        arrays.push((flat, o.columns(), "out".to_string()));
        true
    } else {
        let dict = out.cast::<PyDict>().map_err(|_| {
            bad("tasks: out: expected a float32 (n, columns) array or a dict of them")
        })?;
        for (k, (_, w)) in keys.iter().zip(&o.sources) {
            let array = dict
                .get_item(k)?
                .ok_or_else(|| bad(format!("tasks: out has no {k:?}")))?
                .extract::<PyReadwriteArray2<'py, f32>>()
                .map_err(|e| {
                    bad(format!(
                        "tasks: out[{k:?}]: not a writable 2-D float32 array: {e}"
                    ))
                })?;
            arrays.push((array, *w, format!("out[{k:?}]")));
        }
        false
    };
    for (array, w, name) in &arrays {
        if array.as_array().dim() != (n, *w) || !array.is_c_contiguous() {
            return Err(bad(format!(
                "tasks: {name}: shape {:?}, expected a C-contiguous ({n}, {w})",
                array.shape()
            )));
        }
    }
    Ok((arrays.into_iter().map(|(a, w, _)| (a, w)).collect(), flat))
}

/// `Tasks.observe`'s arithmetic: the observation of every row, each key's columns in
/// `keys`' order, clipped to `lo` and `hi` (one bound per column, float64) and rounded to
/// float32, written into `out`: one float32 array `(n, columns)` (flat) or a dict of one
/// `(n, width)` float32 array per key.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub(crate) fn task_observe(
    hover: bool,
    keys: Vec<String>,
    raw: &Bound<'_, PyDict>,
    targets: PyReadonlyArray3<'_, f64>,
    count: PyReadonlyArray1<'_, i64>,
    index: PyReadonlyArray1<'_, i64>,
    hold_yaw: PyReadonlyArray1<'_, f64>,
    lo: PyReadonlyArray1<'_, f64>,
    hi: PyReadonlyArray1<'_, f64>,
    out: &Bound<'_, PyAny>,
) -> PyResult<()> {
    let item = |k: &str| -> PyResult<PyReadonlyArray2<'_, f64>> {
        raw.get_item(k)?
            .ok_or_else(|| bad(format!("tasks: the raw observation has no {k:?}")))?
            .extract()
            .map_err(|e| bad(format!("tasks: raw {k:?}: not a 2-D float64 array: {e}")))
    };
    let position = item("position")?;
    let n = position.as_array().nrows();
    let hold_yaw = slice1(&hold_yaw, n, "hold_yaw")?;
    let index = index
        .as_slice()
        .map_err(|_| bad("tasks: index: not contiguous"))?;
    let t = Targets::of(&targets, &count, n, index)?;
    // The raw arrays the keys read (position and attitude first), then their values.
    let mut names = vec!["position", "attitude"];
    names.extend(
        keys.iter()
            .map(String::as_str)
            .filter(|k| !["position", "attitude", "waypoint", "yaw_error"].contains(k)),
    );
    let arrays = names
        .iter()
        .map(|k| item(k))
        .collect::<PyResult<Vec<_>>>()?;
    let mut raws = Vec::with_capacity(arrays.len());
    let mut widths = Vec::with_capacity(arrays.len());
    for (k, a) in names.iter().zip(&arrays) {
        let a = a.as_array();
        if a.nrows() != n {
            return Err(bad(format!(
                "tasks: raw {k:?}: {} rows, expected {n}",
                a.nrows()
            )));
        }
        if ["position", "attitude"].contains(k) && a.ncols() != 3 {
            return Err(bad(format!(
                "tasks: raw {k:?}: shape {:?}, expected ({n}, 3)",
                a.shape()
            )));
        }
        raws.push(contiguous(&a, k)?);
        widths.push(a.ncols());
    }
    let find = |k: &str| {
        let a = names
            .iter()
            .position(|name| *name == k)
            .expect("listed above");
        Ok((a, widths[a]))
    };
    let o = Observe::of(
        hover,
        &keys,
        find,
        t,
        hold_yaw,
        lo.as_slice()?,
        hi.as_slice()?,
    )?;
    let columns = o.columns();
    let mut buf = vec![0.0; columns];
    let (mut arrays, flat) = obs_arrays(out, &keys, &o, n)?;
    if flat {
        let dest = arrays[0].0.as_slice_mut()?;
        if columns == 0 {
            return Ok(());
        }
        // Key after key, each over every row: no dispatch per row and value (what `fill`
        // gives, bit for bit, written column by column).
        let (position, attitude) = (raws[o.position], raws[o.attitude]);
        let mut at = 0;
        for &(s, w) in &o.sources {
            let bounds = (&o.lo[at..at + w], &o.hi[at..at + w]);
            let put = |dest: &mut [f32], value: &dyn Fn(usize, usize) -> f64| {
                put_columns(dest, columns, at, bounds, value);
            };
            match s {
                Source::Raw(a) if w == 3 => {
                    let a = raws[a];
                    put_columns3(dest, columns, at, bounds, |i, k| a[3 * i + k])
                }
                Source::Raw(a) if w == 1 => {
                    let a = raws[a];
                    put_columns1(dest, columns, at, bounds, |i| a[i])
                }
                Source::Raw(a) => {
                    let a = raws[a];
                    put(dest, &|i, k| a[w * i + k])
                }
                Source::Attitude => {
                    put_columns3(dest, columns, at, bounds, |i, k| wrap(attitude[3 * i + k]))
                }
                Source::Waypoint => {
                    for (i, row) in dest.chunks_exact_mut(columns).enumerate() {
                        let v = t.vector(i, &position[3 * i..3 * i + 3], index[i]);
                        for k in 0..3 {
                            row[at + k] = clip(v[k], bounds.0[k], bounds.1[k]) as f32;
                        }
                    }
                }
                Source::YawError if hover => {
                    put_columns1(dest, columns, at, bounds, |i| {
                        wrap(hold_yaw[i] - attitude[3 * i + 2])
                    });
                }
                Source::YawError => put_columns1(dest, columns, at, bounds, |_| 0.0),
            }
            at += w;
        }
        return Ok(());
    }
    let mut dests: Vec<_> = arrays
        .iter_mut()
        .map(|(a, w)| (a.as_slice_mut().unwrap_or_default(), *w))
        .collect();
    for (i, &k) in index.iter().enumerate() {
        o.write(&raws, i, i, k, &mut buf, &mut dests);
    }
    Ok(())
}

/// A task's rewards and observations worked out by the stepping threads
/// ([`crate::core::Batch::step`] with a task): each world's rows right after it writes its
/// raw observation, while they are in its thread's caches — what `task_reward` then
/// `task_observe` give over every row after the step, bit for bit.
pub(crate) struct TaskPass<'a> {
    reward: Reward<'a>,
    observe: Observe<'a>,
    /// The battery's raw field ([`crate::FIELDS`]' index).
    battery: usize,
}

/// A task's outputs of every row of a step: its rewards (with the task state they update)
/// and its observation's arrays ([`TaskPass::pieces`]).
pub(crate) type TaskOut<'a> = (RewardOut<'a>, Vec<(&'a mut [f32], usize)>);

/// The outputs of one piece of rows of a [`TaskPass`], from row `first` on.
pub(crate) struct TaskPiece<'a> {
    first: usize,
    reward: RewardOut<'a>,
    /// The observation's arrays: one of every column (flat), or one per key, each with its
    /// width.
    obs: Vec<(&'a mut [f32], usize)>,
    /// One row's values (a row of every column).
    buf: Vec<f64>,
}

impl<'a> TaskPass<'a> {
    /// `out` and `obs` (all `n` rows) cut into `n` pieces of `per` rows.
    pub(crate) fn pieces(
        &self,
        out: RewardOut<'a>,
        obs: Vec<(&'a mut [f32], usize)>,
        per: usize,
        n: usize,
    ) -> Vec<TaskPiece<'a>> {
        let mut obs: Vec<_> = obs
            .into_iter()
            .map(|(a, w)| (a.chunks_mut(per * w.max(1)), w))
            .collect();
        out.split(per, n)
            .into_iter()
            .enumerate()
            .map(|(p, reward)| TaskPiece {
                first: p * per,
                reward,
                obs: obs
                    .iter_mut()
                    .map(|(a, w)| (a.next().unwrap_or_default(), *w))
                    .collect(),
                buf: vec![0.0; self.observe.columns()],
            })
            .collect()
    }

    /// Rows `from..to` of `piece`, from the same rows of the piece's raw observation, written:
    /// its float fields `raws` (in [`crate::FIELDS`]' order), `touched` and `crashed`.
    pub(crate) fn rows(
        &self,
        piece: &mut TaskPiece<'_>,
        (raws, touched, crashed): (&[&[f64]; 9], &[bool], &[bool]),
        from: usize,
        to: usize,
    ) {
        let (position, attitude) = (raws[self.observe.position], raws[self.observe.attitude]);
        let battery = raws[self.battery];
        for j in from..to {
            let i = piece.first + j;
            let row = RawRow::at(j, position, attitude, touched, crashed, battery);
            self.reward.row(i, j, &row, &mut piece.reward);
            let index = piece.reward.index[j];
            self.observe
                .write(raws, i, j, index, &mut piece.buf, &mut piece.obs);
        }
    }
}

/// A task's arrays for `Batch.step_task` (see there), as Python passes them.
pub(crate) struct TaskArrays<'a, 'py> {
    pub(crate) hover: bool,
    pub(crate) keys: &'a [String],
    pub(crate) targets: &'a PyReadonlyArray3<'py, f64>,
    pub(crate) count: &'a PyReadonlyArray1<'py, i64>,
    pub(crate) index: &'a mut PyReadwriteArray1<'py, i64>,
    pub(crate) steps: &'a mut PyReadwriteArray1<'py, i64>,
    pub(crate) prev: &'a mut PyReadwriteArray1<'py, f64>,
    pub(crate) hold_yaw: &'a PyReadonlyArray1<'py, f64>,
    pub(crate) radius: f64,
    pub(crate) max_steps: i64,
    pub(crate) live: &'a PyReadonlyArray1<'py, bool>,
    pub(crate) lo: &'a PyReadonlyArray1<'py, f64>,
    pub(crate) hi: &'a PyReadonlyArray1<'py, f64>,
    /// The observation's float32 array `(n, columns)` or dict of `(n, width)` arrays.
    pub(crate) obs: &'a Bound<'py, PyAny>,
}

/// The task of `a`, checked for a batch of `n` UAVs with `lengths[k]` values in each raw
/// field (in [`crate::FIELDS`]' order), handed as a [`TaskPass`] and its outputs to `step`
/// (which steps the batch with them); returns the rewards as `task_reward` does.
pub(crate) fn step_task<'py>(
    py: Python<'py>,
    a: TaskArrays<'_, 'py>,
    n: usize,
    lengths: [usize; 9],
    step: impl FnOnce(&TaskPass<'_>, TaskOut<'_>) -> PyResult<()>,
) -> PyResult<Rewards<'py>> {
    let (hold_yaw, live) = (
        slice1(a.hold_yaw, n, "hold_yaw")?,
        slice1(a.live, n, "live")?,
    );
    let (index, steps, prev) = task_state(a.index, a.steps, a.prev, n)?;
    let targets = Targets::of(a.targets, a.count, n, index)?;
    let field = |k: &str| {
        let found = crate::FIELDS.iter().position(|(name, _)| *name == k);
        match found {
            Some(f) if lengths[f] == n * crate::FIELDS[f].1 => Ok((f, crate::FIELDS[f].1)),
            _ => Err(bad(format!("tasks: the batch does not observe {k:?}"))),
        }
    };
    let (lo, hi) = (a.lo.as_slice()?, a.hi.as_slice()?);
    let observe = Observe::of(a.hover, a.keys, field, targets, hold_yaw, lo, hi)?;
    let (mut arrays, _) = obs_arrays(a.obs, a.keys, &observe, n)?;
    let obs = arrays
        .iter_mut()
        .map(|(array, w)| (array.as_slice_mut().unwrap_or_default(), *w))
        .collect();
    let reward = Reward {
        hover: a.hover,
        targets,
        hold_yaw,
        live,
        radius: a.radius,
        max_steps: a.max_steps,
    };
    let (battery, _) = field("battery")?;
    let pass = TaskPass {
        reward,
        observe,
        battery,
    };
    let mut rewards = RewardRows::new(n);
    step(&pass, (rewards.rows(index, steps, prev), obs))?;
    Ok(rewards.into_arrays(py))
}

/// One key's columns `at..` (their bounds `lo`, `hi`) of every row of the flat float32
/// `dest` (`columns` a row): `value(row, k)` clipped and rounded.
fn put_columns(
    dest: &mut [f32],
    columns: usize,
    at: usize,
    (lo, hi): (&[f64], &[f64]),
    value: &dyn Fn(usize, usize) -> f64,
) {
    for (i, row) in dest.chunks_exact_mut(columns).enumerate() {
        for (k, d) in row[at..at + lo.len()].iter_mut().enumerate() {
            *d = clip(value(i, k), lo[k], hi[k]) as f32;
        }
    }
}

/// [`put_columns`] of a key three columns wide, inlined.
#[inline(always)]
fn put_columns3(
    dest: &mut [f32],
    columns: usize,
    at: usize,
    (lo, hi): (&[f64], &[f64]),
    value: impl Fn(usize, usize) -> f64,
) {
    let (lo, hi) = (&lo[..3], &hi[..3]);
    for (i, row) in dest.chunks_exact_mut(columns).enumerate() {
        let row = &mut row[at..at + 3];
        for k in 0..3 {
            row[k] = clip(value(i, k), lo[k], hi[k]) as f32;
        }
    }
}

/// [`put_columns`] of a key one column wide, inlined.
#[inline(always)]
fn put_columns1(
    dest: &mut [f32],
    columns: usize,
    at: usize,
    (lo, hi): (&[f64], &[f64]),
    value: impl Fn(usize) -> f64,
) {
    let (lo, hi) = (lo[0], hi[0]);
    for (i, row) in dest.chunks_exact_mut(columns).enumerate() {
        row[at] = clip(value(i), lo, hi) as f32;
    }
}

/// Boxes seen from above, rows of x0, y0, x1, y1 (`MapInfo.boxes`).
struct Boxes(Vec<[f64; 4]>);

impl Boxes {
    fn of(a: &ArrayView2<'_, f64>) -> Self {
        Self(
            a.rows()
                .into_iter()
                .map(|b| [b[0], b[1], b[2], b[3]])
                .collect(),
        )
    }

    /// Whether (x, y) is inside one of them (open: `MapInfo.free`'s test).
    fn inside(&self, x: f64, y: f64) -> bool {
        self.0
            .iter()
            .any(|b| x > b[0] && x < b[2] && y > b[1] && y < b[3])
    }
}

/// `k` free points per row of `rows` (`(len(rows), k, 3)`: x, y, z), each drawn from the
/// row's own stream (`usarsim._task.Streams`: keys and draws made, advanced here), as
/// `MapInfo.sample_rows` describes: three uniform draws per candidate (x, y, then z in
/// `band`), x and y in `lo..hi` or, with `near` (one row per row, x and y read), within
/// `radius` of it and clipped to `lo..hi`; kept when inside no box of `boxes` (rows of
/// x0, y0, x1, y1, open) and at least `spacing` from the row's points before it. At most
/// 20,000 candidates per row.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (keys, drawn, rows, k, lo, hi, band, boxes, spacing, near = None, radius = 0.0))]
pub(crate) fn stream_sample<'py>(
    py: Python<'py>,
    keys: PyReadonlyArray1<'py, u64>,
    mut drawn: PyReadwriteArray1<'py, u64>,
    rows: PyReadonlyArray1<'py, i64>,
    k: usize,
    lo: [f64; 2],
    hi: [f64; 2],
    band: [f64; 2],
    boxes: PyReadonlyArray2<'py, f64>,
    spacing: f64,
    near: Option<PyReadonlyArray2<'py, f64>>,
    radius: f64,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    const TRIES: u64 = 20_000;
    let streams = Streams::of(&keys, &mut drawn, "stream_sample")?;
    let rows = rows.as_array();
    let boxes = boxes.as_array();
    if boxes.ncols() != 4 {
        return Err(bad(format!(
            "stream_sample: boxes {:?} (expected (k, 4))",
            boxes.shape()
        )));
    }
    streams.starts(&rows, "stream_sample")?;
    let near = near.as_ref().map(PyReadonlyArray2::as_array);
    if let Some(near) = &near
        && (near.nrows() != rows.len() || near.ncols() < 2)
    {
        return Err(bad(format!(
            "stream_sample: near {:?} for {} rows",
            near.shape(),
            rows.len()
        )));
    }
    let boxes = Boxes::of(&boxes);
    let mut out = Array3::<f64>::zeros((rows.len(), k, 3));
    for (m, &row) in rows.iter().enumerate() {
        // Read now, not before the call: a row listed twice continues its stream.
        let r = row as usize;
        let mut state = streams.state(r, streams.drawn[r]);
        let mut between = |low: f64, high: f64| low + (high - low) * uniform(&mut state);
        let (mut found, mut tried) = (0, 0_u64);
        while found < k && tried < TRIES {
            tried += 1;
            let (x, y) = match &near {
                Some(near) => (
                    clip(near[[m, 0]] + between(-radius, radius), lo[0], hi[0]),
                    clip(near[[m, 1]] + between(-radius, radius), lo[1], hi[1]),
                ),
                None => (between(lo[0], hi[0]), between(lo[1], hi[1])),
            };
            let z = between(band[0], band[1]);
            let apart = (0..found).all(|j| {
                let (dx, dy) = (x - out[[m, j, 0]], y - out[[m, j, 1]]);
                (dx * dx + dy * dy).sqrt() >= spacing
            });
            if !boxes.inside(x, y) && apart {
                out[[m, found, 0]] = x;
                out[[m, found, 1]] = y;
                out[[m, found, 2]] = z;
                found += 1;
            }
        }
        streams.drawn[r] = streams.drawn[r].wrapping_add(3 * tried);
        if found < k {
            return Err(bad(format!(
                "map: could not find {k} free places {spacing} m apart in the flight band"
            )));
        }
    }
    Ok(out.into_pyarray(py))
}

/// Hover's spawns for `rows` (`Tasks.new_starts`): each row's start pose `base` (x, y, z,
/// yaw) moved by `low + span × u` per axis, `u` three uniform draws of the row's stream
/// (advanced here), where that place is outside every box of `boxes` (rows of x0, y0, x1,
/// y1, open) and above `z_max` (z down: `z < z_max`); else the start itself. What
/// `Tasks._hover_spawns_numpy` gives, bit for bit. With `targets` (rows, waypoints, 3) and
/// `hold_yaw` (rows), each row's start is also its target (the first waypoint) and its yaw
/// the one to hold (the task's own arrays, written in the same loop).
#[pyfunction]
#[pyo3(signature = (keys, drawn, rows, base, low, span, boxes, z_max, targets = None, hold_yaw = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn hover_spawns<'py>(
    py: Python<'py>,
    keys: PyReadonlyArray1<'py, u64>,
    mut drawn: PyReadwriteArray1<'py, u64>,
    rows: PyReadonlyArray1<'py, i64>,
    base: PyReadonlyArray2<'py, f64>,
    low: [f64; 3],
    span: [f64; 3],
    boxes: PyReadonlyArray2<'py, f64>,
    z_max: f64,
    mut targets: Option<PyReadwriteArray3<'py, f64>>,
    mut hold_yaw: Option<PyReadwriteArray1<'py, f64>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let streams = Streams::of(&keys, &mut drawn, "hover_spawns")?;
    let rows = rows.as_array();
    let base = base.as_array();
    let boxes = boxes.as_array();
    if base.dim() != (rows.len(), 4) || boxes.ncols() != 4 {
        return Err(bad(format!(
            "hover_spawns: base {:?} for {} rows, boxes {:?}",
            base.shape(),
            rows.len(),
            boxes.shape()
        )));
    }
    let made = streams.starts(&rows, "hover_spawns")?;
    let n = keys.as_array().len();
    let shape = targets.as_ref().map(|t| t.shape().to_vec());
    if shape
        .as_ref()
        .is_some_and(|t| t[0] != n || t[1] == 0 || t[2] != 3)
        || hold_yaw.as_ref().is_some_and(|h| h.len() != n)
    {
        return Err(bad(format!(
            "hover_spawns: targets {:?} and hold_yaw ({},) for {n} rows: expected ({n}, k >= 1, \
             3) and ({n},)",
            shape.unwrap_or_default(),
            hold_yaw.as_ref().map_or(0, |h| h.len())
        )));
    }
    // Plain slices (the task's own arrays are contiguous): indexing the views element by
    // element cost more than the draws.
    let contiguous = |_| bad("hover_spawns: targets and hold_yaw must be contiguous");
    let mut targets = match targets.as_mut() {
        Some(t) => Some(t.as_slice_mut().map_err(contiguous)?),
        None => None,
    };
    let mut hold_yaw = match hold_yaw.as_mut() {
        Some(h) => Some(h.as_slice_mut().map_err(contiguous)?),
        None => None,
    };
    let width = shape.map_or(0, |t| t[1] * 3);
    let boxes = Boxes::of(&boxes);
    let mut out: Vec<f64> = base.iter().copied().collect();
    for (&(r, made), spawn) in made.iter().zip(out.chunks_exact_mut(4)) {
        let start = [spawn[0], spawn[1], spawn[2], spawn[3]];
        if let Some(t) = targets.as_deref_mut() {
            t[r * width..r * width + 3].copy_from_slice(&start[..3]);
        }
        if let Some(h) = hold_yaw.as_deref_mut() {
            h[r] = start[3];
        }
        let mut state = streams.state(r, made);
        streams.drawn[r] = made.wrapping_add(3);
        let p: [f64; 3] =
            std::array::from_fn(|c| span[c] * uniform(&mut state) + low[c] + start[c]);
        if !boxes.inside(p[0], p[1]) && p[2] < z_max {
            spawn[..3].copy_from_slice(&p);
        }
    }
    Ok(Array2::from_shape_vec((made.len(), 4), out)
        .map_err(|e| bad(format!("hover_spawns: {e}")))?
        .into_pyarray(py))
}
