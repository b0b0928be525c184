//! The in-process simulation behind the Python environments: worlds of `usar_sim`
//! stepped in lockstep, one control period at a time, with the sensor lines folded into a
//! [`UavState`] per UAV and written out as flat arrays. No Python types here.

use std::cell::RefCell;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use crate::tasks::{TaskOut, TaskPass, TaskPiece};
use ucc_client::SpeedCommand;
use ucc_client::uav::UavState;
use usar_proto::SenData;
use usar_proto::{Command, Init, ServerMessage, Vec3};
use usar_sim::robots::{DynamicsKind, PartConfig};
use usar_sim::{CameraFrame, ClientId, Map, RobotCatalog, RobotClass, SimConfig, World};

/// Horizontal sonars + SonarTop + SonarBottom.
pub(crate) const SONARS: usize = 10;
/// The stsAirRobot's Hokuyo URG-04LX beams.
pub(crate) const LASER: usize = 228;
/// Range reported for a sonar or beam that has not read yet (the laser's maximum).
const NO_RANGE: f64 = 4.0;
/// The Rotors part added for rotor speeds in the observation.
const ROTORS: &str = "PyRotors";
/// The largest sensor noise standard deviation a robot file accepts (docs/robots.md).
const MAX_NOISE: f64 = 100.0;

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

/// The largest roll and pitch an attitude action asks for, rad (the crash tilt is 60°).
pub(crate) const MAX_TILT: f64 = 0.6;
/// The largest yaw rate an attitude action asks for, rad/s (100°/s, as DRIVE's maximum).
pub(crate) const MAX_YAW_RATE: f64 = 1.745_329_251_994_329_5;
/// Gravity, m/s² (the quadrotor model's).
const GRAVITY: f64 = 9.80665;

/// How a normalized action row (four values in -1..=1) commands the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum ActionMode {
    /// Forward, right, up, yaw rate: fractions of the robot's maximum speeds (`DRIVE`).
    Velocity,
    /// Roll, pitch (× [`MAX_TILT`]), yaw rate (× [`MAX_YAW_RATE`]) and collective thrust
    /// `weight × (1 + a)` (0 to twice the weight): `QUAD {Attitude} {Thrust}`.
    Attitude {
        /// The vehicle's weight, N.
        weight: f64,
    },
    /// Body rates (roll, pitch, yaw; × `max_rate`) and collective thrust `weight × (1 + a)`:
    /// `QUAD {Rates} {Thrust}`.
    Rates {
        /// The class's largest commanded body rate, rad/s (`max_tilt_rate`).
        max_rate: f64,
        /// The vehicle's weight, N.
        weight: f64,
    },
    /// Four rotor speeds, -1..=1 mapped onto the class's rotor speed range: `QUAD {Rotors}`.
    Rotors {
        /// Rotor speed limits, rad/s.
        min: f64,
        /// Rotor speed limits, rad/s.
        max: f64,
    },
}

/// Settings shared by every world of a batch.
#[derive(Debug, Clone)]
pub(crate) struct Settings {
    /// Shared by every world of the batch (a world only reads them).
    pub(crate) map: Arc<Map>,
    pub(crate) catalog: Arc<RobotCatalog>,
    pub(crate) robot: String,
    pub(crate) period: f64,
    pub(crate) dt: f64,
    /// Without sonars and laser ([`Settings::state_only`]).
    pub(crate) state_only: bool,
    /// How actions command the robot.
    pub(crate) action: ActionMode,
    /// Faults scheduled in each world (the faults file's format; docs/python.md#faults).
    pub(crate) faults: usar_sim::faults::FaultPlan,
    /// Parameter ranges each UAV draws from at each reset (docs/python.md#faults).
    pub(crate) randomize: Option<usar_sim::randomize::Randomization>,
    /// Rotor speeds in the observation (a `Rotors` part added to the class).
    pub(crate) rotors: bool,
    /// The observation camera's width and height ([`Settings::camera`]).
    pub(crate) camera: Option<(u32, u32)>,
    /// Counts [`Settings::configure`] calls: a world made under another count is made
    /// again at its reset instead of being reset in place ([`WorldSim::reset`]).
    pub(crate) version: u64,
}

/// The largest side of an observation image, pixels.
pub(crate) const MAX_IMAGE_SIDE: u32 = 1024;
/// How far the observation camera sees, m: farther (or nothing) reads this depth.
pub(crate) const DEPTH_MAX: f64 = 100.0;

impl Settings {
    /// Checks and loads: `map` is an embedded map name or a map file; `noise` (if given)
    /// replaces the noise standard deviation of every part of the robot class.
    pub(crate) fn new(
        map: &str,
        robot: &str,
        period: f64,
        noise: Option<f64>,
    ) -> Result<Self, SimError> {
        Self::with_rates(map, robot, period, noise, None, &[], None)
    }

