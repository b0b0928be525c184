//! Robot classes: a TOML catalog in the spirit of USARSim's ini sections (see
//! `docs/robots.md`). A new robot is a configuration entry, not code.

use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use super::map::{ConfigError, ConfigFile, check_name, line_of, read_text, sections};

/// The largest robot file read (bytes).
pub const MAX_ROBOT_FILE: u64 = 1 << 20;
use super::quadrotor::QuadrotorConfig;
use super::sensors;
pub use crate::part::PartConfig;

/// The embedded catalog (`usar-sim/robots.toml`).
const EMBEDDED: &str = include_str!("../robots.toml");

/// Flight limits and behaviour (AerialVehicle / AirRobot defaults).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FlightConfig {
    /// m/s reached by `{LinearVelocity 100} {Normalized true}`.
    pub max_linear_speed: f64,
    /// m/s reached by `{LateralVelocity 100} {Normalized true}`.
    pub max_lateral_speed: f64,
    /// m/s reached by `{AltitudeVelocity 100} {Normalized true}`.
    pub max_altitude_speed: f64,
    /// deg/s reached by `{RotationalVelocity 100} {Normalized true}`.
    pub max_rotation_speed: f64,
    /// Pitch/roll target when moving, degrees.
    pub max_tilt: f64,
    /// Pitch/roll slew rate, rad/s (7000 UU/s).
    pub tilt_rate: f64,
    /// Pitch/roll dead band, rad (200 UU).
    pub tilt_margin: f64,
    /// m/s: the most an absolute (not normalized) `LinearVelocity`, `LateralVelocity` or
    /// `AltitudeVelocity` sets; larger values are clamped.
    pub speed_limit: f64,
    /// deg/s: the most an absolute `RotationalVelocity` sets.
    pub rotation_limit: f64,
    /// Degrees: the most an absolute `PitchAngle` or `RollAngle` sets.
    pub tilt_limit: f64,
}

impl Default for FlightConfig {
    fn default() -> Self {
        Self {
            max_linear_speed: 2.0,
            max_lateral_speed: 2.0,
            max_altitude_speed: 2.0,
            max_rotation_speed: 100.0,
            max_tilt: 25.0,
            tilt_rate: 7000.0 / 10_430.378,
            tilt_margin: 200.0 / 10_430.378,
            speed_limit: 50.0,
            rotation_limit: 1800.0,
            tilt_limit: 90.0,
        }
    }
}

/// The flight model of a robot class (`dynamics = ..`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DynamicsKind {
    /// UDK's AerialVehicle: velocities imposed, byte-compatible with USARSim.
    #[default]
    Kinematic,
    /// A rigid-body quadrotor with motors, drag, wind and an onboard controller
    /// (`[robot.quadrotor]`, docs/quadrotor.md).
    Quadrotor,
}

/// When a contact is a crash (`[robot.crash]`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CrashConfig {
    /// m/s into a surface above which a contact is a crash (quadrotor).
    pub speed: f64,
    /// Degrees of tilt above which a contact is a crash (quadrotor).
    pub tilt: f64,
    /// Kinematic model: any contact with the map or another robot is a crash.
    pub on_contact: bool,
}

impl Default for CrashConfig {
    fn default() -> Self {
        Self {
            speed: 1.0,
            tilt: 60.0,
            on_contact: false,
        }
    }
}

/// The collision shape: an upright cylinder around the robot centre.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CollisionConfig {
    /// m.
    pub radius: f64,
    /// m, full height.
    pub height: f64,
}

impl Default for CollisionConfig {
    fn default() -> Self {
        Self {
            radius: 0.45,
            height: 0.2,
        }
    }
}

/// The colour cameras see robots in when their class names none (orange).
pub const ROBOT_COLOR: [u8; 3] = [235, 120, 30];

/// One joint of an actuator.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointConfig {
    /// `Revolute`, `Prismatic` or `Unknown`.
    #[serde(rename = "type", default = "revolute")]
    pub joint_type: String,
    /// Lower limit (rad or m).
    pub min: f64,
    /// Upper limit.
    pub max: f64,
    /// Torque limit (reported only).
    #[serde(default)]
    pub max_torque: f64,
}

fn revolute() -> String {
    "Revolute".to_string()
}

