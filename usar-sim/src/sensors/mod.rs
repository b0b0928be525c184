//! Sensors: one file per sensor type, each with its `XxxConfig` (pub fields + `Default`) and
//! a type implementing [`Sensor`]; [`REGISTRY`] maps a part `type` of the robot
//! configuration to it.
//!
//! Adding a sensor: write `sensors/foo.rs` (config, sensor, `build`, a test), add one line
//! to `REGISTRY`.

mod altitude;
mod barometer;
mod battery;
pub(crate) mod camera;
mod compass;
mod gps;
mod ground_truth;
mod imu;
mod ins;
mod magnetometer;
mod mission_time;
mod position;
mod range_scanner;
mod rotors;
mod sonar;
mod touch;
mod velocity;
mod victim;

pub use altitude::AltitudeConfig;
pub use camera::{CameraConfig, MAX_CAMERA_SIDE};
pub use compass::CompassConfig;
pub use gps::GpsConfig;
pub use ground_truth::GroundTruthConfig;
pub use imu::ImuConfig;
pub use ins::InsConfig;
pub use magnetometer::MagnetometerConfig;
pub use mission_time::MissionTimeConfig;
pub use position::PositionConfig;
pub use range_scanner::RangeScannerConfig;
pub use sonar::{SonarConfig, SonarModel};
pub use touch::{TouchConfig, TouchEvent};
pub use velocity::VelocityConfig;
pub use victim::VictSensorConfig;

use rapier3d::prelude::ColliderHandle;
use serde::de::DeserializeOwned;
use usar_proto::{ConfItem, SenData};

use super::dynamics::{ImuTruth, M3, mul, mul_t};
use super::noise::Noise;
use super::part::PartConfig;
use super::power::Gauge;
use super::scene::{Scene, V3, add, rotate_by, scale};

/// What a sensor sees when it takes a reading.
pub(crate) struct Reading<'a> {
    /// The part name.
    pub(crate) name: &'a str,
    /// The geometry; queries must exclude `me`.
    pub(crate) scene: &'a Scene,
    /// The sensor's own robot body (never seen by its sensors).
    pub(crate) me: ColliderHandle,
    /// World time, s.
    pub(crate) time: f64,
    /// Seconds since the robot spawned.
    pub(crate) since_spawn: f64,
    /// Robot centre, world frame (z down).
    pub(crate) position: V3,
    /// Robot velocity, world frame, m/s.
    pub(crate) velocity: V3,
    /// Robot attitude: roll, pitch, yaw (rad, not normalised).
    pub(crate) rotation: V3,
    /// z of the robot centre at spawn.
    pub(crate) spawn_z: f64,
    /// The sensor's position, world frame.
    pub(crate) origin: V3,
    /// The sensor's heading in the world (robot yaw + mount yaw), rad. Robot pitch and roll
    /// are visual only and do not tilt the sensors.
    pub(crate) yaw: f64,
    /// The mount's pitch (+ = up), rad.
    pub(crate) pitch: f64,
    /// The body's tilt (its rotation without the yaw) for models with physics: directions
    /// built from `pitch` and `yaw` are turned by it before tracing. `None`: level.
    pub(crate) tilt: Option<M3>,
    /// The sine and cosine of minus the robot's yaw (`rotation[2]`) when the robot has
    /// worked them out for its parts (`None`: [`Reading::to_body`] works them out).
    pub(crate) body_trig: Option<(f64, f64)>,
    /// What the IMU measures, for models with physics (`None`: the engine's finite
    /// differences).
    pub(crate) imu: Option<ImuTruth>,
    /// The battery of a model with an energy model (`None`: USARSim's timer or none).
    pub(crate) gauge: Option<Gauge>,
    /// Rotor speeds, rad/s, of a model with rotors.
    pub(crate) rotors: Option<[f64; 4]>,
    /// Whether the body touched something in the last tick.
    pub(crate) contact: bool,
    /// Whether the robot has crashed.
    pub(crate) crashed: bool,
    /// For a sensor whose reading is one ray ([`Sensor::single_ray`]): that ray's hit, when
    /// the robot cast it together with its other parts' rays (exactly what
    /// [`Reading::trace`] would give).
    pub(crate) ray_hit: Option<Option<f64>>,
}

