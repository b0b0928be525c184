//! One iteration of a scenario, flown in-process on the simulator's [`World`]: lockstep by
//! construction (the agents step every period of simulated time, whatever the wall clock
//! does), deterministic under the seed, and as fast as the world steps.

use std::borrow::Cow;
use std::path::Path;
use std::sync::Arc;

use usar_proto::record::{Direction, RecordFile};

use usar_proto::{Command, Init, Vec3};
use usar_server::sim::map::Placed;
use usar_server::sim::{ClientId, Map, RobotCatalog, SimConfig, World};

use super::metrics::{Metrics, Tracker};
use super::model::{Kind, Scenario, Sharing, on_pad};
use super::spec::ScenarioError;
use crate::agents::team::random::SplitMix;
use crate::agents::team::{self, Act, Board, Brief, TeamAgent, TeamStep};
use crate::speed::SpeedCommand;
use crate::uav::UavState;

/// Seconds between two trajectory samples kept for the picture.
const TRACK_EVERY: f64 = 0.5;

/// What the world needs, loaded once for every iteration of a run.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The scenario.
    pub scenario: Scenario,
    /// Its map, without the drawn victims.
    pub map: Map,
    /// The robot classes, with the scenario's battery overrides.
    pub catalog: RobotCatalog,
}

impl Prepared {
    /// Loads the map and the classes; every class must exist.
    pub fn new(scenario: Scenario, catalog: RobotCatalog) -> Result<Self, ScenarioError> {
        let what = scenario
            .path
            .clone()
            .unwrap_or_else(|| format!("embedded:{}", scenario.name).into());
        let invalid = |message: String| ScenarioError::Invalid {
            path: what.clone(),
            line: 0,
            message,
        };
        let map = Map::lookup(&scenario.map).map_err(|e| invalid(format!("`map`: {e}")))?;
        let mut catalog = catalog;
        for group in &scenario.uavs {
            let class = catalog.get_mut(&group.class).ok_or_else(|| {
                invalid(format!(
                    "[[uav]] `class` {:?}: no such robot class",
                    group.class
                ))
            })?;
            if let Some(b) = group.battery {
                class.battery = Some(b);
            }
        }
        if !scenario.targets.is_empty() && catalog.get(TARGET_CLASS).is_none() {
            return Err(invalid(format!(
                "targets need the robot class {TARGET_CLASS}"
            )));
        }
        Ok(Self {
            scenario,
            map,
            catalog,
        })
    }
}

/// The class the world spawns for a moving target.
pub const TARGET_CLASS: &str = "USARBot.Target";

/// How an iteration ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// Every agent said it was done.
    Done,
    /// The time limit.
    TimeUp,
}

/// One iteration's result: its metrics and what the picture draws.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The seed it flew.
    pub seed: u64,
    /// How it ended.
    pub ending: Ending,
    /// The figures.
    pub metrics: Metrics,
    /// Each UAV's path, sampled every half second.
    pub tracks: Vec<Vec<[f64; 3]>>,
    /// Each target's path.
    pub target_tracks: Vec<Vec<[f64; 3]>>,
    /// The victims of the iteration (the map's and the drawn ones) and when each was found.
    pub victims: Vec<(Placed, Option<f64>)>,
    /// Times seen per coverage cell (row-major, x rows), with the grid's shape.
    pub coverage: Option<super::metrics::Grid>,
    /// The relay's link state over time: (time, connected), one entry per change.
    pub link: Vec<(f64, bool)>,
    /// The fire's radius at the end.
    pub fire_radius: Option<f64>,
    /// The log lines, with simulated times.
    pub log: Vec<String>,
}

struct Flyer {
    client: ClientId,
    name: String,
    agent: Box<dyn TeamAgent>,
    state: UavState,
    done: bool,
    crashed: bool,
    charge: f64,
    last_truth: Option<[f64; 3]>,
    velocity: [f64; 3],
    level: Option<f64>,
    /// The INIT line that spawned it (for a recording).
    init: String,
    /// Recharged during its present visit to the pad.
    recharged: bool,
}

struct Mover {
    client: ClientId,
    waypoint: usize,
    rng: SplitMix,
    goal: Option<[f64; 2]>,
}

