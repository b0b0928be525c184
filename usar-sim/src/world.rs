//! The world: map geometry, robots, connections; one `step` per tick.

use std::collections::BTreeMap;
use std::sync::Arc;

use tracing::{debug, warn};
use usar_proto::{Command, Conf, Geo, Init, ItemQuery, Nfo, ServerMessage, StartPose};

use super::map::{self, Map};
use super::render::{self, Image, View};
use super::robot::{Model, Robot, Spawn, bounded_angle};
use super::robots::RobotCatalog;
use super::scene::{Scene, V3};
use super::wind::WindConfig;
use super::{ClientId, SimConfig};
use rapier3d::prelude::ColliderHandle;
use usar_proto::shown::{Repeats, Shown};

/// Ticks between BVH refits (leaf updates only ever grow the tree's inner boxes).
const REFIT_EVERY: u64 = 200;
/// Fewer robots than this per thread are read on the stepping thread alone (starting a
/// thread costs about as much as reading a few dozen robots).
const ROBOTS_PER_THREAD: usize = 64;

/// The world: map, robots, sensors. Synchronous and deterministic: the same seed and the
/// same calls give the same output, bit for bit.
#[derive(Debug)]
pub struct World {
    tick: u64,
    dt: f64,
    seed: u64,
    /// The wind robots with physics feel.
    wind: WindConfig,
    /// Read only, so shared by the worlds made from one (a Python batch's thousand worlds
    /// read one copy, which stays in the caches).
    map: Arc<Map>,
    catalog: Arc<RobotCatalog>,
    /// Each spawned class's parts, built once (found by the catalog's class name).
    models: Vec<Arc<Model>>,
    scene: Scene,
    /// Ordered by serial (spawn order): the order of movement and of output.
    robots: Vec<Robot>,
    /// The robots the last [`World::reset`] took out, for spawns to reuse (their sensors'
    /// allocations), next one last.
    spare: Vec<Robot>,
    /// [`World::step`]'s messages of each run of robots, kept between ticks (emptied, not
    /// dropped: most ticks some robot speaks, and every world allocated them anew).
    emitted: Vec<Vec<(ClientId, ServerMessage)>>,
    /// Each robot's next due tick ([`Robot::next_due`]), at its index in `robots`: a tick
    /// scans this dense array, not the robots, to find the few that have output.
    due: Vec<u64>,
    /// This tick's robots with output due (indices into `robots`, ascending); reused.
    speaking: Vec<usize>,
    /// Connection → serial of the robot it controls.
    clients: Clients,
    next_client: u64,
    next_serial: u64,
    /// Threads that read sensors ([`SimConfig::threads`]).
    threads: usize,
    robots_per_connection: usize,
    /// The image server's tile grid (camera CONF offsets).
    tiles: super::Tiles,
    /// Warnings about each connection's commands (summarised past the first few).
    complaints: BTreeMap<ClientId, Repeats>,
    /// Faults still to come, in time order.
    faults: std::collections::VecDeque<super::faults::PlannedFault>,
    /// The faults to plan from the seed ([`SimConfig::faults`]).
    fault_plan: super::faults::FaultPlan,
    /// Parameter ranges each robot draws from at its spawn.
    randomize: Option<super::randomize::Randomization>,
}

/// Connection → serial of the robot it controls, in connection order (ids only grow): a
/// sorted list, kept allocated when a reset clears it (a map's node was allocated and freed
/// at every Python reset).
#[derive(Debug, Default)]
struct Clients(Vec<(ClientId, Option<u64>)>);

impl Clients {
    fn get(&self, client: ClientId) -> Option<Option<u64>> {
        let i = self.0.binary_search_by_key(&client, |e| e.0).ok()?;
        Some(self.0[i].1)
    }

    /// Sets `client`'s robot; returns the one it had.
    fn insert(&mut self, client: ClientId, serial: Option<u64>) -> Option<Option<u64>> {
        match self.0.binary_search_by_key(&client, |e| e.0) {
            Ok(i) => Some(std::mem::replace(&mut self.0[i].1, serial)),
            Err(i) => {
                self.0.insert(i, (client, serial));
                None
            }
        }
    }

    fn remove(&mut self, client: ClientId) {
        if let Ok(i) = self.0.binary_search_by_key(&client, |e| e.0) {
            self.0.remove(i);
        }
    }

    fn clear(&mut self) {
        self.0.clear();
    }
}

/// Whether to log a warning about `client`'s command: the first few in full, then a
/// summary now and then (a flood of bad commands must not flood the log).
fn complain(complaints: &mut BTreeMap<ClientId, Repeats>, client: ClientId) -> Option<u64> {
    complaints.entry(client).or_default().note()
}

/// An INIT location: non-finite components are 0, the rest within the map's limits.
fn spawn_location(v: usar_proto::Vec3) -> V3 {
    let limit = map::LIMIT - map::EDGE_MARGIN;
    V3::from(v).map(|x| {
        if x.is_finite() {
            x.clamp(-limit, limit)
        } else {
            0.0
        }
    })
}

