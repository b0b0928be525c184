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
    keys: ArrayView1<'a, u64>,
    drawn: numpy::ndarray::ArrayViewMut1<'a, u64>,
}

impl<'a> Streams<'a> {
    fn of(
        keys: &'a PyReadonlyArray1<'_, u64>,
        drawn: &'a mut PyReadwriteArray1<'_, u64>,
        what: &str,
    ) -> PyResult<Self> {
        let (keys, drawn) = (keys.as_array(), drawn.as_array_mut());
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
        rows.iter()
            .map(|&r| match usize::try_from(r) {
                Ok(r) if r < n => Ok((r, self.drawn[r])),
                _ => Err(bad(format!("{what}: row {r} is not in 0..{n}"))),
            })
            .collect()
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
    let mut streams = Streams::of(&keys, &mut drawn, "stream_draws")?;
    let starts = streams.starts(&rows.as_array(), "stream_draws")?;
    let mut out = Array2::<u64>::zeros((starts.len(), k));
    for (mut row, &(r, made)) in out.rows_mut().into_iter().zip(&starts) {
        let mut state = streams.state(r, made);
        row.iter_mut()
            .for_each(|v| *v = usar_sim::splitmix(&mut state));
        streams.drawn[r] = made.wrapping_add(k as u64);
    }
    Ok(out.into_pyarray(py))
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

    /// `Tasks._vector` of row `i`: its current target minus its position (`position`: three
    /// values a row).
    #[inline(always)]
    fn vector(&self, i: usize, position: &[f64], index: i64) -> [f64; 3] {
        let j = index.min(self.count[i] - 1) as usize;
        let at = (i * self.slots + j) * 3;
        let (t, p) = (&self.targets[at..at + 3], &position[3 * i..3 * i + 3]);
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

/// One bool array of `n` rows from `f`.
fn flags<'py>(py: Python<'py>, n: usize, f: impl Fn(usize) -> bool) -> Bound<'py, PyArray1<bool>> {
    (0..n).map(f).collect::<Vec<_>>().into_pyarray(py)
}

type Rewards<'py> = (
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
    let (index, steps, prev) = (
        index.as_slice_mut(),
        steps.as_slice_mut(),
        prev.as_slice_mut(),
    );
    let (Ok(index), Ok(steps), Ok(prev)) = (index, steps, prev) else {
        return Err(bad("tasks: index, steps and prev: not contiguous"));
    };
    if index.len() != n || steps.len() != n || prev.len() != n {
        return Err(bad(format!("tasks: index, steps and prev need {n} rows")));
    }
    let t = Targets::of(&targets, &count, n, index)?;
    let mut reward = vec![0.0; n];
    let (mut terminated, mut reached) = (vec![false; n], vec![false; n]);
    let mut truncated = vec![false; n];
    for i in 0..n {
        let live = live[i];
        steps[i] += i64::from(live);
        let touch = if touched[i] { TOUCH_PENALTY } else { 0.0 };
        let k = index[i];
        let mut dist = length(t.vector(i, position, k));
        let (mut r, mut end, next) = if hover {
            let yaw = wrap(attitude[3 * i + 2] - hold_yaw[i]).abs();
            (-dist - 0.2 * yaw - touch, false, k)
        } else {
            let r = prev[i] - dist - touch;
            reached[i] = dist < radius && live;
            let next = k + i64::from(reached[i]);
            let r = r + if reached[i] { WAYPOINT_BONUS } else { 0.0 };
            dist = length(t.vector(i, position, next));
            (r, next >= t.count[i], next)
        };
        prev[i] = dist;
        r -= if crashed[i] { CRASH_PENALTY } else { 0.0 };
        end = (end || crashed[i]) && live;
        truncated[i] = live && !end && (steps[i] >= max_steps || battery[i] <= 0.0);
        terminated[i] = end;
        reward[i] = if live { r } else { 0.0 };
        index[i] = next;
    }
    Ok((
        reward.into_pyarray(py),
        terminated.into_pyarray(py),
        truncated.into_pyarray(py),
        flags(py, n, |i| touched[i] && live[i]),
        flags(py, n, |i| crashed[i] && live[i]),
        reached.into_pyarray(py),
    ))
}

