//! A spawned robot: AerialVehicle flight, parts with their timers, battery, actuators.

use std::sync::Arc;

use rapier3d::prelude::ColliderHandle;
use tracing::{debug, warn};
use usar_proto::{
    ActuatorJoint, Asta, ConfItem, Drive, GeoItem, LinkValue, Sen, ServerMessage, Sta, StaLayout,
    Time,
};

use super::ClientId;
use super::dynamics::{self, Crash, Dynamics, Fault, Flight, LowLevel, M3, SensorFault, SetPoints};
use super::noise::Noise;
use super::quadrotor::{self, Quadrotor};
use super::render::{ROBOT_SEGMENT, View};
use super::robots::{ActuatorConfig, DynamicsKind, FlightConfig, RobotClass};
use super::scene::{
    BodyShape, Glide, Look, Scene, V3, add, direction, rotate_by, scale, yaw_rotate,
};
use super::sensors::camera::Camera;
use super::sensors::{self, Reading, Sensor};
use super::wind::WindConfig;

/// Angles past a thousand turns are reduced to one turn, [0, 2π): the same direction,
/// printed as a sensible number (smaller angles are kept as given, as USARSim does).
pub(crate) fn bounded_angle(a: f64) -> f64 {
    const MAX_ANGLE: f64 = 1000.0 * std::f64::consts::TAU;
    if a.abs() > MAX_ANGLE {
        a.rem_euclid(std::f64::consts::TAU)
    } else {
        a
    }
}

/// STA period, s (`StatusTimer`).
const STATUS_INTERVAL: f64 = 0.1;
/// `Battery` without a battery part.
const NO_BATTERY: i64 = 99_999;

/// Ticks in `seconds` (at least one).
fn ticks(seconds: f64, dt: f64) -> u64 {
    ((seconds / dt).round() as u64).max(1)
}

/// A DRIVE number within `±limit`; NaN is 0 (logged at debug level: a client could send
/// it on every line).
fn limited(value: f64, limit: f64, key: &str) -> f64 {
    if value.is_nan() {
        debug!(key, "NaN DRIVE value treated as 0");
        return 0.0;
    }
    value.clamp(-limit, limit)
}

/// A robot's phase: where in each interval its timers fire, as a fraction of 2⁶⁴. The
/// robot spawned while `n` others are in the world gets the fractional part of n × 0.618…
/// (Fibonacci hashing): a lone robot gets 0 (so a client that flies, leaves and spawns
/// again sees the same ticks every time), and any number of robots spawned on one tick
/// spread evenly over every interval, so their sensors do not all read on the same tick.
fn phase(others: u64) -> u64 {
    others.wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// A periodic output: interval and next due tick.
#[derive(Debug, Clone, Copy)]
struct Timer {
    every: u64,
    due: u64,
}

impl Timer {
    /// Started at `spawn`, as UDK's timers: first due one `interval` after it, earlier by
    /// the robot's `phase` of an interval (never later), then every `interval`.
    fn new(interval: f64, spawn: u64, dt: f64, phase: u64) -> Self {
        let every = ticks(interval, dt);
        let early = ((u128::from(phase) * u128::from(every)) >> 64) as u64;
        Self {
            every,
            due: spawn + every - early,
        }
    }

    /// Whether it fires at `tick` (without scheduling the next time).
    fn is_due(&self, tick: u64) -> bool {
        tick >= self.due
    }

    /// Whether it fires at `tick` (and if so, schedules the next time).
    fn fire(&mut self, tick: u64) -> bool {
        if !self.is_due(tick) {
            return false;
        }
        self.due += self.every * ((tick - self.due) / self.every + 1);
        true
    }
}

/// What every robot of one class shares, built once (when the class first spawns): the
/// class, its body and each part's mount and a prototype of its sensor. Robots keep only
/// their own state (timers, noise streams, sensor copies); a class's tables, such as a
/// laser's beam directions, are shared.
#[derive(Debug)]
pub(crate) struct Model {
    class: RobotClass,
    shape: BodyShape,
    parts: Vec<PartModel>,
}

/// A part as its class defines it.
#[derive(Debug)]
struct PartModel {
    name: String,
    item_type: &'static str,
    position: V3,
    direction: V3,
    interval: f64,
    /// Its index among the class's parts (its noise stream).
    index: u64,
    noise: f64,
    sensor: Box<dyn Sensor>,
}

impl Model {
    /// The class's catalog name (`USARBot.stsAirRobot`).
    pub(crate) fn class_name(&self) -> &str {
        &self.class.class
    }

    /// The class it was built from.
    pub(crate) fn class(&self) -> &RobotClass {
        &self.class
    }

    /// Builds the parts of `class`; a part of an unknown type or with invalid settings is
    /// skipped with a warning.
    pub(crate) fn new(class: &RobotClass) -> Self {
        let mut parts = Vec::new();
        for (index, p) in class.parts.iter().enumerate() {
            let Some(kind) = sensors::find(&p.kind) else {
                warn!(class = %class.class, part = %p.name, kind = %p.kind,
                    "unknown part type, part skipped");
                continue;
            };
            let sensor = match (kind.build)(p) {
                Ok(sensor) => sensor,
                Err(e) => {
                    warn!(class = %class.class, part = %p.name, error = %e,
                        "invalid part, part skipped");
                    continue;
                }
            };
            parts.push(PartModel {
                name: p.name.clone(),
                item_type: kind.item_type,
                position: p.position,
                direction: p.direction,
                interval: p.interval.unwrap_or(kind.default_interval),
                index: index as u64,
                noise: p.noise,
                sensor,
            });
        }
        Self {
            shape: BodyShape {
                radius: class.collision.radius,
                half_height: class.collision.height / 2.0,
            },
            class: class.clone(),
            parts,
        }
    }
}

/// A robot's own state of one part (the same index as in its [`Model`]).
#[derive(Debug)]
struct Part {
    timer: Timer,
    /// SET asked for an extra reading on the next tick.
    forced: bool,
    noise: Noise,
    sensor: Box<dyn Sensor>,
    /// A `FAULT {Sensor ..}` in force, and the reading a frozen part repeats.
    fault: SensorFault,
    frozen: Option<usar_proto::SenData>,
    /// When the fault began (drift) and ends (`None`: at the next `FAULT` for the part).
    fault_since: f64,
    fault_until: Option<f64>,
    /// The noise a `{Mode Noise}` fault adds (its own stream: the part's is untouched).
    fault_noise: Noise,
}

impl Part {
    /// The part as a new robot's (its sensor aside): timers and noise streams from the spawn,
    /// no fault.
    fn renew(&mut self, timer: Timer, noise: Noise, fault_noise: Noise) {
        self.timer = timer;
        self.forced = false;
        self.noise = noise;
        self.fault = SensorFault::Ok;
        self.frozen = None;
        self.fault_since = 0.0;
        self.fault_until = None;
        self.fault_noise = fault_noise;
    }
}

/// Stream numbers of the fault noise generators (above any part index).
const FAULT_STREAM: u64 = 1 << 32;

/// Adds `offset()` to every measured number of a reading (the numbers the sensor measures;
/// names, counts and flags stay).
fn perturb(data: &mut usar_proto::SenData, mut offset: impl FnMut() -> f64) {
    use usar_proto::SenData as D;
    let mut v3 = |v: &mut usar_proto::Vec3| {
        v.x += offset();
        v.y += offset();
        v.z += offset();
    };
    match data {
        D::Imu {
            acceleration,
            angular_vel,
            angular_accel,
            rotation,
            ..
        } => {
            for v in [acceleration, angular_vel, angular_accel, rotation] {
                v3(v);
            }
        }
        D::GroundTruth {
            location,
            orientation,
            ..
        }
        | D::Ins {
            location,
            orientation,
            ..
        } => {
            v3(location);
            v3(orientation);
        }
        D::Velocity {
            absolute, relative, ..
        } => {
            v3(absolute);
            v3(relative);
        }
        D::Position { location: v, .. }
        | D::Magnetometer { field: v, .. }
        | D::Odometry { pose: v, .. }
        | D::Accel {
            acceleration: v, ..
        }
        | D::AcceleroMeter {
            proper_acceleration: v,
            ..
        } => v3(v),
        D::Sonar { readings, .. } => {
            for r in readings {
                r.range += offset();
            }
        }
        D::Ir(r) => r.range += offset(),
        D::RangeScanner(scan) => {
            for r in &mut scan.ranges {
                *r += offset();
            }
        }
        D::AltitudeSensor {
            relative, absolute, ..
        } => {
            let d = offset();
            *relative += d;
            *absolute += d;
        }
        D::MagneticCompass { angle, .. } => *angle += offset(),
        D::Other { groups, .. } => {
            // Our own lines (Battery, Rotors, Barometer): every number of every value.
            for pair in groups.iter_mut().flat_map(|g| g.pairs.iter_mut()) {
                let numbers: Option<Vec<f64>> = pair
                    .value
                    .split(',')
                    .map(|x| x.trim().parse().ok())
                    .collect();
                if let Some(numbers) = numbers.filter(|n| n.iter().all(|x: &f64| x.is_finite())) {
                    let decimals = pair
                        .value
                        .split(',')
                        .next()
                        .and_then(|x| x.split_once('.'))
                        .map_or(0, |(_, d)| d.trim().len());
                    let text: Vec<String> = numbers
                        .iter()
                        .map(|x| format!("{:.*}", decimals.max(4), x + offset()))
                        .collect();
                    pair.value = text.join(",");
                }
            }
        }
        _ => {}
    }
}

/// An actuator: joint values move to their targets at once.
#[derive(Debug)]
struct Actuator {
    config: ActuatorConfig,
    values: Vec<f64>,
    timer: Timer,
}

/// Where and how a robot spawns.
pub(crate) struct Spawn<'a> {
    pub(crate) model: &'a Arc<Model>,
    pub(crate) serial: u64,
    /// Robots in the world when it spawns (its timers' phase).
    pub(crate) others: u64,
    pub(crate) owner: ClientId,
    /// Its name (INIT `{Name ..}`, else `<Class>_<serial>`).
    pub(crate) name: String,
    pub(crate) position: V3,
    pub(crate) rotation: V3,
    pub(crate) tick: u64,
    pub(crate) dt: f64,
    pub(crate) seed: u64,
    /// The wind robots with physics feel.
    pub(crate) wind: WindConfig,
    /// Parameter ranges to draw from (`--randomize`).
    pub(crate) randomize: Option<&'a super::randomize::Randomization>,
}