/// An INIT rotation: non-finite components are 0, the rest bounded by [`bounded_angle`].
fn spawn_rotation(v: usar_proto::Vec3) -> V3 {
    V3::from(v).map(|x| if x.is_finite() { bounded_angle(x) } else { 0.0 })
}

impl World {
    /// A world with `map` and the robot classes of `robots` (each owned, or shared with other
    /// worlds in an `Arc`: a world only reads them).
    pub fn new(
        map: impl Into<Arc<Map>>,
        robots: impl Into<Arc<RobotCatalog>>,
        config: SimConfig,
    ) -> Self {
        let (map, robots) = (map.into(), robots.into());
        let dt = if config.dt.is_finite() && config.dt > 0.0 {
            config.dt
        } else {
            warn!(dt = config.dt, "invalid dt, using 1/200 s");
            SimConfig::default().dt
        };
        let wind = match config.wind.or(map.wind()) {
            Some(wind) => match wind.check() {
                Ok(()) => wind,
                Err(error) => {
                    warn!(%error, "invalid wind, flying in calm air");
                    WindConfig::default()
                }
            },
            None => WindConfig::default(),
        };
        let scene = Scene::copy_of(&map.scene());
        Self {
            tick: 0,
            dt,
            seed: config.seed,
            wind,
            map,
            catalog: robots,
            models: Vec::new(),
            scene,
            robots: Vec::new(),
            spare: Vec::new(),
            due: Vec::new(),
            speaking: Vec::new(),
            clients: Clients::default(),
            next_client: 0,
            next_serial: 0,
            threads: config.threads.max(1),
            robots_per_connection: config.robots_per_connection,
            tiles: config.tiles,
            complaints: BTreeMap::new(),
            faults: config.faults.schedule(config.seed).into(),
            fault_plan: config.faults,
            randomize: config.randomize,
            emitted: Vec::new(),
        }
    }

    /// Starts over with `seed`: afterwards the world is what [`World::new`] with the same
    /// map, classes and configuration and this seed gives (no robots, no connections, time
    /// 0, the faults planned from the seed), and the same calls give the same output, bit
    /// for bit — without building the map's scene again (its first build is kept; the
    /// robots' bodies are taken out: [`Scene::reset`]). The Python package resets its
    /// worlds this way.
    pub fn reset(&mut self, seed: u64) {
        let mut bodies: Vec<_> = self.robots.iter().map(|r| r.body).collect();
        self.scene.reset(&mut bodies);
        self.tick = 0;
        self.seed = seed;
        // Kept for the next spawns to reuse (first robot last: spawns pop them in order),
        // swapped, not moved; the spares the last episode left are dropped.
        std::mem::swap(&mut self.robots, &mut self.spare);
        self.robots.clear();
        self.spare.reverse();
        self.due.clear();
        self.speaking.clear();
        self.clients.clear();
        self.next_client = 0;
        self.next_serial = 0;
        self.complaints.clear();
        self.faults = self.fault_plan.schedule(seed).into();
    }

    /// The scene's leaf (collider index) of each robot's body, in spawn order.
    #[cfg(test)]
    pub(crate) fn body_leaves(&self) -> Vec<u32> {
        self.robots
            .iter()
            .map(|r| r.body.into_raw_parts().0)
            .collect()
    }

    /// Each robot's body as the scene holds it, in spawn order: its collider's centre and
    /// its tree box (min and max corners).
    #[cfg(test)]
    pub(crate) fn body_boxes(&self) -> Vec<[[f32; 3]; 3]> {
        self.robots
            .iter()
            .map(|r| self.scene.body_box(r.body))
            .collect()
    }

    /// The model this world spawns the class `class` (its catalog name) with, once spawned.
    #[cfg(test)]
    pub(crate) fn model(&self, class: &str) -> Option<&Arc<Model>> {
        self.models.iter().find(|m| m.class_name() == class)
    }

    /// The map's level name for the NFO line.
    pub fn level(&self) -> &str {
        self.map.level()
    }

    /// The NFO `TimeLimit`.
    pub fn time_limit(&self) -> i64 {
        self.map.time_limit()
    }

    /// The game-info `NFO` a server sends each connection on accept.
    pub fn game_info(&self) -> ServerMessage {
        ServerMessage::Nfo(Nfo::GameInfo {
            gametype: "BotDeathMatch".into(),
            level: self.level().to_owned(),
            time_limit: self.time_limit(),
        })
    }

    /// Starts bringing into the caches the memory a control period of a lone robot reads
    /// first (a hint: nothing changes): the world's and its robots' own state, each part's
    /// timer, noise and fault, the solids its last sweeps found near it. A batch of worlds
    /// asks it of the next world while it steps one, so that state arrives in parallel
    /// instead of one miss after another, and [`World::prefetch_early`] of the one after:
    /// this reads the pointers that one brings. (The sensors' own state was tried too:
    /// reaching it stalls on loads of its own, which cost a hovering batch more than it
    /// saved.)
    pub fn prefetch(&self) {
        use crate::prefetch::lines;
        lines(&self.due, 2);
        lines(&self.emitted, 2);
        lines(&self.clients.0, 2);
        for robot in self.robots.iter().take(4) {
            robot.prefetch();
        }
        self.scene.prefetch();
    }

