//! What an iteration is scored by (docs/scenarios.md): every figure is measured against the
//! world's ground truth, not against what the agents believe.

use usar_server::sim::World;
use usar_server::sim::map::Placed;

use super::model::{Delivery, Kind, Scenario, Sensor, fall, on_pad};
use crate::agents::team::{Act, Board, Brief};

/// The figures of one iteration, in the order of the results table's columns (`None`: not
/// measured, an empty cell).
#[derive(Debug, Clone, PartialEq)]
pub struct Metrics {
    /// (column name, value).
    pub values: Vec<(&'static str, Option<f64>)>,
}

impl Metrics {
    /// The value of `name` (`None` when absent or not measured).
    pub fn get(&self, name: &str) -> Option<f64> {
        self.values
            .iter()
            .find(|(n, _)| *n == name)
            .and_then(|(_, v)| *v)
    }
}

/// The coverage grid: how many periods each cell was inside a footprint.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Corner (x_min, y_min), metres.
    pub origin: [f64; 2],
    /// Cell side, metres.
    pub cell: f64,
    /// Cells along x and y.
    pub shape: [usize; 2],
    /// Row-major, x index first.
    pub seen: Vec<u32>,
}

impl Grid {
    /// The fraction of cells seen at least once.
    pub fn covered(&self) -> f64 {
        self.seen.iter().filter(|&&n| n > 0).count() as f64 / self.seen.len().max(1) as f64
    }

    /// Marks the cells whose centres lie within `r` of `(x, y)`.
    fn mark(&mut self, x: f64, y: f64, r: f64) {
        let [nx, ny] = self.shape;
        let c = self.cell;
        let range = |v: f64, o: f64, n: usize| {
            let lo = ((v - r - o) / c - 0.5).ceil().max(0.0) as usize;
            let hi = (((v + r - o) / c - 0.5).floor().max(-1.0) + 1.0).min(n as f64) as usize;
            lo..hi
        };
        for i in range(x, self.origin[0], nx) {
            let cx = self.origin[0] + (i as f64 + 0.5) * c;
            for j in range(y, self.origin[1], ny) {
                let cy = self.origin[1] + (j as f64 + 0.5) * c;
                if (cx - x).powi(2) + (cy - y).powi(2) <= r * r {
                    let k = i * ny + j;
                    self.seen[k] = self.seen[k].saturating_add(1);
                }
            }
        }
    }
}

/// The footprint radius of the downward sensor at height `h` (0 on the ground).
pub fn footprint(sensor: &Sensor, h: f64) -> f64 {
    if h < 0.3 {
        return 0.0;
    }
    let r = h * (sensor.fov.to_radians() / 2.0).tan();
    r.min((sensor.range.powi(2) - h * h).max(0.0).sqrt())
}

/// Measures an iteration as it flies.
#[derive(Debug, Clone)]
pub struct Tracker {
    kind: Kind,
    sensor: Sensor,
    /// Victims and when they were found.
    pub victims: Vec<(Placed, Option<f64>)>,
    /// The coverage grid (search).
    pub grid: Option<Grid>,
    /// Crashes so far.
    pub crashes: usize,
    /// Full batteries used, summed over the UAVs.
    pub battery_used: f64,
    /// Recharges on the base pad.
    pub recharges: usize,
    /// The relay's link changes (time, connected).
    pub link_changes: Vec<(f64, bool)>,
    connected_time: f64,
    outage_start: Option<f64>,
    longest_outage: f64,
    observed_time: f64,
    error_sum: f64,
    error_max: f64,
    error_count: f64,
    seen_time: f64,
    /// Per perimeter sample: when its current or last visit began, and whether a footprint
    /// is on it now.
    samples: Vec<(Option<f64>, bool)>,
    intervals: Vec<f64>,
    deliveries: usize,
    delivery_time: Option<f64>,
    drop_error: Option<f64>,
    delivery: Option<Delivery>,
}

impl Tracker {
    /// A tracker for `scenario` with these victims.
    pub fn new(scenario: &Scenario, victims: &[Placed], _uavs: usize) -> Self {
        let grid = scenario.search.as_ref().map(|s| {
            let [[x0, y0], [x1, y1]] = s.area;
            let shape = [
                ((x1 - x0) / s.cell).ceil().max(1.0) as usize,
                ((y1 - y0) / s.cell).ceil().max(1.0) as usize,
            ];
            Grid {
                origin: [x0, y0],
                cell: s.cell,
                shape,
                seen: vec![0; shape[0] * shape[1]],
            }
        });
        Self {
            kind: scenario.kind,
            sensor: scenario.sensor,
            victims: victims.iter().map(|v| (v.clone(), None)).collect(),
            grid,
            crashes: 0,
            battery_used: 0.0,
            recharges: 0,
            link_changes: Vec::new(),
            connected_time: 0.0,
            outage_start: None,
            longest_outage: 0.0,
            observed_time: 0.0,
            error_sum: 0.0,
            error_max: 0.0,
            error_count: 0.0,
            seen_time: 0.0,
            samples: vec![(None, false); scenario.fire.map_or(0, |f| f.samples)],
            intervals: Vec::new(),
            deliveries: 0,
            delivery_time: None,
            drop_error: None,
            delivery: scenario.delivery.clone(),
        }
    }