/// An actuator (e.g. the AirRobot camera tilt `cam`), reported by ASTA.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuatorConfig {
    /// The actuator name (`ACT {Name ..}`).
    pub name: String,
    /// Mount position, body frame, m.
    #[serde(default)]
    pub position: [f64; 3],
    /// Mount direction: roll, pitch, yaw, rad.
    #[serde(default)]
    pub direction: [f64; 3],
    /// Seconds between ASTA lines.
    #[serde(default = "tenth")]
    pub interval: f64,
    /// The joints, link 1 first.
    pub joints: Vec<JointConfig>,
}

fn tenth() -> f64 {
    0.1
}

/// A robot class a catalog does not have.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown robot class {class:?} (known: {})", known.join(", "))]
pub struct UnknownClass {
    /// The class asked for.
    pub class: String,
    /// The classes the catalog has.
    pub known: Vec<String>,
}

/// A robot class.
#[derive(Debug, Clone)]
pub struct RobotClass {
    /// `Package.Class` as INIT names it (`USARBot.stsAirRobot`); matched case-insensitively.
    pub class: String,
    /// Flight limits.
    pub flight: FlightConfig,
    /// The flight model.
    pub dynamics: DynamicsKind,
    /// The quadrotor's parameters (used when `dynamics` is `Quadrotor`).
    pub quadrotor: QuadrotorConfig,
    /// When a contact is a crash.
    pub crash: CrashConfig,
    /// Collision shape.
    pub collision: CollisionConfig,
    /// Battery life in simulated seconds; `None` = no battery part (`Battery 99999`).
    pub battery: Option<f64>,
    /// The colour cameras see it in (`color = [r, g, b]`; default [`ROBOT_COLOR`]).
    pub color: [u8; 3],
    /// Sensor parts, in output order.
    pub parts: Vec<PartConfig>,
    /// Actuators.
    pub actuators: Vec<ActuatorConfig>,
}

impl RobotClass {
    /// The class name without package (`stsAirRobot`), as CONF/GEO/Mount print it.
    pub fn short_name(&self) -> &str {
        self.class.rsplit('.').next().unwrap_or(&self.class)
    }

    /// Seconds after its spawn by which every sensor of the class has read once: each
    /// sensor's timer starts at the spawn (docs/protocol.md), so this is the longest
    /// interval of its parts (0 without parts).
    pub fn first_readings(&self) -> f64 {
        self.parts.iter().map(interval_of).fold(0.0, f64::max)
    }

    /// Sets the rate of the part named `part` (case-insensitive) to `hz` readings per
    /// simulated second (its `interval` becomes `1 / hz`). A rate that is not a positive
    /// number, or a part the class does not have, is an error naming the robot, the sensor
    /// and the value. Whether the physics step can give the rate is [`RobotClass::check_rates`]'s.
    pub fn set_sensor_rate(&mut self, part: &str, hz: f64) -> Result<(), String> {
        let class = &self.class;
        if !(hz.is_finite() && hz > 0.0) {
            return Err(format!(
                "robot {class}: sensor {part}: the rate must be a positive number of Hz, got {}",
                usar_proto::shown::Number(hz)
            ));
        }
        let names: Vec<&str> = self.parts.iter().map(|p| p.name.as_str()).collect();
        let known = names.join(", ");
        let Some(p) = self
            .parts
            .iter_mut()
            .find(|p| p.name.eq_ignore_ascii_case(part))
        else {
            return Err(format!(
                "robot {class}: no sensor named {part:?} (its sensors: {known})"
            ));
        };
        p.interval = Some(1.0 / hz);
        Ok(())
    }

    /// Checks that a physics step of `dt` seconds can give every part's rate: a sensor reads
    /// on physics ticks, at most once a tick, so its interval must be a whole number of ticks
    /// (a rate above the physics rate, or 150 Hz on 200 Hz ticks, would silently become
    /// another rate). The error names the robot, the sensor and the rate.
    pub fn check_rates(&self, dt: f64) -> Result<(), String> {
        let physics = 1.0 / dt;
        for p in &self.parts {
            let interval = interval_of(p);
            let rate = 1.0 / interval;
            let ticks = interval / dt;
            let shown = |x: f64| usar_proto::shown::Number(x).to_string();
            let what = format!(
                "robot {}: sensor {}: rate {} Hz (interval {} s)",
                self.class,
                p.name,
                shown(rate),
                shown(interval)
            );
            if ticks < 1.0 - 1e-6 {
                return Err(format!(
                    "{what} is above the physics rate of {} Hz (a {} s step): raise the physics \
                     rate (at most {MAX_PHYSICS_RATE} Hz) or lower the sensor's",
                    shown(physics),
                    shown(dt)
                ));
            }
            if (ticks - ticks.round()).abs() > 1e-6 * ticks {
                let (slow, fast) = (ticks.floor(), ticks.ceil());
                return Err(format!(
                    "{what} is not a whole number of {} s physics steps: a sensor reads on \
                     physics ticks (nearest rates: {} or {} Hz)",
                    shown(dt),
                    shown(physics / fast),
                    shown(physics / slow)
                ));
            }
        }
        Ok(())
    }
}

