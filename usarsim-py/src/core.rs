//! The in-process simulation behind the Python environments: worlds of `usar_sim`
//! stepped in lockstep, one control period at a time, with the sensor lines folded into a
//! [`UavState`] per UAV and written out as flat arrays. No Python types here.

use std::path::Path;

use ucc_client::SpeedCommand;
use ucc_client::uav::UavState;
use usar_proto::{Command, Init, ServerMessage, Vec3};
use usar_sim::{ClientId, Map, RobotCatalog, SimConfig, World};

/// Horizontal sonars + SonarTop + SonarBottom.
pub(crate) const SONARS: usize = 10;
/// The stsAirRobot's Hokuyo URG-04LX beams.
pub(crate) const LASER: usize = 228;
/// Range reported for a sonar or beam that has not read yet (the laser's maximum).
const NO_RANGE: f64 = 4.0;

/// What went wrong, with what and where (becomes a Python `ValueError`).
#[derive(Debug, thiserror::Error)]
pub(crate) enum SimError {
    /// Any invalid argument.
    #[error("{0}")]
    Invalid(String),
}

fn invalid(message: impl Into<String>) -> SimError {
    SimError::Invalid(message.into())
}

/// Settings shared by every world of a batch.
#[derive(Debug, Clone)]
pub(crate) struct Settings {
    pub(crate) map: Map,
    pub(crate) catalog: RobotCatalog,
    pub(crate) robot: String,
    pub(crate) period: f64,
    pub(crate) dt: f64,
}

impl Settings {
    /// Checks and loads: `map` is an embedded map name or a map file; `noise` (if given)
    /// replaces the noise standard deviation of every part of the robot class.
    pub(crate) fn new(
        map: &str,
        robot: &str,
        period: f64,
        noise: Option<f64>,
    ) -> Result<Self, SimError> {
        let map = match Map::embedded(map) {
            Some(m) => m,
            None if Path::new(map).is_file() => {
                Map::from_file(Path::new(map)).map_err(|e| invalid(format!("map: {e}")))?
            }
            None => {
                return Err(invalid(format!(
                    "map: unknown map {map:?}: neither an embedded map ({}) nor a file",
                    Map::embedded_names().join(", ")
                )));
            }
        };
        let mut catalog = RobotCatalog::embedded();
        let full = usar_proto::Init::qualified_class(robot);
        if let Err(unknown) = catalog.class(&full) {
            return Err(invalid(format!("robot: {unknown}")));
        }
        let Some(class) = catalog.get_mut(&full) else {
            return Err(invalid(format!("robot: unknown robot class {full:?}")));
        };
        if let Some(noise) = noise {
            if !(noise.is_finite() && noise >= 0.0) {
                return Err(invalid(format!(
                    "noise: must be a finite number >= 0, got {noise}"
                )));
            }
            for part in &mut class.parts {
                part.noise = noise;
            }
        }
        let robot = class.class.clone();
        let dt = SimConfig::default().dt;
        if !(period.is_finite() && period >= dt) {
            return Err(invalid(format!(
                "period: the control period must be a finite number of seconds >= {dt}, got {period}"
            )));
        }
        Ok(Self {
            map,
            catalog,
            robot,
            period,
            dt,
        })
    }

    /// Physics ticks per control period.
    fn ticks(&self) -> usize {
        ((self.period / self.dt).round() as usize).max(1)
    }
}

/// A pose to spawn at: x, y, z (metres, z down) and yaw (rad).
pub(crate) type Pose = [f64; 4];

/// `INIT` of a `class` robot named `name`, level, at `pose`.
pub(crate) fn spawn(class: &str, name: &str, pose: &Pose) -> Command {
    Command::Init(Init {
        class_name: class.to_owned(),
        name: Some(name.to_owned()),
        location: Some(Vec3::new(pose[0], pose[1], pose[2])),
        rotation: Some(Vec3::new(0.0, 0.0, pose[3])),
        start: None,
    })
}

/// The normalized `DRIVE` of an action: forward, right, up, yaw in -1..=1.
pub(crate) fn drive(action: &[f64; 4]) -> Command {
    let command = SpeedCommand {
        forward: action[0] * 100.0,
        right: action[1] * 100.0,
        up: action[2] * 100.0,
        yaw: action[3] * 100.0,
    };
    Command::Drive(command.to_drive())
}

/// One UAV: its connection, what it knows, and the contact flag of the last period.
#[derive(Debug)]
struct Uav {
    client: ClientId,
    state: UavState,
    touched: bool,
}

/// One world with its UAVs.
#[derive(Debug)]
pub(crate) struct WorldSim {
    world: World,
    uavs: Vec<Uav>,
    /// Clients are numbered 1.. in connection order, so `client.0 - first` is the index.
    first: u64,
    out: Vec<(ClientId, ServerMessage)>,
}