impl Reading<'_> {
    /// Distance to the first surface along a direction of the level (yaw-only) frame, or
    /// `None` within `max`; the body's tilt turns the direction first.
    pub(crate) fn trace(&self, dir: V3, max: f64) -> Option<f64> {
        self.scene
            .cast_ray(self.origin, self.tilted(dir), max, Some(self.me))
    }

    /// A direction of the level (yaw-only) frame turned by the body's tilt.
    fn tilted(&self, dir: V3) -> V3 {
        match &self.tilt {
            Some(t) => mul(t, dir),
            None => dir,
        }
    }

    /// [`Reading::trace`] of each direction (same results; many rays share one tree query).
    pub(crate) fn trace_many(&self, dirs: &[V3], max: f64, out: &mut Vec<Option<f64>>) {
        out.clear();
        if dirs.len() < 4 || !self.scene.shortcuts {
            out.extend(dirs.iter().map(|&d| self.trace(d, max)));
            return;
        }
        let dirs: Vec<V3> = dirs.iter().map(|&d| self.tilted(d)).collect();
        let ends = dirs.iter().map(|&d| add(self.origin, scale(d, max)));
        let batch = self.scene.ray_batch(self.origin, ends, Some(self.me));
        out.extend(dirs.iter().map(|&d| batch.cast(d, max)));
    }

    /// [`Reading::trace`] of a fan of directions at once (same results, one tree query):
    /// `dirs[k]` must point at azimuth `base + offsets[k]` (yaw, + = clockwise from above),
    /// `offsets` sorted from largest to smallest within ±π, in the level frame (the body's
    /// tilt turns them, as in [`Reading::trace`]). Writes the hits into `out`.
    pub(crate) fn trace_fan(
        &self,
        dirs: &[V3],
        base: f64,
        offsets: &[f64],
        max: f64,
        out: &mut Vec<Option<f64>>,
    ) {
        if !self.scene.shortcuts {
            out.clear();
            out.extend(dirs.iter().map(|&d| self.trace(d, max)));
            return;
        }
        // A tilted fan: the directions and the axes their azimuths are measured about turn
        // together (the azimuths stay the same).
        let dirs: Vec<V3> = dirs.iter().map(|&d| self.tilted(d)).collect();
        let axes = (self.tilted([1.0, 0.0, 0.0]), self.tilted([0.0, 1.0, 0.0]));
        self.scene.cast_fan(
            self.origin,
            &[],
            &dirs,
            base,
            offsets,
            axes,
            max,
            Some(self.me),
            false,
            out,
        );
    }

    /// A world-frame vector in the body frame (x forward, y right, z down): yaw only for the
    /// kinematic model, the full attitude for models with physics.
    pub(crate) fn to_body(&self, v: V3) -> V3 {
        let level = match &self.tilt {
            Some(t) => mul_t(t, v),
            None => v,
        };
        self.yaw_to_body(level)
    }

    /// A vector of the level frame turned by minus the yaw (into the body frame of the
    /// kinematic model): what `yaw_rotate(-rotation[2], v)` gives.
    pub(crate) fn yaw_to_body(&self, v: V3) -> V3 {
        let (s, c) = self
            .body_trig
            .unwrap_or_else(|| (-self.rotation[2]).sin_cos());
        rotate_by(s, c, v)
    }
}

/// A copy of a sensor as a trait object (each robot of a class gets a copy of the class's
/// sensors, built once).
pub(crate) trait SensorClone {
    fn clone_box(&self) -> Box<dyn Sensor>;
    /// Makes `target` a copy of this sensor: in its own allocation when it is one of this
    /// type (a robot spawned again in a reset world reuses its sensors), else in a new one.
    fn clone_into_box(&self, target: &mut Box<dyn Sensor>);
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any;
    /// A cache hint for the sensor's first line ([`crate::prefetch::line`]).
    fn prefetch(&self);
}