    /// The first part of [`World::prefetch`], a world earlier: the world's own fields that
    /// hold its robots', sensors' and scene's addresses.
    pub fn prefetch_early(&self) {
        use crate::prefetch::line;
        line(&self.tick);
        line(&self.faults);
        line(&self.robots);
        line(&self.due);
        line(&self.emitted);
        line(&self.clients);
        self.scene.prefetch_early();
    }

    /// [`World::prefetch`] for a world about to be [`World::reset`] and have its robots
    /// spawned again: what those write (the robots' own fields and parts, the scene's
    /// tables). Its own fields first, a world earlier: [`World::prefetch_reset_early`].
    pub fn prefetch_reset(&self) {
        use crate::prefetch::lines;
        lines(&self.robots, 4);
        lines(&self.due, 1);
        lines(&self.clients.0, 1);
        for robot in self.robots.iter().take(4) {
            robot.prefetch_reset();
        }
        self.scene
            .prefetch_reset(self.robots.iter().take(4).map(|r| r.body));
    }

    /// The first part of [`World::prefetch_reset`], a world earlier: the world's own fields.
    pub fn prefetch_reset_early(&self) {
        use crate::prefetch::line;
        self.prefetch_early();
        line(&self.spare);
        line(&self.speaking);
        line(&self.complaints);
        line(&self.next_client);
        line(&self.randomize);
        line(&self.models);
    }

    /// Simulated seconds (tick × dt).
    pub fn time(&self) -> f64 {
        self.tick as f64 * self.dt
    }

    /// Seconds per tick.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Robots in the world (including those no connection controls any more).
    pub fn robot_count(&self) -> usize {
        self.robots.len()
    }

    /// Calls `f` with each controlled robot's connection and whether the robot touched
    /// something, or was crashed, in any tick since the last call (what a `Touch` part with
    /// `event = "contact"` read every tick would have said at least once), in spawn order, and
    /// clears the flags: contact for in-process users without a sensor line per tick.
    pub fn take_touched(&mut self, mut f: impl FnMut(ClientId, bool)) {
        for robot in &mut self.robots {
            let touched = robot.take_touched();
            if let Some(owner) = robot.owner {
                f(owner, touched);
            }
        }
    }

    /// Registers a connection (no robot yet).
    pub fn connect(&mut self) -> ClientId {
        self.next_client += 1;
        let id = ClientId(self.next_client);
        self.clients.insert(id, None);
        id
    }

    /// Removes a connection and every robot it spawned.
    pub fn disconnect(&mut self, client: ClientId) {
        self.clients.remove(client);
        self.complaints.remove(&client);
        let (gone, kept) = std::mem::take(&mut self.robots)
            .into_iter()
            .partition(|r| r.spawned_by == client);
        self.robots = kept;
        self.due = self.robots.iter().map(Robot::next_due).collect();
        for robot in gone {
            robot.despawn(&mut self.scene);
        }
    }

    /// Applies one command; returns the immediate replies (NFO StartPoses, CONF, GEO).
    /// INIT, DRIVE, SET, ACT and MISPKG apply silently; anything else is ignored.
    pub fn command(&mut self, client: ClientId, command: Command) -> Vec<ServerMessage> {
        if self.clients.get(client).is_none() {
            debug!(?client, "command from an unknown connection ignored");
            return Vec::new();
        }
        match command {
            Command::Init(init) => {
                self.spawn(client, &init);
                Vec::new()
            }
            Command::GetStartPoses => vec![self.start_poses()],
            command => self.robot_command(client, command),
        }
    }

    /// Advances one tick; appends this tick's STA/SEN/ASTA per connection, robots in spawn
    /// order, each robot's lines as STA, sensors in part order, ASTA.
    pub fn step(&mut self, out: &mut Vec<(ClientId, ServerMessage)>) {
        self.advance();
        self.speak(out);
    }

    /// Appends the output due at the current tick, its moves done.
    fn speak(&mut self, out: &mut Vec<(ClientId, ServerMessage)>) {
        let (tick, dt) = (self.tick, self.dt);
        // Most ticks no robot has output due (sensors report every 0.1-0.3 s).
        if self.due.iter().all(|&due| due > tick) {
            return;
        }
        let scene = &self.scene;
        let speakers = Speakers::at(tick, &mut self.robots, &mut self.due, &mut self.speaking);
        // One run (a few robots, or one thread): straight into `out`, which the caller keeps
        // in the caches (a Python batch's thread reuses one for all its worlds), instead of
        // into this world's own buffer, cold since the world last spoke.
        if runs(speakers.speaking.len(), self.threads) == 1 {
            speakers.each(0, |robot| robot.emit(scene, tick, dt, out));
            return;
        }
        let used = for_threads(speakers, self.threads, &mut self.emitted, |robot, lines| {
            robot.emit(scene, tick, dt, lines)
        });
        for part in &mut self.emitted[..used] {
            // Into an empty `out` (a lone robot's tick, most often) the buffers change places
            // instead of the messages moving.
            if out.is_empty() {
                std::mem::swap(out, part);
            } else {
                out.append(part);
            }
        }
    }