impl WorldSim {
    /// A fresh world with one UAV per pose, seeded with `seed`, after one hovering period
    /// (so every sensor has read once).
    pub(crate) fn new(settings: &Settings, seed: u64, poses: &[Pose]) -> Result<Self, SimError> {
        let config = SimConfig {
            seed,
            dt: settings.dt,
            ..SimConfig::default()
        };
        let mut world = World::new(settings.map.clone(), settings.catalog.clone(), config);
        let mut uavs = Vec::with_capacity(poses.len());
        let mut first = 0;
        for (i, pose) in poses.iter().enumerate() {
            if !pose.iter().all(|v| v.is_finite()) {
                return Err(invalid(format!("start {i}: not finite: {pose:?}")));
            }
            let client = world.connect();
            if i == 0 {
                first = client.0;
            }
            world.command(client, spawn(&settings.robot, &format!("UAV{i}"), pose));
            uavs.push(Uav {
                client,
                state: UavState::new(),
                touched: false,
            });
        }
        if world.robot_count() != poses.len() {
            return Err(invalid(format!(
                "start: could not spawn every UAV ({} of {}): a start is inside a wall, \
                 another UAV or an obstacle; starts: {poses:?}",
                world.robot_count(),
                poses.len()
            )));
        }
        let mut sim = Self {
            world,
            uavs,
            first,
            out: Vec::new(),
        };
        sim.advance(settings.ticks());
        Ok(sim)
    }

    /// Sends each UAV its normalized command (forward, right, up, yaw in -1..=1), then steps
    /// one control period. Actions must be finite (checked by the caller).
    pub(crate) fn step(&mut self, settings: &Settings, actions: &[[f64; 4]]) {
        let before: Vec<[f64; 3]> = self.uavs.iter().map(position).collect();
        for (uav, a) in self.uavs.iter().zip(actions) {
            self.world.command(uav.client, drive(a));
        }
        self.advance(settings.ticks());
        let max = settings.catalog.get(&settings.robot).map(|c| &c.flight);
        for ((uav, a), start) in self.uavs.iter_mut().zip(actions).zip(before) {
            // In contact when the body went less than 70 % of the commanded way.
            let Some(f) = max else { continue };
            let moved = distance(position(uav), start);
            let wanted = ((a[0] * f.max_linear_speed).powi(2)
                + (a[1] * f.max_lateral_speed).powi(2)
                + (a[2] * f.max_altitude_speed).powi(2))
            .sqrt()
                * settings.period;
            uav.touched = wanted > 0.02 && moved < 0.7 * wanted;
        }
    }

    fn advance(&mut self, ticks: usize) {
        for _ in 0..ticks {
            self.world.step(&mut self.out);
        }
        for (client, message) in self.out.drain(..) {
            let index = client.0.wrapping_sub(self.first) as usize;
            if let Some(uav) = self.uavs.get_mut(index)
                && uav.client == client
            {
                uav.state.apply(&message);
            }
        }
    }

    /// Simulated seconds.
    pub(crate) fn time(&self) -> f64 {
        self.world.time()
    }

    /// Appends each UAV's observation to `obs`.
    pub(crate) fn observe(&self, obs: &mut Observations) {
        for uav in &self.uavs {
            obs.push_state(&uav.state, uav.touched, self.world.time());
        }
    }
}