fn init(class: &str, name: &str, at: [f64; 3]) -> Command {
    Command::Init(Init {
        class_name: class.to_owned(),
        name: Some(name.to_owned()),
        location: Some(Vec3::new(at[0], at[1], at[2])),
        rotation: Some(Vec3::new(0.0, 0.0, 0.0)),
        start: None,
    })
}

/// Draws `n` victims in the search area, seeded, none inside a solid or another victim.
fn draw_victims(map: &mut Map, scenario: &Scenario, seed: u64) -> Result<(), String> {
    let Some(search) = &scenario.search else {
        return Ok(());
    };
    let mut rng = SplitMix(seed ^ 0x5EED_1C71_u64);
    let [[x0, y0], [x1, y1]] = search.area;
    for i in 0..search.victims {
        let mut placed = false;
        for _ in 0..1000 {
            let center = [
                x0 + 1.0 + rng.next_f64() * (x1 - x0 - 2.0).max(0.0),
                y0 + 1.0 + rng.next_f64() * (y1 - y0 - 2.0).max(0.0),
                -usar_server::sim::map::VICTIM_SIZE[2] / 2.0,
            ];
            let p = Placed {
                name: format!("Drawn{}", i + 1),
                class: search.victim_class.clone(),
                victim: true,
                center,
                size: usar_server::sim::map::VICTIM_SIZE,
                yaw: rng.next_f64() * std::f64::consts::PI,
                color: None,
            };
            if map.add_placed(p).is_ok() {
                placed = true;
                break;
            }
        }
        if !placed {
            return Err(format!(
                "[search]: no free place for victim {} of {} in the area after 1000 draws",
                i + 1,
                search.victims
            ));
        }
    }
    Ok(())
}

/// Flies one iteration with `seed`, every UAV by its agent.
pub fn fly(prepared: &Prepared, seed: u64, threads: usize) -> Result<Outcome, String> {
    fly_recorded(prepared, seed, threads, None)
}

/// [`fly`], recording each UAV's traffic into `record` ([`Episode::record`]); a recording
/// that stops (a full disk) fails the iteration, naming the file.
pub fn fly_recorded(
    prepared: &Prepared,
    seed: u64,
    threads: usize,
    record: Option<&Path>,
) -> Result<Outcome, String> {
    let mut episode = Episode::new(Arc::new(prepared.clone()), seed, threads)?;
    if let Some(dir) = record {
        episode.record(dir)?;
    }
    while episode.step(&[]).is_none() {}
    if let Some(e) = episode.record_error() {
        return Err(e.to_owned());
    }
    Ok(episode.finish())
}

/// One iteration, stepped a period at a time: [`fly`] for the agents alone, or with some
/// UAVs' commands given from outside (a learning agent, the Python package).
pub struct Episode {
    prepared: Arc<Prepared>,
    seed: u64,
    world: World,
    flyers: Vec<Flyer>,
    movers: Vec<Mover>,
    briefs: Vec<Brief>,
    tracker: Tracker,
    board: Board,
    log: Vec<String>,
    tracks: Vec<Vec<[f64; 3]>>,
    target_tracks: Vec<Vec<[f64; 3]>>,
    out: Vec<(ClientId, usar_proto::ServerMessage)>,
    next_sample: f64,
    first: u64,
    ticks: usize,
    period: f64,
    total: usize,
    ending: Option<Ending>,
    /// Each UAV's traffic ([`Episode::record`]), by index.
    recording: Vec<RecordFile>,
    /// Why a recording stopped.
    record_error: Option<String>,
}