/// A crashed kinematic robot falls at this speed, m/s.
const KINEMATIC_FALL_SPEED: f64 = 2.0;

/// A robot in the world.
#[derive(Debug)]
pub(crate) struct Robot {
    pub(crate) serial: u64,
    /// The connection that receives its output (`None` after a rebinding INIT).
    pub(crate) owner: Option<ClientId>,
    /// The connection that spawned it (removes it on disconnect).
    pub(crate) spawned_by: ClientId,
    /// Its name (USARTruth, the robot monitor, the WSS).
    pub(crate) name: String,
    model: Arc<Model>,
    /// Its body's collider in the scene.
    pub(crate) body: ColliderHandle,
    position: V3,
    velocity: V3,
    /// roll, pitch, yaw, rad.
    rotation: V3,
    /// The kinematic flight's yaw with its sine and cosine ([`YawTrig`]).
    yaw_trig: YawTrig,
    set: SetPoints,
    /// The physics model; `None` for the kinematic AerialVehicle flight.
    dynamics: Option<Box<dyn Dynamics>>,
    /// Set once the robot crashed (it then falls, stops and ignores commands).
    crashed: Option<Crash>,
    /// Whether the body touched something in the last tick.
    contact: bool,
    /// Whether it touched something or was crashed in any tick since
    /// [`Robot::take_touched`] was last called.
    touched: bool,
    spawn_tick: u64,
    /// The tick the battery timer was last full (spawn, or [`Robot::recharge`]).
    charged_tick: u64,
    spawn_z: f64,
    status: Timer,
    parts: Vec<Part>,
    actuators: Vec<Actuator>,
    /// Until when its radio is off (`FAULT {Radio Off}`; infinite without a duration).
    radio_off_until: Option<f64>,
    /// Lines for its connection at the next output (faults the server applied on its own).
    notices: Vec<ServerMessage>,
    /// The parameters drawn for it (`--randomize`).
    drawn: super::randomize::Drawn,
}

/// A yaw with its sine and cosine, kept from tick to tick by the kinematic flight: while
/// the yaw holds they are not computed again, and while it turns at a steady rate the next
/// ones come from the angle-sum formulas with the turn's own sine and cosine (computed once
/// per yaw rate) — exactly again (`sin_cos`) every [`YawTrig::EXACT_EVERY`] ticks, so the
/// rounding of the sums (an ulp or so per tick) never adds up. `sin_cos` was the largest
/// single cost of a robot flying with a yaw rate (issue 24).
#[derive(Debug, Clone, Copy)]
struct YawTrig {
    yaw: f64,
    sin: f64,
    cos: f64,
    /// The last turn per tick (rad) and its sine and cosine.
    turn: (f64, f64, f64),
    /// Ticks the sums may still be used before the next exact value.
    sums_left: u8,
}

impl Default for YawTrig {
    fn default() -> Self {
        Self {
            yaw: f64::NAN,
            sin: f64::NAN,
            cos: f64::NAN,
            turn: (f64::NAN, f64::NAN, f64::NAN),
            sums_left: 0,
        }
    }
}

impl YawTrig {
    const EXACT_EVERY: u8 = 64;

    /// The sine and cosine of `yaw`: kept ones if they are of this yaw, else exact ones.
    #[inline(always)]
    fn at(&mut self, yaw: f64) -> (f64, f64) {
        if self.yaw.to_bits() != yaw.to_bits() {
            self.exact(yaw);
        }
        (self.sin, self.cos)
    }

    /// The exact sine and cosine of `yaw`, kept. Out of line (as [`YawTrig::new_turn`]): the
    /// compiler may otherwise compute them ahead, whether needed or not.
    #[cold]
    #[inline(never)]
    fn exact(&mut self, yaw: f64) {
        (self.sin, self.cos) = yaw.sin_cos();
        self.yaw = yaw;
        self.sums_left = Self::EXACT_EVERY;
    }