    /// One period: coverage, finds, sightings, the link, the perimeter.
    #[allow(clippy::too_many_arguments)]
    pub fn observe(
        &mut self,
        time: f64,
        period: f64,
        uavs: &[[f64; 3]],
        targets: &[[f64; 3]],
        world: &World,
        briefs: &[Brief],
        board: &mut Board,
        log: &mut Vec<String>,
    ) {
        let feet: Vec<f64> = uavs
            .iter()
            .map(|p| footprint(&self.sensor, -p[2]))
            .collect();
        self.observed_time += period;
        if let Some(grid) = &mut self.grid {
            for (p, &r) in uavs.iter().zip(&feet) {
                if r > 0.0 {
                    grid.mark(p[0], p[1], r);
                }
            }
        }
        for (victim, found) in &mut self.victims {
            if found.is_some() {
                continue;
            }
            let c = victim.center;
            let by = uavs.iter().zip(&feet).position(|(p, &r)| {
                r > 0.0
                    && (p[0] - c[0]).hypot(p[1] - c[1]) <= r
                    && world.obstacles_between(*p, c) == 0
            });
            if let Some(k) = by {
                *found = Some(time);
                board.found.push(c);
                log.push(format!(
                    "t={time:.1}s UAV{}: found victim {} at ({:.1}, {:.1})",
                    k + 1,
                    victim.name,
                    c[0],
                    c[1]
                ));
            }
        }
        // Targets: seen when inside a footprint with a clear line; the tracking error is the
        // horizontal distance to the nearest UAV.
        for (j, t) in targets.iter().enumerate() {
            let seen = uavs.iter().zip(&feet).any(|(p, &r)| {
                r > 0.0
                    && (p[0] - t[0]).hypot(p[1] - t[1]) <= r
                    && world.obstacles_between(*p, *t) == 0
            });
            if seen {
                if board.targets[j].is_none() {
                    log.push(format!("t={time:.1}s target {} first seen", j + 1));
                }
                board.targets[j] = Some((*t, time));
                self.seen_time += period / targets.len() as f64;
            }
            if board.targets[j].is_some() {
                let e = uavs
                    .iter()
                    .map(|p| (p[0] - t[0]).hypot(p[1] - t[1]))
                    .fold(f64::INFINITY, f64::min);
                if e.is_finite() {
                    self.error_sum += e;
                    self.error_count += 1.0;
                    self.error_max = self.error_max.max(e);
                }
            }
        }
        // The relay: endpoints connected through UAVs, hop by hop above the cut-off.
        if let Some(relay) = briefs.first().and_then(|b| b.relay) {
            let radio = briefs[0].radio;
            let mut nodes: Vec<[f64; 3]> = vec![relay.endpoints[0], relay.endpoints[1]];
            nodes.extend(uavs.iter().filter(|p| -p[2] > 0.5));
            let n = nodes.len();
            let mut reached = vec![false; n];
            reached[0] = true;
            let mut stack = vec![0];
            while let Some(a) = stack.pop() {
                for b in 0..n {
                    if !reached[b] {
                        let walls = world.obstacles_between(nodes[a], nodes[b]);
                        if radio.reaches(nodes[a], nodes[b], f64::from(walls)) {
                            reached[b] = true;
                            stack.push(b);
                        }
                    }
                }
            }
            let up = reached[1];
            if self.link_changes.last().is_none_or(|&(_, was)| was != up) {
                if self.link_changes.is_empty() || up {
                    log.push(format!(
                        "t={time:.1}s link between the endpoints {}",
                        if up { "up" } else { "down" }
                    ));
                } else {
                    log.push(format!("t={time:.1}s link between the endpoints lost"));
                }
                self.link_changes.push((time, up));
            }
            if up {
                self.connected_time += period;
                if let Some(start) = self.outage_start.take() {
                    self.longest_outage = self.longest_outage.max(time - start);
                }
            } else if self.outage_start.is_none() {
                self.outage_start = Some(time - period);
            }
        }
        // The fire: its radius now; a UAV whose footprint reaches the edge senses it, and
        // visits the perimeter samples under its footprint.
        if let Some(fire) = briefs.first().and_then(|b| b.fire) {
            let radius = fire.radius + fire.rate * time;
            let n = self.samples.len();
            for (p, &r) in uavs.iter().zip(&feet) {
                if r <= 0.0 {
                    continue;
                }
                let d = (p[0] - fire.center[0]).hypot(p[1] - fire.center[1]);
                if (d - radius).abs() <= r {
                    board.fire_radius = Some(radius);
                }
            }
            // The update interval: between the starts of two visits of a sample point.
            for (k, (began, inside)) in self.samples.iter_mut().enumerate() {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                let s = [
                    fire.center[0] + radius * a.cos(),
                    fire.center[1] + radius * a.sin(),
                ];
                let visited = uavs
                    .iter()
                    .zip(&feet)
                    .any(|(p, &r)| r > 0.0 && (p[0] - s[0]).hypot(p[1] - s[1]) <= r);
                if visited && !*inside {
                    if let Some(t) = *began {
                        self.intervals.push(time - t);
                    }
                    *began = Some(time);
                }
                *inside = visited;
            }
        }
    }

