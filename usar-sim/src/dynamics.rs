//! Flight models behind one trait. A robot class picks one in the catalog
//! (`dynamics = "kinematic" | "quadrotor"`, docs/robots.md):
//!
//! * kinematic (the default, `Robot::fly`): UDK's AerialVehicle, velocities imposed, no mass,
//!   no wind — byte-compatible with USARSim, so it has no [`Dynamics`] object;
//! * [`super::quadrotor::Quadrotor`]: a rigid body with four rotors, motors, drag, wind and an
//!   onboard cascaded controller.
//!
//! Everything here is synchronous and deterministic: the same seed and commands give the same
//! bits.

use rapier3d::prelude::ColliderHandle;
use usar_proto::Message;

use super::scene::{BodyShape, Scene, V3};

/// A rotation matrix (rows), body → world.
pub(crate) type M3 = [[f64; 3]; 3];

/// Standard gravity, m/s² (+z is down in the protocol frame).
pub(crate) const GRAVITY: f64 = 9.806_65;

/// The DRIVE set-points (sticky), already scaled to SI units.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub(crate) struct SetPoints {
    /// m/s forward, right, up.
    pub(crate) linear: f64,
    pub(crate) lateral: f64,
    pub(crate) altitude: f64,
    /// rad/s, + = clockwise from above.
    pub(crate) yaw_rate: f64,
    /// rad (the kinematic model's visual tilt; the quadrotor's controller ignores them).
    pub(crate) pitch: f64,
    pub(crate) roll: f64,
}

/// A command of the `QUAD` protocol extension (docs/quadrotor.md): below the velocity
/// controller that DRIVE commands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum LowLevel {
    /// Attitude (roll, pitch in rad), yaw rate (rad/s) and collective thrust (N).
    Attitude {
        /// rad, + = right side down.
        roll: f64,
        /// rad, + = nose up.
        pitch: f64,
        /// rad/s, + = clockwise from above.
        yaw_rate: f64,
        /// N, the sum of the four rotors' thrusts.
        thrust: f64,
    },
    /// Body rates (rad/s: roll, pitch, yaw, about the body's axes) and collective thrust
    /// (N): the controller's rate loop and mixer, no attitude loop.
    Rates {
        /// rad/s, [roll (+ = right side down), pitch (+ = nose up), yaw (+ = clockwise
        /// from above)].
        rates: [f64; 3],
        /// N, the sum of the four rotors' thrusts.
        thrust: f64,
    },
    /// The four rotor speeds, rad/s, in rotor order (docs/quadrotor.md).
    Rotors([f64; 4]),
}

/// Parses `QUAD {Attitude r,p,y} {Thrust t}`, `QUAD {Rates p,q,r} {Thrust t}` or
/// `QUAD {Rotors w1,w2,w3,w4}`; the error says what is wrong.
pub(crate) fn parse_quad(message: &Message) -> Result<LowLevel, String> {
    let numbers = |key: &str, n: usize| -> Result<Vec<f64>, String> {
        let text = message.get(key).unwrap_or_default();
        let values: Vec<f64> = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<_>>()
            .ok_or_else(|| format!("{{{key} {text}}}: expected {n} finite numbers"))?;
        if values.len() == n {
            Ok(values)
        } else {
            Err(format!(
                "{{{key} {text}}}: expected {n} numbers, got {}",
                values.len()
            ))
        }
    };
    if message.get("Rotors").is_some() {
        let w = numbers("Rotors", 4)?;
        return Ok(LowLevel::Rotors([w[0], w[1], w[2], w[3]]));
    }
    let thrust = |key: &str| {
        numbers("Thrust", 1).map(|t| t[0]).map_err(|e| {
            if message.get("Thrust").is_none() {
                format!("{{{key} ..}} needs {{Thrust <newtons>}}")
            } else {
                e
            }
        })
    };
    if message.get("Attitude").is_some() {
        let a = numbers("Attitude", 3)?;
        return Ok(LowLevel::Attitude {
            roll: a[0],
            pitch: a[1],
            yaw_rate: a[2],
            thrust: thrust("Attitude")?,
        });
    }
    if message.get("Rates").is_some() {
        let r = numbers("Rates", 3)?;
        return Ok(LowLevel::Rates {
            rates: [r[0], r[1], r[2]],
            thrust: thrust("Rates")?,
        });
    }
    Err(
        "QUAD needs {Attitude roll,pitch,yawrate} {Thrust t}, {Rates p,q,r} {Thrust t} or \
         {Rotors w1,w2,w3,w4}"
            .into(),
    )
}