    /// A new turn per tick and its sine and cosine, kept. Out of line: inlined, the compiler
    /// hoisted the `sin_cos` out of a glide's loop (a pure call on a loop-invariant turn)
    /// and made it at every call of [`Robot::glide_ticks`], needed or not.
    #[cold]
    #[inline(never)]
    fn new_turn(&mut self, turn: f64) {
        let (sin, cos) = turn.sin_cos();
        self.turn = (turn, sin, cos);
    }

    /// The yaw turned by `turn` to `next`: keeps `next`'s sine and cosine by the sums —
    /// unless `next` is not the kept yaw plus `turn` (wrapped by `bounded_angle`, or set
    /// otherwise), or nothing turned: then the next [`YawTrig::at`] computes them.
    fn turn(&mut self, next: f64, turn: f64) {
        if next.to_bits() == self.yaw.to_bits()
            || next.to_bits() != (self.yaw + turn).to_bits()
            || self.sums_left == 0
        {
            return;
        }
        if self.turn.0.to_bits() != turn.to_bits() {
            self.new_turn(turn);
        }
        let (_, st, ct) = self.turn;
        (self.sin, self.cos) = (self.sin * ct + self.cos * st, self.cos * ct - self.sin * st);
        self.yaw = next;
        self.sums_left -= 1;
    }
}

impl Robot {
    /// [`crate::World::prefetch`]'s part for the robot: its fields and its parts' timers,
    /// noise and faults.
    pub(crate) fn prefetch(&self) {
        use crate::prefetch::line;
        line(&self.position);
        line(&self.set);
        line(&self.yaw_trig);
        line(&self.status);
        line(&self.parts);
        line(&self.notices);
        line(&self.crashed);
        line(&self.drawn);
        line(&self.spawn_tick);
        for part in self.parts.iter().take(16) {
            line(&part.timer);
            line(&part.noise);
            line(&part.fault);
        }
    }

    /// [`crate::World::prefetch_reset`]'s part: what a spawn reusing this robot writes (what
    /// a step reads, [`Robot::prefetch`], and the rest of its fields, parts and sensors).
    pub(crate) fn prefetch_reset(&self) {
        use crate::prefetch::line;
        self.prefetch();
        line(&self.name);
        line(&self.model);
        line(&self.rotation);
        line(&self.dynamics);
        line(&self.actuators);
        for part in self.parts.iter().take(16) {
            line(&part.frozen);
            line(&part.fault_noise);
            part.sensor.prefetch();
        }
    }

    /// Spawns into `scene`; `None` (logged) when the place is taken. A `spare` robot of the
    /// same model (one a reset took out of the world) lends its sensors' allocations and its
    /// model's reference: the new robot is the same as one built afresh.
    pub(crate) fn spawn(spawn: Spawn<'_>, scene: &mut Scene, spare: Option<Self>) -> Option<Self> {
        let model = spawn.model;
        let class = &model.class;
        let shape = model.shape;
        if scene.overlaps(shape, spawn.position, None) {
            return None;
        }
        let phase = phase(spawn.others);
        let drawn = spawn
            .randomize
            .map(|r| r.draw(spawn.seed, spawn.serial))
            .unwrap_or_default();
        let noise_scale = drawn.get("noise");
        // A spare robot's parts are renewed in place: their memory is already the world's.
        let (model, mut parts) = match spare {
            Some(r) if Arc::ptr_eq(&r.model, model) => (r.model, r.parts),
            _ => (model.clone(), Vec::with_capacity(model.parts.len())),
        };
        parts.truncate(model.parts.len());
        for (i, p) in model.parts.iter().enumerate() {
            let timer = Timer::new(p.interval, spawn.tick, spawn.dt, phase);
            let noise = Noise::new(spawn.seed, spawn.serial, p.index, p.noise);
            let fault_noise = Noise::new(spawn.seed, spawn.serial, FAULT_STREAM + p.index, 0.0);
            if let Some(part) = parts.get_mut(i) {
                p.sensor.clone_into_box(&mut part.sensor);
                part.renew(timer, noise, fault_noise);
            } else {
                parts.push(Part {
                    timer,
                    forced: false,
                    noise,
                    sensor: p.sensor.clone_box(),
                    fault: SensorFault::Ok,
                    frozen: None,
                    fault_since: 0.0,
                    fault_until: None,
                    fault_noise,
                });
            }
            if let Some(k) = noise_scale {
                let part = &mut parts[i];
                part.noise.scale(k);
                part.sensor.scale_noise(k);
            }
        }
        let actuators = class
            .actuators
            .iter()
            .map(|a| Actuator {
                values: a
                    .joints
                    .iter()
                    .map(|j| 0.0f64.clamp(j.min, j.max))
                    .collect(),
                timer: Timer::new(a.interval, spawn.tick, spawn.dt, phase),
                config: a.clone(),
            })
            .collect();
        let body = scene.insert_body(shape, spawn.position);
        scene.set_look(
            body,
            Look {
                color: class.color,
                segment: ROBOT_SEGMENT + (spawn.serial % u64::from(ROBOT_SEGMENT)) as u32,
            },
        );
        let dynamics: Option<Box<dyn Dynamics>> = match class.dynamics {
            DynamicsKind::Kinematic => None,
            DynamicsKind::Quadrotor => Some(Box::new(Quadrotor::new(
                {
                    let mut q = class.quadrotor.clone();
                    drawn.apply(&mut q);
                    q
                },
                quadrotor::Limits {
                    max_tilt: class.flight.max_tilt.abs().to_radians().clamp(0.01, 1.4),
                    max_climb: class.flight.max_altitude_speed,
                    crash_speed: class.crash.speed,
                    crash_tilt: class.crash.tilt.to_radians(),
                    battery: class.battery.is_some(),
                },
                spawn.rotation,
                drawn.wind(spawn.wind),
                spawn.seed,
                spawn.serial,
                spawn.dt,
            ))),
        };
        Some(Self {
            serial: spawn.serial,
            owner: Some(spawn.owner),
            spawned_by: spawn.owner,
            name: spawn.name,
            model,
            body,
            position: spawn.position,
            velocity: [0.0; 3],
            rotation: spawn.rotation,
            yaw_trig: YawTrig::default(),
            set: SetPoints::default(),
            dynamics,
            crashed: None,
            contact: false,
            touched: false,
            spawn_tick: spawn.tick,
            charged_tick: spawn.tick,
            spawn_z: spawn.position[2],
            status: Timer::new(STATUS_INTERVAL, spawn.tick, spawn.dt, phase),
            parts,
            actuators,
            radio_off_until: None,
            notices: Vec::new(),
            drawn,
        })
        .map(|mut robot| {
            if !robot.drawn.0.is_empty() {
                let time = spawn.tick as f64 * spawn.dt;
                tracing::info!(
                    serial = robot.serial,
                    time,
                    "randomized: {:?}",
                    robot.drawn.0
                );
                robot.notice("RANDOMIZED", time, robot.drawn.groups());
            }
            robot
        })
    }