fn position(uav: &Uav) -> [f64; 3] {
    uav.state
        .position
        .as_ref()
        .map_or([0.0; 3], |p| [p.value.x, p.value.y, p.value.z])
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Observations of many UAVs, one flat row-major buffer per field.
#[derive(Debug, Default, Clone, PartialEq)]
pub(crate) struct Observations {
    /// x, y, z, m (z down).
    pub(crate) position: Vec<f64>,
    /// World-frame velocity, m/s.
    pub(crate) velocity: Vec<f64>,
    /// Roll, pitch, yaw, rad.
    pub(crate) attitude: Vec<f64>,
    /// Roll, pitch, yaw rates, rad/s.
    pub(crate) angular_velocity: Vec<f64>,
    /// 8 horizontal sonars (0 forward, clockwise), then top, bottom; m.
    pub(crate) sonar: Vec<f64>,
    /// 228 beams, index 0 the rightmost; m.
    pub(crate) laser: Vec<f64>,
    /// Battery fraction left, 0..=1.
    pub(crate) battery: Vec<f64>,
    /// Whether the body was stopped by something during the last period.
    pub(crate) touched: Vec<bool>,
    /// Whether the UAV has crashed (a robot with physics, such as the stsQuadrotor, reports
    /// it with its `Crash` touch sensor; docs/quadrotor.md).
    pub(crate) crashed: Vec<bool>,
    /// Simulated seconds.
    pub(crate) time: Vec<f64>,
}

fn xyz(r: Option<&ucc_client::uav::Reading<ucc_client::Coordinates>>) -> [f64; 3] {
    r.map_or([0.0; 3], |r| [r.value.x, r.value.y, r.value.z])
}

impl Observations {
    /// Room for `n` UAVs.
    pub(crate) fn with_capacity(n: usize) -> Self {
        Self {
            position: Vec::with_capacity(3 * n),
            velocity: Vec::with_capacity(3 * n),
            attitude: Vec::with_capacity(3 * n),
            angular_velocity: Vec::with_capacity(3 * n),
            sonar: Vec::with_capacity(SONARS * n),
            laser: Vec::with_capacity(LASER * n),
            battery: Vec::with_capacity(n),
            touched: Vec::with_capacity(n),
            crashed: Vec::with_capacity(n),
            time: Vec::with_capacity(n),
        }
    }

    pub(crate) fn push_state(&mut self, s: &UavState, touched: bool, time: f64) {
        self.position.extend(xyz(s.position.as_ref()));
        self.velocity.extend(xyz(s.velocity.as_ref()));
        self.attitude.extend(xyz(s.orientation.as_ref()));
        self.angular_velocity
            .extend(xyz(s.angular_velocity.as_ref()));
        let range = |r: &Option<ucc_client::uav::Reading<f64>>| {
            r.as_ref().map_or(NO_RANGE, |r| {
                if r.value.is_finite() {
                    r.value
                } else {
                    NO_RANGE
                }
            })
        };
        self.sonar.extend(s.sonars.iter().map(range));
        self.sonar.push(range(&s.free_above));
        self.sonar.push(range(&s.free_below));
        let beams = s.laser.as_ref().map_or(&[][..], |l| &l.value.ranges[..]);
        self.laser.extend((0..LASER).map(|i| {
            beams
                .get(i)
                .copied()
                .filter(|v| v.is_finite())
                .unwrap_or(NO_RANGE)
        }));
        self.battery
            .push(s.battery.as_ref().map_or(1.0, |b| b.value.level));
        self.touched.push(touched || s.crashed());
        self.crashed.push(s.crashed());
        self.time.push(time);
    }
}

/// Many worlds with the same number of UAVs each, stepped together.
#[derive(Debug)]
pub(crate) struct Batch {
    pub(crate) settings: Settings,
    pub(crate) worlds: Vec<WorldSim>,
    pub(crate) uavs_per_world: usize,
}

impl Batch {
    /// Total UAVs.
    pub(crate) fn len(&self) -> usize {
        self.worlds.len() * self.uavs_per_world
    }

    /// Replaces world `index` by a fresh one.
    pub(crate) fn reset_world(
        &mut self,
        index: usize,
        seed: u64,
        poses: &[Pose],
    ) -> Result<(), SimError> {
        if poses.len() != self.uavs_per_world {
            return Err(invalid(format!(
                "starts: world {index} needs {} starts, got {}",
                self.uavs_per_world,
                poses.len()
            )));
        }
        let world = WorldSim::new(&self.settings, seed, poses)
            .map_err(|e| invalid(format!("world {index}: {e}")))?;
        match self.worlds.get_mut(index) {
            Some(slot) => *slot = world,
            None => return Err(invalid(format!("world index {index} out of range"))),
        }
        Ok(())
    }

    /// Steps every world one control period; `actions` has one row per UAV (world-major).
    /// Worlds are spread over the cores when there are enough of them.
    pub(crate) fn step(&mut self, actions: &[[f64; 4]]) {
        let per = self.uavs_per_world;
        let settings = &self.settings;
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        if threads < 2 || self.worlds.len() < 4 {
            for (w, a) in self.worlds.iter_mut().zip(actions.chunks(per)) {
                w.step(settings, a);
            }
            return;
        }
        let chunk = self.worlds.len().div_ceil(threads);
        std::thread::scope(|scope| {
            for (worlds, actions) in self
                .worlds
                .chunks_mut(chunk)
                .zip(actions.chunks(chunk * per))
            {
                scope.spawn(move || {
                    for (w, a) in worlds.iter_mut().zip(actions.chunks(per)) {
                        w.step(settings, a);
                    }
                });
            }
        });
    }

    /// Every UAV's observation, world-major.
    pub(crate) fn observe(&self) -> Observations {
        let mut obs = Observations::with_capacity(self.len());
        for w in &self.worlds {
            w.observe(&mut obs);
        }
        obs
    }
}