impl<T: Sensor + Clone + 'static> SensorClone for T {
    fn clone_box(&self) -> Box<dyn Sensor> {
        Box::new(self.clone())
    }

    fn clone_into_box(&self, target: &mut Box<dyn Sensor>) {
        match (**target).as_any_mut().downcast_mut::<T>() {
            Some(same) => same.clone_from(self),
            None => *target = self.clone_box(),
        }
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }

    fn prefetch(&self) {
        crate::prefetch::line(self);
    }
}

/// A sensor instance on a robot.
pub(crate) trait Sensor: SensorClone + std::fmt::Debug + Send + Sync {
    /// Takes one reading (the data after `{Type ..}`).
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData;
    /// The GETCONF item.
    fn conf(&self, name: &str, interval: f64) -> ConfItem {
        let _ = interval;
        ConfItem::Plain {
            name: name.to_string(),
        }
    }
    /// If a reading is exactly the hit of one ray along the part's axis (pitch and yaw of
    /// its mount, from its origin), the ray's length: the robot then casts the rays of such
    /// parts together and hands each its hit in [`Reading::ray_hit`].
    fn single_ray(&self) -> Option<f64> {
        None
    }
    /// Whether the SEN line carries `{Time ..}`.
    fn timestamped(&self) -> bool {
        true
    }
    /// A SET opcode and its parameters; `true` asks for an immediate extra reading.
    fn set(&mut self, opcode: &str, params: Option<&str>) -> bool {
        let _ = (opcode, params);
        false
    }
    /// Its error model's noise, bias and bias walk times `k` (domain randomisation).
    fn scale_noise(&mut self, k: f64) {
        let _ = k;
    }
    /// The camera, if this part is one (rendered by `World::render_cameras`).
    fn camera(&self) -> Option<&camera::Camera> {
        None
    }
    /// The camera, if this part is one.
    fn camera_mut(&mut self) -> Option<&mut camera::Camera> {
        None
    }
}

/// How to build a sensor type.
pub(crate) struct SensorKind {
    /// The `{Type ..}` of its SEN/CONF/GEO lines and the `type` in the robot configuration.
    pub(crate) item_type: &'static str,
    /// Seconds between readings when the part sets no `interval` (DefaultUSAR.ini).
    pub(crate) default_interval: f64,
    /// Builds the sensor from its part (settings validated here).
    pub(crate) build: fn(&PartConfig) -> Result<Box<dyn Sensor>, String>,
}

/// Part type → sensor.
pub(crate) const REGISTRY: &[SensorKind] = &[
    kind("IMU", 0.1, imu::build),
    kind("Sonar", 0.2, sonar::build),
    kind("RangeScanner", 0.2, range_scanner::build),
    kind("Position", 0.1, position::build),
    kind("Velocity", 0.1, velocity::build),
    kind("AltitudeSensor", 0.1, altitude::build),
    kind("MagneticCompass", 0.1, compass::build),
    kind("MissionTime", 0.1, mission_time::build),
    kind("Camera", 0.1, camera::build),
    kind("GroundTruth", 0.1, ground_truth::build),
    kind("INS", 0.2, ins::build),
    kind("Touch", 0.1, touch::build),
    kind("Battery", 0.1, battery::build),
    kind("Rotors", 0.1, rotors::build),
    kind("Barometer", 0.05, barometer::build),
    kind("VictSensor", 0.8, victim::build),
    kind("GPS", 0.1, gps::build),
    kind("Magnetometer", 0.1, magnetometer::build),
];

const fn kind(
    item_type: &'static str,
    default_interval: f64,
    build: fn(&PartConfig) -> Result<Box<dyn Sensor>, String>,
) -> SensorKind {
    SensorKind {
        item_type,
        default_interval,
        build,
    }
}

/// The sensor type named `name` (case-insensitive).
pub(crate) fn find(name: &str) -> Option<&'static SensorKind> {
    REGISTRY
        .iter()
        .find(|k| k.item_type.eq_ignore_ascii_case(name))
}

