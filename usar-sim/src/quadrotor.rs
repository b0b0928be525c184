//! The quadrotor: a rigid body with four rotors (x or + configuration), first-order motors,
//! linear and quadratic drag against the air (wind included), and the onboard cascaded
//! controller a real AR-100B autopilot has: velocity → attitude → body rates → rotor speeds.
//! docs/quadrotor.md describes the model, the frames, the rotor order and the `QUAD`
//! extension; docs/robots.md the parameters and their sources.
//!
//! Frames: world x north, y east, z down; body x forward, y right, z down (FRD). Roll + =
//! right side down, pitch + = nose up, yaw + = clockwise from above. Rotor thrust points
//! along body -z; rotor `i` turning counter-clockwise seen from above pushes the body
//! clockwise (yaw +).
//!
//! Integration: semi-implicit Euler substeps of at most [`MAX_SUBSTEP`] (two per 5 ms tick;
//! the controller runs at each, as an autopilot's 400 Hz inner loop would), exact exponential motor lag, quaternion attitude.
//! The body then moves with one swept shape cast per tick, like the kinematic model, so it
//! never passes through anything; a contact faster than the crash speed, or while tilted
//! more than the crash tilt, is a crash.

use serde::Deserialize;

use super::dynamics::{
    Crash, Dynamics, Flight, GRAVITY, ImuTruth, LowLevel, M3, SetPoints, cross, dot, mul_t, norm,
    sub, transpose, wrap_angle,
};
use super::power::{Battery, BatteryConfig, Gauge};
use super::scene::{V3, yaw_rotate};
use super::wind::{Gusts, WindConfig};

/// Longest controller and integration step, s (two per 5 ms tick: a 400 Hz inner loop).
pub(crate) const MAX_SUBSTEP: f64 = 0.0025;

/// m/s: the velocity integral runs only while the error is smaller (no wind-up on steps).
const INTEGRATE_BELOW: f64 = 0.5;

/// m/s and rad/s: the largest set-point the controller takes (absurd DRIVE values stay
/// finite).
const MAX_TARGET: f64 = 100.0;

/// rad: the held heading stays this close to the actual one.
const MAX_YAW_LAG: f64 = 0.5;

/// Fraction of the rotors' top thrust the velocity controller asks for at most (the rest
/// is room for the attitude).
const THRUST_MARGIN: f64 = 0.9;

/// m/s: the autopilot's descent when the battery reaches its reserve.
const LAND_SPEED: f64 = 0.5;

/// m/s: impacts slower than this do not bounce (a resting body would jitter).
const BOUNCE_MIN: f64 = 0.1;

/// rad: the landing gear's tilt at which its righting torque reaches N·r (a stiff gear).
const GEAR_COMPLIANCE: f64 = 0.05;

/// m: a body resting on a surface is still held by it while the surface is within this
/// distance of the body's extent (the 1 cm skin and a margin).
const PROBE: f64 = 0.02;

/// Rotor arrangement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Configuration {
    /// Rotors at ±45° and ±135° from the nose: 1 front-right, 2 rear-right, 3 rear-left,
    /// 4 front-left.
    #[default]
    X,
    /// Rotors on the axes: 1 front, 2 right, 3 rear, 4 left.
    #[serde(rename = "+")]
    Plus,
}

/// Quadrotor parameters (`[robot.quadrotor]`); defaults: an AirRobot AR-100B-sized vehicle
/// (docs/robots.md gives the sources and the derivations).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct QuadrotorConfig {
    /// kg, take-off mass.
    pub mass: f64,
    /// m, centre to rotor axis.
    pub arm_length: f64,
    /// kg·m², principal moments about body x, y, z.
    pub inertia: [f64; 3],
    /// N per (rad/s)²: rotor thrust = k · ω².
    pub thrust_coefficient: f64,
    /// N·m per (rad/s)²: rotor drag torque = k · ω².
    pub torque_coefficient: f64,
    /// s, first-order lag of a rotor's speed behind a higher command (spin-up).
    pub motor_time_constant: f64,
    /// s, the lag behind a lower command (spin-down: without active braking the rotor
    /// coasts down, slower than the motor drives it up).
    pub motor_time_constant_down: f64,
    /// rad/s, idle speed in flight (the controller never commands less).
    pub rotor_speed_min: f64,
    /// rad/s.
    pub rotor_speed_max: f64,
    /// N·s/m: force against the airspeed at hover rotor speed (rotor drag, dominant at low
    /// speed; it grows in proportion to the mean rotor speed).
    pub drag_linear: f64,
    /// N·s²/m²: ½ρ·C_d·A of the airframe.
    pub drag_quadratic: f64,
    /// `"x"` or `"+"`.
    pub configuration: Configuration,
    /// 1/s: velocity error → acceleration.
    pub velocity_gain: f64,
    /// 1/s²: integral of the velocity error → acceleration (holds speed against wind).
    pub velocity_integral_gain: f64,
    /// 1/s: altitude error → climb rate while no climb is commanded (altitude hold).
    pub altitude_gain: f64,
    /// 1/s: attitude error → body rate.
    pub attitude_gain: f64,
    /// 1/s: body-rate error → angular acceleration.
    pub rate_gain: f64,
    /// rad/s: largest commanded roll/pitch rate.
    pub max_tilt_rate: f64,
    /// Coulomb friction coefficient μ against every surface (static = kinetic).
    pub friction: f64,
    /// Coefficient of restitution e of an impact (normal speed after / before).
    pub restitution: f64,
    /// m, distance from the centre to the landing-gear feet.
    pub gear_radius: f64,
    /// m, rotor (propeller) radius.
    pub rotor_radius: f64,
    /// Ground effect (Cheeseman–Bennett) on.
    pub ground_effect: bool,
    /// The battery, used when the class has one (`battery = ..`).
    pub battery: BatteryConfig,
}