impl Episode {
    /// Spawns the UAVs and the targets of `prepared` with `seed` (victims drawn from it).
    pub fn new(prepared: Arc<Prepared>, seed: u64, threads: usize) -> Result<Self, String> {
        let scenario = &prepared.scenario;
        let mut map = prepared.map.clone();
        draw_victims(&mut map, scenario, seed)?;
        let victims: Vec<Placed> = map.placed().iter().filter(|p| p.victim).cloned().collect();
        let config = SimConfig {
            seed,
            threads: threads.max(1),
            ..SimConfig::default()
        };
        let mut world = World::new(map, prepared.catalog.clone(), config);
        let dt = world.dt();
        let ticks = ((scenario.period / dt).round() as usize).max(1);
        let period = ticks as f64 * dt;

        // UAVs, in group order.
        let mut flyers: Vec<Flyer> = Vec::new();
        let mut briefs = Vec::new();
        let total = scenario.uav_count();
        let mut first_index = 0;
        for group in &scenario.uavs {
            let members: Vec<usize> = (first_index..first_index + group.count).collect();
            first_index += group.count;
            let class = prepared.catalog.get(&group.class).ok_or("class vanished")?;
            for (k, &index) in members.iter().enumerate() {
                let at = std::array::from_fn(|i| group.start[i] + k as f64 * group.spacing[i]);
                let client = world.connect();
                let name = format!("UAV{}", index + 1);
                let spawn = init(&group.class, &name, at);
                let init_line = spawn.to_string();
                world.command(client, spawn);
                if world.robot_count() != index + 1 {
                    return Err(format!(
                        "{name} ({}) cannot spawn at {at:?}: the place is inside a solid or another robot",
                        group.class
                    ));
                }
                let info = team::info(&group.agent).ok_or("agent vanished")?;
                let h = group.altitude;
                let half = (scenario.sensor.fov.to_radians() / 2.0).tan();
                let footprint =
                    (h * half).min((scenario.sensor.range.powi(2) - h * h).max(0.0).sqrt());
                let spot = scenario
                    .base
                    .map_or(at, |b| team::landing_spot(&b, at, index));
                if let Some(base) = &scenario.base {
                    let r = team::distance2(spot, base.location);
                    if r > base.radius {
                        return Err(format!(
                            "{name} has no room on the base pad: its landing spot is {r:.1} m \
                             from the centre and the pad's radius is {} m (make [base] \
                             `radius` at least {:.1})",
                            base.radius,
                            r + 0.5
                        ));
                    }
                }
                briefs.push(Brief {
                    index,
                    group: members.clone(),
                    team: total,
                    seed,
                    altitude: h,
                    footprint,
                    speed: class
                        .flight
                        .max_linear_speed
                        .min(class.flight.max_lateral_speed),
                    base: scenario.base,
                    start: at,
                    spot,
                    search: scenario.search.clone(),
                    relay: scenario.relay,
                    radio: scenario.radio,
                    fire: scenario.fire,
                    targets: scenario.targets.iter().map(|t| t.start).collect(),
                    delivery: scenario.delivery.clone(),
                    time_limit: scenario.time_limit,
                });
                flyers.push(Flyer {
                    client,
                    name,
                    agent: (info.create)(),
                    state: UavState::new(),
                    done: false,
                    crashed: false,
                    charge: 0.0,
                    last_truth: None,
                    velocity: [0.0; 3],
                    level: None,
                    init: init_line,
                    recharged: false,
                });
            }
        }
        let mut movers = Vec::new();
        for (j, t) in scenario.targets.iter().enumerate() {
            let client = world.connect();
            world.command(client, init(TARGET_CLASS, &t.name, t.start));
            if world.robot_count() != total + j + 1 {
                return Err(format!(
                    "target {} cannot spawn at {:?}: the place is taken",
                    t.name, t.start
                ));
            }
            movers.push(Mover {
                client,
                waypoint: 0,
                rng: SplitMix(seed ^ (j as u64 + 1).wrapping_mul(0x9E37_79B9)),
                goal: None,
            });
        }
        for (f, b) in flyers.iter_mut().zip(&briefs) {
            f.agent.start(b);
        }
        let tracker = Tracker::new(scenario, &victims, total);
        let board = Board {
            positions: vec![None; total],
            batteries: vec![None; total],
            charging: vec![false; total],
            carrying: vec![false; total],
            targets: vec![None; scenario.targets.len()],
            ..Board::default()
        };
        let log = Vec::new();
        let tracks = vec![Vec::new(); total];
        let target_tracks = vec![Vec::new(); scenario.targets.len()];
        let out = Vec::new();
        let next_sample = 0.0;
        let first = flyers.first().map_or(0, |f| f.client.0);
        Ok(Self {
            prepared,
            seed,
            world,
            flyers,
            movers,
            briefs,
            tracker,
            board,
            log,
            tracks,
            target_tracks,
            out,
            next_sample,
            first,
            ticks,
            period,
            total,
            ending: None,
            recording: Vec::new(),
            record_error: None,
        })
    }