impl RobotClass {
    /// Checks the parts that need something of the map: a `GPS` needs the map's origin
    /// (`[geo]` latitude and longitude). The error names the robot, the sensor and the map.
    pub fn check_map(&self, map: &crate::map::Map) -> Result<(), String> {
        if map.geo().and_then(|g| g.origin()).is_some() {
            return Ok(());
        }
        match self
            .parts
            .iter()
            .find(|p| p.kind.eq_ignore_ascii_case("GPS"))
        {
            Some(p) => Err(format!(
                "robot {}: sensor {}: a GPS needs the map's origin (`[geo]` latitude and \
                 longitude, docs/maps.md#geo); map {} has none",
                self.class,
                p.name,
                map.level()
            )),
            None => Ok(()),
        }
    }
}

/// The seconds between readings of a part: its `interval`, else its type's default (0 for
/// an unknown type).
pub fn interval_of(p: &PartConfig) -> f64 {
    p.interval
        .unwrap_or_else(|| sensors::find(&p.kind).map_or(0.0, |k| k.default_interval))
}

/// The fastest physics rate, Hz (a 1 ms step). Sensors read at most once a physics tick, so
/// it is also the fastest sensor rate: a 1 kHz IMU needs `--physics-rate 1000`.
pub const MAX_PHYSICS_RATE: f64 = 1000.0;

/// The physics step, s, of a physics rate in Hz: `1 / hz` for a number in
/// 1..=[`MAX_PHYSICS_RATE`], else an error naming the value.
pub fn physics_step(hz: f64) -> Result<f64, String> {
    if hz.is_finite() && (1.0..=MAX_PHYSICS_RATE).contains(&hz) {
        Ok(1.0 / hz)
    } else {
        Err(format!(
            "the physics rate must be a number of Hz from 1 to {MAX_PHYSICS_RATE}, got {}",
            usar_proto::shown::Number(hz)
        ))
    }
}