/// A fault of the `FAULT` protocol extension (docs/quadrotor.md#faults).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Fault {
    /// Rotor `rotor` (0-based) gives `thrust` (0 = failed, 1 = healthy) of its thrust and
    /// drag torque.
    Motor { rotor: usize, thrust: f64 },
    /// The battery loses this fraction of the charge it has.
    Battery { loss: f64 },
    /// Part `name` goes silent, freezes, drifts, adds noise or a bias, or works again; for
    /// `duration` seconds when given (then it works again).
    Sensor {
        name: String,
        mode: SensorFault,
        duration: Option<f64>,
    },
    /// The robot's radio goes off (the WSS sees it out of range) or on again; off for
    /// `duration` seconds when given.
    Radio { on: bool, duration: Option<f64> },
}

/// What a sensor fault does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum SensorFault {
    /// Working.
    Ok,
    /// No lines.
    Silent,
    /// The reading at the fault repeats.
    Freeze,
    /// `rate · (t − t₀)` added to every number of the reading (unit per second).
    Drift(f64),
    /// A constant added to every number of the reading.
    Bias(f64),
    /// Gaussian noise of this standard deviation added to every number of the reading.
    Noise(f64),
}

/// Parses `FAULT {Motor i} {Thrust f}`, `FAULT {Battery f}`, `FAULT {Sensor name}
/// {Mode Silent|Freeze|Drift|Bias|Noise|Ok} [{Rate r}|{Value b}|{Std s}] [{Duration d}]` or
/// `FAULT {Radio Off|On} [{Duration d}]`; the error says what is wrong.
pub(crate) fn parse_fault(message: &Message) -> Result<Fault, String> {
    let number = |key: &str| -> Result<f64, String> {
        let text = message.get(key).unwrap_or_default();
        text.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{{{key} {text}}}: expected a finite number"))
    };
    let fraction = |key: &str| -> Result<f64, String> {
        let v = number(key)?;
        if (0.0..=1.0).contains(&v) {
            Ok(v)
        } else {
            Err(format!("{{{key} {v}}}: expected a fraction within [0, 1]"))
        }
    };
    // Sizes of drift, bias and noise: at most a million units (no infinity on the wire).
    let size = |key: &str| -> Result<f64, String> {
        let v = number(key)?;
        if v.abs() <= 1e6 {
            Ok(v)
        } else {
            Err(format!("{{{key} {v}}}: expected at most 1e6 in size"))
        }
    };
    let duration = || -> Result<Option<f64>, String> {
        if message.get("Duration").is_none() {
            return Ok(None);
        }
        let d = number("Duration")?;
        if d > 0.0 {
            Ok(Some(d))
        } else {
            Err(format!("{{Duration {d}}}: expected seconds > 0"))
        }
    };
    if message.get("Motor").is_some() {
        let rotor = number("Motor")?;
        if !(rotor.fract() == 0.0 && (1.0..=4.0).contains(&rotor)) {
            return Err(format!("{{Motor {rotor}}}: expected a rotor number 1 to 4"));
        }
        let thrust = if message.get("Thrust").is_some() {
            fraction("Thrust")?
        } else {
            0.0
        };
        return Ok(Fault::Motor {
            rotor: rotor as usize - 1,
            thrust,
        });
    }
    if message.get("Battery").is_some() {
        return Ok(Fault::Battery {
            loss: fraction("Battery")?,
        });
    }
    if let Some(name) = message.get("Sensor") {
        let mode = match message.get("Mode").unwrap_or_default().trim() {
            m if m.eq_ignore_ascii_case("silent") => SensorFault::Silent,
            m if m.eq_ignore_ascii_case("freeze") => SensorFault::Freeze,
            m if m.eq_ignore_ascii_case("ok") => SensorFault::Ok,
            m if m.eq_ignore_ascii_case("drift") => SensorFault::Drift(size("Rate")?),
            m if m.eq_ignore_ascii_case("bias") => SensorFault::Bias(size("Value")?),
            m if m.eq_ignore_ascii_case("noise") => {
                let std = size("Std")?;
                if std < 0.0 {
                    return Err(format!("{{Std {std}}}: expected a standard deviation >= 0"));
                }
                SensorFault::Noise(std)
            }
            m => {
                return Err(format!(
                    "{{Mode {m}}}: expected Silent, Freeze, Drift, Bias, Noise or Ok"
                ));
            }
        };
        return Ok(Fault::Sensor {
            name: name.trim().to_string(),
            mode,
            duration: duration()?,
        });
    }
    if let Some(state) = message.get("Radio") {
        let on = match state.trim() {
            s if s.eq_ignore_ascii_case("off") => false,
            s if s.eq_ignore_ascii_case("on") => true,
            s => return Err(format!("{{Radio {s}}}: expected Off or On")),
        };
        return Ok(Fault::Radio {
            on,
            duration: duration()?,
        });
    }
    Err(
        "FAULT needs {Motor i} [{Thrust f}], {Battery f}, {Sensor name} {Mode m} or {Radio Off|On}"
            .into(),
    )
}

