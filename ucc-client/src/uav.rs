//! The UAV model: the latest value of every reading, updated from typed server messages.
//!
//! [`UavState::apply`] consumes one [`ServerMessage`] and tells whether new sensor data
//! arrived. It works with the `stsAirRobot` (Position, Velocity, IMU, sonars, laser) and with
//! a stock `AirRobot`: position then comes from GroundTruth or INS, orientation from the IMU,
//! GroundTruth or INS, and velocity is derived from successive positions when no sensor gives
//! it. When several sensors give the same quantity, the best one wins (Position over
//! GroundTruth over INS; GroundTruth over IMU over INS for the orientation).

use std::collections::BTreeMap;
use std::sync::Arc;

use usar_proto::{NamedRange, Scan, SenData, ServerMessage};

use crate::camera::CameraImage;
use crate::radio::{Message, Undelivered};

use crate::geometry::{Coordinates, Num, body_to_world_vector, from_wire, world_to_body_vector};

/// Number of horizontal sonars of the stsAirRobot (`Sonar0` … `Sonar7`).
pub const HORIZONTAL_SONARS: usize = 8;

/// A value and the simulated time it was measured at.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading<T> {
    /// The value.
    pub value: T,
    /// Simulated seconds (the server's `{Time}`).
    pub time: f64,
}

/// The battery as the STA message reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Battery {
    /// Remaining seconds as reported (99999 for a robot without a battery part).
    pub remaining: i64,
    /// `remaining` as a fraction of the first value seen (1.0 = full), as the original
    /// control program computed it.
    pub level: f64,
}

/// A laser scan.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserScan {
    /// Metres; index 0 is the rightmost beam.
    pub ranges: Vec<f64>,
    /// Radians between two beams.
    pub resolution: f64,
    /// Radians, the whole field of view.
    pub fov: f64,
}

/// A beam reading at least this fraction of the scan's farthest reading counts as no return:
/// a beam that hits nothing reads the maximum range, which the sensor's noise blurs by a
/// fraction of a percent, so a bare `== max` would draw the noise as walls.
pub const NO_RETURN_FRACTION: f64 = 0.99;

impl LaserScan {
    /// The bearing of beam `index` in the body frame: radians, + = right (clockwise), 0 ahead.
    pub fn bearing(&self, index: usize) -> f64 {
        self.fov / 2.0 - index as f64 * self.resolution
    }

    /// The beams that hit something, as (beam index, the hit point in the world frame) for a
    /// scan taken at `position` with heading `yaw` (the laser level, as the stsAirRobot's).
    /// Beams at [`NO_RETURN_FRACTION`] of the farthest reading or beyond, and readings that
    /// are not positive finite numbers, are no hits. The one rule for the map picture and
    /// the browser's live view.
    pub fn hits<'a>(
        &'a self,
        position: &'a Coordinates,
        yaw: f64,
    ) -> impl Iterator<Item = (usize, Coordinates)> + 'a {
        let max = self.ranges.iter().copied().fold(0.0, f64::max);
        let heading = Coordinates::new(0.0, 0.0, yaw);
        self.ranges
            .iter()
            .enumerate()
            .filter(move |&(_, &range)| {
                range.is_finite() && range > 0.0 && range < max * NO_RETURN_FRACTION
            })
            .map(move |(i, &range)| {
                let bearing = self.bearing(i);
                let beam = Coordinates::new(bearing.cos(), bearing.sin(), 0.0) * range;
                (i, position + body_to_world_vector(&beam, &heading))
            })
    }
}

/// A victim's body part a VictSensor saw.
#[derive(Debug, Clone, PartialEq)]
pub struct VictimSighting {
    /// `Head`, `Arm`, `Hand`, `Chest`, `Pelvis`, `Leg` or `Foot`.
    pub part: String,
    /// Metres, relative to the sensor: x forward, y right, z down.
    pub location: Coordinates,
}