    /// [`Settings::new`] with a physics rate (Hz, `None`: 200), sensor rates (part name,
    /// Hz) and a robot file (`None`: the embedded catalog): every rate is checked against
    /// the physics rate (a sensor reads at most once a tick, on whole ticks), and a GPS
    /// needs the map's origin; errors name the robot, the sensor and the value.
    pub(crate) fn with_rates(
        map: &str,
        robot: &str,
        period: f64,
        noise: Option<f64>,
        physics_rate: Option<f64>,
        sensor_rates: &[(String, f64)],
        robots: Option<&str>,
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
        let mut catalog = match robots {
            None => RobotCatalog::embedded(),
            Some(path) => RobotCatalog::from_file(Path::new(path))
                .map_err(|e| invalid(format!("robots: {e}")))?,
        };
        let full = usar_proto::Init::qualified_class(robot);
        if let Err(unknown) = catalog.class(&full) {
            return Err(invalid(format!("robot: {unknown}")));
        }
        let Some(class) = catalog.get_mut(&full) else {
            return Err(invalid(format!("robot: unknown robot class {full:?}")));
        };
        let dt = match physics_rate {
            None => SimConfig::default().dt,
            Some(hz) => usar_sim::robots::physics_step(hz)
                .map_err(|e| invalid(format!("physics_rate: {e}")))?,
        };
        let ticks = period / dt;
        if !(period.is_finite() && period >= dt && (ticks - ticks.round()).abs() < 1e-6) {
            return Err(invalid(format!(
                "period: the control period must be a whole multiple of the {dt} s physics \
                 step (at 200 Hz: 0.005, 0.01, ..., 0.1, ...), got {period}"
            )));
        }
        for (part, hz) in sensor_rates {
            class
                .set_sensor_rate(part, *hz)
                .map_err(|e| invalid(format!("sensor_rates: {e}")))?;
        }
        class
            .check_rates(dt)
            .map_err(|e| invalid(format!("sensor_rates: {e} (physics_rate=)")))?;
        class
            .check_map(&map)
            .map_err(|e| invalid(format!("map: {e}")))?;
        if let Some(noise) = noise {
            if !(noise.is_finite() && (0.0..=MAX_NOISE).contains(&noise)) {
                return Err(invalid(format!(
                    "noise: must be a finite standard deviation in 0..={MAX_NOISE}, got {noise}"
                )));
            }
            for part in &mut class.parts {
                part.noise = noise;
            }
        }
        let robot = class.class.clone();
        Ok(Self {
            map: Arc::new(map),
            catalog: Arc::new(catalog),
            robot,
            period,
            dt,
            state_only: false,
            action: ActionMode::Velocity,
            faults: usar_sim::faults::FaultPlan::default(),
            randomize: None,
            rotors: false,
            camera: None,
            version: 0,
        })
    }

    /// Faults (a faults file's text, docs/quadrotor.md#faults), domain randomisation (a
    /// randomisation file's text) and rotor speeds in the observation, for the worlds made
    /// from now on; `None` leaves a setting as it is, an empty text turns it off.
    pub(crate) fn configure(
        &mut self,
        faults: Option<&str>,
        randomize: Option<&str>,
        rotors: Option<bool>,
    ) -> Result<(), SimError> {
        self.version += 1;
        if let Some(text) = faults {
            self.faults = usar_sim::faults::FaultPlan::from_toml(text)
                .map_err(|e| invalid(format!("faults: {e}")))?;
        }
        if let Some(text) = randomize {
            self.randomize = match text.trim() {
                "" => None,
                _ => Some(
                    usar_sim::randomize::Randomization::from_toml(text)
                        .map_err(|e| invalid(format!("randomize: {e}")))?,
                ),
            };
        }
        if let Some(on) = rotors {
            let class = Arc::make_mut(&mut self.catalog)
                .get_mut(&self.robot)
                .ok_or_else(|| invalid(format!("robot: unknown robot class {:?}", self.robot)))?;
            if on && class.dynamics != DynamicsKind::Quadrotor {
                return Err(invalid(format!(
                    "rotor_speeds: needs a robot with rotors (such as stsQuadrotor); {} is \
                     kinematic",
                    self.robot
                )));
            }
            class.parts.retain(|p| p.name != ROTORS);
            if on {
                class.parts.push(PartConfig {
                    kind: "Rotors".to_string(),
                    name: ROTORS.to_string(),
                    position: [0.0; 3],
                    direction: [0.0; 3],
                    interval: Some(self.dt),
                    noise: 0.0,
                    settings: toml::Table::new(),
                });
            }
            self.rotors = on;
        }
        Ok(())
    }

    /// With the action mode `mode`: `"velocity"`, or for a robot with physics `"attitude"`,
    /// `"rates"` or `"rotors"` (the `QUAD` extension, docs/quadrotor.md).
    pub(crate) fn action_mode(mut self, mode: &str) -> Result<Self, SimError> {
        let class = self
            .catalog
            .get(&self.robot)
            .ok_or_else(|| invalid(format!("robot: unknown robot class {:?}", self.robot)))?;
        let q = &class.quadrotor;
        self.action = match mode {
            "velocity" => ActionMode::Velocity,
            "attitude" | "rates" | "rotors" if class.dynamics != DynamicsKind::Quadrotor => {
                return Err(invalid(format!(
                    "action_mode: {mode:?} needs a robot with physics (such as stsQuadrotor); \
                     {} is kinematic",
                    self.robot
                )));
            }
            "attitude" => ActionMode::Attitude {
                weight: q.mass * GRAVITY,
            },
            "rates" => ActionMode::Rates {
                max_rate: q.max_tilt_rate,
                weight: q.mass * GRAVITY,
            },
            "rotors" => ActionMode::Rotors {
                min: q.rotor_speed_min,
                max: q.rotor_speed_max,
            },
            other => {
                return Err(invalid(format!(
                    "action_mode: expected \"velocity\", \"attitude\", \"rates\" or \"rotors\", \
                     got {other:?}"
                )));
            }
        };
        Ok(self)
    }

    /// The command of one action row (values in -1..=1).
    fn command(&self, a: &[f64; 4]) -> Command {
        let line = match self.action {
            ActionMode::Velocity => return drive(a),
            ActionMode::Attitude { weight } => format!(
                "QUAD {{Attitude {},{},{}}} {{Thrust {}}}",
                a[0] * MAX_TILT,
                a[1] * MAX_TILT,
                a[2] * MAX_YAW_RATE,
                weight * (1.0 + a[3])
            ),
            ActionMode::Rates { max_rate, weight } => format!(
                "QUAD {{Rates {},{},{}}} {{Thrust {}}}",
                a[0] * max_rate,
                a[1] * max_rate,
                a[2] * max_rate,
                weight * (1.0 + a[3])
            ),
            ActionMode::Rotors { min, max } => {
                let w = a.map(|v| min + (v + 1.0) / 2.0 * (max - min));
                format!("QUAD {{Rotors {},{},{},{}}}", w[0], w[1], w[2], w[3])
            }
        };
        // Finite numbers always parse; hover (a level DRIVE) if they somehow did not.
        Command::parse(&line).map_or_else(|_| drive(&[0.0; 4]), |p| p.message)
    }