/// A `NAME=HZ` sensor rate (`IMU=500`): the part name and the rate, or an error naming the
/// text (a missing `=`, an empty name, a rate that is not a positive number of Hz).
pub fn parse_sensor_rate(text: &str) -> Result<(String, f64), String> {
    let Some((name, hz)) = text.split_once('=') else {
        return Err(format!("{text:?}: expected NAME=HZ, e.g. IMU=500"));
    };
    let name = name.trim();
    if name.is_empty() {
        return Err(format!(
            "{text:?}: the sensor name is empty (expected NAME=HZ)"
        ));
    }
    let rate: f64 = hz.trim().parse().map_err(|_| {
        format!(
            "sensor {name}: the rate {:?} is not a number of Hz",
            hz.trim()
        )
    })?;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(format!(
            "sensor {name}: the rate must be a positive number of Hz, got {}",
            hz.trim()
        ));
    }
    Ok((name.to_string(), rate))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCatalog {
    /// Required, in one section or another ([`sections`]).
    robot: Option<Vec<Spanned<RawRobot>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRobot {
    class: String,
    #[serde(default)]
    flight: FlightConfig,
    #[serde(default)]
    dynamics: DynamicsKind,
    #[serde(default)]
    quadrotor: Option<QuadrotorConfig>,
    #[serde(default)]
    crash: CrashConfig,
    #[serde(default)]
    collision: CollisionConfig,
    #[serde(default)]
    battery: Option<f64>,
    #[serde(default)]
    color: Option<[u8; 3]>,
    #[serde(default)]
    part: Vec<Spanned<PartConfig>>,
    #[serde(default)]
    actuator: Vec<Spanned<ActuatorConfig>>,
}

/// The robot classes INIT can spawn.
#[derive(Debug, Clone)]
pub struct RobotCatalog {
    robots: Vec<RobotClass>,
    /// What is built from a class (a world's robot model), once for every world sharing
    /// this catalog ([`RobotCatalog::built`]).
    models: Models,
}

/// What a catalog has built from its classes, by class index: filled as worlds spawn,
/// emptied when a class changes ([`RobotCatalog::get_mut`]); a copy of the catalog starts
/// empty.
#[derive(Debug, Default)]
struct Models(std::sync::Mutex<Vec<(usize, Built)>>);

/// One thing built from a class, of the type its builder made.
type Built = std::sync::Arc<dyn std::any::Any + Send + Sync>;

impl Clone for Models {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl RobotCatalog {
    /// Reads a catalog file; files past [`MAX_ROBOT_FILE`] bytes are refused unread.
    pub fn from_file(path: &Path) -> Result<Self, ConfigError> {
        let text = read_text(path, MAX_ROBOT_FILE)
            .map_err(|e| e.into_config_error(ConfigFile::Robots, path, None))?;
        Self::parse(&text, path)
    }

    /// A catalog from TOML text (errors name `path`).
    pub fn from_toml(text: &str, path: &Path) -> Result<Self, ConfigError> {
        Self::parse(text, path)
    }

    /// The built-in catalog: `USARBot.stsAirRobot` and `USARBot.AirRobot`.
    pub fn embedded() -> Self {
        Self::parse(EMBEDDED, Path::new("usar-sim/robots.toml")).unwrap_or_else(|e| {
            // Guarded by a unit test; never happens in a released binary.
            tracing::error!(error = %e, "embedded robot catalog is invalid");
            Self {
                robots: Vec::new(),
                models: Models::default(),
            }
        })
    }

    /// All classes.
    pub fn classes(&self) -> &[RobotClass] {
        &self.robots
    }

    /// The class INIT names `class` (`Package.Class`, case-insensitive).
    pub fn get(&self, class: &str) -> Option<&RobotClass> {
        self.index(class).map(|i| &self.robots[i])
    }

    fn index(&self, class: &str) -> Option<usize> {
        self.robots
            .iter()
            .position(|r| r.class.eq_ignore_ascii_case(class))
    }

    /// What `build` makes of the class INIT names `class` (a world's robot model), made at
    /// the first call from any world that shares this catalog and shared after.
    pub(crate) fn built<T: std::any::Any + Send + Sync>(
        &self,
        class: &str,
        build: impl FnOnce(&RobotClass) -> T,
    ) -> Option<std::sync::Arc<T>> {
        let i = self.index(class)?;
        let mut models = self
            .models
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(built) = models
            .iter()
            .find(|(k, _)| *k == i)
            .and_then(|(_, b)| b.clone().downcast::<T>().ok())
        {
            return Some(built);
        }
        let built = std::sync::Arc::new(build(&self.robots[i]));
        models.push((i, built.clone()));
        Some(built)
    }

    /// The class INIT names `class`, or an error naming the classes this catalog has (the
    /// one "unknown robot class" check of the server, `ucc --local` and the Python package).
    pub fn class(&self, class: &str) -> Result<&RobotClass, UnknownClass> {
        self.get(class).ok_or_else(|| UnknownClass {
            class: class.to_owned(),
            known: self.robots.iter().map(|r| r.class.clone()).collect(),
        })
    }

    /// Sets the rate of the part named `part` in every class that has one
    /// ([`RobotClass::set_sensor_rate`]); an error when no class has such a part.
    pub fn set_sensor_rate(&mut self, part: &str, hz: f64) -> Result<(), String> {
        self.models = Models::default();
        let mut found = false;
        for class in &mut self.robots {
            if class
                .parts
                .iter()
                .any(|p| p.name.eq_ignore_ascii_case(part))
            {
                class.set_sensor_rate(part, hz)?;
                found = true;
            }
        }
        if found {
            Ok(())
        } else {
            Err(format!(
                "sensor {part}: no robot class has a sensor of that name"
            ))
        }
    }

    /// [`RobotClass::check_map`] of every class.
    pub fn check_map(&self, map: &crate::map::Map) -> Result<(), String> {
        self.robots.iter().try_for_each(|r| r.check_map(map))
    }

    /// [`RobotClass::check_rates`] of every class.
    pub fn check_rates(&self, dt: f64) -> Result<(), String> {
        self.robots.iter().try_for_each(|r| r.check_rates(dt))
    }

    /// The class, for changing it (tests, programs that tune robots).
    pub fn get_mut(&mut self, class: &str) -> Option<&mut RobotClass> {
        self.models = Models::default();
        self.robots
            .iter_mut()
            .find(|r| r.class.eq_ignore_ascii_case(class))
    }

    fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        let invalid = |offset: usize, message: String| ConfigError::Invalid {
            path: path.to_path_buf(),
            line: line_of(text, offset),
            message,
        };
        let mut robots: Vec<RobotClass> = Vec::new();
        let mut classes = std::collections::HashSet::new();
        let mut any = false;
        // One section (a `[[robot]]` and its tables) at a time: only one section's parse
        // tree is ever held.
        for (offset, section) in sections(text) {
            let raw: RawCatalog = toml::from_str(section).map_err(|e| {
                invalid(
                    offset + e.span().map_or(0, |s| s.start),
                    e.message().trim_end().to_string(),
                )
            })?;
            let Some(entries) = raw.robot else {
                continue;
            };
            any = true;
            for entry in entries {
                let at = offset + entry.span().start;
                let r = entry.into_inner();
                Self::add(&mut robots, &mut classes, r, offset)
                    .map_err(|(o, m)| invalid(o.unwrap_or(at), m))?;
            }
        }
        if !any {
            return Err(invalid(0, "missing field `robot`".into()));
        }
        Ok(Self {
            robots,
            models: Models::default(),
        })
    }

    /// Checks a `[[robot]]` entry of the section at `offset` and adds it; an error names
    /// the offset of the part or actuator at fault (`None`: the entry's).
    fn add(
        robots: &mut Vec<RobotClass>,
        classes: &mut std::collections::HashSet<String>,
        r: RawRobot,
        offset: usize,
    ) -> Result<(), (Option<usize>, String)> {
        check_name("class", &r.class, true).map_err(|m| (None, m))?;
        if !r.class.contains('.') || r.class.ends_with('.') {
            return Err((
                None,
                format!(
                    "class `{}` needs a package, e.g. `USARBot.{}`",
                    r.class, r.class
                ),
            ));
        }
        if !classes.insert(r.class.to_ascii_lowercase()) {
            return Err((None, format!("duplicate class `{}`", r.class)));
        }
        check_flight(&r).map_err(|m| (None, m))?;
        let mut parts: Vec<PartConfig> = Vec::with_capacity(r.part.len());
        let mut names = std::collections::HashSet::new();
        for part in r.part {
            let at = offset + part.span().start;
            let part = part.into_inner();
            check_part(&r.class, &part, &mut names).map_err(|m| (Some(at), m))?;
            parts.push(part);
        }
        let mut actuators: Vec<ActuatorConfig> = Vec::with_capacity(r.actuator.len());
        for actuator in r.actuator {
            let at = offset + actuator.span().start;
            let a = actuator.into_inner();
            check_actuator(&a).map_err(|m| (Some(at), m))?;
            actuators.push(a);
        }
        robots.push(RobotClass {
            class: r.class,
            flight: r.flight,
            dynamics: r.dynamics,
            quadrotor: r.quadrotor.unwrap_or_default(),
            crash: r.crash,
            collision: r.collision,
            battery: r.battery,
            color: r.color.unwrap_or(ROBOT_COLOR),
            parts,
            actuators,
        });
        Ok(())
    }
}

fn positive(what: &str, v: f64) -> Result<(), String> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(format!(
            "{what} must be a positive number, got {}",
            usar_proto::shown::Number(v)
        ))
    }
}