/// What a flight model moves in one tick.
pub(crate) struct Flight<'a> {
    pub(crate) scene: &'a mut Scene,
    pub(crate) body: ColliderHandle,
    pub(crate) shape: BodyShape,
    /// Centre, world frame, m.
    pub(crate) position: &'a mut V3,
    /// World frame, m/s.
    pub(crate) velocity: &'a mut V3,
    /// Roll, pitch, yaw (rad; yaw not wrapped).
    pub(crate) rotation: &'a mut V3,
    /// Seconds.
    pub(crate) dt: f64,
}

/// Why a robot crashed.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Crash {
    /// Speed into the surface at the contact, m/s.
    pub(crate) speed: f64,
    /// Tilt (angle between body and world vertical) at the contact, rad.
    pub(crate) tilt: f64,
    /// A sentence for the log.
    pub(crate) reason: String,
}

/// What the IMU of a dynamic model measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ImuTruth {
    /// Specific force (what an accelerometer measures: acceleration minus gravity), body
    /// frame x forward, y right, z down, m/s²; hovering reads (0, 0, -g).
    pub(crate) specific_force: V3,
    /// Body rates about x forward, y right, z down, rad/s.
    pub(crate) body_rates: V3,
}

/// A flight model with physics.
pub(crate) trait Dynamics: std::fmt::Debug + Send {
    /// The DRIVE set-points changed (the onboard velocity controller takes over).
    fn drive(&mut self, set: &SetPoints);
    /// A `QUAD` command.
    fn low_level(&mut self, command: LowLevel);
    /// The part of the next tick that only reads the scene (the integration before
    /// contacts), from `start` at velocity `v0`, done ahead on a sensor thread for every
    /// robot before the moves; [`Dynamics::step`] then uses it (or does it itself when it
    /// was not done, or was done from elsewhere). The default does nothing.
    fn integrate(
        &mut self,
        scene: &super::scene::Scene,
        body: rapier3d::prelude::ColliderHandle,
        start: V3,
        v0: V3,
        dt: f64,
    ) {
        let _ = (scene, body, start, v0, dt);
    }
    /// One tick; `Some` when the robot crashed during it.
    fn step(&mut self, flight: Flight<'_>) -> Option<Crash>;
    /// The IMU's truth of the last tick.
    fn imu(&self) -> ImuTruth;
    /// Body → world rotation.
    fn attitude(&self) -> M3;
    /// Whether the body touched something in the last tick.
    fn contact(&self) -> bool;
    /// Stops the motors for good (after a crash).
    fn crash(&mut self);
    /// The battery's state, for a model with an energy model (`None`: the class's battery
    /// is USARSim's timer).
    fn gauge(&self) -> Option<super::power::Gauge> {
        None
    }
    /// Rotor speeds, rad/s, in rotor order.
    fn rotor_speeds(&self) -> Option<[f64; 4]> {
        None
    }
    /// A motor or battery fault; `false` when the model has no such part.
    fn fault(&mut self, fault: &Fault) -> bool {
        let _ = fault;
        false
    }
    /// Fills the battery of the energy model (landed on a charging pad).
    fn recharge(&mut self) {}
    /// Sets the mass carried besides the body, kg; `false` when the model has no mass.
    fn set_payload(&mut self, kg: f64) -> bool {
        let _ = kg;
        false
    }
}

// ---- small vector/matrix helpers (f64, row-major) ----

pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// `m · v`.
pub(crate) fn mul(m: &M3, v: V3) -> V3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// `mᵀ · v`.
pub(crate) fn mul_t(m: &M3, v: V3) -> V3 {
    std::array::from_fn(|i| m[0][i] * v[0] + m[1][i] * v[1] + m[2][i] * v[2])
}

/// `a · b`.
pub(crate) fn mat_mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// `aᵀ`.
pub(crate) fn transpose(a: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

/// The rotation of roll, pitch, yaw (Z-Y-X Tait–Bryan, protocol frame): body → world.
pub(crate) fn euler_to_matrix(r: V3) -> M3 {
    let (sr, cr) = r[0].sin_cos();
    let (sp, cp) = r[1].sin_cos();
    let (sy, cy) = r[2].sin_cos();
    [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
}

/// Roll, pitch, yaw of a rotation (yaw in (-π, π]).
pub(crate) fn matrix_to_euler(m: &M3) -> V3 {
    let pitch = (-m[2][0]).clamp(-1.0, 1.0).asin();
    [m[2][1].atan2(m[2][2]), pitch, m[1][0].atan2(m[0][0])]
}

/// The rotation of a yaw alone.
pub(crate) fn yaw_matrix(yaw: f64) -> M3 {
    euler_to_matrix([0.0, 0.0, yaw])
}

/// `a` wrapped to [-π, π].
pub(crate) fn wrap_angle(a: f64) -> f64 {
    // `rem_euclid` without its software `fmod` where the remainder is `a` itself (the
    // difference of two angles of one turn, an IMU's at every reading).
    let d = if a.abs() < std::f64::consts::TAU {
        if a < 0.0 {
            a + std::f64::consts::TAU
        } else {
            a
        }
    } else {
        a.rem_euclid(std::f64::consts::TAU)
    };
    if d > std::f64::consts::PI {
        d - std::f64::consts::TAU
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_round_trip_and_frame() {
        let r = [0.3, -0.2, 2.5];
        let back = matrix_to_euler(&euler_to_matrix(r));
        for i in 0..3 {
            assert!((back[i] - r[i]).abs() < 1e-12, "{back:?}");
        }
        // Nose down (negative pitch): the body's forward axis points below the horizon (+z).
        let m = euler_to_matrix([0.0, -0.3, 0.0]);
        assert!(mul(&m, [1.0, 0.0, 0.0])[2] > 0.0);
        // Right side down (positive roll): the body's right axis points down.
        let m = euler_to_matrix([0.3, 0.0, 0.0]);
        assert!(mul(&m, [0.0, 1.0, 0.0])[2] > 0.0);
    }

    #[test]
    fn quad_commands_parse_with_clear_errors() {
        let parse = |line: &str| {
            let usar_proto::Command::Other(m) = usar_proto::Command::parse(line).unwrap().message
            else {
                panic!("not an unknown command")
            };
            parse_quad(&m)
        };
        assert_eq!(
            parse("QUAD {Rotors 1,2,3,4}"),
            Ok(LowLevel::Rotors([1.0, 2.0, 3.0, 4.0]))
        );
        assert_eq!(
            parse("QUAD {Attitude 0.1,-0.2,0} {Thrust 12.5}"),
            Ok(LowLevel::Attitude {
                roll: 0.1,
                pitch: -0.2,
                yaw_rate: 0.0,
                thrust: 12.5
            })
        );
        assert!(
            parse("QUAD {Rotors 1,2,3}")
                .unwrap_err()
                .contains("4 numbers")
        );
        assert!(
            parse("QUAD {Rotors 1,2,x,4}")
                .unwrap_err()
                .contains("finite")
        );
        assert!(
            parse("QUAD {Attitude 0,0,0}")
                .unwrap_err()
                .contains("Thrust")
        );
        assert_eq!(
            parse("QUAD {Rates 0.1 -0.2 0.3} {Thrust 12}"),
            Ok(LowLevel::Rates {
                rates: [0.1, -0.2, 0.3],
                thrust: 12.0
            })
        );
        assert!(parse("QUAD {Rates 0,0,0}").unwrap_err().contains("Thrust"));
        assert!(
            parse("QUAD {Rates 0,0} {Thrust 1}")
                .unwrap_err()
                .contains("3 numbers")
        );
        assert!(parse("QUAD {Rotors 1,2,NaN,4}").is_err());
        assert!(parse("QUAD {Foo 1}").unwrap_err().contains("Rotors"));
    }
}