    /// The same without the range sensors (every `Sonar` and `RangeScanner` part removed):
    /// the world casts no rays and observations carry no sonar or laser columns.
    pub(crate) fn state_only(mut self) -> Self {
        if let Some(class) = Arc::make_mut(&mut self.catalog).get_mut(&self.robot) {
            class.parts.retain(|p| {
                !p.kind.eq_ignore_ascii_case("Sonar")
                    && !p.kind.eq_ignore_ascii_case("RangeScanner")
            });
        }
        self.state_only = true;
        self
    }

    /// With one forward-looking camera of `width` × `height` pixels (80° wide, seeing to
    /// [`DEPTH_MAX`]) in place of the robot class's cameras, for image observations.
    pub(crate) fn camera(mut self, width: u32, height: u32) -> Result<Self, SimError> {
        for (what, side) in [("width", width), ("height", height)] {
            if !(1..=MAX_IMAGE_SIDE).contains(&side) {
                return Err(invalid(format!(
                    "camera_size: {what} must be 1 to {MAX_IMAGE_SIDE} pixels, got {side}"
                )));
            }
        }
        if let Some(class) = Arc::make_mut(&mut self.catalog).get_mut(&self.robot) {
            class
                .parts
                .retain(|p| !p.kind.eq_ignore_ascii_case("Camera"));
            class.parts.push(PartConfig {
                kind: "Camera".to_string(),
                name: "Observation".to_string(),
                position: [0.1, 0.0, 0.1],
                direction: [0.0; 3],
                interval: None,
                noise: 0.0,
                settings: toml::Table::from_iter([
                    ("width".to_string(), toml::Value::Integer(i64::from(width))),
                    (
                        "height".to_string(),
                        toml::Value::Integer(i64::from(height)),
                    ),
                    ("range".to_string(), toml::Value::Float(DEPTH_MAX)),
                ]),
            });
        }
        self.camera = Some((width, height));
        Ok(self)
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
    let mut init = Init {
        class_name: class.to_owned(),
        name: Some(name.to_owned()),
        ..Init::default()
    };
    place(&mut init, pose);
    Command::Init(init)
}

/// Puts `init`'s robot at `pose`, level.
fn place(init: &mut Init, pose: &Pose) {
    init.location = Some(Vec3::new(pose[0], pose[1], pose[2]));
    init.rotation = Some(Vec3::new(0.0, 0.0, pose[3]));
}

/// Control periods of `period` seconds a new robot of `class` hovers before its first
/// observation: until every one of its sensors has read once (each sensor's timer starts at
/// the spawn), at least one. The in-process worlds and the remote env both wait this long,
/// so that their first observations are taken at the same time and are as complete.
pub(crate) fn first_periods(class: Option<&RobotClass>, period: f64) -> usize {
    let first = class.map_or(0.0, RobotClass::first_readings);
    ((first / period - 1e-9).ceil() as usize).max(1)
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
    /// The latest rotor speeds, rad/s (with `Settings::rotors`).
    rotors: [f64; 4],
    /// The IMU readings of the last control period: time, acceleration x, y, z (m/s²),
    /// body rates x, y, z (rad/s).
    imu: Vec<[f64; 7]>,
}

/// The UAV of connection `client` (clients are numbered from `first` in the UAVs' order).
fn uav_of(uavs: &mut [Uav], first: u64, client: ClientId) -> Option<&mut Uav> {
    let index = client.0.wrapping_sub(first) as usize;
    uavs.get_mut(index).filter(|u| u.client == client)
}

/// One world with its UAVs.
#[derive(Debug)]
pub(crate) struct WorldSim {
    world: World,
    uavs: Vec<Uav>,
    /// Clients are numbered 1.. in connection order, so `client.0 - first` is the index.
    first: u64,
    /// Each UAV's `INIT` (reused: [`WorldSim::spawn`]).
    inits: Vec<Init>,
    /// The cameras' latest pictures (reused).
    frames: Vec<CameraFrame>,
    /// The [`Settings::version`] it was made under.
    version: u64,
    /// Spawned by [`WorldSim::restart`], not yet settled.
    unsettled: bool,
}

impl WorldSim {
    /// A fresh world with one UAV per pose, seeded with `seed`, after hovering whole control
    /// periods until every sensor has read once (at least one period; sensors speak one
    /// interval after the spawn).
    pub(crate) fn new(settings: &Settings, seed: u64, poses: &[Pose]) -> Result<Self, SimError> {
        let mut sim = Self::empty(settings, seed);
        sim.spawn(settings, poses)?;
        sim.settle(settings);
        Ok(sim)
    }

    /// A fresh world without UAVs.
    fn empty(settings: &Settings, seed: u64) -> Self {
        let config = SimConfig {
            seed,
            dt: settings.dt,
            faults: settings.faults.clone(),
            randomize: settings.randomize.clone(),
            ..SimConfig::default()
        };
        Self {
            world: World::new(settings.map.clone(), settings.catalog.clone(), config),
            uavs: Vec::new(),
            first: 0,
            inits: Vec::new(),
            frames: Vec::new(),
            version: settings.version,
            unsettled: false,
        }
    }

    /// The first half of a reset (a new episode): the world starts over with `seed` and one
    /// UAV spawns per pose, in place (the map's scene is not built again: [`World::reset`])
    /// when the settings are those the world was made under, else in a new world; then
    /// [`WorldSim::settle`] hovers them (bit for bit what a new world would fly). A batch
    /// restarts a piece of worlds, then settles them: the spawn's code and the step's each
    /// stay in the instruction cache over the piece instead of taking turns in it. After an
    /// error (a start inside a wall) the world must be reset again before it steps.
    pub(crate) fn restart(
        &mut self,
        settings: &Settings,
        seed: u64,
        poses: &[Pose],
    ) -> Result<(), SimError> {
        if self.version != settings.version {
            *self = Self::empty(settings, seed);
        } else {
            self.world.reset(seed);
        }
        self.uavs.clear();
        self.spawn(settings, poses)
    }