fn all_finite(what: &str, v: &[f64]) -> Result<(), String> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(format!("{what} must be finite"))
    }
}

/// The largest speed (m/s), rate (deg/s), angle (deg) and size (m) a robot file may give.
const MAX_SPEED: f64 = 1000.0;
const MAX_RATE: f64 = 36_000.0;
const MAX_ANGLE: f64 = 180.0;
const MAX_SIZE: f64 = 100.0;

fn at_most(what: &str, v: f64, max: f64) -> Result<(), String> {
    positive(what, v)?;
    if v > max {
        return Err(format!(
            "{what} must be at most {max}, got {}",
            usar_proto::shown::Number(v)
        ));
    }
    Ok(())
}

fn check_flight(r: &RawRobot) -> Result<(), String> {
    let f = &r.flight;
    for (what, v, max) in [
        ("flight.max_linear_speed", f.max_linear_speed, MAX_SPEED),
        ("flight.max_lateral_speed", f.max_lateral_speed, MAX_SPEED),
        ("flight.max_altitude_speed", f.max_altitude_speed, MAX_SPEED),
        ("flight.speed_limit", f.speed_limit, MAX_SPEED),
        ("flight.max_rotation_speed", f.max_rotation_speed, MAX_RATE),
        ("flight.rotation_limit", f.rotation_limit, MAX_RATE),
        ("flight.tilt_limit", f.tilt_limit, MAX_ANGLE),
        ("flight.tilt_rate", f.tilt_rate, MAX_RATE),
        ("collision.radius", r.collision.radius, MAX_SIZE),
        ("collision.height", r.collision.height, MAX_SIZE),
    ] {
        at_most(what, v, max)?;
    }
    all_finite(
        "flight.max_tilt and flight.tilt_margin",
        &[f.max_tilt, f.tilt_margin],
    )?;
    if f.max_tilt.abs() > MAX_ANGLE || f.tilt_margin.abs() > MAX_ANGLE {
        return Err(format!(
            "flight.max_tilt and flight.tilt_margin must be within ±{MAX_ANGLE}"
        ));
    }
    if let Some(b) = r.battery {
        at_most("battery", b, 1e9)?;
    }
    positive("crash.speed", r.crash.speed)?;
    positive("crash.tilt", r.crash.tilt)?;
    match (&r.quadrotor, r.dynamics) {
        (Some(_), DynamicsKind::Kinematic) => {
            return Err(
                "[robot.quadrotor] needs `dynamics = \"quadrotor\"` (the robot is kinematic)"
                    .into(),
            );
        }
        (Some(q), DynamicsKind::Quadrotor) => q.check()?,
        (None, _) => {}
    }
    Ok(())
}