    /// Queues `KIND {Time t} {Robot n} <groups>` for its connection (a notice of ours).
    fn notice(&mut self, kind: &str, time: f64, rest: Vec<usar_proto::Group>) {
        let group = |key: &str, value: String| usar_proto::Group {
            pairs: vec![usar_proto::Pair {
                key: key.to_string(),
                value,
            }],
        };
        let mut stamp = String::new();
        usar_proto::format::push_fixed(&mut stamp, time, 4);
        let mut groups = vec![
            group("Time", stamp),
            group("Robot", (self.serial + 1).to_string()),
        ];
        groups.extend(rest);
        self.notices.push(ServerMessage::Other(usar_proto::Message {
            kind: kind.to_string(),
            groups,
            verbatim: None,
        }));
    }

    /// The parameters drawn for it (`--randomize`; empty without).
    pub(crate) fn drawn(&self) -> &super::randomize::Drawn {
        &self.drawn
    }

    /// Removes its body from the scene.
    pub(crate) fn despawn(self, scene: &mut Scene) {
        scene.remove(self.body);
    }

    /// The class name without package.
    pub(crate) fn class_name(&self) -> &str {
        self.model.class.short_name()
    }

    /// Remaining battery seconds as STA reports them (rounded up, so 0 means empty).
    fn battery_left(&self, tick: u64, dt: f64) -> i64 {
        match self.seconds_left(tick, dt) {
            None => NO_BATTERY,
            Some((left, most)) => left.ceil().clamp(0.0, most) as i64,
        }
    }

    /// Battery seconds left, unrounded, and the most STA reports of them (`None`: no
    /// battery): with the energy model, those above the reserve at the average draw (up to
    /// [`NO_BATTERY`]); else the class's capacity less the time since the last charge.
    fn seconds_left(&self, tick: u64, dt: f64) -> Option<(f64, f64)> {
        if let Some(gauge) = self.dynamics.as_ref().and_then(|d| d.gauge()) {
            return Some((gauge.time_left, NO_BATTERY as f64));
        }
        let used = tick.saturating_sub(self.charged_tick) as f64 * dt;
        self.model
            .class
            .battery
            .map(|capacity| (capacity - used, f64::INFINITY))
    }

    /// Fills the battery (a charging pad): USARSim's timer restarts at `tick`, the energy
    /// model's battery is full again.
    pub(crate) fn recharge(&mut self, tick: u64) {
        self.charged_tick = tick;
        if let Some(dynamics) = &mut self.dynamics {
            dynamics.recharge();
        }
    }

    /// Sets the mass carried besides the body (kg); `false` for a robot without physics
    /// (the kinematic flight has no mass).
    pub(crate) fn set_payload(&mut self, kg: f64) -> bool {
        self.dynamics.as_mut().is_some_and(|d| d.set_payload(kg))
    }

    /// Whether the battery is empty (commands ignored, sensors silent, robot stopped).
    pub(crate) fn is_dead(&self, tick: u64, dt: f64) -> bool {
        // What `battery_left(..) == 0` says, without its rounding (every tick, every robot):
        // no seconds left above 0 (NaN: none).
        self.seconds_left(tick, dt)
            .is_some_and(|(left, _)| left.is_nan() || left <= 0.0)
    }

    /// Applies a DRIVE (§2.3). Every value is held to the robot's limits (normalized values
    /// to ±100 %, absolute ones to `speed_limit`, `rotation_limit` and `tilt_limit`), so no
    /// number a client sends can make the state non-finite.
    pub(crate) fn drive(&mut self, d: &Drive) {
        if self.crashed.is_some() {
            return;
        }
        self.drive_set_points(d);
        if let Some(dynamics) = &mut self.dynamics {
            dynamics.drive(&self.set);
        }
    }

    /// Applies a `QUAD` command (docs/quadrotor.md); kinematic robots ignore it.
    pub(crate) fn low_level(&mut self, command: LowLevel) {
        match &mut self.dynamics {
            Some(dynamics) if self.crashed.is_none() => dynamics.low_level(command),
            Some(_) => {}
            None => warn!(
                class = %self.class_name(),
                "QUAD ignored: the robot is kinematic (dynamics = \"quadrotor\" in its class)"
            ),
        }
    }

    /// Applies a `FAULT` (docs/quadrotor.md#faults), logged at `info` with the time.
    pub(crate) fn fault(&mut self, fault: &Fault, time: f64) {
        let applied = match fault {
            Fault::Sensor {
                name,
                mode,
                duration,
            } => {
                let mut found = false;
                for (part, model) in self.parts.iter_mut().zip(&self.model.parts) {
                    if model.name.eq_ignore_ascii_case(name) {
                        part.fault = *mode;
                        part.frozen = None;
                        part.fault_since = time;
                        part.fault_until = duration.map(|d| time + d);
                        found = true;
                    }
                }
                found
            }
            Fault::Radio { on, duration } => {
                self.radio_off_until = (!on).then(|| duration.map_or(f64::INFINITY, |d| time + d));
                true
            }
            _ => self.dynamics.as_mut().is_some_and(|d| d.fault(fault)),
        };
        if applied {
            tracing::info!(serial = self.serial, class = %self.class_name(), time, "fault: {fault:?}");
        } else {
            warn!(serial = self.serial, class = %self.class_name(), "FAULT ignored: the robot has no such part: {fault:?}");
        }
    }

    /// Applies a fault the server scheduled (`--faults`) and tells the robot's connection
    /// with `FAULT {Time t} {Robot n} <the fault's groups>` (docs/quadrotor.md#faults).
    pub(crate) fn scheduled_fault(&mut self, fault: &Fault, line: &usar_proto::Message, time: f64) {
        self.fault(fault, time);
        self.notice("FAULT", time, line.groups.clone());
    }

    /// Whether its radio is off at `time` (the robot monitor and the WSS).
    pub(crate) fn radio_off(&self, time: f64) -> bool {
        self.radio_off_until
            .is_some_and(|until| time < until - 1e-9)
    }

    /// Whether the robot has crashed.
    pub(crate) fn crashed(&self) -> bool {
        self.crashed.is_some()
    }

    /// The DRIVE set-points (sticky).
    fn drive_set_points(&mut self, d: &Drive) {
        let f = &self.model.class.flight;
        let normalized = d.normalized == Some(true);
        let scaled = |v: f64, max: f64| {
            if normalized {
                v.clamp(-100.0, 100.0) * 0.01 * max
            } else {
                v
            }
        };
        let speed = |v: f64, key: &str| {
            let limit = if normalized { 100.0 } else { f.speed_limit };
            limited(v, limit, key)
        };
        let rate = |v: f64, key: &str| {
            let limit = if normalized { 100.0 } else { f.rotation_limit };
            limited(v, limit, key)
        };
        let angle = |v: f64, key: &str| {
            let limit = if normalized { 100.0 } else { f.tilt_limit };
            limited(v, limit, key)
        };
        // The tilt that comes with a translation: ±max_tilt, scaled again when normalized.
        let tilt = |v: f64| {
            (-v.signum() * scaled(f.max_tilt, f.max_tilt))
                .trunc()
                .to_radians()
        };
        if let Some(v) = d.linear_velocity {
            let v = speed(v, "LinearVelocity");
            self.set.linear = scaled(v, f.max_linear_speed);
            self.set.pitch = if v == 0.0 { 0.0 } else { tilt(v) };
        }
        if let Some(v) = d.lateral_velocity {
            let v = speed(v, "LateralVelocity");
            self.set.lateral = scaled(v, f.max_lateral_speed);
            self.set.roll = if v == 0.0 { 0.0 } else { -tilt(v) };
        }
        if let Some(v) = d.altitude_velocity {
            self.set.altitude = scaled(speed(v, "AltitudeVelocity"), f.max_altitude_speed);
        }
        if let Some(v) = d.rotational_velocity {
            let degrees = scaled(rate(v, "RotationalVelocity"), f.max_rotation_speed);
            self.set.yaw_rate = degrees.trunc().to_radians();
        }
        if let Some(v) = d.pitch_angle {
            self.set.pitch = scaled(angle(v, "PitchAngle"), f.max_tilt)
                .trunc()
                .to_radians();
        }
        if let Some(v) = d.roll_angle {
            self.set.roll = scaled(angle(v, "RollAngle"), f.max_tilt)
                .trunc()
                .to_radians();
        }
    }