/// Which sensor a position or orientation came from, best last.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Source {
    /// Dead reckoning: the commanded velocities integrated with the reported heading.
    DeadReckoning,
    /// Velocity integrated or derived.
    Derived,
    /// An INS (drifts, 2 decimals).
    Ins,
    /// The IMU's `Rotation` (orientation only).
    Imu,
    /// A GroundTruth sensor.
    GroundTruth,
    /// The stsAirRobot's Position or Velocity sensor.
    Sts,
}

/// Everything known about the UAV.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UavState {
    /// Latest simulated time seen in any message.
    pub time: Option<f64>,
    /// World frame, metres, z down.
    pub position: Option<Reading<Coordinates>>,
    /// Roll, pitch, yaw in radians.
    pub orientation: Option<Reading<Coordinates>>,
    /// World-frame velocity, m/s.
    pub velocity: Option<Reading<Coordinates>>,
    /// Body-frame velocity (x forward, y right, z down), m/s.
    pub relative_velocity: Option<Reading<Coordinates>>,
    /// IMU linear acceleration, m/s², body frame, z up: gravity excluded on USARSim's IMU;
    /// the specific force (gravity included, hovering reads +9.81 on z) on robots with physics
    /// such as the stsQuadrotor.
    pub acceleration: Option<Reading<Coordinates>>,
    /// IMU angular velocity (roll, pitch, yaw rates), rad/s.
    pub angular_velocity: Option<Reading<Coordinates>>,
    /// IMU angular acceleration, rad/s².
    pub angular_acceleration: Option<Reading<Coordinates>>,
    /// Battery.
    pub battery: Option<Reading<Battery>>,
    /// The laser scan.
    pub laser: Option<Reading<LaserScan>>,
    /// Horizontal sonars: index 0 forward, each next 45° clockwise (2 right, 4 back, 6 left).
    pub sonars: [Option<Reading<f64>>; HORIZONTAL_SONARS],
    /// Free space above (SonarTop), metres.
    pub free_above: Option<Reading<f64>>,
    /// Free space below (SonarBottom), metres.
    pub free_below: Option<Reading<f64>>,
    /// Why the UAV crashed, once its crash sensor (a `Touch` part named `Crash`, as the
    /// stsQuadrotor has) reads `True`; the reason says what was known then.
    pub crash: Option<Reading<String>>,
    /// Height above the spawn point (an AltitudeSensor's `relativeAltitude`), metres, + = up.
    pub altitude: Option<Reading<f64>>,
    /// The speed command in force and when it was sent (for dead reckoning).
    pub command: Option<Reading<crate::speed::SpeedCommand>>,
    /// What the latest VictSensor reading saw: victims' body parts (empty: no victims in
    /// view).
    pub victims: Option<Reading<Vec<VictimSighting>>>,
    /// The faults the server applied on its own (`usar-server --faults`): each
    /// `FAULT {Time t} {Robot n} ..` line's fault, as `Motor 1 Thrust 0`, in order.
    pub faults: Vec<Reading<String>>,
    /// The parameters the server drew for this robot (`--randomize`, a `RANDOMIZED` line),
    /// as `mass 1.3021 kf 1.02 ..`.
    pub randomized: Option<Reading<String>>,
    /// The latest frame of the UAV's camera (its tile of the image server's frame), when
    /// the run asks for frames ([`RunSettings::camera`](crate::RunSettings::camera));
    /// shared, not copied, from step to step. The image server sends no time stamp: the
    /// reading's time is the simulated time known when the frame arrived.
    pub image: Option<Reading<Arc<CameraImage>>>,
    /// Radio messages received since the previous step, oldest first (with
    /// [`RunSettings::radio`](crate::RunSettings::radio)).
    pub inbox: Vec<Message>,
    /// Messages of the previous step's [`Step::send`](crate::Step::send) that did not get
    /// through (out of range, behind walls, no such UAV).
    pub undelivered: Vec<Undelivered>,
    /// The radio signal to other UAVs (by name), dBm, as the WSS last reported it: the
    /// peers of [`RadioSettings`](crate::settings::RadioSettings), and every UAV this one
    /// sent to or heard from. NaN: not known yet; below [`CUTOFF`](crate::radio::CUTOFF):
    /// out of range.
    pub signal: BTreeMap<String, f64>,
    /// The z of the dead-reckoning origin (the spawn point).
    reckoning_origin_z: Option<f64>,
    /// The battery value taken as "full".
    first_battery: Option<i64>,
    /// The velocity reading before the latest one (a crash report gives the speed before
    /// the impact, not after it).
    earlier_velocity: Option<Reading<Coordinates>>,
    position_source: Option<Source>,
    orientation_source: Option<Source>,
    velocity_source: Option<Source>,
}