    /// Advances `ticks` ticks, appending their output as [`World::step`] does: the same as
    /// `ticks` calls of it, bit for bit. Faster for a world of one robot without a physics
    /// model (a Python env's): its moves up to the next tick with output due or a refit of
    /// the tree, when no fault comes, are flown together ([`Robot::glide`]), then that
    /// tick's refit and output follow as a step's would.
    pub fn run(&mut self, ticks: u64, out: &mut Vec<(ClientId, ServerMessage)>) {
        let mut left = ticks;
        while left > 0 {
            let quiet = self.quiet_ticks(left);
            if quiet >= 2 {
                self.scene.refresh();
                let flown = self.robots[0].glide(&mut self.scene, self.tick, quiet, self.dt);
                self.tick += flown;
                left -= flown;
                if flown > 0 {
                    if self.tick.is_multiple_of(REFIT_EVERY) {
                        self.scene.refit();
                    }
                    self.speak(out);
                    continue;
                }
            }
            self.step(out);
            left -= 1;
        }
    }

    /// Of the next `ticks` ticks, how many in a row from the next one a lone robot can fly
    /// together: up to the first with output due or a refit of the tree (which come after
    /// the moves of a tick), when no fault is planned (0 when the world does not have
    /// exactly one robot).
    fn quiet_ticks(&self, ticks: u64) -> u64 {
        if self.robots.len() != 1 || !self.faults.is_empty() {
            return 0;
        }
        let due = self.due[0].saturating_sub(self.tick).max(1);
        let refit = REFIT_EVERY - self.tick % REFIT_EVERY;
        ticks.min(due).min(refit)
    }

    /// [`World::step`] with the output printed as the server sends it (each line followed
    /// by CRLF), on the sensor threads: `out` holds each robot's lines of this tick. The
    /// text is the same at any thread count.
    pub fn step_printed(&mut self, out: &mut Printed) {
        self.advance();
        let (tick, dt) = (self.tick, self.dt);
        for part in &mut out.parts {
            part.clear();
        }
        let scene = &self.scene;
        out.used = for_threads(
            Speakers::at(tick, &mut self.robots, &mut self.due, &mut self.speaking),
            self.threads,
            &mut out.parts,
            |robot, part| part.print(robot, scene, tick, dt),
        );
    }

    /// Moves every robot one tick.
    fn advance(&mut self) {
        self.tick += 1;
        let (tick, dt) = (self.tick, self.dt);
        while self
            .faults
            .front()
            .is_some_and(|f| f.time <= tick as f64 * dt + 1e-9)
        {
            let Some(f) = self.faults.pop_front() else {
                break;
            };
            match self.index_of(f.serial) {
                Some(i) => {
                    self.robots[i].scheduled_fault(&f.fault, &f.line, tick as f64 * dt);
                    self.due[i] = self.robots[i].next_due();
                }
                None => warn!(robot = f.serial + 1, "planned fault skipped: no such robot"),
            }
        }
        self.scene.refresh();
        // The physics models' integration reads the scene only: on the sensor threads, each
        // robot from where every robot was at the start of the tick (so at any thread count
        // the same); then the moves, which change the scene, one after the other.
        if self.robots.iter().any(Robot::has_dynamics) {
            let scene = &self.scene;
            for_chunks(&mut self.robots, self.threads, |robot| {
                robot.prepare(scene, tick, dt);
            });
        }
        for robot in &mut self.robots {
            robot.fly(&mut self.scene, tick, dt);
        }
        if tick % REFIT_EVERY == 0 {
            self.scene.refit();
        }
    }

    /// Turns the batched ray casts and skipped sweeps off (on by default): the slow
    /// reference they must equal byte for byte, for tests and `usar-bench --reference`.
    #[doc(hidden)]
    pub fn set_shortcuts(&mut self, on: bool) {
        self.scene.shortcuts = on;
    }

    fn start_poses(&self) -> ServerMessage {
        let poses = self
            .map
            .starts()
            .iter()
            .map(|s| StartPose {
                name: if s.tag.eq_ignore_ascii_case("PlayerStart") {
                    s.name.clone()
                } else {
                    s.tag.clone()
                },
                location: s.location.into(),
                rotation: s.rotation.into(),
            })
            .collect();
        ServerMessage::Nfo(Nfo::StartPoses {
            poses,
            old_layout: false,
        })
    }

    /// [`World::command`] with an `INIT`, taken by reference: a caller that spawns the same
    /// robot again and again (the Python worlds, at every reset) keeps its `Init` and builds
    /// no strings for it each time.
    pub fn init(&mut self, client: ClientId, init: &Init) {
        if self.clients.get(client).is_none() {
            debug!(?client, "INIT from an unknown connection ignored");
            return;
        }
        self.spawn(client, init);
    }