/// The part's type-specific settings as `T` (unknown keys are errors).
pub(crate) fn settings<T: DeserializeOwned>(part: &PartConfig) -> Result<T, String> {
    toml::Value::Table(part.settings.clone())
        .try_into()
        .map_err(|e: toml::de::Error| format!("part `{}`: {}", part.name, e.message().trim_end()))
}

/// Settings of a sensor that has none (any key is an error).
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoSettings {}

/// A value as the engine's 32-bit float (CONF constants reproduce its f32 quirks).
pub(crate) fn f32ish(v: f64) -> f64 {
    f64::from(v as f32)
}

/// The CONF item of a part that reports only its interval (`{Name n} {ScanInterval s}`:
/// GroundTruth, INS, Position, Velocity), in the engine's f32.
pub(crate) fn interval_conf(name: &str, interval: f64) -> ConfItem {
    ConfItem::Interval {
        name: name.to_string(),
        scan_interval: f32ish(interval),
    }
}

/// Unreal rotation units per radian (`C_AngleToURot`).
pub(crate) const URU_PER_RAD: f32 = 10_430.378;

/// An angle the engine stores in whole rotation units: `int(rad · 10430.378)`, in f32.
pub(crate) fn to_uu(rad: f64) -> i32 {
    (rad as f32 * URU_PER_RAD) as i32
}

/// An angle as the engine reports it after storing it in whole rotation units
/// (`{beamAngle 0.3489}` for 0.349, `{Resolution 0.0184}` for the Hokuyo).
pub(crate) fn from_uu(uu: i32) -> f64 {
    f64::from(uu as f32 / URU_PER_RAD)
}

#[cfg(test)]
pub(crate) mod testing {
    //! A box at a known distance, and a reading next to it.
    use super::*;
    use crate::scene::BodyShape;
    use rapier3d::math::Pose;
    use rapier3d::prelude::ColliderBuilder;

    /// A scene with a robot body at the origin and a 1 m thick wall whose near face is at
    /// `x = distance`, plus a floor 2 m below and nothing above.
    pub(crate) fn scene_with_wall(distance: f64) -> (Scene, ColliderHandle) {
        let mut scene = Scene::new();
        scene.insert(
            ColliderBuilder::cuboid(0.5, 50.0, 50.0).position(Pose::translation(
                distance as f32 + 0.5,
                0.0,
                0.0,
            )),
        );
        scene.insert(
            ColliderBuilder::cuboid(50.0, 50.0, 0.5).position(Pose::translation(0.0, 0.0, 2.5)),
        );
        let me = scene.insert_body(
            BodyShape {
                radius: 0.4,
                half_height: 0.1,
            },
            [0.0; 3],
        );
        (scene, me)
    }

    /// A reading at the origin, facing north, at `time`.
    pub(crate) fn reading<'a>(scene: &'a Scene, me: ColliderHandle, time: f64) -> Reading<'a> {
        Reading {
            name: "S",
            scene,
            me,
            time,
            since_spawn: time,
            position: [0.0; 3],
            velocity: [0.0; 3],
            rotation: [0.0; 3],
            spawn_z: 0.0,
            origin: [0.0; 3],
            yaw: 0.0,
            pitch: 0.0,
            tilt: None,
            body_trig: None,
            imu: None,
            gauge: None,
            rotors: None,
            contact: false,
            crashed: false,
            ray_hit: None,
        }
    }

    /// A part of type `kind` with TOML settings.
    pub(crate) fn part(kind: &str, settings: &str) -> PartConfig {
        PartConfig {
            kind: kind.to_string(),
            name: "S".to_string(),
            position: [0.0; 3],
            direction: [0.0; 3],
            interval: None,
            noise: 0.0,
            settings: toml::from_str(settings).expect("test settings"),
        }
    }

    /// Builds the registered sensor for `kind`.
    pub(crate) fn make(kind: &str, settings: &str) -> Box<dyn Sensor> {
        (find(kind).expect("registered").build)(&part(kind, settings)).expect("valid settings")
    }

    /// No noise.
    pub(crate) fn quiet() -> Noise {
        Noise::new(0, 0, 0, 0.0)
    }
}
