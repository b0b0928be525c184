//! `CONF`: replies to GETCONF (protocol.md §3.4).
//!
//! A part is read as a typed [`ConfItem`] only when its keys are exactly the template of
//! that part kind (case-insensitive, in order), so that it prints back byte for byte;
//! anything else is kept as [`ConfItem::Other`] and printed with one space between groups.
//!
//! Formatters (chosen to match the capture): FloatString for ranges, sonar and scanner
//! values and `MaxSpeed` (captured `1.2999`); implicit `%.4f` for `ScanInterval` of the
//! interval parts, camera FOVs, actuator limits, `Mass` and `MaxTorque` (captured `11.9000`,
//! which FloatString of the engine's `11.9f32` would print as `11.8999`).

use super::line::Line;
use super::server::{ActuatorJoint, Conf, ConfItem};
use crate::error::ParseError;
use crate::format::WireBuf;
use crate::message::groups_of;
use crate::value::Reader;

const P: u8 = 4;
const RANGE: &[&str] = &["Name", "MaxRange", "MinRange"];
const SONAR: &[&str] = &[
    "Name",
    "MaxRange",
    "MinRange",
    "ScanInterval",
    "beamAngle",
    "maxAngleOfIncidence",
    "tracesPerCone",
    "numberOfCones",
];
const SCANNER: &[&str] = &[
    "Name",
    "MaxRange",
    "MinRange",
    "Resolution",
    "Fov",
    "Panning",
    "Tilting",
];
const SCANNER_TYPO: &[&str] = &[
    "Name",
    "MaxRange",
    "MinRange",
    "Resolution",
    "Fov",
    "Paning",
    "Tilting",
];
const CAMERA: &[&str] = &[
    "Name",
    "TextureOffsetX",
    "TextureOffsetY",
    "TextureResolutionX",
    "TextureResolutionY",
    "CameraDefFov",
    "CameraMinFov",
    "CameraMaxFov",
    "CameraFov",
];
const JOINT: &[&str] = &["Link", "JointType", "MaxTorque", "MinValue", "MaxValue"];

impl Conf {
    /// `None` for a robot-level layout other than the aerial and ground-vehicle ones.
    pub(crate) fn read(r: Reader<'_, '_>) -> Result<Option<Self>, ParseError> {
        let first = r.pairs.first().map(|p| p.key);
        if first.is_some_and(|k| k.eq_ignore_ascii_case("Type")) {
            let rest = r.sub("", &r.pairs[1..]);
            return Ok(Some(Self::Items {
                kind: r.string("Type")?,
                items: rest
                    .items()
                    .map(|it| ConfItem::read(&it))
                    .collect::<Result<_, _>>()?,
            }));
        }
        if r.keys_are(&["Name"]) {
            return Ok(Some(Self::Robot {
                name: r.string("Name")?,
            }));
        }
        if !r.keys_are(&[
            "Name",
            "Type",
            "SteeringType",
            "Mass",
            "MaxSpeed",
            "MaxTorque",
            "MaxFrontSteer",
            "MaxRearSteer",
        ]) {
            return Ok(None);
        }
        Ok(Some(Self::GroundVehicle {
            name: r.string("Name")?,
            steering_type: r.string("SteeringType")?,
            mass: r.f64("Mass")?,
            max_speed: r.f64("MaxSpeed")?,
            max_torque: r.f64("MaxTorque")?,
            max_front_steer: r.i64("MaxFrontSteer")?,
            max_rear_steer: r.i64("MaxRearSteer")?,
        }))
    }

    pub(crate) fn write(&self, out: &mut impl WireBuf) {
        let mut w = Line::new(out, "CONF");
        match self {
            Self::Robot { name } => {
                w.text("Name", name);
            }
            Self::GroundVehicle {
                name,
                steering_type,
                mass,
                max_speed,
                max_torque,
                max_front_steer,
                max_rear_steer,
            } => {
                w.text("Name", name)
                    .text("Type", "GroundVehicle")
                    .text("SteeringType", steering_type)
                    .fixed("Mass", *mass, 4)
                    .fs("MaxSpeed", *max_speed, P)
                    .fixed("MaxTorque", *max_torque, 4)
                    .int("MaxFrontSteer", *max_front_steer)
                    .int("MaxRearSteer", *max_rear_steer);
            }
            Self::Items { kind, items } => {
                w.text("Type", kind);
                for item in items {
                    item.write(&mut w);
                }
            }
        }
    }
}