/// Where the columns of one observation key come from.
enum Source<'a> {
    /// The raw observation's array (C order), as it is.
    Raw(&'a [f64]),
    /// The raw attitude (C order), wrapped.
    Attitude(&'a [f64]),
    /// The vector to the current target.
    Waypoint,
    /// Hover: the yaw to hold minus the yaw, wrapped; Waypoints: 0.
    YawError,
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
    let position = slice2(&position, n, 3, "position")?;
    let attitude = item("attitude")?;
    let attitude = slice2(&attitude, n, 3, "attitude")?;
    let hold_yaw = slice1(&hold_yaw, n, "hold_yaw")?;
    let index = index
        .as_slice()
        .map_err(|_| bad("tasks: index: not contiguous"))?;
    let t = Targets::of(&targets, &count, n, index)?;
    let arrays = keys
        .iter()
        .filter(|k| !["attitude", "waypoint", "yaw_error"].contains(&k.as_str()))
        .map(|k| Ok((k.as_str(), item(k)?)))
        .collect::<PyResult<Vec<_>>>()?;
    let sources = keys
        .iter()
        .map(|k| match k.as_str() {
            "attitude" => Ok((Source::Attitude(attitude), 3)),
            "waypoint" => Ok((Source::Waypoint, 3)),
            "yaw_error" => Ok((Source::YawError, 1)),
            k => {
                let (_, a) = arrays
                    .iter()
                    .find(|(name, _)| *name == k)
                    .expect("read above");
                let a = a.as_array();
                if a.nrows() != n {
                    return Err(bad(format!(
                        "tasks: raw {k:?}: {} rows, expected {n}",
                        a.nrows()
                    )));
                }
                Ok((Source::Raw(contiguous(&a, k)?), a.ncols()))
            }
        })
        .collect::<PyResult<Vec<_>>>()?;
    let columns: usize = sources.iter().map(|(_, w)| w).sum();
    let (lo, hi) = (lo.as_slice()?, hi.as_slice()?);
    if lo.len() != columns || hi.len() != columns {
        return Err(bad(format!(
            "tasks: {} low and {} high bounds for {columns} columns",
            lo.len(),
            hi.len()
        )));
    }
    // Row `i`'s values, every column clipped, in `buf`.
    let fill = |i: usize, buf: &mut [f64]| {
        let mut at = 0;
        for (s, w) in &sources {
            let b = &mut buf[at..at + w];
            match s {
                Source::Raw(a) => b.copy_from_slice(&a[i * w..(i + 1) * w]),
                Source::Attitude(a) => b
                    .iter_mut()
                    .zip(&a[i * w..(i + 1) * w])
                    .for_each(|(b, v)| *b = wrap(*v)),
                Source::Waypoint => b.copy_from_slice(&t.vector(i, position, index[i])),
                Source::YawError if hover => b[0] = wrap(hold_yaw[i] - attitude[3 * i + 2]),
                Source::YawError => b[0] = 0.0,
            }
            at += w;
        }
        for ((b, lo), hi) in buf.iter_mut().zip(lo).zip(hi) {
            *b = clip(*b, *lo, *hi);
        }
    };
    let mut buf = vec![0.0; columns];
    if let Ok(mut flat) = out.extract::<PyReadwriteArray2<'_, f32>>() {
        let shape = flat.shape().to_vec();
        let dest = match flat.as_slice_mut() {
            Ok(dest) if shape == [n, columns] => dest,
            _ => {
                return Err(bad(format!(
                    "tasks: out: shape {shape:?}, expected a C-contiguous ({n}, {columns})"
                )));
            }
        };
        if columns == 0 {
            return Ok(());
        }
        // Key after key, each over every row: no dispatch per row and value (what `fill`
        // gives, bit for bit, written column by column).
        let mut at = 0;
        for (s, w) in &sources {
            let w = *w;
            let bounds = (&lo[at..at + w], &hi[at..at + w]);
            let put = |dest: &mut [f32], value: &dyn Fn(usize, usize) -> f64| {
                put_columns(dest, columns, at, bounds, value);
            };
            match s {
                Source::Raw(a) if w == 3 => {
                    put_columns3(dest, columns, at, bounds, |i, k| a[3 * i + k])
                }
                Source::Raw(a) if w == 1 => put_columns1(dest, columns, at, bounds, |i| a[i]),
                Source::Raw(a) => put(dest, &|i, k| a[w * i + k]),
                Source::Attitude(a) => {
                    put_columns3(dest, columns, at, bounds, |i, k| wrap(a[3 * i + k]))
                }
                Source::Waypoint => {
                    for (i, row) in dest.chunks_exact_mut(columns).enumerate() {
                        let v = t.vector(i, position, index[i]);
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
    let out = out
        .cast::<PyDict>()
        .map_err(|_| bad("tasks: out: expected a float32 (n, columns) array or a dict of them"))?;
    let mut dests = Vec::with_capacity(keys.len());
    for (k, (_, w)) in keys.iter().zip(&sources) {
        let a = out
            .get_item(k)?
            .ok_or_else(|| bad(format!("tasks: out has no {k:?}")))?
            .extract::<PyReadwriteArray2<'_, f32>>()
            .map_err(|e| {
                bad(format!(
                    "tasks: out[{k:?}]: not a writable 2-D float32 array: {e}"
                ))
            })?;
        if a.as_array().dim() != (n, *w) {
            return Err(bad(format!(
                "tasks: out[{k:?}]: shape {:?}, expected ({n}, {w})",
                a.as_array().shape()
            )));
        }
        dests.push(a);
    }
    let mut dests: Vec<_> = dests.iter_mut().map(|a| a.as_array_mut()).collect();
    for i in 0..n {
        fill(i, &mut buf);
        let mut at = 0;
        for dest in &mut dests {
            let w = dest.ncols();
            dest.row_mut(i)
                .iter_mut()
                .zip(&buf[at..at + w])
                .for_each(|(d, v)| *d = *v as f32);
            at += w;
        }
    }
    Ok(())
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
    let mut streams = Streams::of(&keys, &mut drawn, "stream_sample")?;
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
    let mut streams = Streams::of(&keys, &mut drawn, "hover_spawns")?;
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
    let mut targets = targets.as_mut().map(|t| t.as_array_mut());
    let mut hold_yaw = hold_yaw.as_mut().map(|h| h.as_array_mut());
    if targets
        .as_ref()
        .is_some_and(|t| t.shape()[0] != n || t.shape()[1] == 0 || t.shape()[2] != 3)
        || hold_yaw.as_ref().is_some_and(|h| h.len() != n)
    {
        return Err(bad(format!(
            "hover_spawns: targets {:?} and hold_yaw ({},) for {n} rows: expected ({n}, k >= 1, \
             3) and ({n},)",
            targets.as_ref().map_or(&[][..], |t| t.shape()),
            hold_yaw.as_ref().map_or(0, |h| h.len())
        )));
    }
    let boxes = Boxes::of(&boxes);
    let mut out = base.to_owned();
    for (m, &(r, made)) in made.iter().enumerate() {
        if let Some(t) = targets.as_mut() {
            for c in 0..3 {
                t[[r, 0, c]] = base[[m, c]];
            }
        }
        if let Some(h) = hold_yaw.as_mut() {
            h[r] = base[[m, 3]];
        }
        let mut state = streams.state(r, made);
        streams.drawn[r] = made.wrapping_add(3);
        let p: [f64; 3] =
            std::array::from_fn(|c| span[c] * uniform(&mut state) + low[c] + base[[m, c]]);
        if !boxes.inside(p[0], p[1]) && p[2] < z_max {
            for (c, v) in p.into_iter().enumerate() {
                out[[m, c]] = v;
            }
        }
    }
    Ok(out.into_pyarray(py))
}
