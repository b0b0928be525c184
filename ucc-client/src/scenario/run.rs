//! Loops a scenario's iterations: iteration i flies seed + i, then its row goes into
//! `results.csv` (written row by row), its log into `iteration-NNN.log` and its picture into
//! `iteration-NNN.{png,svg}`. Memory stays flat: only each metric's running sum is kept.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::engine::{Ending, Outcome, Prepared, fly_recorded};
use crate::picture::MapGeometry;

/// How to run a scenario.
#[derive(Debug, Clone)]
pub struct ScenarioRun {
    /// Iterations to fly.
    pub iterations: usize,
    /// The first iteration's seed (`None`: the scenario's).
    pub seed: Option<u64>,
    /// Where the files go (`None`: no files).
    pub log_dir: Option<PathBuf>,
    /// Draw each iteration's picture.
    pub pictures: bool,
    /// Sensor threads of the world.
    pub threads: usize,
    /// Write into a folder that holds an earlier run's results.
    pub force: bool,
    /// Record each UAV's traffic into `DIR/iteration-NNN/connection-KKKK.usarlog`
    /// ([`super::engine::Episode::record`]).
    pub record: Option<PathBuf>,
}

impl Default for ScenarioRun {
    fn default() -> Self {
        Self {
            iterations: 1,
            seed: None,
            log_dir: None,
            pictures: true,
            threads: 1,
            force: false,
            record: None,
        }
    }
}

/// What the run reports as it goes.
#[derive(Debug)]
pub enum ScenarioProgress<'a> {
    /// An iteration is over (1-based), its files written.
    Finished {
        /// 1-based.
        iteration: usize,
        /// What happened.
        outcome: &'a Outcome,
    },
}

/// The run's figures: each metric's mean over the iterations that measured it.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioSummary {
    /// Iterations flown.
    pub iterations: usize,
    /// (metric, mean, iterations that measured it).
    pub means: Vec<(&'static str, f64, usize)>,
    /// Wall seconds the run took.
    pub wall: f64,
    /// Simulated seconds flown in all.
    pub simulated: f64,
}

/// A run that could not go on.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ScenarioRunError(pub String);