    /// From now on (call it before the first step), records each UAV's traffic as
    /// `usar-server --record` would (docs/recording.md): `dir/connection-NNNN.usarlog`, UAV
    /// k in connection k, holding the game info, its INIT, every line the world sent it and
    /// every command it flew, stamped with simulated time. A write error stops the recording
    /// (see [`Episode::record_error`]); the flight goes on.
    pub fn record(&mut self, dir: &Path) -> Result<(), String> {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let time = self.world.time();
        let info = self.world.game_info().to_string();
        self.recording.clear();
        for (i, f) in self.flyers.iter().enumerate() {
            let path = dir.join(format!("connection-{:04}.usarlog", i + 1));
            let mut file = RecordFile::create(&path)
                .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
            let wrote = file.with(|w| {
                w.write_at(time, Direction::Server, &info)?;
                w.write(Direction::Client, &f.init)
            });
            if let Err(stopped) = wrote {
                return Err(format!(
                    "cannot write {}: {}",
                    path.display(),
                    stopped.error
                ));
            }
            self.recording.push(file);
        }
        Ok(())
    }

    /// Why the recording stopped (a full disk), naming the file; `None` while it goes on.
    pub fn record_error(&self) -> Option<&str> {
        self.record_error.as_deref()
    }

    /// Writes one line into UAV `i`'s recording, if there is one.
    fn note(
        recording: &mut [RecordFile],
        error: &mut Option<String>,
        i: usize,
        time: f64,
        direction: Direction,
        line: &dyn std::fmt::Display,
    ) {
        let Some(file) = recording.get_mut(i) else {
            return;
        };
        if let Err(stopped) = file.with(|w| w.write_at(time, direction, &line.to_string())) {
            let kept = stopped
                .kept
                .map_or_else(|e| format!("not cut: {e}"), |n| format!("{n} bytes kept"));
            error.get_or_insert(format!(
                "recording {} stopped: {} ({kept})",
                file.path().display(),
                stopped.error
            ));
        }
    }

