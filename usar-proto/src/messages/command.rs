//! Typed client → server commands (protocol.md §2).

use crate::message::Message;
use crate::primitive::Vec3;

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
    /// `SYNC {Time t}`: join or advance the lockstep barrier (our extension,
    /// docs/lockstep.md). A `SYNC` without a readable time is [`Command::Other`].
    Sync(Barrier),
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

impl Init {
    /// The package every stock robot class lives in (`USARBot.stsAirRobot`).
    pub const PACKAGE: &'static str = "USARBot";

    /// The INIT class name for a robot a user named: `robot` as given when it names a
    /// package (`Package.Class`), otherwise with `USARBot.` in front (`stsAirRobot` ->
    /// `USARBot.stsAirRobot`). The one home of this rule for the client, the Python
    /// package, the browser and the benchmark.
    pub fn qualified_class(robot: &str) -> String {
        if robot.contains('.') {
            robot.to_owned()
        } else {
            format!("{}.{robot}", Self::PACKAGE)
        }
    }
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

use super::line::Line;
use super::sync::{Barrier, SYNC_WORD};
use crate::error::{ParseError, TextError};
use crate::format::WireBuf;
use crate::message::{Deviation, Parsed, Raw, RawPair};
use crate::value::{Lenient, lenient_f64, lenient_i64};

/// Every DRIVE key: the numeric ones in printing order (the order of the `Drive` fields),
/// then the flags.
const DRIVE_KEYS: [&str; 15] = [
    "AltitudeVelocity",
    "LinearVelocity",
    "LateralVelocity",
    "RotationalVelocity",
    "PitchAngle",
    "RollAngle",
    "Spin1",
    "Spin2",
    "Left",
    "Right",
    "Speed",
    "FrontSteer",
    "RearSteer",
    "Normalized",
    "Light",
];

/// The numeric DRIVE keys.
const DRIVE_NUMBERS: [&str; 13] = {
    let mut numbers = [""; 13];
    let mut i = 0;
    while i < numbers.len() {
        numbers[i] = DRIVE_KEYS[i];
        i += 1;
    }
    numbers
};

impl Drive {
    fn numbers(&self) -> [Option<f64>; 13] {
        [
            self.altitude_velocity,
            self.linear_velocity,
            self.lateral_velocity,
            self.rotational_velocity,
            self.pitch_angle,
            self.roll_angle,
            self.spin1,
            self.spin2,
            self.left,
            self.right,
            self.speed,
            self.front_steer,
            self.rear_steer,
        ]
    }