    /// Whether a physics model flies it (else the kinematic flight).
    pub(crate) fn has_dynamics(&self) -> bool {
        self.dynamics.is_some()
    }

    /// The part of the next tick's flight that only reads the scene (the physics model's
    /// integration, [`Dynamics::integrate`]); [`World`](super::World) runs it for every
    /// robot on the sensor threads before the moves.
    pub(crate) fn prepare(&mut self, scene: &Scene, tick: u64, dt: f64) {
        let dead = self.is_dead(tick, dt);
        if let Some(dynamics) = &mut self.dynamics {
            if dead && self.crashed.is_none() && dynamics.gauge().is_none() {
                dynamics.crash(); // an empty timer stops the motors
            }
            dynamics.integrate(scene, self.body, self.position, self.velocity, dt);
        }
    }

    /// One tick of flight: the physics model's step, or the kinematic flight.
    /// A physics model's robot must have been [prepared](Robot::prepare) this tick (which
    /// also stops the motors of an empty timer).
    pub(crate) fn fly(&mut self, scene: &mut Scene, tick: u64, dt: f64) {
        self.move_body(scene, tick, dt);
        self.touched |= self.contact || self.crashed.is_some();
    }

    /// What a `Touch` part reading `contact` every tick would have said in any of them since
    /// the last call (the body touched something, or it has crashed); clears it.
    pub(crate) fn take_touched(&mut self) -> bool {
        std::mem::take(&mut self.touched)
    }

    fn move_body(&mut self, scene: &mut Scene, tick: u64, dt: f64) {
        if let Some(dynamics) = &mut self.dynamics {
            let crash = dynamics.step(Flight {
                scene,
                body: self.body,
                shape: self.model.shape,
                position: &mut self.position,
                velocity: &mut self.velocity,
                rotation: &mut self.rotation,
                dt,
            });
            self.contact = dynamics.contact();
            if let Some(crash) = crash.filter(|_| self.crashed.is_none()) {
                dynamics.crash();
                self.report_crash(crash, tick, dt);
            }
            return;
        }
        self.kinematic(tick, dt, false, |body, shape, start, motion| {
            scene.sweep_contact(body, shape, start, motion)
        });
    }

    /// Flies the ticks after `tick`, up to `ticks` of them, as [`Robot::fly`] would one by
    /// one, bit for bit — faster, for the scene's only robot and a kinematic one: the solids
    /// it can reach meanwhile are found once ([`Scene::glide_begin`]). Returns the ticks
    /// flown: none when that does not apply (no robot of its own in the scene, a physics
    /// model, a crash, a solid near that is not a box), fewer than `ticks` when it crashed.
    /// The caller makes sure that nothing else happens in them but their moves (no fault,
    /// and no output or refit of the tree before the last one's moves).
    pub(crate) fn glide(&mut self, scene: &mut Scene, tick: u64, ticks: u64, dt: f64) -> u64 {
        if self.dynamics.is_some() || self.crashed.is_some() {
            return 0;
        }
        // No tick moves the body farther than its set speeds (a slide only shortens a
        // motion; an empty battery stops it); the sine and cosine kept by sums may stray
        // from 1 by rounding, which the slack covers.
        let s = self.set;
        let speed = s.linear.abs() + s.lateral.abs() + s.altitude.abs();
        let reach = ticks as f64 * dt * speed * (1.0 + 1e-6) + 1e-6;
        if !reach.is_finite() {
            return 0;
        }
        let (body, shape) = (self.body, self.model.shape);
        // The seconds left only fall from tick to tick: a battery not empty at the glide's
        // last tick is not empty at any of them (each tick's own test then says the same).
        let alive = !self.is_dead(tick + ticks, dt);
        // Without set speeds nothing moves (a hovering UAV, one that only turns): no sweep
        // to prepare.
        let glide = if speed > 0.0 {
            let Some(glide) = scene.glide_begin(body, shape, self.position, reach) else {
                return 0;
            };
            Some(glide)
        } else {
            None
        };
        // Without set speeds and with a battery alive throughout, a tick is a function of the
        // robot's own state alone (no sweep, no crash, no tick-dependent test): once a tick
        // leaves that state as it found it (the tilt has come within its margin, the yaw
        // does not turn), every later tick of the glide would too, and they are skipped.
        let mut last = (glide.is_none() && alive).then(|| self.tick_state());
        let mut flown = 0;
        // A moving glide that cannot crash (a battery alive throughout, no crash on contact):
        // its ticks on copies of the robot's state.
        if let Some(glide) = glide
            .as_ref()
            .filter(|_| alive && !self.model.class.crash.on_contact)
        {
            flown = self.glide_ticks(scene, glide, ticks, dt);
        }
        while flown < ticks && self.crashed.is_none() {
            flown += 1;
            self.kinematic(
                tick + flown,
                dt,
                alive,
                |body, shape, start, motion| match &glide {
                    Some(glide) => scene.glide_sweep(glide, body, shape, start, motion),
                    None => (start, None),
                },
            );
            self.touched |= self.contact || self.crashed.is_some();
            if let Some(before) = &mut last {
                let after = self.tick_state();
                if *before == after {
                    flown = ticks;
                }
                *before = after;
            }
        }
        if let Some(glide) = glide {
            scene.glide_end(glide, body, self.position);
        }
        flown
    }

    /// The `ticks` ticks of a moving glide that cannot crash (a battery alive throughout, no
    /// crash on contact): [`Robot::kinematic`]'s arithmetic, bit for bit, on copies of the
    /// robot's state kept in registers (no velocity but the last tick's); a sweep that meets
    /// none of the glide's solids moves without a cast ([`Scene::glide_free`]). Returns
    /// `ticks`.
    fn glide_ticks(&mut self, scene: &mut Scene, glide: &Glide, ticks: u64, dt: f64) -> u64 {
        let s = self.set;
        let flight = &self.model.class.flight;
        let (body, shape) = (self.body, self.model.shape);
        let (mut pos, mut rotation, mut trig) = (self.position, self.rotation, self.yaw_trig);
        let (mut start, mut contact, mut touched) = (pos, false, false);
        for _ in 0..ticks {
            let motion = set_motion(&s, &mut trig, rotation[2], dt);
            start = pos;
            contact = false;
            if motion != [0.0; 3] {
                pos = match scene.glide_free(glide, body, shape, pos, motion) {
                    Ok(next) => next,
                    Err(meets) => {
                        let (next, hit) = scene.glide_slide(glide, body, shape, pos, meets);
                        contact = hit.is_some();
                        touched |= contact;
                        next
                    }
                };
            }
            turn_and_tilt(&s, flight, &mut rotation, &mut trig, dt);
        }
        (self.position, self.rotation, self.yaw_trig) = (pos, rotation, trig);
        self.velocity = std::array::from_fn(|i| (pos[i] - start[i]) / dt);
        self.contact = contact;
        self.touched |= touched;
        ticks
    }