    /// Steps one period: the world, the metrics, the targets and every agent; the UAVs
    /// with a command in `overrides` (by index; `None` or a short slice: the agent's) fly
    /// that instead, and their agents do not step (a payload is then taken and set down
    /// by standing on the pads).
    /// `Some` once the iteration has ended (then nothing more happens).
    pub fn step(&mut self, overrides: &[Option<SpeedCommand>]) -> Option<Ending> {
        if self.ending.is_some() {
            return self.ending.clone();
        }
        let prepared = Arc::clone(&self.prepared);
        let scenario = &prepared.scenario;
        for _ in 0..self.ticks {
            let from = self.out.len();
            self.world.step(&mut self.out);
            if !self.recording.is_empty() {
                let time = self.world.time();
                for (client, message) in &self.out[from..] {
                    let i = client.0.wrapping_sub(self.first) as usize;
                    if self.flyers.get(i).is_some_and(|f| f.client == *client) {
                        let (files, error) = (&mut self.recording, &mut self.record_error);
                        Self::note(files, error, i, time, Direction::Server, message);
                    }
                }
            }
        }
        for (client, message) in self.out.drain(..) {
            let i = client.0.wrapping_sub(self.first) as usize;
            if let Some(f) = self.flyers.get_mut(i)
                && f.client == client
            {
                f.state.apply(&message);
            }
        }
        let time = self.world.time();
        let truth = self.world.robots_truth();
        let uav_truth: Vec<[f64; 3]> = truth.iter().take(self.total).map(|r| r.location).collect();
        let target_truth: Vec<[f64; 3]> =
            truth.iter().skip(self.total).map(|r| r.location).collect();
        if time >= self.next_sample {
            self.next_sample += TRACK_EVERY;
            for (t, p) in self.tracks.iter_mut().zip(&uav_truth) {
                t.push(*p);
            }
            for (t, p) in self.target_tracks.iter_mut().zip(&target_truth) {
                t.push(*p);
            }
        }
        // Crashes, charging, energy.
        for (i, f) in self.flyers.iter_mut().enumerate() {
            if !f.crashed && (self.world.crashed(f.client) || f.state.crashed()) {
                f.crashed = true;
                self.tracker.crashes += 1;
                self.log.push(format!("t={time:.1}s {}: crashed", f.name));
            }
            let p = uav_truth.get(i).copied().unwrap_or_default();
            f.velocity = f.last_truth.map_or([0.0; 3], |q| {
                std::array::from_fn(|k| (p[k] - q[k]) / self.period)
            });
            let speed = f.velocity.iter().map(|v| v * v).sum::<f64>().sqrt();
            f.last_truth = Some(p);
            let level = team::battery_level(&f.state);
            if let Some(prev) = f.level
                && level < prev
            {
                self.tracker.battery_used += prev - level;
            }
            f.level = Some(level);
            self.board.charging[i] = false;
            if let Some(base) = &scenario.base
                && on_pad(base, p, speed)
                && !f.crashed
            {
                self.board.charging[i] = true;
                f.charge += self.period;
                if f.charge >= base.charge_time && level < 0.999 {
                    // The pad keeps a parked UAV topped up; a recharge counts once a visit.
                    self.world.recharge(f.client);
                    f.charge = 0.0;
                    if !f.recharged {
                        f.recharged = true;
                        self.tracker.recharges += 1;
                        self.log.push(format!(
                            "t={time:.1}s {}: recharged on the base pad",
                            f.name
                        ));
                    }
                }
            } else {
                f.charge = 0.0;
                f.recharged = false;
            }
        }
        self.tracker.observe(
            time,
            self.period,
            &uav_truth,
            &target_truth,
            &self.world,
            &self.briefs,
            &mut self.board,
            &mut self.log,
        );
        // The self.board.
        self.board.time = time;
        for (i, f) in self.flyers.iter().enumerate() {
            self.board.positions[i] = team::position(&f.state);
            self.board.batteries[i] = Some(team::battery_level(&f.state));
        }
        // Targets move.
        for (j, (m, t)) in self.movers.iter_mut().zip(&scenario.targets).enumerate() {
            let Some(&p) = target_truth.get(j) else {
                continue;
            };
            let goal = if t.path.is_empty() {
                let [[x0, y0], [x1, y1]] = t.bounds.unwrap_or([[p[0], p[1]], [p[0], p[1]]]);
                let reached = m
                    .goal
                    .is_none_or(|g| (g[0] - p[0]).hypot(g[1] - p[1]) < 1.0);
                if reached {
                    m.goal = Some([
                        x0 + m.rng.next_f64() * (x1 - x0),
                        y0 + m.rng.next_f64() * (y1 - y0),
                    ]);
                }
                m.goal
            } else {
                let w = t.path[m.waypoint.min(t.path.len() - 1)];
                if (w[0] - p[0]).hypot(w[1] - p[1]) < 0.5 {
                    if m.waypoint + 1 < t.path.len() {
                        m.waypoint += 1;
                    } else if t.looped {
                        m.waypoint = 0;
                    }
                }
                let w = t.path[m.waypoint.min(t.path.len() - 1)];
                Some(w)
            };
            let command = match goal {
                Some(g) => {
                    let top = prepared
                        .catalog
                        .get(TARGET_CLASS)
                        .map_or(5.0, |c| c.flight.max_linear_speed);
                    let mut c = team::fly_to(
                        p,
                        0.0,
                        [g[0], g[1], t.start[2]],
                        (t.speed / top).min(1.0),
                        0.5,
                    );
                    c.yaw = 0.0;
                    c
                }
                None => SpeedCommand::STOP,
            };
            self.world
                .command(m.client, Command::Drive(command.to_drive()));
        }
        // The agents.
        let networks = if scenario.sharing == Sharing::Radio {
            radio_networks(&self.world, &scenario.radio, &uav_truth)
        } else {
            Vec::new()
        };
        let mut notes = Vec::new();
        for (i, f) in self.flyers.iter_mut().enumerate() {
            if f.crashed {
                continue;
            }
            let step = match overrides.get(i) {
                // Flown from outside: its agent does not step (it would post notes and
                // requests for a UAV it does not fly); a payload is taken when it stands on
                // the pickup pad and set down when it stands on the drop-off pad.
                Some(Some(command)) => {
                    let carrying = self.board.carrying.get(i).copied().unwrap_or(false);
                    let speed = f.velocity.iter().map(|v| v * v).sum::<f64>().sqrt();
                    let act = match &scenario.delivery {
                        Some(job) if carrying && on_pad(&job.dropoff, uav_truth[i], speed) => {
                            Some(Act::Drop)
                        }
                        Some(_) if !carrying => Some(Act::PickUp),
                        _ => None,
                    };
                    TeamStep {
                        command: Some(*command),
                        act,
                        ..TeamStep::default()
                    }
                }
                _ => {
                    // The whole board is lent as it is; a partial view is built only when
                    // the agent may not see all of it.
                    let view = match scenario.sharing {
                        Sharing::Blackboard => Cow::Borrowed(&self.board),
                        Sharing::Nothing => Cow::Owned(view(&self.board, i, |_| false)),
                        Sharing::Radio => {
                            Cow::Owned(view(&self.board, i, |k| networks[i] == networks[k]))
                        }
                    };
                    f.agent.step(&f.state, &view, time)
                }
            };
            for line in step.log {
                self.log.push(format!(
                    "t={time:.1}s {} {}: {line}",
                    f.name,
                    f.agent.name()
                ));
            }
            if scenario.sharing != Sharing::Nothing {
                notes.extend(step.notes.into_iter().map(|n| (i, n)));
            }
            if let Some(act) = step.act {
                self.tracker.act(
                    act,
                    i,
                    time,
                    uav_truth[i],
                    f.velocity,
                    &mut self.board,
                    &mut self.log,
                    &f.name,
                    |kg| {
                        self.world.set_payload(f.client, kg);
                    },
                );
            }
            f.done = step.done;
            if let Some(c) = step.command {
                let drive = Command::Drive(c.to_drive());
                let (files, error) = (&mut self.recording, &mut self.record_error);
                Self::note(files, error, i, time, Direction::Client, &drive);
                self.world.command(f.client, drive);
            }
        }
        for (i, (key, value)) in notes {
            match value {
                Some(v) => {
                    self.board.notes.insert(key, (i, v));
                }
                None => {
                    self.board.notes.remove(&key);
                }
            }
        }
        let all_done = self.flyers.iter().all(|f| f.done || f.crashed);
        let done = match scenario.kind {
            Kind::Search | Kind::Delivery => all_done,
            Kind::Relay | Kind::Tracking => false,
        };
        if done {
            self.ending = Some(Ending::Done);
            return self.ending.clone();
        }
        if time >= scenario.time_limit - 1e-9 {
            self.ending = Some(Ending::TimeUp);
            return self.ending.clone();
        }
        None
    }