    /// Spawns one UAV per pose in the (empty) world.
    fn spawn(&mut self, settings: &Settings, poses: &[Pose]) -> Result<(), SimError> {
        self.unsettled = false;
        let world = &mut self.world;
        let uavs = &mut self.uavs;
        let mut first = 0;
        for (i, pose) in poses.iter().enumerate() {
            if !pose.iter().all(|v| v.is_finite()) {
                return Err(invalid(format!("start {i}: not finite: {pose:?}")));
            }
            let client = world.connect();
            if i == 0 {
                first = client.0;
            }
            // Each UAV's INIT is kept from reset to reset: only its pose changes (the class
            // is the settings', which a reset under other settings makes a new world for).
            if self.inits.len() == i {
                self.inits.push(Init {
                    class_name: settings.robot.clone(),
                    name: Some(format!("UAV{i}")),
                    ..Init::default()
                });
            }
            let init = &mut self.inits[i];
            place(init, pose);
            world.init(client, init);
            uavs.push(Uav {
                client,
                state: UavState::new(),
                touched: false,
                rotors: [0.0; 4],
                imu: Vec::new(),
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
        self.first = first;
        self.unsettled = true;
        Ok(())
    }

    /// The second half of a reset (a no-op unless a restart has just spawned the UAVs):
    /// hovers whole control periods until every sensor has read once.
    pub(crate) fn settle(&mut self, settings: &Settings) {
        if std::mem::take(&mut self.unsettled) {
            let periods = first_periods(settings.catalog.get(&settings.robot), settings.period);
            self.advance(periods * settings.ticks());
        }
    }

    /// Sends each UAV its normalized command (forward, right, up, yaw in -1..=1), then steps
    /// one control period. Actions must be finite (checked by the caller).
    pub(crate) fn step(&mut self, settings: &Settings, actions: &[[f64; 4]]) {
        for (uav, a) in self.uavs.iter().zip(actions) {
            self.world.command(uav.client, settings.command(a));
        }
        self.advance(settings.ticks());
    }

    /// Steps `ticks` physics ticks; a UAV touched something in them when its body touched
    /// something in any tick, or it had crashed (the server's own contact test, any robot:
    /// [`World::take_touched`]).
    fn advance(&mut self, ticks: usize) {
        thread_local! {
            /// The messages of the world a thread steps, one buffer for all its worlds (in
            /// the caches, where a world's own would be cold by its next period).
            static OUT: RefCell<Vec<(ClientId, ServerMessage)>> = const { RefCell::new(Vec::new()) };
        }
        OUT.with_borrow_mut(|out| {
            out.clear(); // (empty unless a panic left it so)
            self.world.run(ticks as u64, out);
            let (uavs, first) = (&mut self.uavs, self.first);
            for uav in uavs.iter_mut() {
                uav.imu.clear();
            }
            self.world.take_touched(|client, touched| {
                if let Some(uav) = uav_of(uavs, first, client) {
                    uav.touched = touched;
                }
            });
            // Read in place, then dropped together: each message is moved once less.
            for (client, message) in out.iter() {
                let Some(uav) = uav_of(uavs, first, *client) else {
                    continue;
                };
                if let ServerMessage::Sen(sen) = message
                    && let SenData::Other { kind, groups } = &sen.data
                    && kind == "Rotors"
                {
                    let speeds = groups
                        .iter()
                        .flat_map(|g| &g.pairs)
                        .find(|p| p.key == "Speeds");
                    let w: Vec<f64> = speeds.map_or_else(Vec::new, |p| {
                        p.value.split(',').filter_map(|v| v.parse().ok()).collect()
                    });
                    if let [a, b, c, d] = w[..] {
                        uav.rotors = [a, b, c, d];
                    }
                    continue;
                }
                if let ServerMessage::Sen(sen) = message
                    && let SenData::Imu {
                        acceleration: a,
                        angular_vel: w,
                        ..
                    } = &sen.data
                {
                    let t = sen.time.map_or(f64::NAN, |t| t.seconds);
                    uav.imu.push([t, a.x, a.y, a.z, w.x, w.y, w.z]);
                }
                uav.state.apply(message);
            }
            out.clear();
        });
    }

    /// The IMU readings of UAV `index` in the last control period (`None`: no such UAV).
    pub(crate) fn imu_readings(&self, index: usize) -> Option<&[[f64; 7]]> {
        self.uavs.get(index).map(|u| u.imu.as_slice())
    }

    /// Simulated seconds.
    pub(crate) fn time(&self) -> f64 {
        self.world.time()
    }

    /// Starts bringing the world's and its UAVs' memory into the caches (a hint:
    /// [`World::prefetch`]); the batch asks it of the next world while it steps one.
    pub(crate) fn prefetch(&self) {
        self.world.prefetch();
        usar_sim::prefetch::lines(&self.uavs, 16);
    }

    /// The part of [`WorldSim::prefetch`] the batch asks a world earlier
    /// ([`World::prefetch_early`]).
    pub(crate) fn prefetch_early(&self) {
        self.world.prefetch_early();
        usar_sim::prefetch::line(&self.uavs);
    }

    /// [`WorldSim::prefetch`] for a world about to restart ([`World::prefetch_reset`]).
    pub(crate) fn prefetch_reset(&self) {
        self.world.prefetch_reset();
        usar_sim::prefetch::lines(&self.uavs, 16);
        usar_sim::prefetch::lines(&self.inits, 4);
    }

    /// The part of [`WorldSim::prefetch_reset`] the batch asks a world earlier.
    pub(crate) fn prefetch_reset_early(&self) {
        self.world.prefetch_reset_early();
        usar_sim::prefetch::line(&self.uavs);
        usar_sim::prefetch::line(&self.inits);
    }

    /// Renders every UAV's camera and appends, per UAV, its R, G, B bytes (`rgb`) and its
    /// depths in metres, [`DEPTH_MAX`] where nothing is nearer (`depth`).
    pub(crate) fn render(&mut self, rgb: Option<&mut Vec<u8>>, depth: Option<&mut Vec<f32>>) {
        self.world.render_cameras(&mut self.frames);
        if let Some(rgb) = rgb {
            for f in &self.frames {
                rgb.extend_from_slice(&f.image.rgb);
            }
        }
        if let Some(depth) = depth {
            for f in &self.frames {
                depth.extend(f.image.depth.iter().map(|d| d.min(DEPTH_MAX as f32)));
            }
        }
    }

    /// The radio signal between every two UAVs, dBm (row-major `n × n`, the WSS's default
    /// model: distance and walls between their centres; 0 on the diagonal).
    pub(crate) fn signals(&self, out: &mut Vec<f64>) {
        let model = usar_proto::wss::PathLoss::default();
        let robots = self.world.robots_truth();
        for a in &robots {
            for b in &robots {
                out.push(if std::ptr::eq(a, b) {
                    0.0
                } else {
                    let walls = f64::from(self.world.obstacles_between(a.location, b.location));
                    model.strength(a.location, b.location, walls)
                });
            }
        }
    }

    /// Writes each UAV's observation into `rows`, UAV `k` of the world as row `at + k`.
    pub(crate) fn write(&self, rows: &mut Rows<'_>, at: usize) {
        let time = self.world.time();
        for (k, uav) in (at..).zip(&self.uavs) {
            rows.write(k, &uav.state, uav.touched, time);
            if let Some(r) = rows.rotor_speeds.get_mut(4 * k..4 * k + 4) {
                r.copy_from_slice(&uav.rotors);
            }
        }
    }

    /// The parameters each UAV drew (domain randomisation), in UAV order.
    pub(crate) fn randomized(&self) -> Vec<usar_sim::randomize::Drawn> {
        self.world.randomized()
    }
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
    /// Leave `sonar` and `laser` empty.
    pub(crate) no_ranges: bool,
    /// Rotor speeds, rad/s, four per UAV (with `with_rotors`).
    pub(crate) rotor_speeds: Vec<f64>,
    /// Fill `rotor_speeds`.
    pub(crate) with_rotors: bool,
}

fn xyz(r: Option<&ucc_client::uav::Reading<ucc_client::Coordinates>>) -> [f64; 3] {
    r.map_or([0.0; 3], |r| [r.value.x, r.value.y, r.value.z])
}

impl Observations {
    /// Every buffer sized for `n` UAVs (keeping its memory; `sonar` and `laser` empty with
    /// `no_ranges`, `rotor_speeds` without `with_rotors`), to be written through
    /// [`Observations::rows`].
    pub(crate) fn resize(&mut self, n: usize) {
        let ranges = usize::from(!self.no_ranges);
        let rotors = usize::from(self.with_rotors);
        for (v, width) in [
            (&mut self.position, 3),
            (&mut self.velocity, 3),
            (&mut self.attitude, 3),
            (&mut self.angular_velocity, 3),
            (&mut self.sonar, SONARS * ranges),
            (&mut self.laser, LASER * ranges),
            (&mut self.battery, 1),
            (&mut self.time, 1),
            (&mut self.rotor_speeds, 4 * rotors),
        ] {
            v.resize(n * width, 0.0);
        }
        self.touched.resize(n, false);
        self.crashed.resize(n, false);
    }

    /// The buffers as [`Rows`].
    pub(crate) fn rows(&mut self) -> Rows<'_> {
        Rows {
            position: &mut self.position,
            velocity: &mut self.velocity,
            attitude: &mut self.attitude,
            angular_velocity: &mut self.angular_velocity,
            sonar: &mut self.sonar,
            laser: &mut self.laser,
            battery: &mut self.battery,
            time: &mut self.time,
            rotor_speeds: &mut self.rotor_speeds,
            touched: &mut self.touched,
            crashed: &mut self.crashed,
        }
    }

    /// Appends one UAV's observation (rotor speeds left at 0).
    pub(crate) fn push_state(&mut self, s: &UavState, touched: bool, time: f64) {
        let k = self.battery.len();
        self.resize(k + 1);
        self.rows().write(k, s, touched, time);
    }
}

/// Observations written in place: for each field, the rows of some UAVs, one after the other
/// (UAV-major, the field's width per UAV: 3 for `position`, [`SONARS`] for `sonar`, ...;
/// `sonar` and `laser` empty without range sensors, `rotor_speeds` without rotor speeds).
/// The slices are a NumPy array's memory (`Batch.step(..., out=...)`) or an
/// [`Observations`]' buffers.
#[derive(Debug)]
pub(crate) struct Rows<'a> {
    pub(crate) position: &'a mut [f64],
    pub(crate) velocity: &'a mut [f64],
    pub(crate) attitude: &'a mut [f64],
    pub(crate) angular_velocity: &'a mut [f64],
    pub(crate) sonar: &'a mut [f64],
    pub(crate) laser: &'a mut [f64],
    pub(crate) battery: &'a mut [f64],
    pub(crate) time: &'a mut [f64],
    pub(crate) rotor_speeds: &'a mut [f64],
    pub(crate) touched: &'a mut [bool],
    pub(crate) crashed: &'a mut [bool],
}

/// `s` cut into `n` consecutive pieces of `size` (`n` empty pieces when `s` is empty).
fn pieces<T>(s: &mut [T], n: usize, size: usize) -> std::vec::IntoIter<&mut [T]> {
    if s.is_empty() || size == 0 {
        (0..n).map(|_| <&mut [T]>::default()).collect::<Vec<_>>()
    } else {
        s.chunks_mut(size).collect()
    }
    .into_iter()
}

impl<'a> Rows<'a> {
    /// Cut into `n` pieces of the rows of `per` consecutive UAVs each (the last one
    /// shorter when the UAVs run out).
    pub(crate) fn split(self, per: usize, n: usize) -> Vec<Self> {
        let mut position = pieces(self.position, n, 3 * per);
        let mut velocity = pieces(self.velocity, n, 3 * per);
        let mut attitude = pieces(self.attitude, n, 3 * per);
        let mut angular_velocity = pieces(self.angular_velocity, n, 3 * per);
        let mut sonar = pieces(self.sonar, n, SONARS * per);
        let mut laser = pieces(self.laser, n, LASER * per);
        let mut battery = pieces(self.battery, n, per);
        let mut time = pieces(self.time, n, per);
        let mut rotor_speeds = pieces(self.rotor_speeds, n, 4 * per);
        let mut touched = pieces(self.touched, n, per);
        let mut crashed = pieces(self.crashed, n, per);
        (0..n)
            .map(|_| Rows {
                position: position.next().unwrap_or_default(),
                velocity: velocity.next().unwrap_or_default(),
                attitude: attitude.next().unwrap_or_default(),
                angular_velocity: angular_velocity.next().unwrap_or_default(),
                sonar: sonar.next().unwrap_or_default(),
                laser: laser.next().unwrap_or_default(),
                battery: battery.next().unwrap_or_default(),
                time: time.next().unwrap_or_default(),
                rotor_speeds: rotor_speeds.next().unwrap_or_default(),
                touched: touched.next().unwrap_or_default(),
                crashed: crashed.next().unwrap_or_default(),
            })
            .collect()
    }