impl ConfItem {
    fn read(r: &Reader<'_, '_>) -> Result<Self, ParseError> {
        let name = || r.string("Name");
        let joints = r.pairs.len() > 1
            && (r.pairs.len() - 1).is_multiple_of(JOINT.len())
            && r.pairs[1..]
                .chunks(JOINT.len())
                .all(|c| r.sub("", c).keys_are(JOINT));
        Ok(if r.keys_are(&["Name"]) {
            Self::Plain { name: name()? }
        } else if r.keys_are(RANGE) {
            Self::Range {
                name: name()?,
                max_range: r.f64("MaxRange")?,
                min_range: r.f64("MinRange")?,
            }
        } else if r.keys_are(SONAR) {
            Self::Sonar {
                name: name()?,
                max_range: r.f64("MaxRange")?,
                min_range: r.f64("MinRange")?,
                scan_interval: r.f64("ScanInterval")?,
                beam_angle: r.f64("beamAngle")?,
                max_angle_of_incidence: r.f64("maxAngleOfIncidence")?,
                traces_per_cone: r.i64("tracesPerCone")?,
                number_of_cones: r.i64("numberOfCones")?,
            }
        } else if r.keys_are(SCANNER) || r.keys_are(SCANNER_TYPO) {
            let paning_typo = r.keys_are(SCANNER_TYPO);
            Self::Scanner {
                name: name()?,
                max_range: r.f64("MaxRange")?,
                min_range: r.f64("MinRange")?,
                resolution: r.f64("Resolution")?,
                fov: r.f64("Fov")?,
                panning: r.bool(if paning_typo { "Paning" } else { "Panning" })?,
                tilting: r.bool("Tilting")?,
                paning_typo,
            }
        } else if r.keys_are(&["Name", "ScanInterval"]) {
            Self::Interval {
                name: name()?,
                scan_interval: r.f64("ScanInterval")?,
            }
        } else if r.keys_are(CAMERA) {
            Self::Camera {
                name: name()?,
                texture_offset_x: r.i64("TextureOffsetX")?,
                texture_offset_y: r.i64("TextureOffsetY")?,
                texture_resolution_x: r.i64("TextureResolutionX")?,
                texture_resolution_y: r.i64("TextureResolutionY")?,
                default_fov: r.f64("CameraDefFov")?,
                min_fov: r.f64("CameraMinFov")?,
                max_fov: r.f64("CameraMaxFov")?,
                fov: r.f64("CameraFov")?,
            }
        } else if joints {
            Self::Actuator {
                name: name()?,
                joints: r.pairs[1..]
                    .chunks(JOINT.len())
                    .map(|c| {
                        let j = r.sub("", c);
                        Ok(ActuatorJoint {
                            link: j.i64("Link")?,
                            joint_type: j.string("JointType")?,
                            max_torque: j.f64("MaxTorque")?,
                            min_value: j.f64("MinValue")?,
                            max_value: j.f64("MaxValue")?,
                        })
                    })
                    .collect::<Result<_, ParseError>>()?,
            }
        } else {
            Self::Other {
                groups: groups_of(r.pairs),
            }
        })
    }