    /// Simulated seconds.
    pub fn time(&self) -> f64 {
        self.world.time()
    }

    /// How it ended (`None` while it goes on).
    pub fn ending(&self) -> Option<Ending> {
        self.ending.clone()
    }

    /// UAVs in all.
    pub fn uav_count(&self) -> usize {
        self.total
    }

    /// UAV `i`'s own readings.
    pub fn state(&self, i: usize) -> Option<&UavState> {
        self.flyers.get(i).map(|f| &f.state)
    }

    /// UAV `i`'s brief.
    pub fn brief(&self, i: usize) -> Option<&Brief> {
        self.briefs.get(i)
    }

    /// The shared board (what the agents know).
    pub fn board(&self) -> &Board {
        &self.board
    }

    /// Whether UAV `i` has crashed.
    pub fn crashed(&self, i: usize) -> bool {
        self.flyers.get(i).is_some_and(|f| f.crashed)
    }

    /// The figures so far.
    pub fn metrics(&self) -> super::metrics::Metrics {
        self.tracker
            .finish(self.world.time(), &self.prepared.scenario)
    }

    /// Whether the relay's endpoints are connected now (`None`: not a relay scenario).
    pub fn link_up(&self) -> Option<bool> {
        self.tracker.link_changes.last().map(|&(_, up)| up)
    }

    /// The log so far.
    pub fn log(&self) -> &[String] {
        &self.log
    }

    /// UAV `i`'s name in the world and the log (`UAV1`, …).
    pub fn name(&self, i: usize) -> Option<&str> {
        self.flyers.get(i).map(|f| f.name.as_str())
    }

    /// The victims (the map's and the drawn ones) and when each was found (`None`: not yet),
    /// for a live view.
    pub fn victims(&self) -> &[(Placed, Option<f64>)] {
        &self.tracker.victims
    }

    /// The coverage grid so far (search scenarios), for a live heat map.
    pub fn coverage(&self) -> Option<&super::metrics::Grid> {
        self.tracker.grid.as_ref()
    }

    /// The fire's radius now (`None`: no fire).
    pub fn fire_radius(&self) -> Option<f64> {
        self.prepared
            .scenario
            .fire
            .map(|f| f.radius + f.rate * self.world.time())
    }