    /// What a kinematic tick reads and writes of the robot besides its set points, bit for
    /// bit ([`Robot::glide`]'s test that a tick changed nothing).
    fn tick_state(&self) -> ([u64; 15], u8, bool) {
        let (p, v, r, t) = (self.position, self.velocity, self.rotation, &self.yaw_trig);
        let values = [
            p[0], p[1], p[2], v[0], v[1], v[2], r[0], r[1], r[2], t.yaw, t.sin, t.cos, t.turn.0,
            t.turn.1, t.turn.2,
        ];
        (values.map(f64::to_bits), t.sums_left, self.contact)
    }

    /// One tick of the kinematic flight: the set points' motion, `sweep`(body, shape, start,
    /// motion) giving where it ends and the normal of what it touched. `alive`: the battery
    /// is known not to be empty at `tick` (else the tick tests it).
    fn kinematic(
        &mut self,
        tick: u64,
        dt: f64,
        alive: bool,
        sweep: impl FnOnce(ColliderHandle, BodyShape, V3, V3) -> (V3, Option<V3>),
    ) {
        if (!alive && self.is_dead(tick, dt)) || self.crashed.is_some() {
            self.set = SetPoints::default();
        }
        let s = self.set;
        let mut motion = set_motion(&s, &mut self.yaw_trig, self.rotation[2], dt);
        if self.crashed.is_some() {
            motion = [0.0, 0.0, KINEMATIC_FALL_SPEED * dt];
        }
        let start = self.position;
        self.contact = false;
        if motion != [0.0; 3] {
            let (position, hit) = sweep(self.body, self.model.shape, start, motion);
            self.position = position;
            self.contact = hit.is_some();
            if hit.is_some() && self.model.class.crash.on_contact && self.crashed.is_none() {
                let speed = dynamics::norm(motion) / dt;
                let reason = format!("touched an obstacle at {speed:.2} m/s (crash on contact)");
                self.report_crash(
                    Crash {
                        speed,
                        tilt: 0.0,
                        reason,
                    },
                    tick,
                    dt,
                );
            }
        }
        self.velocity = std::array::from_fn(|i| (self.position[i] - start[i]) / dt);
        let flight = &self.model.class.flight;
        turn_and_tilt(&s, flight, &mut self.rotation, &mut self.yaw_trig, dt);
    }

    fn report_crash(&mut self, crash: Crash, tick: u64, dt: f64) {
        tracing::info!(
            serial = self.serial,
            class = %self.class_name(),
            time = tick as f64 * dt,
            speed = crash.speed,
            tilt_deg = crash.tilt.to_degrees(),
            "crash: {}",
            crash.reason
        );
        self.crashed = Some(crash);
        self.set = SetPoints::default();
    }

    /// The tilt of the sensors: body rotation without its yaw (`None` for the kinematic
    /// model, whose pitch and roll are visual only).
    fn tilt(&self) -> Option<M3> {
        let attitude = self.dynamics.as_ref()?.attitude();
        Some(dynamics::mat_mul(
            &attitude,
            &dynamics::transpose(&dynamics::yaw_matrix(self.rotation[2])),
        ))
    }

    /// The next tick at which [`Robot::emit`] has output: the earliest timer, at once
    /// after a SET asked for a reading, never for a robot no connection controls.
    pub(crate) fn next_due(&self) -> u64 {
        if self.owner.is_none() {
            return u64::MAX;
        }
        if !self.notices.is_empty() || self.parts.iter().any(|p| p.forced) {
            return 0;
        }
        let parts = self.parts.iter().map(|p| p.timer.due);
        let actuators = self.actuators.iter().map(|a| a.timer.due);
        parts.chain(actuators).fold(self.status.due, u64::min)
    }

    /// Appends the output due at `tick` (STA, then sensors in part order, then ASTA).
    pub(crate) fn emit(
        &mut self,
        scene: &Scene,
        tick: u64,
        dt: f64,
        out: &mut Vec<(ClientId, ServerMessage)>,
    ) {
        let Some(owner) = self.owner else {
            return;
        };
        out.extend(self.notices.drain(..).map(|n| (owner, n)));
        // Most ticks nothing is due (sensors report every 0.1-0.3 s): return before any work.
        if !self.status.is_due(tick)
            && self
                .parts
                .iter()
                .all(|p| !p.timer.is_due(tick) && !p.forced)
            && self.actuators.iter().all(|a| !a.timer.is_due(tick))
        {
            return;
        }
        let time = tick as f64 * dt;
        if self.status.fire(tick) {
            out.push((
                owner,
                ServerMessage::Sta(Sta {
                    time: Time::udk(time),
                    battery: self.battery_left(tick, dt),
                    vehicle: None,
                    layout: StaLayout::Udk,
                }),
            ));
        }
        if !self.is_dead(tick, dt) {
            let mut heading = Heading::new(self.rotation[2]);
            // The body frame's yaw, for the parts that turn a vector into it.
            let mut body = Heading::new(-self.rotation[2]);
            let tilt = self.tilt();
            let imu = self.dynamics.as_ref().map(|d| d.imu());
            let gauge = self.dynamics.as_ref().and_then(|d| d.gauge());
            let rotors = self.dynamics.as_ref().and_then(|d| d.rotor_speeds());
            let hits = self.cast_single_rays(scene, tick, tilt.as_ref(), &mut heading);
            // What every part's reading shares, made at the first part due; each part then
            // sets its own name, mount and ray.
            let mut shared: Option<Reading<'_>> = None;
            for (i, (part, model)) in self.parts.iter_mut().zip(&self.model.parts).enumerate() {
                let due = part.timer.fire(tick);
                if !(due || std::mem::take(&mut part.forced)) {
                    continue;
                }
                let (origin, yaw, pitch) = mount(self.position, &mut heading, tilt.as_ref(), model);
                let reading = shared.get_or_insert_with(|| Reading {
                    name: "",
                    scene,
                    me: self.body,
                    time,
                    since_spawn: (tick - self.spawn_tick) as f64 * dt,
                    position: self.position,
                    velocity: self.velocity,
                    rotation: self.rotation,
                    spawn_z: self.spawn_z,
                    origin,
                    yaw,
                    pitch,
                    tilt,
                    body_trig: Some(body.sin_cos()),
                    imu,
                    gauge,
                    rotors,
                    contact: self.contact,
                    crashed: self.crashed.is_some(),
                    ray_hit: None,
                });
                (reading.name, reading.origin, reading.yaw, reading.pitch) =
                    (&model.name, origin, yaw, pitch);
                reading.ray_hit = hits.get(i).copied().flatten();
                let reading = &*reading;
                if part.fault_until.is_some_and(|until| time >= until - 1e-9) {
                    (part.fault, part.frozen, part.fault_until) = (SensorFault::Ok, None, None);
                }
                if part.fault == SensorFault::Silent {
                    continue;
                }
                let mut data = match (&part.frozen, part.fault) {
                    (Some(data), SensorFault::Freeze) => data.clone(),
                    _ => part.sensor.read(reading, &mut part.noise),
                };
                match part.fault {
                    SensorFault::Freeze if part.frozen.is_none() => {
                        part.frozen = Some(data.clone());
                    }
                    SensorFault::Drift(rate) => {
                        let d = rate * (time - part.fault_since);
                        perturb(&mut data, || d);
                    }
                    SensorFault::Bias(b) => perturb(&mut data, || b),
                    SensorFault::Noise(std) => {
                        let rng = &mut part.fault_noise;
                        perturb(&mut data, || std * rng.draw());
                    }
                    _ => {}
                }
                let time = part.sensor.timestamped().then_some(Time::udk(time));
                out.push((owner, ServerMessage::Sen(Sen { time, data })));
            }
        } else {
            // Silent until recharged ([`Robot::recharge`]): the timers move on, so that
            // only STA's keeps the robot due.
            for part in &mut self.parts {
                part.timer.fire(tick);
                part.forced = false;
            }
        }
        for actuator in &mut self.actuators {
            if actuator.timer.fire(tick) {
                let links = (1..)
                    .zip(&actuator.values)
                    .map(|(link, &value)| LinkValue { link, value })
                    .collect();
                out.push((
                    owner,
                    ServerMessage::Asta(Asta {
                        time: Time::udk(time),
                        name: actuator.config.name.clone(),
                        links,
                    }),
                ));
            }
        }
    }