impl UavState {
    /// An empty state.
    pub fn new() -> Self {
        Self::default()
    }

    /// The yaw in radians (0 when unknown).
    pub fn yaw(&self) -> f64 {
        self.orientation.as_ref().map_or(0.0, |o| o.value.z)
    }

    /// Whether the UAV has reported a crash.
    pub fn crashed(&self) -> bool {
        self.crash.is_some()
    }

    /// Whether the battery is known to be empty.
    pub fn battery_empty(&self) -> bool {
        self.battery
            .as_ref()
            .is_some_and(|b| b.value.remaining <= 0)
    }

    /// Updates the state from one message. Returns `true` when it carried sensor data (a SEN
    /// line this model uses), which is when an agent should step.
    pub fn apply(&mut self, message: &ServerMessage) -> bool {
        match message {
            ServerMessage::Sta(sta) => {
                let time = self.stamp(Some(sta.time.seconds));
                let first = *self.first_battery.get_or_insert(sta.battery);
                let level = if first > 0 {
                    sta.battery as f64 / first as f64
                } else {
                    0.0
                };
                self.battery = Some(Reading {
                    value: Battery {
                        remaining: sta.battery,
                        level,
                    },
                    time,
                });
                false
            }
            ServerMessage::Sen(sen) => {
                let time = self.stamp(sen.time.map(|t| t.seconds));
                self.apply_sensor(&sen.data, time)
            }
            // usar-server's notices (docs/quadrotor.md#faults, #domain-randomisation).
            ServerMessage::Other(m)
                if m.kind.eq_ignore_ascii_case("FAULT")
                    || m.kind.eq_ignore_ascii_case("RANDOMIZED") =>
            {
                let time = self.stamp(m.get("Time").and_then(|t| t.trim().parse().ok()));
                let value = m
                    .groups
                    .iter()
                    .flat_map(|g| &g.pairs)
                    .filter(|p| {
                        !p.key.eq_ignore_ascii_case("Time") && !p.key.eq_ignore_ascii_case("Robot")
                    })
                    .map(|p| format!("{} {}", p.key, p.value))
                    .collect::<Vec<_>>()
                    .join(" ");
                let reading = Reading { value, time };
                if m.kind.eq_ignore_ascii_case("FAULT") {
                    self.faults.push(reading);
                } else {
                    self.randomized = Some(reading);
                }
                false
            }
            _ => false,
        }
    }

    /// Records a time stamp, or takes the latest known time for lines without one (INS).
    fn stamp(&mut self, time: Option<f64>) -> f64 {
        match time {
            Some(t) => {
                self.time = Some(self.time.map_or(t, |old| old.max(t)));
                t
            }
            None => self.time.unwrap_or(0.0),
        }
    }