    fn write<B: WireBuf>(&self, w: &mut Line<'_, B>) {
        match self {
            Self::Plain { name } => {
                w.text("Name", name);
            }
            Self::Range {
                name,
                max_range,
                min_range,
            } => {
                w.text("Name", name)
                    .fs("MaxRange", *max_range, P)
                    .fs("MinRange", *min_range, P);
            }
            Self::Sonar {
                name,
                max_range,
                min_range,
                scan_interval,
                beam_angle,
                max_angle_of_incidence,
                traces_per_cone,
                number_of_cones,
            } => {
                w.text("Name", name)
                    .fs("MaxRange", *max_range, P)
                    .fs("MinRange", *min_range, P)
                    .fs("ScanInterval", *scan_interval, P)
                    .fs("beamAngle", *beam_angle, P)
                    .fs("maxAngleOfIncidence", *max_angle_of_incidence, P)
                    .int("tracesPerCone", *traces_per_cone)
                    .int("numberOfCones", *number_of_cones);
            }
            Self::Scanner {
                name,
                max_range,
                min_range,
                resolution,
                fov,
                panning,
                tilting,
                paning_typo,
            } => {
                w.text("Name", name)
                    .fs("MaxRange", *max_range, P)
                    .fs("MinRange", *min_range, P)
                    .fs("Resolution", *resolution, P)
                    .fs("Fov", *fov, P)
                    .bool(if *paning_typo { "Paning" } else { "Panning" }, *panning)
                    .bool("Tilting", *tilting);
            }
            Self::Interval {
                name,
                scan_interval,
            } => {
                w.text("Name", name)
                    .fixed("ScanInterval", *scan_interval, 4);
            }
            Self::Camera {
                name,
                texture_offset_x,
                texture_offset_y,
                texture_resolution_x,
                texture_resolution_y,
                default_fov,
                min_fov,
                max_fov,
                fov,
            } => {
                // The engine concatenates these with `$`: no spaces between the groups.
                w.text("Name", name)
                    .glue()
                    .int("TextureOffsetX", *texture_offset_x)
                    .glue()
                    .int("TextureOffsetY", *texture_offset_y)
                    .glue()
                    .int("TextureResolutionX", *texture_resolution_x)
                    .glue()
                    .int("TextureResolutionY", *texture_resolution_y)
                    .glue()
                    .fixed("CameraDefFov", *default_fov, 4)
                    .glue()
                    .fixed("CameraMinFov", *min_fov, 4)
                    .glue()
                    .fixed("CameraMaxFov", *max_fov, 4)
                    .glue()
                    .fixed("CameraFov", *fov, 4);
            }
            Self::Actuator { name, joints } => {
                w.text("Name", name);
                for j in joints {
                    w.int("Link", j.link)
                        .text("JointType", &j.joint_type)
                        .fixed("MaxTorque", j.max_torque, 4)
                        .fixed("MinValue", j.min_value, 4)
                        .fixed("MaxValue", j.max_value, 4);
                }
            }
            Self::Other { groups } => {
                let mut s = String::new();
                crate::message::write_groups(&mut s, groups);
                w.raw(&s);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::messages::testutil::round_trip;
    use crate::{Conf, ConfItem, ServerMessage};

    #[test]
    fn capture_lines() {
        let m = round_trip(
            "CONF {Type Camera} {Name Camera}{TextureOffsetX 320}{TextureOffsetY 0}{TextureResolutionX 320}{TextureResolutionY 240}{CameraDefFov 80.0000}{CameraMinFov 20.0000}{CameraMaxFov 120.0000}{CameraFov 80.0000}",
        );
        let ServerMessage::Conf(Conf::Items { kind, items }) = m else {
            panic!()
        };
        assert_eq!(kind, "Camera");
        assert!(
            matches!(&items[0], ConfItem::Camera { texture_offset_x: 320, fov, .. } if *fov == 80.0)
        );
        let m = round_trip(
            "CONF {Name P3AT} {Type GroundVehicle} {SteeringType SkidSteered} {Mass 11.9000} {MaxSpeed 1.2999} {MaxTorque 50000.0000} {MaxFrontSteer 0} {MaxRearSteer 0}",
        );
        assert!(
            matches!(m, ServerMessage::Conf(Conf::GroundVehicle { max_speed, .. }) if max_speed == 1.2999)
        );
        round_trip(
            "CONF {Type RangeScanner} {Name lms200} {MaxRange 20.0000} {MinRange 0.1000} {Resolution 0.0174} {Fov 3.1414} {Panning True} {Tilting False}",
        );
        round_trip("CONF {Type INS} {Name InsTest} {ScanInterval 0.2000}");
        round_trip("CONF {Name AirRobot}");
        round_trip("CONF {Type IMU} {Name IMU}");
        round_trip(
            "CONF {Type Sonar} {Name S1} {MaxRange 5.0000} {MinRange 0.1000} {ScanInterval 0.2000} {beamAngle 0.3489} {maxAngleOfIncidence 0.1745} {tracesPerCone 16} {numberOfCones 10}",
        );
        round_trip(
            "CONF {Type Sonar} {Name S1} {MaxRange 5.0000} {MinRange 0.1000} {Name S2} {MaxRange 5.0000} {MinRange 0.1000}",
        );
        round_trip(
            "CONF {Type RangeScanner} {Name urg} {MaxRange 4.0000} {MinRange 0.1000} {Resolution 0.0184} {Fov 4.1889} {Paning True} {Tilting False}",
        );
        round_trip(
            "CONF {Type Actuator} {Name cam} {Link 1} {JointType Revolute} {MaxTorque 10.0000} {MinValue -1.5700} {MaxValue 1.5700}",
        );
        let m = round_trip(
            "CONF {Type Sonar} {Name R8} {MaxRange 5.0000} {MinRange 0.1000} {BeamAngle 0.3491}",
        );
        assert!(
            matches!(m, ServerMessage::Conf(Conf::Items { items, .. }) if matches!(items[0], ConfItem::Other { .. }))
        );
    }
}