    /// The rays of the parts due at `tick` whose reading is one ray in the plane of the
    /// body ([`Sensor::single_ray`] with a level mount: the eight horizontal sonars), cast
    /// together when there are at least four of the same length: one gathering of the solids
    /// near the robot instead of a tree walk per ray. The hit of part `i` is at `i` (`None`
    /// for parts not cast here; empty when none is).
    fn cast_single_rays(
        &self,
        scene: &Scene,
        tick: u64,
        tilt: Option<&M3>,
        heading: &mut Heading,
    ) -> Vec<Option<Option<f64>>> {
        if !scene.shortcuts {
            return Vec::new();
        }
        let (yaw, mut length) = (heading.angle, None);
        let mut fan = Vec::new();
        for (i, (part, model)) in self.parts.iter().zip(&self.model.parts).enumerate() {
            let Some(range) = part.sensor.single_ray() else {
                continue;
            };
            if !(part.forced || part.timer.is_due(tick))
                || model.direction[1] != 0.0
                || length.is_some_and(|l| l != range)
            {
                continue;
            }
            length = Some(range);
            let (origin, ray_yaw, pitch) = mount(self.position, heading, tilt, model);
            // As the sensor builds its direction (`Reading::trace` then tilts it).
            let dir = direction(pitch + 0.0, ray_yaw + 0.0);
            let dir = tilt.map_or(dir, |t| dynamics::mul(t, dir));
            // The azimuth from the body's heading, within ±π.
            let offset = (ray_yaw - yaw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            fan.push((i, origin, dir, offset));
        }
        let Some(length) = length.filter(|_| fan.len() >= 4) else {
            return Vec::new();
        };
        // Largest azimuth first, as `cast_fan` wants.
        fan.sort_by(|a, b| b.3.total_cmp(&a.3));
        let origins: Vec<V3> = fan.iter().map(|r| r.1).collect();
        let dirs: Vec<V3> = fan.iter().map(|r| r.2).collect();
        let offsets: Vec<f64> = fan.iter().map(|r| r.3).collect();
        let axes = match tilt {
            Some(t) => (
                dynamics::mul(t, [1.0, 0.0, 0.0]),
                dynamics::mul(t, [0.0, 1.0, 0.0]),
            ),
            None => ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        };
        let mut out = Vec::with_capacity(fan.len());
        scene.cast_fan(
            self.position,
            &origins,
            &dirs,
            yaw,
            &offsets,
            axes,
            length,
            Some(self.body),
            true,
            &mut out,
        );
        let mut hits = vec![None; self.parts.len()];
        for (ray, hit) in fan.iter().zip(out) {
            hits[ray.0] = Some(hit);
        }
        hits
    }

    /// CONF items of the parts of type `kind` (and name `name`).
    pub(crate) fn conf(&self, kind: &str, name: Option<&str>) -> Vec<ConfItem> {
        let mut items: Vec<ConfItem> = self
            .matching_parts(kind, name)
            .map(|(part, model)| part.sensor.conf(&model.name, model.interval))
            .collect();
        items.extend(self.matching_actuators(kind, name).map(|a| {
            ConfItem::Actuator {
                name: a.config.name.clone(),
                joints: (1..)
                    .zip(&a.config.joints)
                    .map(|(link, j)| ActuatorJoint {
                        link,
                        joint_type: j.joint_type.clone(),
                        max_torque: f64::from(j.max_torque as f32),
                        min_value: f64::from(j.min as f32),
                        max_value: f64::from(j.max as f32),
                    })
                    .collect(),
            }
        }));
        items
    }

    /// GEO items: mount offset in the world frame (yaw-rotated), mount direction.
    pub(crate) fn geo(&self, kind: &str, name: Option<&str>) -> Vec<GeoItem> {
        let yaw = self.rotation[2];
        let item = |name: &str, position: V3, direction: V3| GeoItem {
            name: name.to_string(),
            location: yaw_rotate(yaw, position).into(),
            orientation: direction.into(),
            mount: self.class_name().to_string(),
            mount_link: None,
            layout: Default::default(),
        };
        let mut items: Vec<GeoItem> = self
            .matching_parts(kind, name)
            .map(|(_, model)| item(&model.name, model.position, model.direction))
            .collect();
        items.extend(
            self.matching_actuators(kind, name)
                .map(|a| item(&a.config.name, a.config.position, a.config.direction)),
        );
        items
    }

    /// SET: passes the opcode to the matching parts.
    pub(crate) fn set(
        &mut self,
        kind: &str,
        name: Option<&str>,
        opcode: &str,
        params: Option<&str>,
    ) {
        for (part, model) in self.parts.iter_mut().zip(&self.model.parts) {
            if matches(model.item_type, &model.name, kind, name) && part.sensor.set(opcode, params)
            {
                part.forced = true;
            }
        }
    }

    /// ACT/MISPKG: sets joint `index` (0-based) of actuator `name`.
    pub(crate) fn actuate(&mut self, name: &str, index: i64, value: f64) {
        if !value.is_finite() {
            debug!(actuator = name, value, "non-finite ACT value ignored");
            return;
        }
        let actuator = self
            .actuators
            .iter_mut()
            .find(|a| a.config.name.eq_ignore_ascii_case(name));
        let Some(actuator) = actuator else { return };
        let joint = usize::try_from(index)
            .ok()
            .and_then(|i| Some((actuator.values.get_mut(i)?, actuator.config.joints.get(i)?)));
        if let Some((slot, joint)) = joint {
            *slot = value.clamp(joint.min, joint.max);
        }
    }

    fn matching_parts<'a>(
        &'a self,
        kind: &'a str,
        name: Option<&'a str>,
    ) -> impl Iterator<Item = (&'a Part, &'a PartModel)> + 'a {
        self.parts
            .iter()
            .zip(&self.model.parts)
            .filter(move |(_, m)| matches(m.item_type, &m.name, kind, name))
    }

    fn matching_actuators<'a>(
        &'a self,
        kind: &'a str,
        name: Option<&'a str>,
    ) -> impl Iterator<Item = &'a Actuator> + 'a {
        self.actuators
            .iter()
            .filter(move |a| matches("Actuator", &a.config.name, kind, name))
    }

    /// Its cameras, in part order.
    pub(crate) fn cameras(&self) -> impl Iterator<Item = &Camera> {
        self.parts.iter().filter_map(|p| p.sensor.camera())
    }

    /// Its cameras, in part order, to change.
    pub(crate) fn cameras_mut(&mut self) -> impl Iterator<Item = &mut Camera> {
        self.parts.iter_mut().filter_map(|p| p.sensor.camera_mut())
    }

    /// Its cameras, in part order: the part name, the camera and where it looks now
    /// (mount, pan/tilt actuator, field of view; a body with physics tilts it).
    pub(crate) fn camera_views(&self) -> impl Iterator<Item = (&str, &Camera, View)> {
        let tilt = self.tilt();
        self.parts
            .iter()
            .zip(&self.model.parts)
            .filter_map(move |(part, model)| {
                let camera = part.sensor.camera()?;
                let (origin, mut yaw, mut pitch) = mount(
                    self.position,
                    &mut Heading::new(self.rotation[2]),
                    tilt.as_ref(),
                    model,
                );
                if let Some(actuator) = camera.config.mount.as_deref().and_then(|name| {
                    self.actuators
                        .iter()
                        .find(|a| a.config.name.eq_ignore_ascii_case(name))
                }) {
                    pitch += actuator.values.first().copied().unwrap_or(0.0);
                    yaw += actuator.values.get(1).copied().unwrap_or(0.0);
                }
                let forward = direction(pitch, yaw);
                let right = direction(0.0, yaw + std::f64::consts::FRAC_PI_2);
                let down = cross(forward, right);
                let turn = |v: V3| tilt.as_ref().map_or(v, |t| dynamics::mul(t, v));
                let view = View {
                    origin,
                    forward: turn(forward),
                    right: turn(right),
                    down: turn(down),
                    fov: camera.fov.to_radians(),
                    width: camera.config.width as u32,
                    height: camera.config.height as u32,
                    range: camera.config.range,
                };
                Some((model.name.as_str(), camera, view))
            })
    }

    /// The robot's own body (its cameras do not see it).
    pub(crate) fn body(&self) -> ColliderHandle {
        self.body
    }

    /// Position and rotation (roll, pitch, yaw), protocol frame.
    pub(crate) fn pose(&self) -> (V3, V3) {
        (self.position, self.rotation)
    }

    #[cfg(test)]
    pub(crate) fn velocity(&self) -> V3 {
        self.velocity
    }
}

