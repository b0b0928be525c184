//! The results of a run: one [`IterationSummary`] per iteration, the [`Summary`] of all,
//! their [`Statistics`], and the results table (`PREFIX-results.csv`).

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::geometry::Coordinates;
use crate::output::fixed4;
use crate::record::TrajectoryPoint;

/// How an iteration ended.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum IterationStatus {
    /// Every mission done.
    #[default]
    Done,
    /// It failed; why.
    Failed(String),
    /// The run was stopped during it.
    Interrupted,
}

impl IterationStatus {
    /// The word of the results table: `ok`, `failed` or `interrupted`.
    pub fn word(&self) -> &'static str {
        match self {
            Self::Done => "ok",
            Self::Failed(_) => "failed",
            Self::Interrupted => "interrupted",
        }
    }
}

/// The result of one iteration.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IterationSummary {
    /// How it ended.
    pub status: IterationStatus,
    /// Missions completed.
    pub missions_done: usize,
    /// Simulated seconds from the start to the last mission done.
    pub duration: f64,
    /// Metres flown (along the recorded path).
    pub distance: f64,
    /// Simulated seconds from the first to the last trajectory sample.
    pub simulated_seconds: f64,
    /// The recorded trajectory; empty in the iterations a run does not keep whole
    /// (see [`RunSettings::kept_iterations`](crate::RunSettings::kept_iterations)).
    pub trajectory: Vec<TrajectoryPoint>,
    /// Files written for this iteration.
    pub files: Vec<PathBuf>,
    /// Faults the server applied (`usar-server --faults`).
    pub faults: usize,
    /// The parameters drawn for the robot (`--randomize`), as `mass 1.3021 kf 1.02 ..`.
    pub randomized: String,
}

impl IterationSummary {
    /// Whether every mission was done.
    pub fn is_done(&self) -> bool {
        self.status == IterationStatus::Done
    }

    /// Why it failed, if it did.
    pub fn error(&self) -> Option<&str> {
        match &self.status {
            IterationStatus::Failed(e) => Some(e),
            _ => None,
        }
    }

    /// The path: the trajectory's positions.
    pub fn path(&self) -> Vec<Coordinates> {
        self.trajectory.iter().map(|p| p.position).collect()
    }
}

/// The overlay draws at most this many different paths; more iterations that flew a path
/// already drawn make it darker, other ones are counted in its title.
pub const OVERLAY_PATHS: usize = 1000;

/// Paths are simplified to this many metres before they are kept for the overlay (a
/// picture's pixel is several centimetres).
const OVERLAY_TOLERANCE: f64 = 0.01;

/// The result of a whole run.
///
/// Its memory does not grow with the number of iterations: the figures are kept as running
/// sums, the results table is written as each iteration ends, the overlay keeps each
/// different path once, and only the first
/// [`RunSettings::kept_iterations`](crate::RunSettings::kept_iterations) iterations are
/// kept whole in [`iterations`](Self::iterations).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Summary {
    /// The first iterations flown, completed, failed or interrupted, whole.
    pub iterations: Vec<IterationSummary>,
    /// Iterations flown, also those beyond [`iterations`](Self::iterations).
    pub flown: usize,
    /// Missions completed in all iterations.
    pub missions_done: usize,
    /// Files written for the iterations.
    pub files_written: usize,
    /// The first failed iteration's error.
    pub first_error: Option<String>,
    /// The overlay pictures (every iteration's path on one map).
    pub overlay: Vec<PathBuf>,
    /// The results table (`PREFIX-results.csv`), when a log directory is set.
    pub results: Option<PathBuf>,
    /// Whether the run was stopped before its last iteration ended.
    pub interrupted: bool,
    statistics: Statistics,
    durations: Running,
    distances: Running,
    /// The first completed iteration's path: the others' deviations are measured from it.
    reference: Option<Vec<Coordinates>>,
    /// The first iteration's start.
    start: Option<Coordinates>,
    /// The different paths for the overlay (simplified), each with how many iterations
    /// flew it.
    paths: Vec<(Vec<Coordinates>, usize)>,
    /// Iterations whose path the overlay leaves out (more than [`OVERLAY_PATHS`]).
    paths_left_out: usize,
}

