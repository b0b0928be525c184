//! The results of a run: one [`IterationSummary`] per iteration, the [`Summary`] of all,
//! their [`Statistics`], and the results table (`PREFIX-results.csv`).

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::geometry::Coordinates;
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
    /// The recorded trajectory.
    pub trajectory: Vec<TrajectoryPoint>,
    /// Files written for this iteration.
    pub files: Vec<PathBuf>,
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

    /// Simulated seconds from the first to the last trajectory sample.
    pub fn simulated_seconds(&self) -> f64 {
        match (self.trajectory.first(), self.trajectory.last()) {
            (Some(a), Some(b)) => b.time - a.time,
            _ => 0.0,
        }
    }

    /// The path: the trajectory's positions.
    pub fn path(&self) -> Vec<Coordinates> {
        self.trajectory.iter().map(|p| p.position).collect()
    }
}

/// The result of a whole run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Summary {
    /// One entry per iteration flown, completed, failed or interrupted.
    pub iterations: Vec<IterationSummary>,
    /// The overlay pictures (every iteration's path on one map).
    pub overlay: Vec<PathBuf>,
    /// The results table (`PREFIX-results.csv`), when a log directory is set.
    pub results: Option<PathBuf>,
    /// Whether the run was stopped before its last iteration ended.
    pub interrupted: bool,
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
        let done: Vec<&IterationSummary> = self.iterations.iter().filter(|i| i.is_done()).collect();
        let first = done.first().map(|i| i.path());
        Statistics {
            completed: done.len(),
            failed: self
                .iterations
                .iter()
                .filter(|i| i.error().is_some())
                .count(),
            duration: mean_and_spread(done.iter().map(|i| i.duration)),
            distance: mean_and_spread(done.iter().map(|i| i.distance)),
            max_deviation: first.as_ref().map_or(0.0, |first| {
                done.iter()
                    .map(|i| hausdorff(first, &i.path()))
                    .fold(0.0, f64::max)
            }),
            // + 0.0: an empty sum is -0.0.
            simulated_seconds: self
                .iterations
                .iter()
                .map(IterationSummary::simulated_seconds)
                .sum::<f64>()
                + 0.0,
        }
    }

    /// How far each iteration's path lies from the first completed one's (metres).
    fn deviations(&self) -> Vec<Option<f64>> {
        let first = self
            .iterations
            .iter()
            .find(|i| i.is_done())
            .map(|i| i.path());
        self.iterations
            .iter()
            .map(|i| first.as_ref().map(|f| hausdorff(f, &i.path())))
            .collect()
    }

    /// Writes one line per iteration: its number, status, missions done, completion time,
    /// path length, distance of its path from the first one's, simulated time, and the error.
    pub fn write_results(&self, path: &Path) -> std::io::Result<()> {
        let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
        writeln!(
            out,
            "iteration,status,missions_done,duration_s,distance_m,deviation_m,simulated_s,error"
        )?;
        for (n, (i, deviation)) in self.iterations.iter().zip(self.deviations()).enumerate() {
            writeln!(
                out,
                "{},{},{},{:.4},{:.4},{},{:.4},{}",
                n + 1,
                i.status.word(),
                i.missions_done,
                i.duration,
                i.distance,
                deviation.map_or(String::new(), |d| format!("{d:.4}")),
                i.simulated_seconds(),
                i.error().unwrap_or("").replace([',', '\n'], " "),
            )?;
        }
        out.flush()
    }
}

fn mean_and_spread(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let values: Vec<f64> = values.collect();
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt())
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