    /// The float64 fields, in [`crate::FIELDS`]' order (empty where not observed).
    pub(crate) fn floats(&self) -> [&[f64]; 9] {
        [
            self.position,
            self.velocity,
            self.attitude,
            self.angular_velocity,
            self.sonar,
            self.laser,
            self.battery,
            self.time,
            self.rotor_speeds,
        ]
    }

    /// Writes the observation of the UAV in state `s` as row `k` (the range rows only where
    /// there are range slices).
    pub(crate) fn write(&mut self, k: usize, s: &UavState, touched: bool, time: f64) {
        self.position[3 * k..3 * k + 3].copy_from_slice(&xyz(s.position.as_ref()));
        self.velocity[3 * k..3 * k + 3].copy_from_slice(&xyz(s.velocity.as_ref()));
        self.attitude[3 * k..3 * k + 3].copy_from_slice(&xyz(s.orientation.as_ref()));
        self.angular_velocity[3 * k..3 * k + 3].copy_from_slice(&xyz(s.angular_velocity.as_ref()));
        // At most 1: a quadrotor's battery reports the time left at the current draw, which
        // grows above the first report when the draw falls (docs/quadrotor.md).
        self.battery[k] = s.battery.as_ref().map_or(1.0, |b| b.value.level.min(1.0));
        self.touched[k] = touched || s.crashed();
        self.crashed[k] = s.crashed();
        self.time[k] = time;
        let range = |r: &Option<ucc_client::uav::Reading<f64>>| {
            r.as_ref()
                .map(|r| r.value)
                .filter(|v| v.is_finite())
                .unwrap_or(NO_RANGE)
        };
        if let Some(sonar) = self.sonar.get_mut(SONARS * k..SONARS * (k + 1)) {
            let ranges = s.sonars.iter().chain([&s.free_above, &s.free_below]);
            for (out, r) in sonar.iter_mut().zip(ranges) {
                *out = range(r);
            }
        }
        if let Some(laser) = self.laser.get_mut(LASER * k..LASER * (k + 1)) {
            let beams = s.laser.as_ref().map_or(&[][..], |l| &l.value.ranges[..]);
            for (i, out) in laser.iter_mut().enumerate() {
                *out = beams
                    .get(i)
                    .copied()
                    .filter(|v| v.is_finite())
                    .unwrap_or(NO_RANGE);
            }
        }
    }
}

/// Many worlds with the same number of UAVs each, stepped together.
#[derive(Debug)]
pub(crate) struct Batch {
    pub(crate) settings: Settings,
    pub(crate) worlds: Vec<WorldSim>,
    pub(crate) uavs_per_world: usize,
}

/// The threads that step the batches besides the calling thread: one per other core,
/// started at the first step that needs them and kept (starting a thread at every step cost
/// about 60 µs: more than stepping a few dozen hovering worlds). A process forked since
/// (Python's `multiprocessing`, a `SubprocVecEnv`) has none of its parent's threads: it
/// starts its own. `None` when they cannot be started (then the calling thread steps every
/// world).
fn pool() -> Option<Arc<rayon_core::ThreadPool>> {
    static POOL: Mutex<Option<(u32, Arc<rayon_core::ThreadPool>)>> = Mutex::new(None);
    let mut pool = POOL.lock().unwrap_or_else(PoisonError::into_inner);
    let pid = std::process::id();
    if pool.as_ref().is_some_and(|(owner, _)| *owner != pid) {
        // The parent's pool: its threads do not exist here, so it is never told to stop.
        std::mem::forget(pool.take());
    }
    if pool.is_none() {
        // The calling thread steps a share too: one thread fewer than cores (none on one
        // core; rayon would read 0 as "one per core").
        let others = usar_sim::default_threads()
            .checked_sub(1)
            .filter(|&n| n > 0)?;
        let built = rayon_core::ThreadPoolBuilder::new()
            .num_threads(others)
            .thread_name(|i| format!("usarsim-step-{i}"))
            .build()
            .ok()?;
        *pool = Some((pid, Arc::new(built)));
    }
    pool.as_ref().map(|(_, threads)| threads.clone())
}

/// Runs `f` on every item (a world) with its index, spread over the
/// cores when there are enough (this thread and [`pool`]'s): each thread steps its own
/// share of the items (the same share at every call), a small piece at a time, and a thread
/// done with its share takes the pieces left of the others'. Not a fixed share each: a
/// thread the machine holds up (or a share whose UAVs are pressed against walls, each
/// tick's sweep then casting) no longer keeps the others waiting at the end of the step.
/// Not pieces in turn from one queue either: a world then moved between threads from call
/// to call, and what a reset freed went back to another thread's heap (resets were slower).
/// Fewer than `min` items are stepped on the calling thread alone: handing work to a thread
/// and waiting for it costs tens of microseconds on a VM whose idle cores sleep.
/// Each piece (consecutive items) has its own state, made by `states(piece length, pieces)`
/// (one per piece, in order; dropped after the piece): `f` gets each item with its index,
/// its index in the piece and the piece's state (a Python batch's: the piece's rows of the
/// observation arrays). Before each item a thread passes the next of its piece to
/// `ahead(item, false)` and the one after to `ahead(item, true)` (cache hints, [`WorldSim::prefetch`] and
/// [`WorldSim::prefetch_early`]: a world's state is scattered over a few kilobytes of the
/// heap, and finding it reads a world's own fields first). `first` has each piece (with the
/// index of its first item) before `f` has any of its items: work of other code than `f`'s
/// (a batch's resets' spawns), done in one run so that each code stays in the instruction
/// cache.
fn par_each<T: Send, S: Send, B, F, A>(
    items: &mut [T],
    min: usize,
    states: impl FnOnce(usize, usize) -> Vec<S>,
    ahead: A,
    first: B,
    f: F,
) where
    B: Fn(usize, &mut [T]) + Sync,
    F: Fn(usize, usize, &mut T, &mut S) + Sync,
    A: Fn(&T, bool) + Sync,
{
    let hint = |items: &[T], j: usize| {
        if let Some(next) = items.get(j + 2) {
            ahead(next, true);
        }
        if let Some(next) = items.get(j + 1) {
            ahead(next, false);
        }
    };
    let each = |at: usize, piece: &mut [T], state: &mut S| {
        first(at, piece);
        for j in 0..piece.len() {
            hint(piece, j);
            f(at + j, j, &mut piece[j], state);
        }
    };
    let pool = (items.len() >= min.max(2)).then(pool).flatten();
    let Some(pool) = pool else {
        if let Some(state) = states(items.len(), 1).first_mut() {
            each(0, items, state);
        }
        return;
    };
    let threads = pool.current_num_threads() + 1;
    // About 32 pieces per thread: few enough that taking one costs nothing next to
    // stepping it (a lock), enough that the last one is short: 1024 state-only worlds on
    // two threads are pieces of 16 worlds (some 80 µs), where pieces of 64 left a thread
    // waiting up to a third of a millisecond at the end of each step.
    let chunk = items.len().div_ceil(threads * 32);
    let n = items.len().div_ceil(chunk);
    type Piece<'a, T, S> = Mutex<Option<(&'a mut [T], S)>>;
    let pieces: Vec<Piece<'_, T, S>> = items
        .chunks_mut(chunk)
        .zip(states(chunk, n))
        .map(|p| Mutex::new(Some(p)))
        .collect();
    let end = |share: usize| (share + 1) * n / threads;
    // The next piece of each share.
    let next: Vec<AtomicUsize> = (0..threads)
        .map(|share| AtomicUsize::new(share * n / threads))
        .collect();
    let run = |me: usize| {
        for share in (0..threads).map(|k| (me + k) % threads) {
            loop {
                let p = next[share].fetch_add(1, Ordering::Relaxed);
                if p >= end(share) {
                    break;
                }
                let piece = pieces[p]
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .take();
                if let Some((piece, mut state)) = piece {
                    each(p * chunk, piece, &mut state);
                }
            }
        }
    };
    // Threads done with every share.
    let finished = AtomicUsize::new(0);
    let run = |me: usize| {
        run(me);
        finished.fetch_add(1, Ordering::Release);
    };
    // This thread steps the first share, the pool's threads the others; a panic in `f`
    // reaches the caller once every thread is done. Done first, this thread waits for the
    // others spinning, a while: blocked, it would sleep, and a sleeping core takes tens of
    // microseconds to wake on a VM (the others finish within a piece of it, as each takes
    // what is left of the others' shares).
    pool.in_place_scope(|scope| {
        let run = &run;
        for me in 1..threads {
            scope.spawn(move |_| run(me));
        }
        run(0);
        let start = std::time::Instant::now();
        while finished.load(Ordering::Acquire) < threads
            && start.elapsed() < std::time::Duration::from_micros(500)
        {
            std::hint::spin_loop();
        }
        // The pool marks a job done just after it returns.
        for _ in 0..256 {
            std::hint::spin_loop();
        }
    });
}

/// The fewest worlds a step shares out among the threads. On the 2-core VM of docs/benchmarks-history.md
/// ("Issue 24, twenty-third round") a step's hand-over to the other thread and the wait for
/// it cost a 16-UAV vector env step more than that thread saved (180 µs against 161 µs on one
/// core); at 32 UAVs the two threads were ahead (195 µs against 211 µs).
const PARALLEL_WORLDS: usize = 24;

/// A world to replace by a fresh one: its seed and one start pose per UAV.
pub(crate) type Reset<'a> = (u64, &'a [Pose]);

