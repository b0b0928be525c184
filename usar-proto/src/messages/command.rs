//! Typed client → server commands (protocol.md §2).

use super::common::Vec3;
use crate::message::Message;

/// A command a client sends to the server.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Command {
    /// `INIT {ClassName ..} {Name ..} {Location ..} {Rotation ..}` or `{Start ..}` (§2.1).
    Init(Init),
    /// `DRIVE {...}` (§2.3).
    Drive(Drive),
    /// `GETSTARTPOSES` (§2.2).
    GetStartPoses,
    /// `GETCONF {Type ..} [{Name ..}]` (§2.4).
    GetConf(ItemQuery),
    /// `GETGEO {Type ..} [{Name ..}]` (§2.4).
    GetGeo(ItemQuery),
    /// `SET {Type ..} [{Name ..}] {Opcode ..} {Params ..}` (§2.5).
    Set(Set),
    /// `ACT {Name ..} {Link i} {Value f} ...` (§2.6).
    Act(Act),
    /// `MISPKG {Name ..} {Link i} {Value f} {Order 0}` (§2.6, deprecated).
    MisPkg(MisPkg),
    /// Any other command, kept as read (UDK ignores these silently).
    Other(Message),
}

/// `INIT`: spawn a robot (§2.1).
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Init {
    /// Full `Package.Class`, e.g. `USARBot.stsAirRobot`.
    pub class_name: String,
    /// Becomes the robot's tag; never echoed.
    pub name: Option<String>,
    /// Metres, protocol frame (z down).
    pub location: Option<Vec3>,
    /// Radians, roll, pitch, yaw.
    pub rotation: Option<Vec3>,
    /// A PlayerStart tag or name; when present, location and rotation are ignored.
    pub start: Option<String>,
}

/// `DRIVE`: sticky set-points; every key is optional (§2.3).
///
/// Aerial keys (`AerialVehicle`), ground keys (skid steer and Ackerman) and the generic
/// `Light` and `Normalized` keys. A key absent from the line is `None`.
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default))]
pub struct Drive {
    /// m/s, + = climb (or ±100 when normalized).
    pub altitude_velocity: Option<f64>,
    /// m/s along the heading, + = forward.
    pub linear_velocity: Option<f64>,
    /// m/s along the heading's right axis, + = right.
    pub lateral_velocity: Option<f64>,
    /// Degrees per second, truncated to an integer by the server; + = clockwise from above.
    pub rotational_velocity: Option<f64>,
    /// Degrees, + = nose up.
    pub pitch_angle: Option<f64>,
    /// Degrees.
    pub roll_angle: Option<f64>,
    /// Propeller pair FL+BR joint velocity (visual only).
    pub spin1: Option<f64>,
    /// Propeller pair FR+BL joint velocity (visual only).
    pub spin2: Option<f64>,
    /// `Some(true)` only for the exact lowercase `{Normalized true}`; any other value reads
    /// as `Some(false)` (with a deviation when it was `True`), as the UDK server does.
    pub normalized: Option<bool>,
    /// Skid steer: left wheels (rad/s, or ±100 normalized).
    pub left: Option<f64>,
    /// Skid steer: right wheels.
    pub right: Option<f64>,
    /// Ackerman: speed.
    pub speed: Option<f64>,
    /// Ackerman: front steering angle.
    pub front_steer: Option<f64>,
    /// Ackerman: rear steering angle.
    pub rear_steer: Option<f64>,
    /// Headlights.
    pub light: Option<bool>,
}

/// The body of `GETCONF` and `GETGEO`: which parts to describe (§2.4).
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ItemQuery {
    /// `Robot` (exact case) for the robot itself, else a part type matched case-insensitively;
    /// echoed as sent in the reply.
    pub kind: String,
    /// Restrict to the part with this name (case-insensitive).
    pub name: Option<String>,
}

/// `SET`: an opcode for matching parts (§2.5).
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Set {
    /// Part type.
    pub kind: String,
    /// Part name, if restricted.
    pub name: Option<String>,
    /// Opcode, e.g. `SCAN`.
    pub opcode: String,
    /// Parameters as text (their meaning depends on the opcode).
    pub params: Option<String>,
}

/// One `{Link i} {Value f}` pair of ACT/MISPKG/ASTA.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct LinkValue {
    /// Link number (0-based for ACT, 1-based for MISPKG and ASTA).
    pub link: i64,
    /// Joint target or value.
    pub value: f64,
}

/// `ACT`: set actuator joint targets (§2.6).
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Act {
    /// Actuator name, e.g. `cam`.
    pub name: String,
    /// Link targets in order.
    pub links: Vec<LinkValue>,
    /// `{Gripper n}`.
    pub gripper: Option<i64>,
    /// `{Sequence n}`.
    pub sequence: Option<i64>,
}

/// `MISPKG` (deprecated ACT): links are 1-based; acts only with `Order 0`.
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct MisPkg {
    /// Mission package (actuator) name.
    pub name: String,
    /// Link targets in order.
    pub links: Vec<LinkValue>,
    /// `{Order n}`.
    pub order: Option<i64>,
}