impl Default for QuadrotorConfig {
    fn default() -> Self {
        Self {
            mass: 1.3,
            arm_length: 0.3,
            inertia: [0.0218, 0.0207, 0.0377],
            thrust_coefficient: 2.678e-5,
            torque_coefficient: 5.197e-7,
            motor_time_constant: 0.03,
            motor_time_constant_down: 0.03,
            rotor_speed_min: 48.9,
            rotor_speed_max: 488.9,
            drag_linear: 0.25,
            drag_quadratic: 0.05,
            configuration: Configuration::X,
            velocity_gain: 4.0,
            velocity_integral_gain: 2.0,
            altitude_gain: 1.5,
            attitude_gain: 8.0,
            rate_gain: 20.0,
            max_tilt_rate: 4.0,
            friction: 0.5,
            restitution: 0.2,
            gear_radius: 0.2,
            rotor_radius: 0.1524,
            ground_effect: true,
            battery: BatteryConfig::default(),
        }
    }
}

impl QuadrotorConfig {
    /// Checks the numbers; the message names the bad one.
    pub fn check(&self) -> Result<(), String> {
        for (what, v) in [
            ("quadrotor.mass", self.mass),
            ("quadrotor.arm_length", self.arm_length),
            ("quadrotor.inertia", self.inertia[0]),
            ("quadrotor.inertia", self.inertia[1]),
            ("quadrotor.inertia", self.inertia[2]),
            ("quadrotor.thrust_coefficient", self.thrust_coefficient),
            ("quadrotor.torque_coefficient", self.torque_coefficient),
            ("quadrotor.motor_time_constant", self.motor_time_constant),
            (
                "quadrotor.motor_time_constant_down",
                self.motor_time_constant_down,
            ),
            ("quadrotor.rotor_speed_max", self.rotor_speed_max),
            ("quadrotor.velocity_gain", self.velocity_gain),
            ("quadrotor.altitude_gain", self.altitude_gain),
            ("quadrotor.attitude_gain", self.attitude_gain),
            ("quadrotor.rate_gain", self.rate_gain),
            ("quadrotor.max_tilt_rate", self.max_tilt_rate),
            ("quadrotor.gear_radius", self.gear_radius),
            ("quadrotor.rotor_radius", self.rotor_radius),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{what} must be a positive number, got {v}"));
            }
        }
        for (what, v) in [
            ("quadrotor.rotor_speed_min", self.rotor_speed_min),
            ("quadrotor.drag_linear", self.drag_linear),
            ("quadrotor.drag_quadratic", self.drag_quadratic),
            (
                "quadrotor.velocity_integral_gain",
                self.velocity_integral_gain,
            ),
            ("quadrotor.friction", self.friction),
            ("quadrotor.restitution", self.restitution),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{what} must be >= 0, got {v}"));
            }
        }
        for (what, v, max) in [
            ("quadrotor.mass", self.mass, 1000.0),
            ("quadrotor.arm_length", self.arm_length, 100.0),
            (
                "quadrotor.motor_time_constant",
                self.motor_time_constant,
                10.0,
            ),
            (
                "quadrotor.motor_time_constant_down",
                self.motor_time_constant_down,
                10.0,
            ),
            ("quadrotor.rotor_speed_max", self.rotor_speed_max, 1e5),
            ("quadrotor.drag_linear", self.drag_linear, 1e3),
            ("quadrotor.drag_quadratic", self.drag_quadratic, 1e3),
            ("quadrotor.velocity_gain", self.velocity_gain, 50.0),
            (
                "quadrotor.velocity_integral_gain",
                self.velocity_integral_gain,
                50.0,
            ),
            ("quadrotor.altitude_gain", self.altitude_gain, 50.0),
            ("quadrotor.attitude_gain", self.attitude_gain, 100.0),
            ("quadrotor.rate_gain", self.rate_gain, 200.0),
            ("quadrotor.max_tilt_rate", self.max_tilt_rate, 100.0),
            ("quadrotor.friction", self.friction, 10.0),
            ("quadrotor.restitution", self.restitution, 1.0),
            ("quadrotor.gear_radius", self.gear_radius, 100.0),
            ("quadrotor.rotor_radius", self.rotor_radius, 100.0),
        ] {
            if v > max {
                return Err(format!(
                    "{what} must be at most {max}, got {}",
                    usar_proto::shown::Number(v)
                ));
            }
        }
        self.battery.check()?;
        if self.rotor_speed_min >= self.rotor_speed_max {
            return Err("quadrotor.rotor_speed_min must be below rotor_speed_max".into());
        }
        let max_thrust = 4.0 * self.thrust_coefficient * self.rotor_speed_max.powi(2);
        if max_thrust <= self.mass * GRAVITY * 1.1 {
            return Err(format!(
                "quadrotor cannot hover: 4 rotors give at most {max_thrust:.2} N for a weight of \
                 {:.2} N (raise thrust_coefficient or rotor_speed_max)",
                self.mass * GRAVITY
            ));
        }
        Ok(())
    }

    /// Rotor speed at which the four rotors carry the weight, rad/s.
    pub fn hover_speed(&self) -> f64 {
        (self.mass * GRAVITY / (4.0 * self.thrust_coefficient)).sqrt()
    }

    /// Rotor positions (body x, y) and spin (+1 counter-clockwise from above, -1 clockwise).
    fn rotors(&self) -> [(f64, f64, f64); 4] {
        let l = self.arm_length;
        let d = l * std::f64::consts::FRAC_1_SQRT_2;
        match self.configuration {
            Configuration::X => [(d, d, 1.0), (-d, d, -1.0), (-d, -d, 1.0), (d, -d, -1.0)],
            Configuration::Plus => [
                (l, 0.0, 1.0),
                (0.0, l, -1.0),
                (-l, 0.0, 1.0),
                (0.0, -l, -1.0),
            ],
        }
    }
}

