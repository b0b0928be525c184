//! The scenario the page shows (issue #22, docs/scenarios.md): which embedded scenario runs,
//! its UAVs — ordinary [`Uav`]s of the hub, so that the map, the UAV list and the live panel
//! show them as any other — and what a scenario adds: the coverage grid (as levels, sent as
//! the cells whose level changed), the victims found or not, the targets, the fire, the
//! link over time, the metrics, and each iteration's row of results.
//!
//! The requests are checked here; the scenario's thread (`crate::scenario`) reports into
//! the hub through [`Hub::scenario_iteration`], [`Hub::scenario_sample`],
//! [`Hub::scenario_row`] and [`Hub::scenario_finished`]; [`Hub::scenario_json`] gives a
//! page what changed since its [`ScenarioCursor`].

use std::sync::Arc;

use serde_json::{Value, json};
use tokio_util::sync::CancellationToken;
use ucc_client::scenario::engine::{Ending, Episode};
use ucc_client::scenario::spec::EMBEDDED;
use ucc_client::scenario::{Outcome, Prepared, Scenario};
use ucc_client::{Coordinates, Start};
use usar_server::TimeScale;

use super::request::MAX_UAVS;
pub use super::request::ScenarioPlan;
use super::request::{field, shown};
use super::{Action, Hub, Live, RequestError, Status, Uav};

/// The most iterations one scenario start may ask for (each row of results is kept).
pub const MAX_SCENARIO_ITERATIONS: usize = 1000;
/// Link changes kept for the strip (the indicator shows the state beyond).
pub const MAX_LINK_CHANGES: usize = 10_000;
/// Coverage grids larger than this are not sent to the page (the metric still is).
pub const MAX_GRID_CELLS: usize = 1 << 22;
/// The highest heat level of a cell: level `k` ≥ 1 means seen for at least 2^(k-1)
/// periods.
pub const LEVELS: u8 = 9;

/// The heat level of a cell seen for `periods` periods: 0 never, then 1 + log2, at most
/// [`LEVELS`]. A cell changes level at most [`LEVELS`] times, so the page is sent few cells.
pub fn level(periods: u32) -> u8 {
    if periods == 0 {
        0
    } else {
        (1 + (31 - periods.leading_zeros()) as u8).min(LEVELS)
    }
}

/// The embedded scenarios for the page's list: name, kind, UAVs, time limit, map, what it is.
pub fn list() -> Vec<Value> {
    EMBEDDED
        .iter()
        .filter_map(|(name, _)| {
            let s = Scenario::lookup(name).ok()?;
            Some(json!({
                "name": name,
                "kind": s.kind.name(),
                "uavs": s.uav_count(),
                "time_limit": s.time_limit,
                "map": s.map,
                "seed": s.seed,
                "description": s.description,
            }))
        })
        .collect()
}

/// One iteration's row of results, as in `results.csv`.
#[derive(Debug, Clone)]
pub struct Row {
    /// 1-based.
    pub iteration: usize,
    /// The seed it flew.
    pub seed: u64,
    /// `done` or `time_up`.
    pub ending: &'static str,
    /// The metrics, in the order of [`ScenarioView::columns`].
    pub values: Vec<Option<f64>>,
}

/// A victim as the page shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct VictimView {
    /// Its name.
    pub name: String,
    /// Where, metres.
    pub at: [f64; 2],
    /// When it was found (simulated seconds).
    pub found: Option<f64>,
}