impl Batch {
    /// Wakes the other threads for a step about to come (a no-op job each: a thread that
    /// just ran one looks for work a while before it sleeps again), so that their wake-up
    /// (tens of microseconds on a VM whose idle cores sleep) overlaps the step's
    /// preparation instead of delaying their share of the worlds.
    pub(crate) fn wake(&self) {
        if self.worlds.len() >= PARALLEL_WORLDS
            && let Some(pool) = pool()
        {
            for _ in 0..pool.current_num_threads() {
                pool.spawn(|| {});
            }
        }
    }

    /// Total UAVs.
    pub(crate) fn len(&self) -> usize {
        self.worlds.len() * self.uavs_per_world
    }

    /// One pass over the worlds, spread over the cores: a world with a `resets` entry is
    /// replaced by a fresh one (its actions ignored); the others step one control period with
    /// their rows of `actions` (one per UAV, world-major), or stay as they are when `actions`
    /// is None. `resets` is empty or one entry per world. With `out` (one row per UAV), each
    /// world then writes its observations there, in the same pass. A reset that cannot spawn
    /// leaves its world as it was and is the error (the lowest world index if several fail);
    /// the other worlds have stepped or reset. With `task` too (its pass and its outputs of
    /// every row), each world then works out its rows' rewards and task observations.
    pub(crate) fn step(
        &mut self,
        actions: Option<&[[f64; 4]]>,
        resets: &[Option<Reset<'_>>],
        out: Option<Rows<'_>>,
        task: Option<(&TaskPass<'_>, TaskOut<'_>)>,
    ) -> Result<(), SimError> {
        let per = self.uavs_per_world;
        for (i, (_, poses)) in resets
            .iter()
            .enumerate()
            .filter_map(|(i, r)| Some((i, r.as_ref()?)))
        {
            if poses.len() != per {
                return Err(invalid(format!(
                    "starts: world {i} needs {per} starts, got {}",
                    poses.len()
                )));
            }
        }
        let settings = &self.settings;
        let failed = Mutex::new(None::<(usize, SimError)>);
        // Each piece of worlds writes its observations into its own rows of `out` (and its
        // task's outputs into its own rows of those).
        let pass = task.as_ref().map(|(pass, _)| *pass);
        let states = |worlds: usize, n: usize| -> Vec<(Option<Rows<'_>>, Option<TaskPiece<'_>>)> {
            let rows = match out {
                Some(rows) => rows.split(per * worlds, n).into_iter().map(Some).collect(),
                None => (0..n).map(|_| None).collect::<Vec<_>>(),
            };
            let tasks = match task {
                Some((pass, (reward, obs))) => pass
                    .pieces(reward, obs, per * worlds, n)
                    .into_iter()
                    .map(Some)
                    .collect(),
                None => (0..n).map(|_| None).collect::<Vec<_>>(),
            };
            rows.into_iter().zip(tasks).collect()
        };
        par_each(
            &mut self.worlds,
            PARALLEL_WORLDS,
            states,
            |w, early| {
                if early {
                    w.prefetch_early();
                } else {
                    w.prefetch();
                }
            },
            |at, piece| {
                // The piece's resets, each with the next two's memory on its way.
                let mut due =
                    (0..piece.len()).filter_map(|j| Some((j, resets.get(at + j)?.as_ref()?)));
                let (mut now, mut next) = (due.next(), due.next());
                for &(k, _) in now.iter().chain(&next) {
                    piece[k].prefetch_reset_early();
                }
                while let Some((j, (seed, poses))) = now {
                    let after = due.next();
                    if let Some((k, _)) = after {
                        piece[k].prefetch_reset_early();
                    }
                    if let Some((k, _)) = next {
                        piece[k].prefetch_reset();
                    }
                    if let Err(e) = piece[j].restart(settings, *seed, poses) {
                        let i = at + j;
                        let mut failed = failed.lock().unwrap_or_else(PoisonError::into_inner);
                        if failed.as_ref().is_none_or(|(j, _)| i < *j) {
                            *failed = Some((i, e));
                        }
                    }
                    (now, next) = (next, after);
                }
            },
            |i, j, w, (rows, piece)| {
                match (resets.get(i).and_then(Option::as_ref), actions) {
                    (Some(_), _) => w.settle(settings),
                    (None, Some(actions)) => w.step(settings, &actions[i * per..(i + 1) * per]),
                    (None, None) => {}
                }
                if let Some(rows) = rows {
                    w.write(rows, j * per);
                    if let (Some(pass), Some(piece)) = (pass, piece) {
                        let raw = (&rows.floats(), &*rows.touched, &*rows.crashed);
                        pass.rows(piece, raw, j * per, (j + 1) * per);
                    }
                }
            },
        );
        match failed.into_inner().unwrap_or_else(PoisonError::into_inner) {
            Some((i, e)) => Err(invalid(format!("world {i}: {e}"))),
            None => Ok(()),
        }
    }

    /// Every UAV's camera picture, world-major: R, G, B bytes (`rgb`) and depths (`depth`),
    /// rendered in parallel over the worlds.
    pub(crate) fn images(&mut self, rgb: bool, depth: bool) -> (Vec<u8>, Vec<f32>) {
        let parts: Vec<Mutex<(Vec<u8>, Vec<f32>)>> =
            self.worlds.iter().map(|_| Mutex::default()).collect();
        par_each(
            &mut self.worlds,
            2,
            |_, n| vec![(); n],
            |_, _| {},
            |_, _| {},
            |i, _, w, ()| {
                let mut part = parts[i].lock().unwrap_or_else(PoisonError::into_inner);
                let (r, d) = &mut *part;
                w.render(rgb.then_some(r), depth.then_some(d));
            },
        );
        let (mut r, mut d) = (Vec::new(), Vec::new());
        for part in parts {
            let (pr, pd) = part.into_inner().unwrap_or_else(PoisonError::into_inner);
            r.extend(pr);
            d.extend(pd);
        }
        (r, d)
    }

    /// The radio signal between the UAVs of each world, dBm: `uavs_per_world²` values per
    /// world (see [`WorldSim::signals`]).
    pub(crate) fn signals(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.worlds.len() * self.uavs_per_world.pow(2));
        for w in &self.worlds {
            w.signals(&mut out);
        }
        out
    }

    /// Every UAV's observation, world-major.
    pub(crate) fn observe(&self) -> Observations {
        let mut obs = Observations::default();
        self.observe_into(&mut obs);
        obs
    }

    /// [`Batch::observe`] into `obs`, reusing its buffers.
    pub(crate) fn observe_into(&self, obs: &mut Observations) {
        obs.no_ranges = self.settings.state_only;
        obs.with_rotors = self.settings.rotors;
        obs.resize(self.len());
        self.write(obs.rows());
    }

    /// Every UAV's observation written into `rows` (one row per UAV, world-major).
    pub(crate) fn write(&self, mut rows: Rows<'_>) {
        for (i, w) in self.worlds.iter().enumerate() {
            w.write(&mut rows, i * self.uavs_per_world);
        }
    }
}