    /// An agent's request: a pickup granted when landed on the pickup pad, a drop anywhere
    /// (a flying UAV's payload falls; it is delivered when it lands within the drop-off pad).
    #[allow(clippy::too_many_arguments)]
    pub fn act(
        &mut self,
        act: Act,
        i: usize,
        time: f64,
        p: [f64; 3],
        v: [f64; 3],
        board: &mut Board,
        log: &mut Vec<String>,
        name: &str,
        mut set_payload: impl FnMut(f64),
    ) {
        let Some(job) = &self.delivery else { return };
        let speed = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let carrying = board.carrying.get(i).copied().unwrap_or(false);
        match act {
            Act::PickUp => {
                if !carrying && self.deliveries == 0 && on_pad(&job.pickup, p, speed) {
                    board.carrying[i] = true;
                    set_payload(job.payload);
                    log.push(format!(
                        "t={time:.1}s {name}: picked up the payload ({} kg)",
                        job.payload
                    ));
                }
            }
            Act::Drop => {
                if !carrying {
                    return;
                }
                board.carrying[i] = false;
                set_payload(0.0);
                let (at, fell) = fall(p, v, job.dropoff.location[2]);
                let error =
                    (at[0] - job.dropoff.location[0]).hypot(at[1] - job.dropoff.location[1]);
                self.drop_error = Some(error);
                let how = if fell > 0.05 {
                    format!("dropped; it fell {fell:.2} s and")
                } else {
                    "set down; it".to_owned()
                };
                if error <= job.dropoff.radius {
                    self.deliveries += 1;
                    self.delivery_time.get_or_insert(time);
                    log.push(format!("t={time:.1}s {name}: payload {how} lies {error:.2} m from the pad's centre: delivered"));
                } else {
                    log.push(format!("t={time:.1}s {name}: payload {how} lies {error:.2} m from the pad's centre: missed the pad"));
                }
            }
        }
    }

    /// The figures at the end.
    pub fn finish(&self, time: f64, scenario: &Scenario) -> Metrics {
        let mut values: Vec<(&'static str, Option<f64>)> = vec![
            ("time_s", Some(time)),
            ("crashes", Some(self.crashes as f64)),
            ("battery_used", Some(self.battery_used)),
            ("recharges", Some(self.recharges as f64)),
        ];
        match self.kind {
            Kind::Search => {
                let found: Vec<f64> = self.victims.iter().filter_map(|(_, t)| *t).collect();
                let all = found.len() == self.victims.len() && !self.victims.is_empty();
                values.extend([
                    (
                        "coverage_pct",
                        self.grid.as_ref().map(|g| 100.0 * g.covered()),
                    ),
                    ("victims_found", Some(found.len() as f64)),
                    ("victims_total", Some(self.victims.len() as f64)),
                    ("first_find_s", found.iter().copied().reduce(f64::min)),
                    (
                        "all_found_s",
                        if all {
                            found.iter().copied().reduce(f64::max)
                        } else {
                            None
                        },
                    ),
                ]);
            }
            Kind::Relay => {
                let open = self.outage_start.map_or(0.0, |s| time - s);
                values.extend([
                    (
                        "link_pct",
                        Some(100.0 * self.connected_time / self.observed_time.max(1e-9)),
                    ),
                    ("longest_outage_s", Some(self.longest_outage.max(open))),
                ]);
            }
            Kind::Tracking => {
                if !scenario.targets.is_empty() {
                    values.extend([
                        (
                            "target_seen_pct",
                            Some(100.0 * self.seen_time / self.observed_time.max(1e-9)),
                        ),
                        (
                            "tracking_error_m",
                            (self.error_count > 0.0).then(|| self.error_sum / self.error_count),
                        ),
                        (
                            "tracking_error_max_m",
                            (self.error_count > 0.0).then_some(self.error_max),
                        ),
                    ]);
                }
                if scenario.fire.is_some() {
                    let mean = (!self.intervals.is_empty())
                        .then(|| self.intervals.iter().sum::<f64>() / self.intervals.len() as f64);
                    let max = self.intervals.iter().copied().reduce(f64::max);
                    values.extend([("update_interval_s", mean), ("update_interval_max_s", max)]);
                }
            }
            Kind::Delivery => {
                values.extend([
                    ("deliveries", Some(self.deliveries as f64)),
                    ("delivery_time_s", self.delivery_time),
                    ("drop_error_m", self.drop_error),
                ]);
            }
        }
        if let Some(keep) = &scenario.metrics {
            values.retain(|(n, _)| *n == "time_s" || keep.iter().any(|k| k == n));
        }
        Metrics { values }
    }
}