    fn read(l: &mut Lenient<'_, '_>) -> Self {
        let [
            altitude_velocity,
            linear_velocity,
            lateral_velocity,
            rotational_velocity,
            pitch_angle,
            roll_angle,
            spin1,
            spin2,
            left,
            right,
            speed,
            front_steer,
            rear_steer,
        ] = DRIVE_NUMBERS.map(|k| l.f64(k));
        Self {
            altitude_velocity,
            linear_velocity,
            lateral_velocity,
            rotational_velocity,
            pitch_angle,
            roll_angle,
            spin1,
            spin2,
            normalized: l.flag("Normalized"),
            left,
            right,
            speed,
            front_steer,
            rear_steer,
            light: l.flag("Light"),
        }
    }
}

/// `{Link i} {Value f}` pairs in line order (a `Value` before any `Link` gets link 0).
fn read_links(pairs: &[RawPair<'_>], devs: &mut Vec<Deviation>) -> Vec<LinkValue> {
    let mut links = Vec::new();
    let mut link = 0;
    for p in pairs {
        if p.key.eq_ignore_ascii_case("Link") {
            link = lenient_i64("Link", p.value, devs);
        } else if p.key.eq_ignore_ascii_case("Value") {
            let value = lenient_f64("Value", p.value, devs);
            links.push(LinkValue { link, value });
        }
    }
    links
}

fn write_links<B: WireBuf>(w: &mut Line<'_, B>, links: &[LinkValue]) {
    for l in links {
        w.int("Link", l.link).num("Value", l.value);
    }
}

/// The time of a `SYNC`: strictly a finite number (a barrier at a guessed time would stall or
/// race the world), unlike the lenient numbers of the stock commands.
fn sync_time(l: &mut Lenient<'_, '_>) -> Option<f64> {
    let text = l.text("Time")?;
    text.trim().parse::<f64>().ok().filter(|t| t.is_finite())
}

impl Command {
    /// Parses a client line leniently, as the UDK server would read it: never fails except
    /// on an empty line; what was tolerated is in [`Parsed::deviations`]. Unknown command
    /// words give [`Command::Other`].
    ///
    /// ```
    /// use usar_proto::{Command, Deviation};
    /// let p = Command::parse("drive {LinearVelocity +1,5}").unwrap();
    /// let Command::Drive(d) = &p.message else { panic!() };
    /// assert_eq!(d.linear_velocity, Some(1.5));
    /// assert_eq!(p.deviations[0], Deviation::CommandCase("drive".into()));
    /// assert_eq!(p.message.to_string(), "DRIVE {LinearVelocity 1.5}");
    /// ```
    pub fn parse(line: &str) -> Result<Parsed<Self>, ParseError> {
        let mut devs = Vec::new();
        let raw = Raw::parse(line, false, &mut devs)?;
        let word = raw.kind;
        if word.bytes().any(|b| b.is_ascii_lowercase()) {
            devs.push(Deviation::CommandCase(word.to_owned()));
        }
        let mut l = Lenient {
            pairs: &raw.pairs,
            devs,
        };
        let is = |w: &str| word.eq_ignore_ascii_case(w);
        let (message, known): (Self, &[&str]) = if is("INIT") {
            let init = Init {
                class_name: l.string("ClassName").unwrap_or_default(),
                name: l.string("Name"),
                location: l.vec3("Location"),
                rotation: l.vec3("Rotation"),
                start: l.string("Start"),
            };
            let known = &["ClassName", "Name", "Location", "Rotation", "Start"];
            (Self::Init(init), known)
        } else if is("DRIVE") {
            let drive = Drive::read(&mut l);
            (Self::Drive(drive), &DRIVE_KEYS)
        } else if is("GETSTARTPOSES") {
            (Self::GetStartPoses, &[])
        } else if is("GETCONF") || is("GETGEO") {
            let q = ItemQuery {
                kind: l.string("Type").unwrap_or_default(),
                name: l.string("Name"),
            };
            let m = if is("GETCONF") {
                Self::GetConf(q)
            } else {
                Self::GetGeo(q)
            };
            (m, &["Type", "Name"])
        } else if is("SET") {
            let set = Set {
                kind: l.string("Type").unwrap_or_default(),
                name: l.string("Name"),
                opcode: l.string("Opcode").unwrap_or_default(),
                params: l.string("Params"),
            };
            (Self::Set(set), &["Type", "Name", "Opcode", "Params"])
        } else if is("ACT") {
            let act = Act {
                name: l.string("Name").unwrap_or_default(),
                links: read_links(l.pairs, &mut l.devs),
                gripper: l.i64("Gripper"),
                sequence: l.i64("Sequence"),
            };
            (
                Self::Act(act),
                &["Name", "Link", "Value", "Gripper", "Sequence"],
            )
        } else if let Some(time) = is(SYNC_WORD).then(|| sync_time(&mut l)).flatten() {
            (Self::Sync(Barrier::at(time)), &["Time"])
        } else if is("MISPKG") {
            let mis = MisPkg {
                name: l.string("Name").unwrap_or_default(),
                links: read_links(l.pairs, &mut l.devs),
                order: l.i64("Order"),
            };
            (Self::MisPkg(mis), &["Name", "Link", "Value", "Order"])
        } else {
            l.devs.push(Deviation::UnknownCommand(word.to_owned()));
            (Self::Other(raw.to_message()), &[])
        };
        let mut deviations = if matches!(message, Self::Other(_)) {
            l.devs
        } else {
            l.finish(known)
        };
        let mut seen = Vec::with_capacity(deviations.len());
        deviations.retain(|d| {
            let new = !seen.contains(d);
            seen.push(d.clone());
            new
        });
        Ok(Parsed {
            message,
            deviations,
        })
    }

    /// Appends the canonical wire form, without the line terminator. Numbers use Rust's
    /// shortest round-trip form, so `Command::parse` gives the same command back.
    pub fn write_to(&self, out: &mut impl WireBuf) {
        match self {
            Self::Init(i) => {
                let mut w = Line::new(out, "INIT");
                w.text("ClassName", &i.class_name);
                if let Some(n) = &i.name {
                    w.text("Name", n);
                }
                if let Some(v) = i.location {
                    w.vec("Location", v);
                }
                if let Some(v) = i.rotation {
                    w.vec("Rotation", v);
                }
                if let Some(s) = &i.start {
                    w.text("Start", s);
                }
            }
            Self::Drive(d) => {
                let mut w = Line::new(out, "DRIVE");
                for (key, v) in DRIVE_NUMBERS.iter().zip(d.numbers()) {
                    if let Some(v) = v {
                        w.num(key, v);
                    }
                }
                if let Some(b) = d.light {
                    w.text("Light", if b { "true" } else { "false" });
                }
                if let Some(b) = d.normalized {
                    w.text("Normalized", if b { "true" } else { "false" });
                }
            }
            Self::GetStartPoses => out.push_text("GETSTARTPOSES"),
            Self::Sync(b) => b.write(out),
            Self::GetConf(q) | Self::GetGeo(q) => {
                let word = if matches!(self, Self::GetConf(_)) {
                    "GETCONF"
                } else {
                    "GETGEO"
                };
                let mut w = Line::new(out, word);
                w.text("Type", &q.kind);
                if let Some(n) = &q.name {
                    w.text("Name", n);
                }
            }
            Self::Set(s) => {
                let mut w = Line::new(out, "SET");
                w.text("Type", &s.kind);
                if let Some(n) = &s.name {
                    w.text("Name", n);
                }
                w.text("Opcode", &s.opcode);
                if let Some(p) = &s.params {
                    w.text("Params", p);
                }
            }
            Self::Act(a) => {
                let mut w = Line::new(out, "ACT");
                w.text("Name", &a.name);
                write_links(&mut w, &a.links);
                if let Some(g) = a.gripper {
                    w.int("Gripper", g);
                }
                if let Some(s) = a.sequence {
                    w.int("Sequence", s);
                }
            }
            Self::MisPkg(m) => {
                let mut w = Line::new(out, "MISPKG");
                w.text("Name", &m.name);
                write_links(&mut w, &m.links);
                if let Some(o) = m.order {
                    w.int("Order", o);
                }
            }
            Self::Other(m) => m.write_to(out),
        }
    }

    /// Appends the wire form and `\r\n` (for batching several lines into one write).
    pub fn write_line(&self, out: &mut impl WireBuf) {
        self.write_to(out);
        out.push_text("\r\n");
    }

    /// Checks that every text value can be printed into one line: no control character
    /// (CR, LF, TAB, NUL, ...) and no brace, which would end the line or the group and let
    /// a value inject a command. The printers do not check (they are the hot path); every
    /// door that sends commands built from user input does: the client codec (`ServerCodec`)
    /// and the `ucc-client` connection.
    ///
    /// ```
    /// use usar_proto::{Command, Init};
    /// let init = Command::Init(Init {
    ///     class_name: "USARBot.stsAirRobot".into(),
    ///     name: Some("UAV1\r\nGETSTARTPOSES".into()),
    ///     ..Init::default()
    /// });
    /// let error = init.check().unwrap_err();
    /// assert!(error.to_string().starts_with("INIT {Name ..}: \"UAV1\\r\\nGETSTARTPOSES\" holds a carriage return"));
    /// ```
    pub fn check(&self) -> Result<(), TextError> {
        let check = |word: &str, fields: &[(&str, Option<&str>)]| {
            fields.iter().try_for_each(|(key, value)| {
                value.map_or(Ok(()), |v| TextError::check(word, key, v))
            })
        };
        match self {
            Self::Init(i) => check(
                "INIT",
                &[
                    ("ClassName", Some(&i.class_name)),
                    ("Name", i.name.as_deref()),
                    ("Start", i.start.as_deref()),
                ],
            ),
            Self::GetConf(q) | Self::GetGeo(q) => check(
                if matches!(self, Self::GetConf(_)) {
                    "GETCONF"
                } else {
                    "GETGEO"
                },
                &[("Type", Some(&q.kind)), ("Name", q.name.as_deref())],
            ),
            Self::Set(s) => check(
                "SET",
                &[
                    ("Type", Some(&s.kind)),
                    ("Name", s.name.as_deref()),
                    ("Opcode", Some(&s.opcode)),
                    ("Params", s.params.as_deref()),
                ],
            ),
            Self::Act(a) => check("ACT", &[("Name", Some(&a.name))]),
            Self::MisPkg(m) => check("MISPKG", &[("Name", Some(&m.name))]),
            Self::Drive(_) | Self::GetStartPoses | Self::Sync(_) => Ok(()),
            Self::Other(m) => {
                TextError::check(&m.kind, "word", &m.kind)?;
                if let Some(line) = &m.verbatim {
                    TextError::check(&m.kind, "line", line)?;
                }
                m.groups.iter().flat_map(|g| &g.pairs).try_for_each(|p| {
                    TextError::check(&m.kind, "key", &p.key)?;
                    TextError::check(&m.kind, &p.key, &p.value)
                })
            }
        }
    }
}

impl std::fmt::Display for Command {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut s = String::new();
        self.write_to(&mut s);
        f.write_str(&s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cmd(line: &str) -> (Command, Vec<Deviation>) {
        let p = Command::parse(line).unwrap();
        (p.message, p.deviations)
    }

    #[test]
    fn a_class_without_package_is_a_usarbot_class() {
        assert_eq!(Init::qualified_class("stsAirRobot"), "USARBot.stsAirRobot");
        assert_eq!(Init::qualified_class("My.Robot"), "My.Robot");
    }

    #[test]
    fn init_with_location_and_start() {
        let (c, d) = cmd(
            "INIT {ClassName USARBot.pioneer3at_with_sensors}{Name p3}{Location 1,-1,0}{Rotation 0,0,0}{Battery 3600}",
        );
        assert_eq!(
            c,
            Command::Init(Init {
                class_name: "USARBot.pioneer3at_with_sensors".into(),
                name: Some("p3".into()),
                location: Some(Vec3::new(1.0, -1.0, 0.0)),
                rotation: Some(Vec3::new(0.0, 0.0, 0.0)),
                start: None,
            })
        );
        assert_eq!(
            d,
            vec![
                Deviation::MissingSpace,
                Deviation::UnknownKey("Battery".into())
            ]
        );
        assert_eq!(
            c.to_string(),
            "INIT {ClassName USARBot.pioneer3at_with_sensors} {Name p3} {Location 1,-1,0} {Rotation 0,0,0}"
        );
        let (c, _) = cmd("INIT {ClassName USARBot.stsAirRobot} {Name UAV1} {Start Point1}");
        assert_eq!(
            c.to_string(),
            "INIT {ClassName USARBot.stsAirRobot} {Name UAV1} {Start Point1}"
        );
    }

    #[test]
    fn drive_keys_any_case_and_normalized() {
        let (c, d) = cmd("DRIVE {RIGHT 1.0} {LEFT 1.0}");
        let Command::Drive(drive) = &c else {
            panic!("{c:?}")
        };
        assert_eq!((drive.left, drive.right), (Some(1.0), Some(1.0)));
        assert_eq!(
            d[0],
            Deviation::KeyCase {
                found: "LEFT".into(),
                expected: "Left".into()
            }
        );
        let (c, d) = cmd(
            "DRIVE {AltitudeVelocity 1} {LinearVelocity 0} {LateralVelocity 0} {RotationalVelocity 56} {PitchAngle 5} {RollAngle -5} {Spin1 7} {Spin2 7} {Normalized True}",
        );
        let Command::Drive(drive) = &c else {
            panic!("{c:?}")
        };
        assert_eq!(drive.normalized, Some(false));
        assert_eq!(drive.rotational_velocity, Some(56.0));
        assert_eq!(drive.pitch_angle, Some(5.0));
        assert_eq!(drive.spin2, Some(7.0));
        assert_eq!(
            d,
            vec![Deviation::BoolCase {
                key: "Normalized".into(),
                value: "True".into()
            }]
        );
        assert_eq!(
            c.to_string(),
            "DRIVE {AltitudeVelocity 1} {LinearVelocity 0} {LateralVelocity 0} {RotationalVelocity 56} {PitchAngle 5} {RollAngle -5} {Spin1 7} {Spin2 7} {Normalized false}"
        );
    }

    #[test]
    fn values_that_would_break_the_line_are_refused() {
        let init = |name: &str| {
            Command::Init(Init {
                class_name: "USARBot.stsAirRobot".into(),
                name: Some(name.into()),
                ..Init::default()
            })
        };
        assert_eq!(init("UAV1").check(), Ok(()));
        for (name, what) in [
            ("a\r\nGETSTARTPOSES", "a carriage return"),
            ("a\nb", "a line feed"),
            ("a\tb", "a tab"),
            ("a\0b", "a NUL"),
            ("a\u{1b}[2J", "a control character (U+001B)"),
            ("a} {Location 0,0,-50", "a brace (})"),
        ] {
            let e = init(name).check().unwrap_err();
            assert_eq!((e.command.as_str(), e.key.as_str()), ("INIT", "Name"));
            assert!(e.to_string().contains(what), "{e}");
        }
        let start = Command::Init(Init {
            start: Some("Start1\r\n".into()),
            ..Init::default()
        });
        assert_eq!(start.check().unwrap_err().key, "Start");
        let class = Command::Init(Init {
            class_name: "USARBot.x\r\nDRIVE {Left 1}".into(),
            ..Init::default()
        });
        assert_eq!(class.check().unwrap_err().key, "ClassName");
        let set = cmd("SET {Type Camera} {Opcode Zoom} {Params 0.5}").0;
        assert_eq!(set.check(), Ok(()));
        let mut other = cmd("MULTIDRIVE {FRFlipper 1.5}").0;
        assert_eq!(other.check(), Ok(()));
        if let Command::Other(m) = &mut other {
            m.groups[0].pairs[0].value = "1\r\nGETSTARTPOSES".into();
        }
        assert_eq!(other.check().unwrap_err().key, "FRFlipper");
        let long = init(&format!("{}\n", "x".repeat(500))).check().unwrap_err();
        assert!(long.to_string().len() < 250, "{long}");
    }

    #[test]
    fn other_commands() {
        assert_eq!(cmd("GETSTARTPOSES").0, Command::GetStartPoses);
        assert_eq!(
            cmd("GETGEO {Type Camera} ").0,
            Command::GetGeo(ItemQuery {
                kind: "Camera".into(),
                name: None
            })
        );
        let (c, _) = cmd("SET {Type Camera} {Name cams} {Opcode Zoom} {Params 0.5}");
        assert_eq!(
            c.to_string(),
            "SET {Type Camera} {Name cams} {Opcode Zoom} {Params 0.5}"
        );
        let (c, _) = cmd("ACT {Name cam} {Link 0} {Value 0.5} {Link 1} {Value -1}");
        assert_eq!(
            c,
            Command::Act(Act {
                name: "cam".into(),
                links: vec![
                    LinkValue {
                        link: 0,
                        value: 0.5
                    },
                    LinkValue {
                        link: 1,
                        value: -1.0
                    }
                ],
                gripper: None,
                sequence: None
            })
        );
        let (c, _) = cmd("MISPKG {Name cam} {Link 1} {Value 0.2} {Order 0}");
        assert_eq!(
            c.to_string(),
            "MISPKG {Name cam} {Link 1} {Value 0.2} {Order 0}"
        );
        let (c, d) = cmd("MULTIDRIVE {FRFlipper 1.5}{FLflipper 1.5}");
        assert_eq!(c.to_string(), "MULTIDRIVE {FRFlipper 1.5} {FLflipper 1.5}");
        assert!(d.contains(&Deviation::UnknownCommand("MULTIDRIVE".into())));
    }
}