    fn spawn(&mut self, client: ClientId, init: &Init) {
        let spawned = self
            .robots
            .iter()
            .filter(|r| r.spawned_by == client)
            .count();
        if spawned >= self.robots_per_connection {
            if let Some(n) = complain(&mut self.complaints, client) {
                warn!(
                    ?client,
                    limit = self.robots_per_connection,
                    count = n,
                    "INIT ignored: this connection has spawned its robots already"
                );
            }
            return;
        }
        // The model is the catalog's, shared by the worlds that share the catalog; a world
        // spawns one class or a few (a list: no hashing of the name at every spawn, and the
        // catalog, which holds no two classes equal but for case, asked only for a new one).
        let known = self
            .models
            .iter()
            .position(|m| m.class_name().eq_ignore_ascii_case(&init.class_name));
        let model = match known {
            Some(i) => &self.models[i],
            None => {
                let Some(class) = self.catalog.get(&init.class_name) else {
                    if let Some(n) = complain(&mut self.complaints, client) {
                        warn!(?client, class = %Shown(&init.class_name), count = n,
                            "spawn failed: unknown robot class");
                    }
                    return;
                };
                let model = self
                    .catalog
                    .built(&class.class, Model::new)
                    .unwrap_or_else(|| Arc::new(Model::new(class)));
                self.models.push(model);
                &self.models[self.models.len() - 1]
            }
        };
        let class = model.class();
        let (position, rotation) = match init.start.as_deref().filter(|s| !s.is_empty()) {
            Some(tag) => match self.map.find_start(tag) {
                Some(start) => (start.location, start.rotation),
                None => {
                    if let Some(n) = complain(&mut self.complaints, client) {
                        warn!(?client, start = %Shown(tag), count = n,
                            "no such PlayerStart, spawning at 0,0,0");
                    }
                    ([0.0; 3], [0.0; 3])
                }
            },
            None => (
                init.location.map_or([0.0; 3], spawn_location),
                init.rotation.map_or([0.0; 3], spawn_rotation),
            ),
        };
        let name = match init.name.as_deref().map(str::trim) {
            Some(n) if !n.is_empty() && !n.contains([' ', '{', '}']) => n.to_owned(),
            _ => format!("{}_{}", class.short_name(), self.next_serial),
        };
        let spawn = Spawn {
            model,
            serial: self.next_serial,
            others: self.robots.len() as u64,
            owner: client,
            name,
            position,
            rotation,
            tick: self.tick,
            dt: self.dt,
            seed: self.seed,
            wind: self.wind,
            randomize: self.randomize.as_ref(),
        };
        let Some(robot) = Robot::spawn(spawn, &mut self.scene, self.spare.pop()) else {
            if let Some(n) = complain(&mut self.complaints, client) {
                warn!(
                    ?client,
                    ?position,
                    count = n,
                    "spawn failed: place is occupied"
                );
            }
            return;
        };
        self.next_serial += 1;
        let each = self
            .fault_plan
            .for_spawn(self.seed, robot.serial, self.tick as f64 * self.dt);
        if !each.is_empty() {
            self.faults.extend(each);
            self.faults
                .make_contiguous()
                .sort_by(|a, b| a.time.total_cmp(&b.time));
        }
        let mut robot = robot;
        self.assign_tiles(&mut robot);
        let previous = self.clients.insert(client, Some(robot.serial)).flatten();
        if let Some(old) = previous.and_then(|s| self.robot_mut(s)) {
            old.owner = None;
        }
        self.due.push(robot.next_due());
        self.robots.push(robot);
    }

    /// The index in `robots` of the robot `serial`.
    fn index_of(&self, serial: u64) -> Option<usize> {
        self.robots.binary_search_by_key(&serial, |r| r.serial).ok()
    }

    /// Gives each camera of a new robot the lowest tile no other camera holds.
    fn assign_tiles(&self, robot: &mut Robot) {
        // Most robots have no camera: then nothing to look at (a spawn of the 5000th robot
        // went through every part of the 4999 before it).
        if robot.cameras_mut().next().is_none() {
            return;
        }
        let mut taken: Vec<usize> = self
            .robots
            .iter()
            .flat_map(|r| r.cameras().map(|c| c.tile))
            .collect();
        taken.sort_unstable();
        let tiles = self.tiles;
        for camera in robot.cameras_mut() {
            let mut tile = 0;
            for &t in &taken {
                if t == tile {
                    tile += 1;
                } else if t > tile {
                    break;
                }
            }
            camera.tile = tile;
            camera.offset = tiles.offset(tile);
            let at = taken.partition_point(|&t| t < tile);
            taken.insert(at, tile);
        }
    }