/// Flies the iterations.
pub fn run_scenario(
    prepared: &Prepared,
    settings: &ScenarioRun,
    observer: &mut dyn FnMut(ScenarioProgress<'_>),
) -> Result<ScenarioSummary, ScenarioRunError> {
    let scenario = &prepared.scenario;
    let start = std::time::Instant::now();
    let mut table = match &settings.log_dir {
        Some(dir) => Some(open_results(dir, settings.force, prepared)?),
        None => None,
    };
    let geometry = MapGeometry::from(&prepared.map);
    let seed = settings.seed.unwrap_or(scenario.seed);
    let mut sums: Vec<(&'static str, f64, usize)> = Vec::new();
    let mut simulated = 0.0;
    let mut overlay: Option<Outcome> = None;
    for i in 0..settings.iterations {
        let seed = seed.wrapping_add(i as u64);
        let record = settings
            .record
            .as_ref()
            .map(|dir| dir.join(format!("iteration-{:03}", i + 1)));
        let outcome = fly_recorded(prepared, seed, settings.threads, record.as_deref())
            .map_err(|e| ScenarioRunError(format!("iteration {}: {e}", i + 1)))?;
        simulated += outcome.metrics.get("time_s").unwrap_or(0.0);
        for (name, value) in &outcome.metrics.values {
            let Some(v) = value else { continue };
            match sums.iter_mut().find(|(n, _, _)| n == name) {
                Some(s) => {
                    s.1 += v;
                    s.2 += 1;
                }
                None => sums.push((name, *v, 1)),
            }
        }
        if let (Some(dir), Some((path, out))) = (&settings.log_dir, &mut table) {
            let wrote = |e: std::io::Error, p: &Path| {
                ScenarioRunError(format!("cannot write {}: {e}", p.display()))
            };
            let ending = match outcome.ending {
                Ending::Done => "done",
                Ending::TimeUp => "time_up",
            };
            let cells: Vec<String> = outcome
                .metrics
                .values
                .iter()
                .map(|(_, v)| v.map_or(String::new(), |v| format!("{v:.3}")))
                .collect();
            writeln!(out, "{},{},{},{}", i + 1, seed, ending, cells.join(","))
                .and_then(|()| out.flush())
                .map_err(|e| wrote(e, path))?;
            let log = dir.join(format!("iteration-{:03}.log", i + 1));
            std::fs::write(&log, outcome.log.join("\n") + "\n").map_err(|e| wrote(e, &log))?;
            if settings.pictures {
                super::picture::write(
                    scenario,
                    &geometry,
                    &outcome,
                    i + 1,
                    &dir.join(format!("iteration-{:03}", i + 1)),
                )
                .map_err(|e| ScenarioRunError(e.to_string()))?;
            }
        }
        if settings.pictures && settings.log_dir.is_some() {
            add_to_overlay(&mut overlay, &outcome);
        }
        observer(ScenarioProgress::Finished {
            iteration: i + 1,
            outcome: &outcome,
        });
    }
    let means: Vec<(&'static str, f64, usize)> = sums
        .into_iter()
        .map(|(n, s, k)| (n, s / k as f64, k))
        .collect();
    if let (Some(dir), Some(mut overlay)) = (&settings.log_dir, overlay) {
        overlay.seed = settings.iterations as u64;
        overlay.metrics.values = means.iter().map(|&(n, m, _)| (n, Some(m))).collect();
        super::picture::write(scenario, &geometry, &overlay, 0, &dir.join("overlay"))
            .map_err(|e| ScenarioRunError(e.to_string()))?;
    }
    Ok(ScenarioSummary {
        iterations: settings.iterations,
        means,
        wall: start.elapsed().as_secs_f64(),
        simulated,
    })
}

/// Creates the folder and `results.csv` with its header (refusing an earlier run's unless
/// `force`).
fn open_results(
    dir: &Path,
    force: bool,
    prepared: &Prepared,
) -> Result<(PathBuf, std::io::BufWriter<std::fs::File>), ScenarioRunError> {
    let path = dir.join("results.csv");
    if path.exists() && !force {
        return Err(ScenarioRunError(format!(
            "{} holds an earlier run's results.csv; choose another --log-dir or add --force",
            dir.display()
        )));
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| ScenarioRunError(format!("cannot create {}: {e}", dir.display())))?;
    let file = std::fs::File::create(&path)
        .map_err(|e| ScenarioRunError(format!("cannot write {}: {e}", path.display())))?;
    let mut out = std::io::BufWriter::new(file);
    let columns = super::metrics::Tracker::new(&prepared.scenario, &[], 0)
        .finish(0.0, &prepared.scenario)
        .values
        .iter()
        .map(|(n, _)| *n)
        .collect::<Vec<_>>()
        .join(",");
    writeln!(out, "iteration,seed,ending,{columns}")
        .map_err(|e| ScenarioRunError(format!("cannot write {}: {e}", path.display())))?;
    Ok((path, out))
}

/// Paths kept in the overlay (the first iterations'); later ones add to the coverage and
/// the victims only, so a long run's overlay stays small.
pub const OVERLAY_PATHS: usize = 30;
/// Victims kept in the overlay.
const OVERLAY_VICTIMS: usize = 2000;

/// Adds an iteration to the run's overlay: every iteration's coverage summed per cell, the
/// first [`OVERLAY_PATHS`] iterations' paths, the victims (each found or missed).
fn add_to_overlay(overlay: &mut Option<Outcome>, outcome: &Outcome) {
    let Some(o) = overlay else {
        let mut first = outcome.clone();
        first.link.clear();
        first.log.clear();
        // The overlay's heat map counts iterations that saw a cell.
        if let Some(grid) = &mut first.coverage {
            for n in &mut grid.seen {
                *n = u32::from(*n > 0);
            }
        }
        *overlay = Some(first);
        return;
    };
    if let (Some(sum), Some(grid)) = (&mut o.coverage, &outcome.coverage)
        && sum.seen.len() == grid.seen.len()
    {
        for (s, g) in sum.seen.iter_mut().zip(&grid.seen) {
            *s = s.saturating_add(u32::from(*g > 0));
        }
    }
    if o.tracks.len() < OVERLAY_PATHS * outcome.tracks.len().max(1) {
        o.tracks.extend(outcome.tracks.iter().cloned());
        o.target_tracks
            .extend(outcome.target_tracks.iter().cloned());
    }
    for v in &outcome.victims {
        if o.victims.len() < OVERLAY_VICTIMS
            && !o
                .victims
                .iter()
                .any(|(p, t)| p.center == v.0.center && t.is_some() == v.1.is_some())
        {
            o.victims.push(v.clone());
        }
    }
    o.fire_radius = outcome.fire_radius;
}