/// A kinematic tick's motion by the set points `s` at the yaw `yaw` (its sine and cosine
/// from `trig`).
#[inline(always)]
fn set_motion(s: &SetPoints, trig: &mut YawTrig, yaw: f64, dt: f64) -> V3 {
    let (sin, cos) = trig.at(yaw);
    let horizontal = rotate_by(sin, cos, [s.linear, s.lateral, 0.0]);
    scale(add(horizontal, [0.0, 0.0, -s.altitude]), dt)
}

/// A kinematic tick's turn by the set yaw rate (the yaw's sine and cosine kept by `trig`)
/// and its tilt toward the set roll and pitch (visual only).
#[inline(always)]
fn turn_and_tilt(
    s: &SetPoints,
    flight: &FlightConfig,
    rotation: &mut V3,
    trig: &mut YawTrig,
    dt: f64,
) {
    let turn = s.yaw_rate * dt;
    rotation[2] = bounded_angle(rotation[2] + turn);
    trig.turn(rotation[2], turn);
    let step = flight.tilt_rate * dt;
    for (angle, target) in [(0, s.roll), (1, s.pitch)] {
        let error = target - rotation[angle];
        if error.abs() > flight.tilt_margin {
            rotation[angle] += error.clamp(-step, step);
        }
    }
}

/// A part's origin in the world and its yaw and pitch (the [`Reading`] fields).
fn mount(position: V3, yaw: &mut Heading, tilt: Option<&M3>, model: &PartModel) -> (V3, f64, f64) {
    let (s, c) = yaw.sin_cos();
    let level = rotate_by(s, c, model.position);
    let origin = add(position, tilt.map_or(level, |t| dynamics::mul(t, level)));
    (origin, yaw.angle + model.direction[2], model.direction[1])
}

/// A yaw and its sine and cosine, worked out at the first use and kept: a robot's parts all
/// mount on the same yaw (one `sin_cos` for them all instead of one per part).
struct Heading {
    angle: f64,
    trig: Option<(f64, f64)>,
}

impl Heading {
    fn new(angle: f64) -> Self {
        Self { angle, trig: None }
    }

    fn sin_cos(&mut self) -> (f64, f64) {
        *self.trig.get_or_insert_with(|| self.angle.sin_cos())
    }
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// GETCONF/GETGEO/SET matching: type and (optional) name, case-insensitive.
fn matches(item_type: &str, item_name: &str, kind: &str, name: Option<&str>) -> bool {
    item_type.eq_ignore_ascii_case(kind) && name.is_none_or(|n| item_name.eq_ignore_ascii_case(n))
}

#[cfg(test)]
mod yaw_trig_tests {
    use super::YawTrig;

    /// Turning at steady rates for many ticks, wrapping past ±π and the 1000 turns of
    /// `bounded_angle`, the kept sine and cosine stay as near `sin_cos` as the yaw's own
    /// rounding allows: each tick's `yaw + turn` is rounded to the yaw's ulp, which the sums
    /// (of the unrounded angle) do not follow, for up to `EXACT_EVERY` ticks.
    #[test]
    fn the_kept_sine_and_cosine_follow_a_steady_turn() {
        for (start, rate) in [(0.0, 1.0), (3.1, -2.7), (6283.0, 0.3), (-1.0, 1e-9)] {
            let (mut trig, mut yaw) = (YawTrig::default(), start);
            let mut worst: f64 = 0.0;
            for _ in 0..10_000 {
                let (s, c) = trig.at(yaw);
                let (es, ec) = yaw.sin_cos();
                let ulps = f64::from(YawTrig::EXACT_EVERY) * f64::EPSILON * yaw.abs().max(1.0);
                worst = worst.max((s - es).abs().max((c - ec).abs()) / ulps);
                let turn = rate * 0.005;
                yaw = super::bounded_angle(yaw + turn);
                trig.turn(yaw, turn);
            }
            assert!(worst < 1.0, "start {start}, rate {rate}: {worst}");
        }
    }

    /// A yaw set from outside (not by a turn) is computed exactly; so is a yaw that holds.
    #[test]
    fn another_yaw_is_computed_exactly() {
        let mut trig = YawTrig::default();
        trig.at(0.5);
        trig.turn(0.505, 0.005);
        assert_eq!(trig.at(2.0), 2.0f64.sin_cos());
        assert_eq!(trig.at(2.0), 2.0f64.sin_cos());
        assert!(trig.at(f64::NAN).0.is_nan());
    }
}