/// Checks a part; `names` holds the robot's part names so far (lower case).
fn check_part(
    class: &str,
    part: &PartConfig,
    names: &mut std::collections::HashSet<String>,
) -> Result<(), String> {
    check_name("part name", &part.name, true)?;
    let kind = sensors::find(&part.kind).ok_or_else(|| {
        let known: Vec<&str> = sensors::REGISTRY.iter().map(|k| k.item_type).collect();
        format!(
            "unknown part type `{}` (known: {})",
            part.kind,
            known.join(", ")
        )
    })?;
    if !names.insert(part.name.to_ascii_lowercase()) {
        return Err(format!("duplicate part name `{}`", part.name));
    }
    all_finite(
        "position and direction",
        &[part.position, part.direction].concat(),
    )?;
    if [part.position, part.direction]
        .concat()
        .iter()
        .any(|x| x.abs() > MAX_SIZE)
    {
        return Err(format!("position and direction must be within ±{MAX_SIZE}"));
    }
    if let Some(interval) = part.interval {
        at_most("interval", interval, 1e6)
            .map_err(|m| format!("robot {class}: sensor {}: {m}", part.name))?;
    }
    if !(part.noise.is_finite() && (0.0..=100.0).contains(&part.noise)) {
        return Err(format!(
            "noise must be >= 0, got {}",
            usar_proto::shown::Number(part.noise)
        ));
    }
    (kind.build)(part).map(drop)
}