    /// Renders every camera of every robot as the world is now (robots in spawn order,
    /// each robot's cameras in part order) into `frames` (its images are reused), on up to
    /// [`SimConfig::threads`] threads: the same pixels at any count.
    pub fn render_cameras(&self, frames: &mut Vec<CameraFrame>) {
        let mut jobs = Vec::new();
        let mut count = 0;
        for robot in &self.robots {
            for (name, camera, view) in robot.camera_views() {
                if frames.len() <= count {
                    frames.push(CameraFrame::default());
                }
                let frame = &mut frames[count];
                frame.client = robot.owner;
                frame.serial = robot.serial;
                frame.name.clear();
                frame.name.push_str(name);
                frame.tile = camera.tile;
                frame.time = self.time();
                jobs.push((robot.body(), view));
                count += 1;
            }
        }
        frames.truncate(count);
        let scene = &self.scene;
        let draw = |frames: &mut [CameraFrame], jobs: &[(ColliderHandle, View)]| {
            for (frame, (body, view)) in frames.iter_mut().zip(jobs) {
                render::render(scene, view, Some(*body), &mut frame.image);
            }
        };
        let threads = self.threads.min(jobs.len()).max(1);
        if threads == 1 {
            draw(frames, &jobs);
            return;
        }
        let chunk = jobs.len().div_ceil(threads);
        std::thread::scope(|scope| {
            let mut parts = frames.chunks_mut(chunk).zip(jobs.chunks(chunk));
            let mine = parts.next();
            let others: Vec<_> = parts
                .map(|(f, j)| scope.spawn(move || draw(f, j)))
                .collect();
            if let Some((f, j)) = mine {
                draw(f, j);
            }
            for other in others {
                if let Err(panic) = other.join() {
                    std::panic::resume_unwind(panic);
                }
            }
        });
    }

    fn robot_mut(&mut self, serial: u64) -> Option<&mut Robot> {
        let index = self.index_of(serial)?;
        self.robots.get_mut(index)
    }

    /// DRIVE/GETCONF/GETGEO/SET/ACT/MISPKG: only with a robot whose battery is not empty.
    fn robot_command(&mut self, client: ClientId, command: Command) -> Vec<ServerMessage> {
        let (tick, dt) = (self.tick, self.dt);
        let serial = self.clients.get(client).flatten();
        let Some(index) = serial.and_then(|s| self.index_of(s)) else {
            return Vec::new();
        };
        let robot = &mut self.robots[index];
        if robot.is_dead(tick, dt) {
            return Vec::new();
        }
        match command {
            Command::Drive(drive) => robot.drive(&drive),
            // The QUAD extension (docs/quadrotor.md): lower-level commands for robots with
            // physics; a stock USARSim ignores it like any unknown command.
            Command::Other(message) if message.kind.eq_ignore_ascii_case("QUAD") => {
                match super::dynamics::parse_quad(&message) {
                    Ok(command) => robot.low_level(command),
                    Err(error) => warn!(?client, %error, "QUAD ignored"),
                }
            }
            // The FAULT extension (docs/quadrotor.md#faults).
            Command::Other(message) if message.kind.eq_ignore_ascii_case("FAULT") => {
                match super::dynamics::parse_fault(&message) {
                    Ok(fault) => robot.fault(&fault, tick as f64 * dt),
                    Err(error) => warn!(?client, %error, "FAULT ignored"),
                }
            }
            Command::GetConf(query) => return conf(robot, &query).into_iter().collect(),
            Command::GetGeo(query) => return geo(robot, &query).into_iter().collect(),
            Command::Set(set) => robot.set(
                &set.kind,
                set.name.as_deref(),
                &set.opcode,
                set.params.as_deref(),
            ),
            Command::Act(act) => {
                for link in &act.links {
                    robot.actuate(&act.name, link.link, link.value);
                }
            }
            Command::MisPkg(pkg) if pkg.order.unwrap_or(0) == 0 => {
                for link in &pkg.links {
                    robot.actuate(&pkg.name, link.link.saturating_sub(1), link.value);
                }
            }
            _ => {}
        }
        // A SET may have asked for a reading on the next tick.
        self.due[index] = self.robots[index].next_due();
        Vec::new()
    }

    /// Every robot as ground truth sees it, in spawn order.
    pub fn robots_truth(&self) -> Vec<RobotTruth> {
        self.robots
            .iter()
            .map(|r| {
                let (location, rotation) = r.pose();
                RobotTruth {
                    name: r.name.clone(),
                    class: r.class_name().to_owned(),
                    location,
                    rotation,
                    battery_empty: r.is_dead(self.tick, self.dt),
                    radio_off: r.radio_off(self.time()),
                }
            })
            .collect()
    }

    /// The parameters each robot drew (`SimConfig::randomize`), in spawn order.
    pub fn randomized(&self) -> Vec<super::randomize::Drawn> {
        self.robots.iter().map(|r| r.drawn().clone()).collect()
    }

    /// The map's victims and objects.
    pub fn placed(&self) -> &[map::Placed] {
        self.map.placed()
    }

    /// Walls between two points as USARSim's robot monitor counts them (a ray restarted
    /// 0.2 m past each hit; robots and victims do not count).
    pub fn obstacles_between(&self, a: V3, b: V3) -> u32 {
        if a.iter()
            .chain(&b)
            .any(|x| !x.is_finite() || x.abs() > map::LIMIT)
        {
            return 0;
        }
        self.scene.obstacles_between(a, b)
    }

    #[cfg(test)]
    pub(crate) fn scene_ray(&self, origin: V3, dir: V3, max: f64) -> Option<f64> {
        self.scene.cast_ray(origin, dir, max, None)
    }