    fn apply_sensor(&mut self, data: &SenData, time: f64) -> bool {
        match data {
            SenData::Position { location, .. } => {
                self.set_position(from_wire(*location), Source::Sts, time)
            }
            SenData::GroundTruth {
                location,
                orientation,
                ..
            } => {
                self.set_orientation(from_wire(*orientation), Source::GroundTruth, time);
                self.set_position(from_wire(*location), Source::GroundTruth, time);
            }
            SenData::Ins {
                location,
                orientation,
                ..
            } => {
                self.set_orientation(from_wire(*orientation), Source::Ins, time);
                self.set_position(from_wire(*location), Source::Ins, time);
            }
            SenData::Velocity {
                absolute, relative, ..
            } => {
                self.velocity_source = Some(Source::Sts);
                let earlier = self.velocity.replace(Reading {
                    value: from_wire(*absolute),
                    time,
                });
                if earlier.as_ref().is_some_and(|e| e.time < time) {
                    self.earlier_velocity = earlier;
                }
                self.relative_velocity = Some(Reading {
                    value: from_wire(*relative),
                    time,
                });
            }
            SenData::Imu {
                acceleration,
                angular_vel,
                angular_accel,
                rotation,
                ..
            } => {
                let reading = |v| {
                    Some(Reading {
                        value: from_wire(v),
                        time,
                    })
                };
                self.acceleration = reading(*acceleration);
                self.angular_velocity = reading(*angular_vel);
                self.angular_acceleration = reading(*angular_accel);
                self.set_orientation(from_wire(*rotation), Source::Imu, time);
            }
            SenData::AltitudeSensor { relative, .. } => {
                self.altitude = Some(Reading {
                    value: *relative,
                    time,
                });
            }
            SenData::Sonar { readings, .. } => {
                for r in readings {
                    self.set_sonar(r, time);
                }
            }
            SenData::Touch { name, touch } => {
                if *touch && name.eq_ignore_ascii_case("Crash") && self.crash.is_none() {
                    self.crash = Some(Reading {
                        value: self.crash_reason(name),
                        time,
                    });
                }
                return false;
            }
            SenData::VictSensor { parts, .. } => {
                self.victims = Some(Reading {
                    value: parts
                        .iter()
                        .map(|p| VictimSighting {
                            part: p.part.clone(),
                            location: Coordinates::new(p.location.x, p.location.y, p.location.z),
                        })
                        .collect(),
                    time,
                });
            }
            SenData::RangeScanner(Scan {
                ranges,
                resolution,
                fov,
                ..
            }) => {
                self.laser = Some(Reading {
                    value: LaserScan {
                        ranges: ranges.clone(),
                        resolution: *resolution,
                        fov: *fov,
                    },
                    time,
                });
            }
            _ => return false,
        }
        true
    }

    /// What the state knew when the crash sensor fired: the last speed and tilt.
    fn crash_reason(&self, sensor: &str) -> String {
        let mut reason = format!("crash sensor {sensor} fired");
        // The fastest of the last two readings: the one of the crash tick may be after the
        // impact.
        let speed = [&self.earlier_velocity, &self.velocity]
            .into_iter()
            .flatten()
            .map(|v| v.value.norm())
            .reduce(f64::max);
        if let Some(speed) = speed {
            reason.push_str(&format!(", speed before impact {} m/s", Num(speed, 2)));
        }
        if let Some(o) = &self.orientation {
            let tilt = (o.value.x.cos() * o.value.y.cos()).clamp(-1.0, 1.0).acos();
            reason.push_str(&format!(", tilt {:.0}°", tilt.to_degrees()));
        }
        if let Some(p) = &self.position {
            let p = p.value;
            reason.push_str(&format!(
                " at ({}, {}, {})",
                Num(p.x, 2),
                Num(p.y, 2),
                Num(p.z, 2)
            ));
        }
        reason
    }

    fn set_sonar(&mut self, reading: &NamedRange, time: f64) {
        let value = Some(Reading {
            value: reading.range,
            time,
        });
        match reading.name.as_str() {
            "SonarTop" => self.free_above = value,
            "SonarBottom" => self.free_below = value,
            name => {
                let index = name
                    .strip_prefix("Sonar")
                    .and_then(|i| i.parse::<usize>().ok())
                    .filter(|i| *i < HORIZONTAL_SONARS);
                match index {
                    Some(i) => self.sonars[i] = value,
                    None => tracing::trace!(name, "ignoring an unknown sonar"),
                }
            }
        }
    }

    fn set_orientation(&mut self, value: Coordinates, source: Source, time: f64) {
        if self.orientation_source.is_some_and(|best| best > source) {
            return;
        }
        self.orientation_source = Some(source);
        self.orientation = Some(Reading { value, time });
        // Keep a sensor-given relative velocity consistent only when it is derived.
        if self.velocity_source == Some(Source::Derived) {
            self.derive_relative_velocity();
        }
    }