/// Limits the controller takes from the robot's flight settings.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Limits {
    /// rad.
    pub(crate) max_tilt: f64,
    /// m/s, the fastest climb or descent the altitude hold commands.
    pub(crate) max_climb: f64,
    /// m/s into a surface that still is no crash.
    pub(crate) crash_speed: f64,
    /// rad of tilt at a contact that still is no crash.
    pub(crate) crash_tilt: f64,
    /// The class has a battery: the energy model runs (otherwise energy is unlimited).
    pub(crate) battery: bool,
}

/// Who commands the rotors.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    /// After spawn, before any command: level attitude, altitude hold (drifts with the wind,
    /// like an AR-100B with centred sticks).
    Level,
    /// DRIVE: ground velocity in the yaw frame, altitude hold while no climb is commanded.
    Velocity(SetPoints),
    /// QUAD {Attitude}.
    Attitude {
        roll: f64,
        pitch: f64,
        yaw_rate: f64,
        thrust: f64,
    },
    /// QUAD {Rates}: body rates (rad/s) and collective thrust (N).
    Rates { rates: V3, thrust: f64 },
    /// QUAD {Rotors}.
    Rotors([f64; 4]),
    /// The battery reached its reserve: the autopilot descends at [`LAND_SPEED`] and
    /// stops the motors on the ground; commands are ignored.
    Land,
    /// Crashed: motors off.
    Off,
}

/// The quadrotor's state.
/// A tick's integration before contacts: from where, and to where it would go.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Planned {
    start: V3,
    v0: V3,
    p: V3,
    v: V3,
}

#[derive(Debug)]
pub(crate) struct Quadrotor {
    config: QuadrotorConfig,
    limits: Limits,
    /// Rotor positions and spins.
    rotors: [(f64, f64, f64); 4],
    /// [T, τx, τy, τz] → ω² per rotor.
    unmix: [[f64; 4]; 4],
    /// Motor lag factors per substep: spin-up, spin-down.
    motor_alpha: (f64, f64),
    /// Thrust factor of each rotor's ground effect (1 out of it), per tick.
    ground: [f64; 4],
    /// Substeps per tick.
    substeps: usize,
    /// Attitude, body → world, as a unit quaternion (w, x, y, z).
    q: [f64; 4],
    /// Body rates, rad/s.
    rates: V3,
    /// Rotor speeds, rad/s.
    speeds: [f64; 4],
    mode: Mode,
    /// Integral of the velocity error (world frame), m.
    integral: V3,
    /// Altitude held while no climb is commanded.
    hold_z: Option<f64>,
    /// Heading the controller holds, rad.
    yaw_ref: f64,
    gusts: Gusts,
    imu: ImuTruth,
    contact: bool,
    /// Outward normal of the surface the body touched in the last tick (it is then held
    /// by it: [`Quadrotor::hold`]).
    surface: Option<V3>,
    /// The integration blew up once (logged once).
    diverged: bool,
    /// This tick's integration, done ahead on a sensor thread ([`Dynamics::integrate`]).
    planned: Option<Planned>,
    /// The energy model (`None`: unlimited energy).
    battery: Option<Battery>,
    /// rad/s, the rotors' top speed at the battery's voltage.
    top_speed: f64,
    /// kg carried besides the body ([`Dynamics::set_payload`]); the controller does not
    /// know it (its integral takes it up), the physics does.
    payload: f64,
    /// Fraction of each rotor's thrust and torque left (motor faults): the motor turns at
    /// √health of the speed asked, so `speeds` are the rotors' true speeds.
    health: [f64; 4],
}