/// Figures over the iterations of a run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Statistics {
    /// Iterations that completed every mission.
    pub completed: usize,
    /// Iterations that failed (an interrupted one is neither completed nor failed).
    pub failed: usize,
    /// Mean and standard deviation of the completion time of the completed iterations
    /// (simulated seconds).
    pub duration: (f64, f64),
    /// Mean and standard deviation of their path length (metres).
    pub distance: (f64, f64),
    /// The largest distance between any completed iteration's path and the first one's
    /// (symmetric Hausdorff distance in metres); 0 when every path is the same.
    pub max_deviation: f64,
    /// Simulated seconds flown in all iterations.
    pub simulated_seconds: f64,
}

impl Summary {
    /// The figures of the run.
    pub fn statistics(&self) -> Statistics {
        Statistics {
            duration: self.durations.mean_and_spread(),
            distance: self.distances.mean_and_spread(),
            // + 0.0: an empty sum is -0.0.
            simulated_seconds: self.statistics.simulated_seconds + 0.0,
            ..self.statistics.clone()
        }
    }

    /// Counts an iteration; keeps it whole if fewer than `keep` are kept, and its path for
    /// the overlay if `overlay`. Returns how far its path lies from the first completed
    /// iteration's (symmetric Hausdorff distance, metres), or `None` before one completed.
    pub fn add(&mut self, iteration: &IterationSummary, keep: usize, overlay: bool) -> Option<f64> {
        let path = iteration.path();
        if iteration.is_done() {
            self.statistics.completed += 1;
            self.durations.add(iteration.duration);
            self.distances.add(iteration.distance);
            if self.reference.is_none() {
                self.reference = Some(path.clone());
            }
        }
        if let Some(error) = iteration.error() {
            self.statistics.failed += 1;
            self.first_error.get_or_insert_with(|| error.to_owned());
        }
        let deviation = self.reference.as_ref().map(|r| hausdorff(r, &path));
        if iteration.is_done()
            && let Some(d) = deviation
        {
            self.statistics.max_deviation = self.statistics.max_deviation.max(d);
        }
        self.statistics.simulated_seconds += iteration.simulated_seconds;
        self.flown += 1;
        self.missions_done += iteration.missions_done;
        self.files_written += iteration.files.len();
        if self.start.is_none() {
            self.start = path.first().copied();
        }
        if overlay && !path.is_empty() {
            self.add_path(simplify(&path, OVERLAY_TOLERANCE));
        }
        if self.iterations.len() < keep {
            self.iterations.push(iteration.clone());
        }
        deviation
    }

    fn add_path(&mut self, path: Vec<Coordinates>) {
        // A few iterations keep a path each (the picture gives each its own colour).
        if self.paths.len() >= LEGEND_PATHS
            && let Some((_, n)) = self.paths.iter_mut().find(|(p, _)| *p == path)
        {
            *n += 1;
        } else if self.paths.len() < OVERLAY_PATHS {
            self.paths.push((path, 1));
        } else {
            self.paths_left_out += 1;
        }
    }

    /// The paths for the overlay, each with the number of iterations that flew it, and how
    /// many iterations' paths are left out.
    pub fn overlay_paths(&self) -> (&[(Vec<Coordinates>, usize)], usize) {
        (&self.paths, self.paths_left_out)
    }

    /// Where the first iteration started.
    pub fn start(&self) -> Option<Coordinates> {
        self.start
    }
}

/// Up to this many iterations' paths are kept apart for the overlay even when equal, so that
/// the picture can give each a colour and a legend entry.
const LEGEND_PATHS: usize = crate::picture::LEGEND_ITERATIONS;