    fn set_position(&mut self, value: Coordinates, source: Source, time: f64) {
        if self.position_source.is_some_and(|best| best > source) {
            return;
        }
        let previous = self.position.replace(Reading { value, time });
        self.position_source = Some(source);
        if self.velocity_source.is_some_and(|s| s > Source::Derived)
            || source == Source::DeadReckoning
        {
            return;
        }
        if let Some(prev) = previous {
            let dt = time - prev.time;
            if dt > 1e-6 {
                self.velocity_source = Some(Source::Derived);
                self.velocity = Some(Reading {
                    value: (value - prev.value) / dt,
                    time,
                });
                self.derive_relative_velocity();
            }
        }
    }

    fn derive_relative_velocity(&mut self) {
        if let (Some(v), Some(o)) = (&self.velocity, &self.orientation) {
            self.relative_velocity = Some(Reading {
                value: world_to_body_vector(&v.value, &o.value),
                time: v.time,
            });
        }
    }

    /// Starts dead reckoning at `start` (the spawn point) when no sensor gives a position;
    /// returns whether it did.
    pub fn seed_position(&mut self, start: Coordinates, time: f64) -> bool {
        if self.position.is_some() {
            return false;
        }
        self.position = Some(Reading { value: start, time });
        self.position_source = Some(Source::DeadReckoning);
        self.reckoning_origin_z = Some(start.z);
        true
    }

    /// Notes the speed command sent at `time`.
    pub fn set_command(&mut self, command: crate::speed::SpeedCommand, time: f64) {
        if self.position_source == Some(Source::DeadReckoning) {
            self.dead_reckon(time);
        }
        self.command = Some(Reading {
            value: command,
            time,
        });
    }

    /// Advances a dead-reckoned position to `time`: the commanded velocity (the AirRobot's
    /// maxima, protocol.md §5.1: 2 m/s) turned by the reported heading, integrated since the
    /// last estimate; the height from an AltitudeSensor when there is one. USARSim imposes
    /// commanded velocities, so this is exact until the robot touches something. Does nothing
    /// when a sensor gives the position.
    pub fn dead_reckon(&mut self, time: f64) {
        if self.position_source != Some(Source::DeadReckoning) {
            return;
        }
        let Some(last) = self.position.clone() else {
            return;
        };
        let dt = time - last.time;
        if dt <= 0.0 {
            return;
        }
        let c = self.command.as_ref().map(|c| c.value).unwrap_or_default();
        let body = Coordinates::new(c.forward, c.right, -c.up) * (crate::speed::FULL_SPEED / 100.0);
        let velocity =
            crate::geometry::body_to_world_vector(&body, &Coordinates::new(0.0, 0.0, self.yaw()));
        let mut value = last.value + velocity * dt;
        if let (Some(alt), Some(z0)) = (&self.altitude, self.reckoning_origin_z) {
            value.z = z0 - alt.value;
        }
        self.position = Some(Reading { value, time });
        self.velocity = Some(Reading {
            value: velocity,
            time,
        });
        self.relative_velocity = Some(Reading { value: body, time });
        self.velocity_source = Some(Source::DeadReckoning);
    }