    /// Fills the battery of the robot `client` controls (a charging pad; not a USARSim
    /// command: scenarios call it). `false` when the client controls no robot.
    pub fn recharge(&mut self, client: ClientId) -> bool {
        let tick = self.tick;
        self.client_robot(client)
            .map(|r| r.recharge(tick))
            .is_some()
    }

    /// Sets the mass (kg, 0 ..= 1000) the robot `client` controls carries besides its body:
    /// a payload picked up (scenarios call it). `false` when the client controls no robot or
    /// the robot has no physics (the kinematic stsAirRobot flies the same with any load).
    pub fn set_payload(&mut self, client: ClientId, kg: f64) -> bool {
        self.client_robot(client).is_some_and(|r| r.set_payload(kg))
    }

    fn client_robot(&mut self, client: ClientId) -> Option<&mut Robot> {
        let serial = self.clients.get(client).flatten()?;
        self.robot_mut(serial)
    }

    /// Whether the robot `client` controls has crashed.
    pub fn crashed(&self, client: ClientId) -> bool {
        let serial = self.clients.get(client).flatten();
        self.robots
            .iter()
            .any(|r| Some(r.serial) == serial && r.crashed())
    }

    #[cfg(test)]
    pub(crate) fn robot(&self, client: ClientId) -> Option<&Robot> {
        let serial = self.clients.get(client).flatten()?;
        self.robots.iter().find(|r| r.serial == serial)
    }
}

/// One camera's picture ([`World::render_cameras`]).
#[derive(Debug, Clone, Default)]
pub struct CameraFrame {
    /// The connection that controls the robot (`None` after a rebinding INIT).
    pub client: Option<ClientId>,
    /// The robot's spawn number (0 for the first robot of the world).
    pub serial: u64,
    /// The camera part's name (`cams` on the AirRobot).
    pub name: String,
    /// Its tile in the image server's frame ([`super::Tiles`]).
    pub tile: usize,
    /// Simulated seconds when it was taken.
    pub time: f64,
    /// What it saw.
    pub image: Image,
}

/// A robot as ground truth sees it ([`World::robots_truth`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotTruth {
    /// Its name (INIT `{Name ..}`, else `<Class>_<serial>`).
    pub name: String,
    /// The class without package (`stsAirRobot`).
    pub class: String,
    /// Centre, metres, protocol frame (z down).
    pub location: [f64; 3],
    /// Roll, pitch, yaw, rad.
    pub rotation: [f64; 3],
    /// Whether its battery is empty.
    pub battery_empty: bool,
    /// Whether its radio is off (`FAULT {Radio Off}`, docs/quadrotor.md#faults).
    pub radio_off: bool,
}

/// One tick's output as text ([`World::step_printed`]): for each robot that has output,
/// its lines (STA, SEN…, ASTA, each followed by CRLF), robots in spawn order. Reuse one
/// across ticks: its buffers are kept.
#[derive(Debug, Default)]
pub struct Printed {
    /// One per sensor thread, in robot order (the first `used` are this tick's).
    parts: Vec<PrintedPart>,
    used: usize,
}

impl Printed {
    /// Whether no robot had output this tick.
    pub fn is_empty(&self) -> bool {
        self.parts[..self.used].iter().all(|p| p.robots.is_empty())
    }

    /// Each robot's output: the connection it goes to and its lines.
    pub fn robots(&self) -> impl Iterator<Item = (ClientId, &[u8])> {
        self.parts[..self.used]
            .iter()
            .flat_map(|p| p.robots.iter().map(|(c, r)| (*c, &p.text[r.clone()])))
    }
}

/// What one sensor thread printed.
#[derive(Debug, Default)]
struct PrintedPart {
    text: Vec<u8>,
    robots: Vec<(ClientId, std::ops::Range<usize>)>,
    /// One robot's messages before they are printed.
    messages: Vec<(ClientId, ServerMessage)>,
}

impl PrintedPart {
    fn clear(&mut self) {
        self.text.clear();
        self.robots.clear();
    }

    fn print(&mut self, robot: &mut Robot, scene: &Scene, tick: u64, dt: f64) {
        robot.emit(scene, tick, dt, &mut self.messages);
        let Some(&(owner, _)) = self.messages.first() else {
            return;
        };
        let start = self.text.len();
        for (_, message) in self.messages.drain(..) {
            message.write_to(&mut self.text);
            self.text.extend_from_slice(b"\r\n");
        }
        self.robots.push((owner, start..self.text.len()));
    }
}

/// The robots with output due at a tick ([`World::speakers`]).
struct Speakers<'a> {
    robots: &'a mut [Robot],
    /// Each robot's next due tick, at its index.
    due: &'a mut [u64],
    /// The indices of the robots due now, ascending.
    speaking: &'a [usize],
}

impl<'a> Speakers<'a> {
    /// The robots of `robots` with output due at `tick` (`speaking` is reused).
    fn at(
        tick: u64,
        robots: &'a mut [Robot],
        due: &'a mut [u64],
        speaking: &'a mut Vec<usize>,
    ) -> Self {
        speaking.clear();
        speaking.extend(
            due.iter()
                .enumerate()
                .filter(|&(_, &due)| due <= tick)
                .map(|(i, _)| i),
        );
        Speakers {
            robots,
            due,
            speaking,
        }
    }