/// The results table, written a row at a time as iterations end (so that a run stopped by
/// anything has the rows of every iteration that ended).
pub struct ResultsTable {
    path: PathBuf,
    out: Option<std::io::BufWriter<std::fs::File>>,
    rows: usize,
}

impl ResultsTable {
    /// A table to write at `path`; the file is made at the first row.
    pub fn new(path: PathBuf) -> Self {
        Self {
            path,
            out: None,
            rows: 0,
        }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes one line: the iteration's number, status, missions done, completion time,
    /// path length, distance of its path from the first completed one's (empty before one
    /// completed), simulated time, and the error.
    pub fn row(&mut self, i: &IterationSummary, deviation: Option<f64>) -> std::io::Result<()> {
        let out = match &mut self.out {
            Some(out) => out,
            None => {
                let mut out = std::io::BufWriter::new(std::fs::File::create(&self.path)?);
                writeln!(
                    out,
                    "iteration,status,missions_done,duration_s,distance_m,deviation_m,simulated_s,faults,randomized,error"
                )?;
                self.out.insert(out)
            }
        };
        self.rows += 1;
        writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{}",
            self.rows,
            i.status.word(),
            i.missions_done,
            fixed4(i.duration),
            fixed4(i.distance),
            deviation.map_or(String::new(), fixed4),
            fixed4(i.simulated_seconds),
            i.faults,
            i.randomized.replace([',', '\n'], " "),
            i.error().unwrap_or("").replace([',', '\n'], " "),
        )?;
        out.flush()
    }
}

/// Running mean and spread (Welford).
#[derive(Debug, Clone, PartialEq, Default)]
struct Running {
    n: usize,
    mean: f64,
    m2: f64,
}

impl Running {
    fn add(&mut self, v: f64) {
        self.n += 1;
        let d = v - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (v - self.mean);
    }

    /// Mean and (population) standard deviation; zeros when empty.
    fn mean_and_spread(&self) -> (f64, f64) {
        if self.n == 0 {
            return (0.0, 0.0);
        }
        (self.mean, (self.m2 / self.n as f64).max(0.0).sqrt())
    }
}

/// The path with the points dropped that lie within `tolerance` of the line between the
/// points kept around them (Ramer–Douglas–Peucker); the ends are kept.
fn simplify(path: &[Coordinates], tolerance: f64) -> Vec<Coordinates> {
    if path.len() < 3 {
        return path.to_vec();
    }
    let mut keep = vec![false; path.len()];
    keep[0] = true;
    keep[path.len() - 1] = true;
    let mut spans = vec![(0, path.len() - 1)];
    while let Some((a, b)) = spans.pop() {
        let (pa, pb) = (path[a], path[b]);
        let ab = pb - pa;
        let len2 = ab.norm_squared();
        let distance = |p: &Coordinates| {
            let t = if len2 > 0.0 {
                ((p - pa).dot(&ab) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (p - (pa + ab * t)).norm()
        };
        let far = (a + 1..b)
            .map(|i| (i, distance(&path[i])))
            .fold((a, 0.0), |m, c| if c.1 > m.1 { c } else { m });
        if far.1 > tolerance {
            keep[far.0] = true;
            spans.push((a, far.0));
            spans.push((far.0, b));
        }
    }
    path.iter()
        .zip(keep)
        .filter(|(_, k)| *k)
        .map(|(p, _)| *p)
        .collect()
}

/// The symmetric Hausdorff distance between two sampled paths.
fn hausdorff(a: &[Coordinates], b: &[Coordinates]) -> f64 {
    let directed = |from: &[Coordinates], to: &[Coordinates]| {
        from.iter()
            .map(|p| {
                to.iter()
                    .map(|q| (p - q).norm())
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    };
    if a.is_empty() || b.is_empty() {
        return if a.len() == b.len() {
            0.0
        } else {
            f64::INFINITY
        };
    }
    directed(a, b).max(directed(b, a))
}