    /// Where the UAV's velocity would take it in the world frame for a body-frame vector
    /// (a convenience for agents).
    pub fn body_to_world(&self, v: &Coordinates) -> Coordinates {
        match &self.orientation {
            Some(o) => body_to_world_vector(v, &o.value),
            None => *v,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use usar_proto::{Sen, Sta, StaLayout, Time, Vec3};

    fn sen(t: Option<f64>, data: SenData) -> ServerMessage {
        ServerMessage::Sen(Sen {
            time: t.map(Time::udk),
            data,
        })
    }

    fn sta(t: f64, battery: i64) -> ServerMessage {
        ServerMessage::Sta(Sta {
            time: Time::udk(t),
            battery,
            vehicle: None,
            layout: StaLayout::Udk,
        })
    }

    fn sonar(name: &str, range: f64) -> SenData {
        SenData::Sonar {
            readings: vec![NamedRange {
                name: name.into(),
                range,
            }],
            grouped: false,
        }
    }

    fn imu(yaw: f64) -> SenData {
        SenData::Imu {
            name: "IMU".into(),
            acceleration: Vec3::new(0.1, 0.2, 0.3),
            angular_vel: Vec3::new(0.0, 0.0, 0.5),
            angular_accel: Vec3::default(),
            rotation: Vec3::new(0.0, 0.0, yaw),
        }
    }

    #[test]
    fn sts_air_robot_stream() {
        let mut uav = UavState::new();
        assert!(!uav.apply(&sta(1.0, 1200)));
        assert!(!uav.apply(&sta(1.1, 600)));
        let battery = uav.battery.clone().unwrap();
        assert_eq!(battery.value.remaining, 600);
        assert!((battery.value.level - 0.5).abs() < 1e-12);
        assert_eq!(battery.time, 1.1);

        assert!(uav.apply(&sen(
            Some(1.2),
            SenData::Position {
                name: "Position".into(),
                location: Vec3::new(1.0, 2.0, -3.0),
            }
        )));
        assert!(uav.apply(&sen(
            Some(1.2),
            SenData::Velocity {
                name: "Velocity".into(),
                absolute: Vec3::new(0.0, 2.0, 0.0),
                relative: Vec3::new(2.0, 0.0, 0.0),
            }
        )));
        assert!(uav.apply(&sen(Some(1.25), imu(1.5))));
        assert!(uav.apply(&sen(Some(1.3), sonar("Sonar2", 1.5))));
        assert!(uav.apply(&sen(Some(1.3), sonar("SonarTop", 3.0))));
        assert!(uav.apply(&sen(Some(1.3), sonar("SonarBottom", 0.4))));
        assert!(uav.apply(&sen(
            Some(1.4),
            SenData::RangeScanner(Scan {
                kind: "RangeScanner".into(),
                name: "Scanner".into(),
                resolution: 0.0184,
                fov: 4.1889,
                ranges: vec![4.0; 228],
                range_decimals: 2,
            })
        )));

        assert_eq!(
            uav.position.clone().unwrap().value,
            Coordinates::new(1.0, 2.0, -3.0)
        );
        assert_eq!(
            uav.velocity.clone().unwrap().value,
            Coordinates::new(0.0, 2.0, 0.0)
        );
        assert_eq!(
            uav.relative_velocity.clone().unwrap().value,
            Coordinates::new(2.0, 0.0, 0.0)
        );
        assert_eq!(uav.yaw(), 1.5);
        assert_eq!(uav.acceleration.clone().unwrap().value.z, 0.3);
        assert_eq!(uav.angular_velocity.clone().unwrap().value.z, 0.5);
        assert_eq!(uav.sonars[2].clone().unwrap().value, 1.5);
        assert!(uav.sonars[0].is_none());
        assert_eq!(uav.free_above.clone().unwrap().value, 3.0);
        assert_eq!(uav.free_below.clone().unwrap().value, 0.4);
        let laser = uav.laser.clone().unwrap();
        assert_eq!(laser.value.ranges.len(), 228);
        assert_eq!(laser.time, 1.4);
        assert!((laser.value.bearing(0) - 2.09445).abs() < 1e-4);
        assert_eq!(uav.time, Some(1.4));
    }

    #[test]
    fn stock_air_robot_with_ground_truth_derives_velocity() {
        let mut uav = UavState::new();
        uav.apply(&sta(10.0, 99999));
        let gt = |t: f64, x: f64| {
            sen(
                Some(t),
                SenData::GroundTruth {
                    name: "GroundTruth".into(),
                    location: Vec3::new(x, 0.0, -1.0),
                    orientation: Vec3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
                    decimals: 3,
                },
            )
        };
        assert!(uav.apply(&gt(10.0, 1.0)));
        assert!(uav.velocity.is_none());
        assert!(uav.apply(&gt(10.5, 2.0)));
        assert_eq!(uav.position.clone().unwrap().value.x, 2.0);
        let v = uav.velocity.clone().unwrap().value;
        assert!((v - Coordinates::new(2.0, 0.0, 0.0)).norm() < 1e-9);
        // Heading east, moving north: the velocity points to the UAV's left.
        let rel = uav.relative_velocity.clone().unwrap().value;
        assert!((rel - Coordinates::new(0.0, -2.0, 0.0)).norm() < 1e-9);
        assert_eq!(uav.battery.clone().unwrap().value.level, 1.0);
        // An INS reading does not override the better GroundTruth.
        uav.apply(&sen(
            None,
            SenData::Ins {
                name: "INS".into(),
                location: Vec3::new(50.0, 0.0, 0.0),
                orientation: Vec3::new(0.0, 0.0, 3.0),
            },
        ));
        assert_eq!(uav.position.clone().unwrap().value.x, 2.0);
        assert_eq!(uav.yaw(), std::f64::consts::FRAC_PI_2);
    }

    #[test]
    fn ins_only_uses_latest_time() {
        let mut uav = UavState::new();
        uav.apply(&sta(3.0, 99999));
        uav.apply(&sen(
            None,
            SenData::Ins {
                name: "INS".into(),
                location: Vec3::new(1.0, 1.0, -2.0),
                orientation: Vec3::new(0.0, 0.0, 0.5),
            },
        ));
        let p = uav.position.clone().unwrap();
        assert_eq!(p.time, 3.0);
        assert_eq!(uav.yaw(), 0.5);
    }

    #[test]
    fn a_crash_sensor_that_fires_marks_the_state_crashed_with_a_reason() {
        let mut uav = UavState::new();
        let crash = |t: f64, touch: bool| {
            sen(
                Some(t),
                SenData::Touch {
                    name: "Crash".into(),
                    touch,
                },
            )
        };
        uav.apply(&sen(
            Some(1.0),
            SenData::Velocity {
                name: "Velocity".into(),
                absolute: Vec3::new(3.0, 0.0, 0.0),
                relative: Vec3::new(3.0, 0.0, 0.0),
            },
        ));
        assert!(!uav.apply(&crash(1.0, false)));
        assert!(!uav.crashed());
        // Another touch sensor (a bumper) is no crash.
        uav.apply(&sen(
            Some(1.05),
            SenData::Touch {
                name: "Bumper".into(),
                touch: true,
            },
        ));
        assert!(!uav.crashed());
        uav.apply(&crash(1.1, true));
        let report = uav.crash.clone().expect("crashed");
        assert_eq!(report.time, 1.1);
        assert!(
            report.value.contains("speed before impact 3.00 m/s"),
            "{}",
            report.value
        );
        // Later lines keep the first report.
        uav.apply(&crash(1.2, true));
        assert_eq!(uav.crash.unwrap().time, 1.1);
    }

    #[test]
    fn ignores_unknown_sonars_and_other_messages() {
        let mut uav = UavState::new();
        assert!(uav.apply(&sen(Some(1.0), sonar("F1", 2.0))));
        assert!(uav.apply(&sen(Some(1.0), sonar("Sonar9", 2.0))));
        assert!(uav.sonars.iter().all(Option::is_none));
        assert!(!uav.apply(&sen(Some(1.0), SenData::Camera)));
        assert!(!uav.battery_empty());
        uav.apply(&sta(2.0, 0));
        assert!(uav.battery_empty());
    }

    #[test]
    fn victim_sensor_lines_become_sightings() {
        let mut state = UavState::new();
        let line = "SEN {Time 2.0000} {Type VictSensor} {Name V} {PartName Chest} {Location 2.05,0.33,0.46}";
        assert!(state.apply(&ServerMessage::parse(line).unwrap().message));
        let seen = state.victims.as_ref().unwrap();
        assert_eq!(seen.time, 2.0);
        assert_eq!(seen.value[0].part, "Chest");
        assert_eq!(seen.value[0].location, Coordinates::new(2.05, 0.33, 0.46));
        let none = "SEN {Time 3.0000} {Type VictSensor} {Status NoVictims}";
        state.apply(&ServerMessage::parse(none).unwrap().message);
        assert!(state.victims.as_ref().unwrap().value.is_empty());
    }
}