/// The rotation of a unit quaternion (w, x, y, z): body → world.
fn quat_matrix(q: [f64; 4]) -> M3 {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// The quaternion of roll, pitch, yaw (Z-Y-X).
fn euler_quat(r: V3) -> [f64; 4] {
    let (sr, cr) = (r[0] / 2.0).sin_cos();
    let (sp, cp) = (r[1] / 2.0).sin_cos();
    let (sy, cy) = (r[2] / 2.0).sin_cos();
    [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]
}

/// `a ⊗ b`.
fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// The inverse of a 4×4 matrix (Gauss–Jordan with partial pivoting); the mixer is regular
/// for every valid configuration.
fn invert4(m: [[f64; 4]; 4]) -> [[f64; 4]; 4] {
    let mut a = m;
    let mut inv: [[f64; 4]; 4] =
        std::array::from_fn(|i| std::array::from_fn(|j| f64::from(u8::from(i == j))));
    for col in 0..4 {
        let pivot = (col..4)
            .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
            .unwrap_or(col);
        a.swap(col, pivot);
        inv.swap(col, pivot);
        let p = a[col][col];
        for j in 0..4 {
            a[col][j] /= p;
            inv[col][j] /= p;
        }
        for row in 0..4 {
            if row != col {
                let f = a[row][col];
                for j in 0..4 {
                    a[row][j] -= f * a[col][j];
                    inv[row][j] -= f * inv[col][j];
                }
            }
        }
    }
    inv
}

impl Quadrotor {
    /// A quadrotor hovering at `rotation` (its rotors at hover speed).
    pub(crate) fn new(
        config: QuadrotorConfig,
        limits: Limits,
        rotation: V3,
        wind: WindConfig,
        seed: u64,
        serial: u64,
        dt: f64,
    ) -> Self {
        let rotors = config.rotors();
        let (kf, km) = (config.thrust_coefficient, config.torque_coefficient);
        let mix = [
            [kf; 4],
            std::array::from_fn(|i| -rotors[i].1 * kf),
            std::array::from_fn(|i| rotors[i].0 * kf),
            std::array::from_fn(|i| rotors[i].2 * km),
        ];
        let substeps = ((dt / MAX_SUBSTEP - 1e-9).ceil() as usize).max(1);
        let h = dt / substeps as f64;
        let hover = config.hover_speed();
        Self {
            unmix: invert4(mix),
            rotors,
            motor_alpha: (
                1.0 - (-h / config.motor_time_constant).exp(),
                1.0 - (-h / config.motor_time_constant_down).exp(),
            ),
            ground: [1.0; 4],
            substeps,
            q: euler_quat(rotation),
            rates: [0.0; 3],
            speeds: [hover; 4],
            mode: Mode::Level,
            integral: [0.0; 3],
            hold_z: None,
            yaw_ref: rotation[2],
            gusts: Gusts::new(wind, seed, serial),
            imu: ImuTruth {
                specific_force: [0.0, 0.0, -GRAVITY],
                body_rates: [0.0; 3],
            },
            contact: false,
            surface: None,
            diverged: false,
            planned: None,
            battery: limits.battery.then(|| Battery::new(config.battery.clone())),
            top_speed: config.rotor_speed_max,
            payload: 0.0,
            health: [1.0; 4],
            config,
            limits,
        }
    }

    /// Rotor speed commands for the current mode.
    fn control(&mut self, p: V3, v: V3, r: &M3, h: f64) -> [f64; 4] {
        // The held heading never runs away from the actual one (weak yaw authority).
        let yaw = r[1][0].atan2(r[0][0]);
        let lag = wrap_angle(self.yaw_ref - yaw);
        if lag.abs() > MAX_YAW_LAG {
            self.yaw_ref = yaw + lag.clamp(-MAX_YAW_LAG, MAX_YAW_LAG);
        }
        let c = &self.config;
        let m = c.mass;
        let top = self.top_speed.max(c.rotor_speed_min);
        let (desired, thrust, yaw_ff) = match self.mode {
            Mode::Off => return [0.0; 4],
            Mode::Rotors(w) => return w.map(|w| w.clamp(c.rotor_speed_min, top)),
            Mode::Attitude {
                roll,
                pitch,
                yaw_rate,
                thrust,
            } => {
                let yaw_rate = yaw_rate.clamp(-MAX_TARGET, MAX_TARGET);
                self.yaw_ref += yaw_rate * h;
                let desired = super::dynamics::euler_to_matrix([roll, pitch, self.yaw_ref]);
                (desired, thrust, yaw_rate)
            }
            // The rate loop alone (below); the held heading follows the actual one, so that
            // a later mode holds the heading the rates left.
            Mode::Rates { thrust, .. } => {
                self.yaw_ref = yaw;
                (*r, thrust, 0.0)
            }
            Mode::Level | Mode::Velocity(_) | Mode::Land => {
                let set = match self.mode {
                    Mode::Velocity(s) => Some(s),
                    Mode::Land => Some(SetPoints {
                        altitude: -LAND_SPEED,
                        ..SetPoints::default()
                    }),
                    _ => None,
                };
                let climb = set.map_or(0.0, |s| s.altitude.clamp(-MAX_TARGET, MAX_TARGET));
                let vz = if climb == 0.0 {
                    let z = *self.hold_z.get_or_insert(p[2]);
                    (c.altitude_gain * (z - p[2]))
                        .clamp(-self.limits.max_climb, self.limits.max_climb)
                } else {
                    self.hold_z = None;
                    -climb
                };
                let a_max = GRAVITY * self.limits.max_tilt.tan();
                let ki = c.velocity_integral_gain;
                let mut accel = [0.0; 3];
                // PI on the velocity error. The integral (which holds the speed against wind)
                // only runs near the target, so a large step does not wind it up.
                let pi = |i: usize, target: f64, limit: f64, integral: &mut V3| {
                    let e = target - v[i];
                    if e.abs() < INTEGRATE_BELOW {
                        integral[i] += e * h;
                    }
                    if ki > 0.0 {
                        integral[i] = integral[i].clamp(-limit / ki, limit / ki);
                    }
                    c.velocity_gain * e + ki * integral[i]
                };
                accel[2] = pi(2, vz, 0.3 * GRAVITY, &mut self.integral);
                match set {
                    Some(s) => {
                        let (linear, lateral) = (
                            s.linear.clamp(-MAX_TARGET, MAX_TARGET),
                            s.lateral.clamp(-MAX_TARGET, MAX_TARGET),
                        );
                        let target = yaw_rotate(self.yaw_ref, [linear, lateral, 0.0]);
                        // Feed-forward: the drag of the commanded speed in calm air.
                        let speed = target[0].hypot(target[1]);
                        let ff = (c.drag_linear + c.drag_quadratic * speed) / m;
                        accel[0] =
                            pi(0, target[0], 0.5 * a_max, &mut self.integral) + ff * target[0];
                        accel[1] =
                            pi(1, target[1], 0.5 * a_max, &mut self.integral) + ff * target[1];
                        let horizontal = accel[0].hypot(accel[1]);
                        if horizontal > a_max {
                            accel[0] *= a_max / horizontal;
                            accel[1] *= a_max / horizontal;
                        }
                        self.yaw_ref += s.yaw_rate.clamp(-MAX_TARGET, MAX_TARGET) * h;
                    }
                    None => {
                        self.integral[0] = 0.0;
                        self.integral[1] = 0.0;
                    }
                }
                // The thrust vector that gives this acceleration against gravity (never
                // pushing down).
                let mut force = [m * accel[0], m * accel[1], m * (accel[2] - GRAVITY)];
                force[2] = force[2].min(-0.2 * m * GRAVITY);
                // The tilt limit holds whatever the vertical demand: a descent lightens the
                // vertical thrust, and the same horizontal force would tilt the body further
                // (issue #54: 41° at a 25° limit).
                let horizontal = force[0].hypot(force[1]);
                let widest = -force[2] * self.limits.max_tilt.tan();
                if horizontal > widest {
                    force[0] *= widest / horizontal;
                    force[1] *= widest / horizontal;
                }
                // Thrust runs out: the horizontal part (the attitude) wins, the climb gets
                // what is left (a climb demand must not starve the forward motion).
                let most = THRUST_MARGIN * 4.0 * c.thrust_coefficient * top * top;
                if norm(force) > most {
                    let horizontal = force[0].hypot(force[1]);
                    let keep = horizontal.min(most * self.limits.max_tilt.sin());
                    if horizontal > 0.0 {
                        force[0] *= keep / horizontal;
                        force[1] *= keep / horizontal;
                    }
                    force[2] = -(most * most - keep * keep).sqrt();
                }
                let b3 = force.map(|f| -f / norm(force));
                let heading = [self.yaw_ref.cos(), self.yaw_ref.sin(), 0.0];
                let b2 = cross(b3, heading);
                let b2 = b2.map(|x| x / norm(b2));
                let b1 = cross(b2, b3);
                let desired = [
                    [b1[0], b2[0], b3[0]],
                    [b1[1], b2[1], b3[1]],
                    [b1[2], b2[2], b3[2]],
                ];
                // Thrust along the body's actual axis: no climb while the attitude catches up.
                let axis = [r[0][2], r[1][2], r[2][2]];
                let thrust = -dot(force, axis);
                (desired, thrust, set.map_or(0.0, |s| s.yaw_rate))
            }
        };
        let tilt_rate = c.max_tilt_rate;
        let want = if let Mode::Rates { rates, .. } = self.mode {
            rates.map(|w| w.clamp(-tilt_rate, tilt_rate))
        } else {
            // Attitude error (Lee et al. 2010): e = ½ vee(R_dᵀR − RᵀR_d).
            let a = super::dynamics::mat_mul(&transpose(&desired), r);
            let e = [
                0.5 * (a[2][1] - a[1][2]),
                0.5 * (a[0][2] - a[2][0]),
                0.5 * (a[1][0] - a[0][1]),
            ];
            [
                (-c.attitude_gain * e[0]).clamp(-tilt_rate, tilt_rate),
                (-c.attitude_gain * e[1]).clamp(-tilt_rate, tilt_rate),
                (-c.attitude_gain * e[2] + yaw_ff).clamp(-tilt_rate, tilt_rate),
            ]
        };
        let w = self.rates;
        let inertia = c.inertia;
        let iw = std::array::from_fn(|i| inertia[i] * w[i]);
        let gyro = cross(w, iw);
        let torque: V3 =
            std::array::from_fn(|i| inertia[i] * c.rate_gain * (want[i] - w[i]) + gyro[i]);
        let thrust = thrust.clamp(0.0, 4.0 * c.thrust_coefficient * top.powi(2));
        // Mixer with priorities: thrust, roll and pitch first; yaw gets what the rotor speed
        // limits leave (a saturated yaw demand must not cost the attitude).
        let (lo, hi) = (c.rotor_speed_min.powi(2), top.powi(2));
        // Roll and pitch before the collective: the collective moves within the room the
        // roll and pitch differences leave (all four rotors within their limits).
        let tilt: [f64; 4] =
            std::array::from_fn(|i| self.unmix[i][1] * torque[0] + self.unmix[i][2] * torque[1]);
        let (floor, ceiling) = (0..4).fold((f64::MIN, f64::MAX), |(a, b), i| {
            (a.max(lo - tilt[i]), b.min(hi - tilt[i]))
        });
        let collective = self.unmix[0][0] * thrust;
        let collective = if floor <= ceiling {
            collective.clamp(floor, ceiling)
        } else {
            (floor + ceiling) / 2.0
        };
        let base: [f64; 4] = std::array::from_fn(|i| (collective + tilt[i]).clamp(lo, hi));
        let yaw: [f64; 4] = std::array::from_fn(|i| self.unmix[i][3] * torque[2]);
        let share = (0..4).fold(1.0f64, |share, i| {
            let room = if yaw[i] > 0.0 {
                hi - base[i]
            } else {
                base[i] - lo
            };
            if yaw[i].abs() > 0.0 {
                share.min((room / yaw[i].abs()).max(0.0))
            } else {
                share
            }
        });
        std::array::from_fn(|i| (base[i] + share * yaw[i]).clamp(lo, hi).sqrt())
    }

    /// The velocity after an impact on a surface of outward normal `n`: the normal speed
    /// reversed and scaled by the restitution (below [`BOUNCE_MIN`] it is removed), the
    /// tangential speed reduced by the friction impulse μ·|Δv_n| (Coulomb, impulse form).
    fn impact(&self, v: V3, n: V3) -> V3 {
        let vn = dot(v, n);
        if vn >= 0.0 {
            return v;
        }
        let e = if -vn > BOUNCE_MIN {
            self.config.restitution
        } else {
            0.0
        };
        let tangent: V3 = std::array::from_fn(|i| v[i] - vn * n[i]);
        let slide = norm(tangent);
        let keep = if slide > 0.0 {
            (1.0 - self.config.friction * (1.0 + e) * -vn / slide).max(0.0)
        } else {
            0.0
        };
        std::array::from_fn(|i| keep * tangent[i] - e * vn * n[i])
    }

    /// A substep on the surface of outward normal `n` the body touched: while the net force
    /// presses it on the surface, the surface carries the pressing component N, Coulomb
    /// friction (at most μ·N) holds or brakes the tangential motion, and — on a floor (a
    /// normal within 45° of up) — the landing gear rights the body: feet `gear_radius` from
    /// the centre give at most N·r of torque towards the nearest resting attitude
    /// (upright, or on its back), with a compliance of [`GEAR_COMPLIANCE`] and critical
    /// damping, added to the rotors' torque. Yaw is held by the feet's friction (at most
    /// μ·N·r).
    fn hold(&mut self, n: V3, r: &M3, h: f64, v: &mut V3, force: &mut V3, torque: &mut V3) {
        let c = &self.config;
        let pressing = -dot(*force, n);
        let vn = dot(*v, n);
        if pressing <= 0.0 || vn > 1e-9 {
            return; // lifting off
        }
        for i in 0..3 {
            force[i] += pressing * n[i];
            v[i] -= vn * n[i];
        }
        // Friction: the tangential force that would stop the body within this substep.
        let stop: V3 = std::array::from_fn(|i| force[i] + (c.mass + self.payload) * v[i] / h);
        let limit = c.friction * pressing;
        let need = norm(stop);
        let f = if need <= limit { 1.0 } else { limit / need };
        for i in 0..3 {
            force[i] -= f * stop[i];
        }
        if n[2] > -std::f64::consts::FRAC_1_SQRT_2 {
            return; // a wall or a steep slope: no gear contact
        }
        let most = pressing * c.gear_radius;
        // The body's down axis and the resting direction it turns to (into the surface,
        // or out of it for a body on its back), in the body frame.
        let down = mul_t(r, n.map(|x| -x));
        let target = if down[2] >= 0.0 {
            down
        } else {
            down.map(|x| -x)
        };
        let axis = cross([0.0, 0.0, 1.0], target);
        let sin = norm(axis);
        let angle = sin.atan2(target[2]);
        for i in 0..3 {
            let (inertia, w) = (c.inertia[i], self.rates[i]);
            if i < 2 {
                let stiffness = most / GEAR_COMPLIANCE;
                let damping = 2.0 * (stiffness * inertia).sqrt();
                let spring = if sin > 0.0 {
                    (stiffness * angle).min(most) * axis[i] / sin
                } else {
                    0.0
                };
                torque[i] += spring - damping * w;
            } else {
                // Yaw: the feet's friction, static up to μ·N·r.
                let stop = torque[i] + inertia * w / h;
                let limit = c.friction * most;
                torque[i] -= stop.clamp(-limit, limit);
            }
        }
    }

    /// Draws the rotors' and the avionics' power for `h` seconds; the battery's voltage sets
    /// the rotors' top speed (`rotor_speed_max` at full charge, in proportion below: a
    /// motor's no-load speed is K_v·V); at the reserve the autopilot lands, empty the
    /// motors stop.
    fn use_energy(&mut self, h: f64) {
        let Some(battery) = &mut self.battery else {
            return;
        };
        let c = &self.config;
        // The mechanical power the motors deliver: each rotor's drag torque km·ω² (the
        // torque that yaws the body) times its speed.
        let shaft: f64 = self
            .speeds
            .iter()
            .map(|w| c.torque_coefficient * w * w * w)
            .sum();
        // The avionics (autopilot, radio, sensors) draw their power whatever the motors do:
        // landed, crashed or with its motors stopped, a vehicle still reports.
        battery.draw(battery.electrical(shaft), h);
        self.top_speed = c.rotor_speed_max * battery.voltage_ratio();
        if battery.empty() {
            self.mode = Mode::Off;
        } else if battery.at_reserve() && !matches!(self.mode, Mode::Off | Mode::Land) {
            self.mode = Mode::Land;
            self.hold_z = None;
        }
    }

    /// The tick's integration without contacts: the ground effect's rays, then the
    /// substeps. It only reads the scene, so every robot's runs on the sensor threads
    /// before the moves ([`Dynamics::integrate`]).
    fn plan(
        &mut self,
        scene: &super::scene::Scene,
        body: rapier3d::prelude::ColliderHandle,
        start: V3,
        v0: V3,
        dt: f64,
    ) -> Planned {
        let h = dt / self.substeps as f64;
        let (mut p, mut v) = (start, v0);
        let c = self.config.clone();
        let mean = self.gusts.mean();
        let wind = self.gusts.step(dt, norm(sub(v, mean)));
        self.ground = if c.ground_effect {
            self.ground_effect(scene, body, start)
        } else {
            [1.0; 4]
        };
        for _ in 0..self.substeps {
            let r = quat_matrix(self.q);
            let command = self.control(p, v, &r, h);
            for ((speed, target), health) in self.speeds.iter_mut().zip(command).zip(self.health) {
                // A motor at a fraction `health` of its thrust turns at √health of the speed
                // asked (thrust ∝ ω²): a failed one spins down to a stop with its lag.
                let target = if health < 1.0 {
                    target * health.sqrt()
                } else {
                    target
                };
                let alpha = if target > *speed {
                    self.motor_alpha.0
                } else {
                    self.motor_alpha.1
                };
                *speed += (target - *speed) * alpha;
            }
            let (thrust, mut torque) = self.wrench();
            // Air through the rotors along the thrust (+ = climbing).
            self.use_energy(h);
            let air = sub(v, wind);
            let spin = self.speeds.iter().sum::<f64>() / (4.0 * c.hover_speed());
            let drag = c.drag_linear * spin + c.drag_quadratic * norm(air);
            let mass = c.mass + self.payload;
            let mut force: V3 = std::array::from_fn(|i| {
                -r[i][2] * thrust - drag * air[i] + if i == 2 { mass * GRAVITY } else { 0.0 }
            });
            if let Some(n) = self.surface {
                self.hold(n, &r, h, &mut v, &mut force, &mut torque);
            }
            for i in 0..3 {
                v[i] += force[i] / mass * h;
                p[i] += v[i] * h;
            }
            let w = self.rates;
            let iw: V3 = std::array::from_fn(|i| c.inertia[i] * w[i]);
            let gyro = cross(w, iw);
            for i in 0..3 {
                self.rates[i] += (torque[i] - gyro[i]) / c.inertia[i] * h;
            }
            let w = self.rates;
            let angle = norm(w) * h;
            if angle > 0.0 {
                let (s, co) = (angle / 2.0).sin_cos();
                let k = s / norm(w);
                self.q = quat_mul(self.q, [co, w[0] * k, w[1] * k, w[2] * k]);
                let n = self.q.iter().map(|x| x * x).sum::<f64>().sqrt();
                self.q = self.q.map(|x| x / n);
            }
        }
        Planned { start, v0, p, v }
    }

    /// Each rotor's thrust factor near the ground (Cheeseman & Bennett, *The effect of the
    /// ground on a helicopter rotor in forward flight*, ARC R&M 3021, 1955):
    /// `T/T∞ = 1 / (1 − (R/4z)²)` at the height `z` of the rotor above the surface below
    /// it (one ray straight down from each rotor hub); `z` is taken as at least `R/2`
    /// (the formula's pole is at `R/4`; at most 4/3); beyond `4R` the effect (under 0.4 %)
    /// is left out.
    fn ground_effect(
        &self,
        scene: &super::scene::Scene,
        body: rapier3d::prelude::ColliderHandle,
        centre: V3,
    ) -> [f64; 4] {
        let radius = self.config.rotor_radius;
        // Nothing within reach of any hub's ray (the hubs lie within `arm` of the centre
        // however the body tilts): no ray can hit, as at cruise height, so none is cast.
        let arm = self
            .rotors
            .iter()
            .map(|&(x, y, _)| x.hypot(y))
            .fold(0.0, f64::max);
        let lo = [centre[0] - arm, centre[1] - arm, centre[2] - arm];
        let hi = [
            centre[0] + arm,
            centre[1] + arm,
            centre[2] + arm + 4.0 * radius,
        ];
        if scene.alone_in(Some(body), lo, hi) {
            return [1.0; 4];
        }
        let r = quat_matrix(self.q);
        std::array::from_fn(|i| {
            let (x, y, _) = self.rotors[i];
            let hub: V3 = std::array::from_fn(|k| centre[k] + r[k][0] * x + r[k][1] * y);
            match scene.cast_ray(hub, [0.0, 0.0, 1.0], 4.0 * radius, Some(body)) {
                Some(z) => {
                    let k = radius / (4.0 * z.max(radius / 2.0));
                    1.0 / (1.0 - k * k)
                }
                None => 1.0,
            }
        })
    }

    /// Thrust (N) and body torque of the current rotor speeds.
    fn wrench(&self) -> (f64, V3) {
        let (kf, km) = (
            self.config.thrust_coefficient,
            self.config.torque_coefficient,
        );
        let mut thrust = 0.0;
        let mut torque = [0.0; 3];
        for (i, &(x, y, spin)) in self.rotors.iter().enumerate() {
            let w2 = self.speeds[i] * self.speeds[i];
            let t = kf * w2 * self.ground[i];
            thrust += t;
            // r × (0, 0, -t) = (-y·t, x·t, 0); the reaction torque turns the body against
            // the rotor's spin.
            torque[0] -= y * t;
            torque[1] += x * t;
            torque[2] += spin * km * w2;
        }
        (thrust, torque)
    }
}

impl Dynamics for Quadrotor {
    fn drive(&mut self, set: &SetPoints) {
        if !matches!(self.mode, Mode::Off | Mode::Land) {
            if !matches!(self.mode, Mode::Velocity(_)) {
                self.integral = [0.0; 3];
                self.hold_z = None;
            }
            self.mode = Mode::Velocity(*set);
        }
    }

    fn low_level(&mut self, command: LowLevel) {
        if matches!(self.mode, Mode::Off | Mode::Land) {
            return;
        }
        self.mode = match command {
            LowLevel::Attitude {
                roll,
                pitch,
                yaw_rate,
                thrust,
            } => Mode::Attitude {
                roll,
                pitch,
                yaw_rate,
                thrust,
            },
            LowLevel::Rates { rates, thrust } => Mode::Rates { rates, thrust },
            LowLevel::Rotors(w) => Mode::Rotors(w),
        };
    }

    fn integrate(
        &mut self,
        scene: &super::scene::Scene,
        body: rapier3d::prelude::ColliderHandle,
        start: V3,
        v0: V3,
        dt: f64,
    ) {
        self.planned = Some(self.plan(scene, body, start, v0, dt));
    }

    fn step(&mut self, f: Flight<'_>) -> Option<Crash> {
        let dt = f.dt;
        let start = *f.position;
        let v0 = *f.velocity;
        let planned = match self.planned.take() {
            Some(plan) if plan.start == start && plan.v0 == v0 => plan,
            _ => self.plan(f.scene, f.body, start, v0, dt),
        };
        let (p, mut v) = (planned.p, planned.v);
        let finite = p.iter().chain(&v).chain(&self.rates).all(|x| x.is_finite())
            && self.q.iter().all(|x| x.is_finite());
        if !finite {
            // Parameters the explicit integration cannot follow (absurd gains or drag): stop
            // the robot where it was instead of putting NaN on the wire.
            if !std::mem::replace(&mut self.diverged, true) {
                tracing::warn!(
                    "quadrotor integration diverged: check its [robot.quadrotor] parameters"
                );
            }
            self.q = euler_quat([0.0, 0.0, f.rotation[2]]);
            self.rates = [0.0; 3];
            self.speeds = [0.0; 4];
            self.mode = Mode::Off;
            *f.velocity = [0.0; 3];
            return Some(Crash {
                speed: 0.0,
                tilt: 0.0,
                reason: "the integration diverged (check the quadrotor parameters)".into(),
            });
        }
        let motion = sub(p, start);
        let (moved, mut hit) = f.scene.sweep_contact(f.body, f.shape, start, motion);
        if let Some(n) = self
            .surface
            .filter(|&n| hit.is_none() && dot(motion, n) <= 0.0)
        {
            // Resting on a surface and not leaving it: still held if it is still there
            // (a ray along −n from the centre; off an edge the body falls).
            let reach = n[2].abs() * f.shape.half_height
                + (1.0 - n[2] * n[2]).max(0.0).sqrt() * f.shape.radius
                + PROBE;
            if f.scene
                .cast_ray(moved, n.map(|x| -x), reach, Some(f.body))
                .is_some()
            {
                hit = Some(n);
            }
        }
        *f.position = moved;
        let r = quat_matrix(self.q);
        self.contact = hit.is_some();
        self.surface = hit;
        if self.mode == Mode::Land && hit.is_some_and(|n| n[2] < -0.7) {
            self.mode = Mode::Off; // landed: the autopilot stops the motors
        }
        let mut crash = None;
        if let Some(normal) = hit {
            let speed = (-dot(v, normal)).max(0.0);
            let tilt = r[2][2].clamp(-1.0, 1.0).acos();
            v = self.impact(v, normal);
            if self.mode != Mode::Off
                && (speed > self.limits.crash_speed || tilt > self.limits.crash_tilt)
            {
                crash = Some(Crash {
                    speed,
                    tilt,
                    reason: if speed > self.limits.crash_speed {
                        format!(
                            "hit an obstacle at {speed:.2} m/s (crash speed {:.2} m/s)",
                            self.limits.crash_speed
                        )
                    } else {
                        format!(
                            "touched an obstacle tilted {:.0}° (crash tilt {:.0}°)",
                            tilt.to_degrees(),
                            self.limits.crash_tilt.to_degrees()
                        )
                    },
                });
            }
        }
        // The accelerometer: what moved the body (contacts included), minus gravity.
        let accel: V3 = std::array::from_fn(|i| (v[i] - v0[i]) / dt);
        self.imu = ImuTruth {
            specific_force: mul_t(&r, sub(accel, [0.0, 0.0, GRAVITY])),
            body_rates: self.rates,
        };
        *f.velocity = v;
        let euler = super::dynamics::matrix_to_euler(&r);
        let yaw = f.rotation[2] + wrap_angle(euler[2] - f.rotation[2]);
        *f.rotation = [euler[0], euler[1], yaw];
        crash
    }

    fn imu(&self) -> ImuTruth {
        self.imu
    }

    fn attitude(&self) -> M3 {
        quat_matrix(self.q)
    }

    fn contact(&self) -> bool {
        self.contact
    }

    fn crash(&mut self) {
        self.mode = Mode::Off;
    }

    fn gauge(&self) -> Option<Gauge> {
        self.battery.as_ref().map(Battery::gauge)
    }

    fn rotor_speeds(&self) -> Option<[f64; 4]> {
        Some(self.speeds)
    }

    fn recharge(&mut self) {
        if let Some(battery) = &mut self.battery {
            let emptied = battery.empty() && matches!(self.mode, Mode::Off);
            *battery = Battery::new(self.config.battery.clone());
            self.top_speed = self.config.rotor_speed_max * battery.voltage_ratio();
            if emptied || matches!(self.mode, Mode::Land) {
                self.mode = Mode::Level;
            }
        }
    }

    fn set_payload(&mut self, kg: f64) -> bool {
        self.payload = if kg.is_finite() {
            kg.clamp(0.0, 1000.0)
        } else {
            0.0
        };
        true
    }

    fn fault(&mut self, fault: &super::dynamics::Fault) -> bool {
        match *fault {
            super::dynamics::Fault::Motor { rotor, thrust } => {
                self.health[rotor] = thrust;
                true
            }
            super::dynamics::Fault::Battery { loss } => match &mut self.battery {
                Some(battery) => {
                    battery.lose(loss);
                    true
                }
                None => false,
            },
            super::dynamics::Fault::Sensor { .. } | super::dynamics::Fault::Radio { .. } => false,
        }
    }
}