    /// `work` on each robot due, in order, then its next due tick noted.
    fn each(self, base: usize, mut work: impl FnMut(&mut Robot)) {
        for &i in self.speaking {
            let robot = &mut self.robots[i - base];
            work(robot);
            self.due[i - base] = robot.next_due();
        }
    }

    /// Split into `runs` contiguous runs with about as many speaking robots each, with
    /// the index of each run's first robot.
    fn split(self, runs: usize) -> Vec<(usize, Self)> {
        let chunk = self.speaking.len().div_ceil(runs.max(1)).max(1);
        let (mut robots, mut due, mut base) = (self.robots, self.due, 0);
        let mut out = Vec::new();
        for speaking in self.speaking.chunks(chunk) {
            let end = speaking[speaking.len() - 1] + 1 - base;
            let (run, rest) = robots.split_at_mut(end);
            let (run_due, rest_due) = due.split_at_mut(end);
            out.push((
                base,
                Speakers {
                    robots: run,
                    due: run_due,
                    speaking,
                },
            ));
            (robots, due, base) = (rest, rest_due, base + end);
        }
        out
    }
}

/// `work` on each of `items`, on up to `threads` threads (at least [`ROBOTS_PER_THREAD`]
/// items each, contiguous runs).
fn for_chunks<T: Send>(items: &mut [T], threads: usize, work: impl Fn(&mut T) + Sync) {
    let threads = threads.min(items.len() / ROBOTS_PER_THREAD).max(1);
    if threads == 1 {
        items.iter_mut().for_each(work);
        return;
    }
    let size = items.len().div_ceil(threads);
    let work = &work;
    std::thread::scope(|scope| {
        let mut chunks = items.chunks_mut(size);
        let mine = chunks.next();
        let others: Vec<_> = chunks
            .map(|chunk| scope.spawn(move || chunk.iter_mut().for_each(work)))
            .collect();
        mine.into_iter().flatten().for_each(work);
        // Joined, not left to the scope: a thread the scope lets go may not have exited
        // (and given its malloc arena back) before the next tick's threads start, and
        // glibc then makes new arenas (the Python soak's creep, issue 26).
        for other in others {
            if let Err(panic) = other.join() {
                std::panic::resume_unwind(panic);
            }
        }
    });
}

/// How many runs [`for_threads`] splits `speaking` robots into on up to `threads` threads.
fn runs(speaking: usize, threads: usize) -> usize {
    threads.min(speaking / ROBOTS_PER_THREAD).max(1)
}

/// `work` on each robot with output due, on up to `threads` threads (at least
/// [`ROBOTS_PER_THREAD`] robots each, contiguous runs), each run with its own state from
/// `states` (grown as needed, in robot order); returns how many runs there were. Sensors
/// only read the scene, so what each run gives does not depend on the thread count.
fn for_threads<S: Default + Send>(
    speakers: Speakers<'_>,
    threads: usize,
    states: &mut Vec<S>,
    work: impl Fn(&mut Robot, &mut S) + Sync,
) -> usize {
    let threads = runs(speakers.speaking.len(), threads);
    if states.len() < threads {
        states.resize_with(threads, S::default);
    }
    if threads == 1 {
        let state = &mut states[0];
        speakers.each(0, |robot| work(robot, state));
        return 1;
    }
    let mut runs = speakers.split(threads).into_iter().zip(states.iter_mut());
    let Some(((base, mine), my_state)) = runs.next() else {
        return 0;
    };
    let work = &work;
    let run = move |base: usize, run: Speakers<'_>, state: &mut S| {
        run.each(base, |robot| work(robot, state));
    };
    let run = &run;
    std::thread::scope(|scope| {
        let others: Vec<_> = runs
            .map(|((base, speakers), state)| scope.spawn(move || run(base, speakers, state)))
            .collect();
        run(base, mine, my_state);
        let count = 1 + others.len();
        for other in others {
            if let Err(panic) = other.join() {
                std::panic::resume_unwind(panic);
            }
        }
        count
    })
}

fn conf(robot: &Robot, query: &ItemQuery) -> Option<ServerMessage> {
    if query.kind == "Robot" {
        return Some(ServerMessage::Conf(Conf::Robot {
            name: robot.class_name().to_string(),
        }));
    }
    let items = robot.conf(&query.kind, query.name.as_deref());
    (!items.is_empty()).then(|| {
        ServerMessage::Conf(Conf::Items {
            kind: query.kind.clone(),
            items,
        })
    })
}

fn geo(robot: &Robot, query: &ItemQuery) -> Option<ServerMessage> {
    if query.kind == "Robot" {
        return Some(ServerMessage::Geo(Geo::Robot {
            name: robot.class_name().to_string(),
        }));
    }
    let items = robot.geo(&query.kind, query.name.as_deref());
    (!items.is_empty()).then(|| {
        ServerMessage::Geo(Geo::Items {
            kind: query.kind.clone(),
            items,
        })
    })
}