fn check_actuator(a: &ActuatorConfig) -> Result<(), String> {
    check_name("actuator name", &a.name, true)?;
    at_most("interval", a.interval, 1e6)?;
    all_finite(
        "position and direction",
        &[a.position, a.direction].concat(),
    )?;
    if [a.position, a.direction]
        .concat()
        .iter()
        .any(|x| x.abs() > MAX_SIZE)
    {
        return Err(format!("position and direction must be within ±{MAX_SIZE}"));
    }
    if a.joints.is_empty() {
        return Err(format!("actuator `{}` needs at least one joint", a.name));
    }
    for j in &a.joints {
        check_name("joint type", &j.joint_type, true)?;
        all_finite("joint limits", &[j.min, j.max, j.max_torque])?;
        if [j.min, j.max, j.max_torque].iter().any(|x| x.abs() > 1e6) {
            return Err(format!(
                "actuator `{}`: joint numbers must be within ±1e6",
                a.name
            ));
        }
        if j.min > j.max {
            return Err(format!("actuator `{}`: joint min > max", a.name));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unknown_class_names_the_known_ones() {
        let catalog = RobotCatalog::embedded();
        assert!(catalog.class("usarbot.STSAIRROBOT").is_ok());
        let e = catalog.class("USARBot.Nope").unwrap_err().to_string();
        assert!(
            e.starts_with("unknown robot class \"USARBot.Nope\" (known: "),
            "{e}"
        );
        assert!(e.contains("USARBot.stsAirRobot"), "{e}");
    }

    #[test]
    fn embedded_catalog() {
        let catalog = RobotCatalog::embedded();
        let sts = catalog.get("usarbot.STSAIRROBOT").expect("stsAirRobot");
        assert_eq!(sts.short_name(), "stsAirRobot");
        assert_eq!(sts.battery, Some(1200.0));
        let names: Vec<&str> = sts.parts.iter().map(|p| p.name.as_str()).collect();
        for n in [
            "Position",
            "Velocity",
            "IMU",
            "Sonar0",
            "Sonar7",
            "SonarTop",
            "SonarBottom",
            "Scanner",
        ] {
            assert!(names.contains(&n), "{n} missing");
        }
        let quad = catalog.get("USARBot.stsQuadrotor").expect("stsQuadrotor");
        assert_eq!(quad.dynamics, DynamicsKind::Quadrotor);
        assert_eq!(
            quad.parts.len(),
            sts.parts.len() + 1,
            "the sts parts plus Crash"
        );
        assert_eq!(sts.dynamics, DynamicsKind::Kinematic);
        let air = catalog.get("USARBot.AirRobot").expect("AirRobot");
        assert_eq!(air.battery, None);
        assert_eq!(air.actuators[0].name, "cam");
        assert!(catalog.get("AirRobot").is_none(), "the package is required");
    }

    fn parse(text: &str) -> String {
        RobotCatalog::parse(text, Path::new("r.toml"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn errors_name_file_line_and_problem() {
        let e = parse(
            "[[robot]]\nclass = \"USARBot.X\"\n[[robot.part]]\ntype = \"Laser\"\nname = \"L\"\n",
        );
        assert!(
            e.starts_with("r.toml:3:") && e.contains("unknown part type `Laser`"),
            "{e}"
        );
        let e = parse(
            "[[robot]]\nclass = \"USARBot.X\"\n\n[[robot.part]]\ntype = \"Sonar\"\nname = \"S\"\nmax_range = -1.0\n",
        );
        assert!(e.starts_with("r.toml:4:") && e.contains("min_range"), "{e}");
        let e = parse("[[robot]]\nclass = \"USARBot.X\"\n[robot.collision]\nradius = \"big\"\n");
        assert!(e.starts_with("r.toml:4:"), "{e}");
        let e = parse("[[robot]]\nclass = \"X\"\n");
        assert!(e.contains("package"), "{e}");
        let e = parse("[[robot]]\nclass = \"USARBot.X\"\nbattery = -3.0\n");
        assert!(e.starts_with("r.toml:1:") && e.contains("battery"), "{e}");
        let e = parse("[[robot]]\nclass = \"USARBot.X\"\n[robot.quadrotor]\nmass = 2.0\n");
        assert!(e.contains("needs `dynamics = \"quadrotor\"`"), "{e}");
        let e = parse(
            "[[robot]]\nclass = \"USARBot.X\"\ndynamics = \"quadrotor\"\n\
             [robot.quadrotor]\nmass = 20.0\n",
        );
        assert!(
            e.starts_with("r.toml:1:") && e.contains("cannot hover"),
            "{e}"
        );
        let e = parse("[[robot]]\nclass = \"USARBot.X\"\ndynamics = \"helicopter\"\n");
        assert!(
            e.starts_with("r.toml:3:") && e.contains("helicopter"),
            "{e}"
        );
        let e = parse(
            "[[robot]]\nclass = \"USARBot.X\"\ndynamics = \"quadrotor\"\n\
             [robot.quadrotor]\nconfiguration = \"y\"\n",
        );
        assert!(e.contains("configuration") || e.contains("`y`"), "{e}");
        let e = parse("[[robot]]\nclass = \"USARBot.X\"\n[robot.crash]\nspeed = 0.0\n");
        assert!(e.contains("crash.speed"), "{e}");
    }
}