/// The scenario shown: the last one started, running or ended.
#[derive(Debug)]
pub struct ScenarioView {
    /// Its name.
    pub name: String,
    /// Where the run stands.
    pub status: Status,
    /// Why it failed.
    pub error: Option<String>,
    /// The iteration flying (1-based; 0 before the first).
    pub iteration: usize,
    /// Iterations asked for.
    pub iterations: usize,
    /// The seed of the iteration flying.
    pub seed: u64,
    /// How fast it flies (simulated seconds per wall second, or as fast as it can).
    pub speed: TimeScale,
    /// Simulated seconds of the iteration.
    pub time: f64,
    /// The hub's ids of its UAVs.
    pub uavs: Vec<u32>,
    /// What does not change during the run: the map, the area, the pads, the endpoints…
    pub fixed: Value,
    /// The metrics' names (the results' columns).
    pub columns: Vec<&'static str>,
    /// The metrics so far.
    pub metrics: Vec<(&'static str, Option<f64>)>,
    /// Each coverage cell's level ([`level`]), row-major, x index first.
    pub levels: Vec<u8>,
    /// The cells whose level changed this iteration, in order: (index, level).
    pub grid_changes: Vec<(u32, u8)>,
    /// The victims of the iteration.
    pub victims: Vec<VictimView>,
    /// The targets' positions.
    pub targets: Vec<[f64; 3]>,
    /// The fire's radius now.
    pub fire_radius: Option<f64>,
    /// The link's changes this iteration: (time, up).
    pub link: Vec<(f64, bool)>,
    /// The rows of the iterations flown.
    pub rows: Vec<Row>,
    /// Stops the run.
    pub cancel: Option<CancellationToken>,
    /// Bumped at every start (a page takes `fixed` again).
    pub epoch: u64,
    /// Bumped at every iteration (a page starts its grid, victims and strip over).
    pub iteration_epoch: u64,
    /// Bumped at every change.
    pub version: u64,
    victims_version: u64,
}

/// What a page has of the scenario.
#[derive(Debug, Default, Clone)]
pub struct ScenarioCursor {
    epoch: u64,
    iteration_epoch: u64,
    version: u64,
    victims: u64,
    grid: usize,
    link: usize,
    rows: usize,
}

/// A whole number within `range` from what the user typed, `default` when empty.
fn whole(
    name: &'static str,
    text: &str,
    default: u64,
    max: u64,
    min: u64,
) -> Result<u64, RequestError> {
    let t = text.trim();
    if t.is_empty() {
        return Ok(default);
    }
    t.parse::<u64>()
        .ok()
        .filter(|n| (min..=max).contains(n))
        .ok_or_else(|| {
            field(
                name,
                format!("{} is not a whole number from {min} to {max}", shown(t)),
            )
        })
}

/// The JSON of a pad.
fn pad_json(pad: &ucc_client::scenario::spec::Pad) -> Value {
    json!({"at": [pad.location[0], pad.location[1]], "radius": pad.radius})
}

/// What does not change during a run of `prepared`.
fn fixed_json(prepared: &Prepared) -> Value {
    let s = &prepared.scenario;
    // The victims are drawn from the scenario's state (found or not), not as the map's.
    let mut geometry = ucc_client::picture::MapGeometry::from(&prepared.map);
    let victims: Vec<_> = geometry.victims.drain(..).map(|v| v.footprint).collect();
    geometry.footprints.retain(|f| !victims.contains(f));
    let grid = s.search.as_ref().map(|search| {
        let [[x0, y0], [x1, y1]] = search.area;
        let shape = [
            ((x1 - x0) / search.cell).ceil().max(1.0) as usize,
            ((y1 - y0) / search.cell).ceil().max(1.0) as usize,
        ];
        json!({"origin": [x0, y0], "cell": search.cell, "shape": shape, "area": search.area})
    });
    let mut pads = Vec::new();
    if let Some(b) = &s.base {
        pads.push(json!({"name": "base", "pad": pad_json(b)}));
    }
    if let Some(d) = &s.delivery {
        pads.push(json!({"name": "pickup", "pad": pad_json(&d.pickup)}));
        pads.push(json!({"name": "drop-off", "pad": pad_json(&d.dropoff)}));
    }
    json!({
        "name": s.name,
        "kind": s.kind.name(),
        "description": s.description,
        "map": s.map,
        "time_limit": s.time_limit,
        "geometry": super::update::geometry_json(Some(&geometry)),
        "grid": grid,
        "pads": pads,
        "endpoints": s.relay.map(|r| r.endpoints.map(|e| [e[0], e[1]])),
        "fire": s.fire.map(|f| json!({"center": f.center, "radius": f.radius})),
        "targets": s.targets.iter().map(|t| t.name.clone()).collect::<Vec<_>>(),
        "waypoints": s.delivery.as_ref().map(|d| d.waypoints.iter().map(|w| [w[0], w[1]]).collect::<Vec<_>>()),
    })
}

/// A number for the page: finite, else null.
fn finite(v: f64) -> Value {
    if v.is_finite() {
        Value::from(v)
    } else {
        Value::Null
    }
}

impl Hub {
    /// Checks a scenario start; creates its UAVs (the last scenario's, ended, go).
    pub(super) fn scenario_start(
        &mut self,
        name: &str,
        iterations: &str,
        seed: &str,
        speed: &str,
    ) -> Result<Action, RequestError> {
        let name = name.trim();
        // Only the embedded scenarios: a page never names a file on this machine.
        let Some((known, _)) = EMBEDDED.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)) else {
            let names: Vec<&str> = EMBEDDED.iter().map(|(n, _)| *n).collect();
            return Err(field(
                "scenario",
                format!(
                    "{} is not an embedded scenario (they are: {})",
                    shown(name),
                    names.join(", ")
                ),
            ));
        };
        if let Some(s) = &self.scenario
            && matches!(s.status, Status::Running | Status::Stopping)
        {
            return Err(RequestError::State(format!(
                "scenario {} is running: stop it before starting another",
                s.name
            )));
        }
        let iterations = whole(
            "scenario iterations",
            iterations,
            1,
            MAX_SCENARIO_ITERATIONS as u64,
            1,
        )? as usize;
        let scenario = Scenario::lookup(known).map_err(|e| RequestError::State(e.to_string()))?;
        let seed = whole("scenario seed", seed, scenario.seed, u64::MAX, 0)?;
        let speed = match speed.trim() {
            "" => TimeScale::Factor(1.0),
            t => t
                .parse::<TimeScale>()
                .map_err(|e| field("scenario speed", e))?,
        };
        // The UAVs of the last scenario go (they have ended), once this one can start.
        let count = scenario.uav_count();
        let old: Vec<u32> = self
            .scenario
            .as_ref()
            .map_or_else(Vec::new, |s| s.uavs.clone());
        let gone = |u: &Uav| old.contains(&u.id) && !u.flying();
        let kept = self.uavs.iter().filter(|u| !gone(u)).count();
        if kept + count > MAX_UAVS {
            return Err(RequestError::State(format!(
                "scenario {known} has {count} UAVs: at most {MAX_UAVS} in all, remove some first"
            )));
        }
        let prepared = Prepared::new(scenario, self.catalog.clone())
            .map_err(|e| RequestError::State(e.to_string()))?;
        self.uavs.retain(|u| !gone(u));
        let cancel = CancellationToken::new();
        let mut ids = Vec::with_capacity(count);
        let mut index = 0;
        for group in &prepared.scenario.uavs {
            for k in 0..group.count {
                index += 1;
                let id = self.next_id;
                self.next_id += 1;
                let at: [f64; 3] =
                    std::array::from_fn(|i| group.start[i] + k as f64 * group.spacing[i]);
                let name = self.free_name(&format!("UAV{index}"));
                let mut u = Uav::new(
                    id,
                    name.clone(),
                    super::request::prefix_of(&name),
                    group.class.trim_start_matches("USARBot.").to_owned(),
                    group.agent.clone(),
                    Start::Pose {
                        location: Coordinates::new(at[0], at[1], at[2]),
                        rotation: Coordinates::new(0.0, 0.0, 0.0),
                    },
                );
                u.iterations = iterations;
                u.status = Status::Running;
                u.autosave = false;
                u.pictures = ucc_client::Pictures::None;
                u.cancel = Some(cancel.clone());
                self.uavs.push(u);
                ids.push(id);
            }
        }
        let columns = ucc_client::scenario::metrics::Tracker::new(&prepared.scenario, &[], 0)
            .finish(0.0, &prepared.scenario)
            .values
            .iter()
            .map(|(n, _)| *n)
            .collect();
        let epoch = self.scenario_epoch + 1;
        self.scenario_epoch = epoch;
        self.scenario = Some(ScenarioView {
            name: known.to_string(),
            status: Status::Running,
            error: None,
            iteration: 0,
            iterations,
            seed,
            speed,
            time: 0.0,
            uavs: ids.clone(),
            fixed: fixed_json(&prepared),
            columns,
            metrics: Vec::new(),
            levels: Vec::new(),
            grid_changes: Vec::new(),
            victims: Vec::new(),
            targets: Vec::new(),
            fire_radius: None,
            link: Vec::new(),
            rows: Vec::new(),
            cancel: Some(cancel.clone()),
            epoch,
            iteration_epoch: 0,
            version: 0,
            victims_version: 0,
        });
        self.log(
            0,
            "info",
            format!(
                "scenario {known}: {count} UAV(s), {iterations} iteration(s) from seed {seed}, speed {speed}"
            ),
        );
        Ok(Action::Scenario(Box::new(ScenarioPlan {
            prepared: Arc::new(prepared),
            uavs: ids,
            iterations,
            seed,
            cancel,
        })))
    }

    /// Stops the scenario's run (nothing when none runs).
    pub(super) fn scenario_stop(&mut self) -> Result<Action, RequestError> {
        let Some(s) = &mut self.scenario else {
            return Err(RequestError::State("no scenario has been started".into()));
        };
        if let Some(cancel) = &s.cancel
            && s.status == Status::Running
        {
            cancel.cancel();
            s.status = Status::Stopping;
            s.version += 1;
        }
        let ids = s.uavs.clone();
        for id in ids {
            if let Ok(u) = self.uav(id)
                && u.status == Status::Running
            {
                u.status = Status::Stopping;
                u.touch();
            }
        }
        Ok(Action::None)
    }

    /// Changes how fast the scenario flies (also while it runs).
    pub(super) fn scenario_speed(&mut self, value: &str) -> Result<Action, RequestError> {
        let speed = value
            .trim()
            .parse::<TimeScale>()
            .map_err(|e| field("scenario speed", e))?;
        let Some(s) = &mut self.scenario else {
            return Err(RequestError::State("no scenario has been started".into()));
        };
        s.speed = speed;
        s.version += 1;
        Ok(Action::None)
    }

    /// An iteration begins: the UAVs' trails go to the overlay, the grid, victims and strip
    /// start over.
    pub fn scenario_iteration(&mut self, iteration: usize, seed: u64, episode: &Episode) {
        let ids = match &self.scenario {
            Some(s) => s.uavs.clone(),
            None => return,
        };
        for &id in &ids {
            self.new_iteration(id, iteration);
        }
        let Some(s) = &mut self.scenario else { return };
        s.iteration = iteration;
        s.seed = seed;
        s.time = 0.0;
        s.iteration_epoch += 1;
        s.levels = match episode.coverage() {
            Some(g) if g.seen.len() <= MAX_GRID_CELLS => vec![0; g.seen.len()],
            _ => Vec::new(),
        };
        s.grid_changes.clear();
        s.link.clear();
        s.victims.clear();
        s.version += 1;
        self.scenario_sample(episode, true);
    }

    /// The state after a step: each UAV's sample (its trail and live panel); with `all`,
    /// the scenario's things and metrics too.
    pub fn scenario_sample(&mut self, episode: &Episode, all: bool) {
        let Some(s) = &self.scenario else { return };
        let (ids, iteration) = (s.uavs.clone(), s.iteration);
        let time = episode.time();
        for (i, &id) in ids.iter().enumerate() {
            let Some(state) = episode.state(i) else {
                continue;
            };
            self.sample(id, iteration, Live::of(time, state, None, false));
            if episode.crashed(i)
                && let Ok(u) = self.uav(id)
                && u.error.is_none()
            {
                u.error = Some(format!("crashed in iteration {iteration}"));
                u.touch();
            }
        }
        if !all {
            return;
        }
        let Some(s) = &mut self.scenario else { return };
        s.time = time;
        if let Some(grid) = episode.coverage()
            && grid.seen.len() == s.levels.len()
        {
            for (k, (&n, l)) in grid.seen.iter().zip(&mut s.levels).enumerate() {
                let now = level(n);
                if now != *l {
                    *l = now;
                    s.grid_changes.push((k as u32, now));
                }
            }
        }
        let victims: Vec<VictimView> = episode
            .victims()
            .iter()
            .map(|(p, found)| VictimView {
                name: p.name.clone(),
                at: [p.center[0], p.center[1]],
                found: *found,
            })
            .collect();
        if victims != s.victims {
            s.victims = victims;
            s.victims_version += 1;
        }
        s.targets = episode.targets();
        s.fire_radius = episode.fire_radius();
        for &change in episode.link_changes().iter().skip(s.link.len()) {
            if s.link.len() < MAX_LINK_CHANGES {
                s.link.push(change);
            }
        }
        s.metrics = episode.metrics().values;
        s.version += 1;
    }

    /// An iteration ended: its row of results.
    pub fn scenario_row(&mut self, iteration: usize, outcome: &Outcome) {
        let Some(s) = &mut self.scenario else { return };
        s.rows.push(Row {
            iteration,
            seed: outcome.seed,
            ending: match outcome.ending {
                Ending::Done => "done",
                Ending::TimeUp => "time_up",
            },
            values: outcome.metrics.values.iter().map(|(_, v)| *v).collect(),
        });
        s.metrics = outcome.metrics.values.clone();
        s.version += 1;
    }

    /// The run ended (done, stopped or failed): its UAVs too.
    pub fn scenario_finished(&mut self, status: Status, error: Option<String>) {
        let Some(s) = &mut self.scenario else { return };
        s.status = status.clone();
        s.error = error.clone();
        s.cancel = None;
        s.version += 1;
        for id in s.uavs.clone() {
            self.finished(id, status.clone(), error.clone());
        }
    }

    /// What a page has not seen of the scenario (`None`: nothing new).
    pub fn scenario_json(&self, cursor: &mut ScenarioCursor) -> Option<Value> {
        let s = self.scenario.as_ref()?;
        if cursor.epoch == s.epoch && cursor.version == s.version {
            return None;
        }
        let mut out = serde_json::Map::new();
        if cursor.epoch != s.epoch {
            *cursor = ScenarioCursor {
                epoch: s.epoch,
                ..ScenarioCursor::default()
            };
            out.insert("fixed".into(), s.fixed.clone());
        }
        if cursor.iteration_epoch != s.iteration_epoch {
            cursor.iteration_epoch = s.iteration_epoch;
            cursor.grid = 0;
            cursor.link = 0;
            cursor.victims = 0;
            out.insert("reset".into(), true.into());
            // The whole grid, one digit a cell; then only the changes.
            if !s.levels.is_empty() {
                let full: String = s.levels.iter().map(|&l| char::from(b'0' + l)).collect();
                out.insert("grid_full".into(), full.into());
            }
            cursor.grid = s.grid_changes.len();
        }
        let changes = &s.grid_changes[cursor.grid.min(s.grid_changes.len())..];
        if !changes.is_empty() {
            let flat: Vec<u32> = changes
                .iter()
                .flat_map(|&(k, l)| [k, u32::from(l)])
                .collect();
            out.insert("grid".into(), flat.into());
        }
        cursor.grid = s.grid_changes.len();
        if cursor.victims != s.victims_version {
            cursor.victims = s.victims_version;
            out.insert(
                "victims".into(),
                s.victims
                    .iter()
                    .map(|v| json!({"name": v.name, "at": v.at.map(finite), "found": v.found.map(finite)}))
                    .collect(),
            );
        }
        let link = &s.link[cursor.link.min(s.link.len())..];
        if !link.is_empty() {
            out.insert(
                "link".into(),
                link.iter().map(|&(t, up)| json!([finite(t), up])).collect(),
            );
        }
        cursor.link = s.link.len();
        let rows = &s.rows[cursor.rows.min(s.rows.len())..];
        if !rows.is_empty() {
            out.insert(
                "rows".into(),
                rows.iter()
                    .map(|r| {
                        json!({
                            "iteration": r.iteration,
                            "seed": r.seed.to_string(),
                            "ending": r.ending,
                            "values": r.values.iter().map(|v| v.map_or(Value::Null, finite)).collect::<Vec<_>>(),
                        })
                    })
                    .collect(),
            );
        }
        cursor.rows = s.rows.len();
        cursor.version = s.version;
        out.insert("name".into(), s.name.clone().into());
        out.insert("status".into(), json!(s.status));
        out.insert("error".into(), json!(s.error));
        out.insert("iteration".into(), s.iteration.into());
        out.insert("iterations".into(), s.iterations.into());
        // As text: a seed may exceed what JavaScript's numbers hold exactly.
        out.insert("seed".into(), s.seed.to_string().into());
        out.insert("speed".into(), s.speed.to_string().into());
        out.insert("time".into(), finite(s.time));
        out.insert("uavs".into(), json!(s.uavs));
        out.insert("columns".into(), json!(s.columns));
        out.insert(
            "metrics".into(),
            s.metrics
                .iter()
                .map(|(n, v)| json!([n, v.map_or(Value::Null, finite)]))
                .collect(),
        );
        out.insert(
            "targets".into(),
            s.targets
                .iter()
                .map(|t| json!([finite(t[0]), finite(t[1])]))
                .collect(),
        );
        out.insert(
            "fire_radius".into(),
            s.fire_radius.map_or(Value::Null, finite),
        );
        out.insert(
            "link_up".into(),
            s.link.last().map_or(Value::Null, |&(_, up)| up.into()),
        );
        Some(Value::Object(out))
    }

    /// The results so far as CSV, as `ucc scenario` writes them (`None`: no scenario).
    pub fn scenario_csv(&self) -> Option<String> {
        let s = self.scenario.as_ref()?;
        let mut out = format!("iteration,seed,ending,{}\n", s.columns.join(","));
        for r in &s.rows {
            let cells: Vec<String> = r
                .values
                .iter()
                .map(|v| v.map_or(String::new(), |v| format!("{v:.3}")))
                .collect();
            out.push_str(&format!(
                "{},{},{},{}\n",
                r.iteration,
                r.seed,
                r.ending,
                cells.join(",")
            ));
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_grow_with_the_log_of_the_time_seen() {
        assert_eq!(level(0), 0);
        assert_eq!(level(1), 1);
        assert_eq!(level(2), 2);
        assert_eq!(level(3), 2);
        assert_eq!(level(4), 3);
        assert_eq!(level(256), LEVELS);
        assert_eq!(level(u32::MAX), LEVELS);
    }
}