    /// The moving targets' true positions now, in the scenario's order.
    pub fn targets(&self) -> Vec<[f64; 3]> {
        self.world
            .robots_truth()
            .iter()
            .skip(self.total)
            .map(|r| r.location)
            .collect()
    }

    /// The relay link's changes so far: (time, connected), one entry per change.
    pub fn link_changes(&self) -> &[(f64, bool)] {
        &self.tracker.link_changes
    }

    /// Ends the iteration (at the time limit if it has not ended yet) and gives its result.
    pub fn finish(self) -> Outcome {
        let scenario = &self.prepared.scenario;
        let time = self.world.time();
        let metrics = self.tracker.finish(time, scenario);
        Outcome {
            seed: self.seed,
            ending: self.ending.unwrap_or(Ending::TimeUp),
            metrics,
            tracks: self.tracks,
            target_tracks: self.target_tracks,
            victims: self.tracker.victims.clone(),
            coverage: self.tracker.grid.clone(),
            link: self.tracker.link_changes.clone(),
            fire_radius: scenario.fire.map(|f| f.radius + f.rate * time),
            log: self.log,
        }
    }
}

/// The board as UAV `i` sees it: the scenario's facts, and the positions, batteries and
/// notes of itself and of the UAVs `heard` says it hears.
fn view(board: &Board, i: usize, heard: impl Fn(usize) -> bool) -> Board {
    let seen = |k: usize| k == i || heard(k);
    Board {
        time: board.time,
        positions: board
            .positions
            .iter()
            .enumerate()
            .map(|(k, p)| if seen(k) { *p } else { None })
            .collect(),
        batteries: board
            .batteries
            .iter()
            .enumerate()
            .map(|(k, b)| if seen(k) { *b } else { None })
            .collect(),
        charging: board.charging.clone(),
        carrying: board.carrying.clone(),
        found: board.found.clone(),
        targets: board.targets.clone(),
        fire_radius: board.fire_radius,
        notes: board
            .notes
            .iter()
            .filter(|(_, (by, _))| seen(*by))
            .map(|(k, v)| (k.clone(), *v))
            .collect(),
    }
}

/// Each UAV's radio network (the same number for UAVs that reach each other): direct links
/// by the radio model between their true positions (walls counted by the scene's rays), and
/// what the UAVs in between forward, as a mesh of relays does.
fn radio_networks(world: &World, radio: &super::model::Radio, at: &[[f64; 3]]) -> Vec<usize> {
    let n = at.len();
    let mut network: Vec<usize> = (0..n).collect();
    fn root(network: &mut [usize], mut a: usize) -> usize {
        while network[a] != a {
            network[a] = network[network[a]];
            a = network[a];
        }
        a
    }
    for a in 0..n {
        for b in a + 1..n {
            if root(&mut network, a) == root(&mut network, b) {
                continue;
            }
            let walls = world.obstacles_between(at[a], at[b]);
            if radio.reaches(at[a], at[b], f64::from(walls)) {
                let (ra, rb) = (root(&mut network, a), root(&mut network, b));
                network[ra.max(rb)] = ra.min(rb);
            }
        }
    }
    (0..n).map(|a| root(&mut network, a)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_agent_sees_only_what_its_network_carries() {
        let mut board = Board {
            positions: vec![Some([0.0; 3]), Some([1.0; 3]), Some([2.0; 3])],
            batteries: vec![Some(1.0), Some(0.5), Some(0.2)],
            ..Board::default()
        };
        board.notes.insert("relieve:2".into(), (2, 2.0));
        board.notes.insert("ready:1".into(), (1, 1.0));
        // UAV 0 hears UAV 1, not UAV 2.
        let v = view(&board, 0, |k| k == 1);
        assert_eq!(v.positions, vec![Some([0.0; 3]), Some([1.0; 3]), None]);
        assert_eq!(v.batteries, vec![Some(1.0), Some(0.5), None]);
        assert!(v.notes.contains_key("ready:1") && !v.notes.contains_key("relieve:2"));
        let alone = view(&board, 2, |_| false);
        assert_eq!(alone.positions, vec![None, None, Some([2.0; 3])]);
        assert_eq!(alone.notes.len(), 1, "its own note only");
    }
}
