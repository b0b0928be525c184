//! `GEO`: replies to GETGEO (protocol.md §3.4): `GEO {Name AirRobot}`, the ground-vehicle
//! line as captured (`GEO  {Name P3AT} ...`, two spaces, 4-decimal implicit floats), and part
//! lines `GEO {Type T} {Name n} {Location ..} {Orientation ..}{Mount m}[{MountLink k}] ...`
//! (implicit vectors, `{Mount` glued to the group before it, or after a space in other real
//! UDK lines: [`GeoLayout`], kept per item so that both print back exactly). The UT2004 layout
//! `{Name F2 Location .. Orientation .. Mount HARD}` is read too (and printed in UDK layout).

use super::line::Line;
use super::server::{Geo, GeoItem, GeoLayout};
use crate::error::ParseError;
use crate::format::WireBuf;
use crate::message::{RawPair, find};
use crate::primitive::Vec3;
use crate::value::Reader;

impl Geo {
    /// `None` for a robot-level layout other than the aerial and ground-vehicle ones. `line`
    /// is the line the pairs borrow from (for the spacing before each `{Mount`).
    pub(crate) fn read(r: Reader<'_, '_>, line: &str) -> Result<Option<Self>, ParseError> {
        let first = r.pairs.first().map(|p| p.key);
        if first.is_some_and(|k| k.eq_ignore_ascii_case("Type")) {
            let rest = r.sub("", &r.pairs[1..]);
            return Ok(Some(Self::Items {
                kind: r.string("Type")?,
                items: rest
                    .items()
                    .map(|it| {
                        Ok(GeoItem {
                            name: it.string("Name")?,
                            location: it.vec3("Location")?,
                            orientation: it.vec3("Orientation")?,
                            mount: it.string("Mount")?,
                            mount_link: it.opt_i64("MountLink")?,
                            layout: {
                                let spaced =
                                    |key| find(it.pairs, key).is_some_and(|p| spaced(line, p));
                                match (spaced("Mount"), spaced("MountLink")) {
                                    (true, true) => GeoLayout::SpacedLink,
                                    (true, false) => GeoLayout::Spaced,
                                    (false, _) => GeoLayout::Glued,
                                }
                            },
                        })
                    })
                    .collect::<Result<_, ParseError>>()?,
            }));
        }
        if r.keys_are(&["Name"]) {
            return Ok(Some(Self::Robot {
                name: r.string("Name")?,
            }));
        }
        if !r.has("Dimensions") {
            return Ok(None);
        }
        Ok(Some(Self::GroundVehicle {
            name: r.string("Name")?,
            dimensions: r.vec3("Dimensions")?,
            cog: r.vec3("COG")?,
            wheel_radius: r.f64("WheelRadius")?,
            wheel_separation: r.f64("WheelSeparation")?,
            wheel_base: r.f64("WheelBase")?,
        }))
    }

    pub(crate) fn write(&self, out: &mut impl WireBuf) {
        match self {
            Self::Robot { name } => {
                Line::new(out, "GEO").text("Name", name);
            }
            Self::GroundVehicle {
                name,
                dimensions,
                cog,
                wheel_radius,
                wheel_separation,
                wheel_base,
            } => {
                let list = |v: &Vec3| [v.x, v.y, v.z];
                Line::new(out, "GEO ")
                    .text("Name", name)
                    .text("Type", "GroundVehicle")
                    .fixed_list("Dimensions", &list(dimensions), 4)
                    .fixed_list("COG", &list(cog), 4)
                    .fixed("WheelRadius", *wheel_radius, 4)
                    .fixed("WheelSeparation", *wheel_separation, 4)
                    .fixed("WheelBase", *wheel_base, 4);
            }
            Self::Items { kind, items } => {
                let mut w = Line::new(out, "GEO");
                w.text("Type", kind);
                for it in items {
                    w.text("Name", &it.name)
                        .ivec("Location", it.location)
                        .ivec("Orientation", it.orientation);
                    if it.layout == GeoLayout::Glued {
                        w.glue();
                    }
                    w.text("Mount", &it.mount);
                    if let Some(k) = it.mount_link {
                        if it.layout != GeoLayout::SpacedLink {
                            w.glue();
                        }
                        w.int("MountLink", k);
                    }
                }
            }
        }
    }
}

/// Whether the group of `pair` (a pair borrowed from `line`) starts with `{` right after a
/// space: ` {Mount P3AT}`, not `}{Mount P3AT}` nor `{Name F2 .. Mount HARD}`.
fn spaced(line: &str, pair: &RawPair<'_>) -> bool {
    let at = (pair.key.as_ptr() as usize).checked_sub(line.as_ptr() as usize);
    let Some(before) = at.and_then(|at| line.as_bytes().get(..at)) else {
        return false;
    };
    before
        .trim_ascii_end()
        .strip_suffix(b"{")
        .is_some_and(|b| b.ends_with(b" "))
}

#[cfg(test)]
mod tests {
    use crate::messages::testutil::round_trip;
    use crate::{Geo, GeoItem, GeoLayout, ServerMessage, Vec3};

    #[test]
    fn capture_lines() {
        let m = round_trip(
            "GEO {Type RangeScanner} {Name lms200} {Location 0.21,-0.00,-0.20} {Orientation 0.00,-0.00,-0.00}{Mount P3AT}",
        );
        assert_eq!(
            m,
            ServerMessage::Geo(Geo::Items {
                kind: "RangeScanner".into(),
                items: vec![GeoItem {
                    name: "lms200".into(),
                    location: Vec3::new(0.21, -0.0, -0.2),
                    orientation: Vec3::new(0.0, -0.0, -0.0),
                    mount: "P3AT".into(),
                    mount_link: None,
                    layout: GeoLayout::Glued,
                }]
            })
        );
        round_trip(
            "GEO  {Name P3AT} {Type GroundVehicle} {Dimensions 0.2480,0.3600,0.0000} {COG 0.0000,0.0000,0.0000} {WheelRadius 0.0980} {WheelSeparation 0.3600} {WheelBase 0.2480}",
        );
        round_trip("GEO {Name AirRobot}");
        round_trip(
            "GEO {Type Camera} {Name cams} {Location 0.10,-0.00,0.05} {Orientation 0.00,-0.79,0.00}{Mount cam}{MountLink 1}",
        );
        // A space before `{Mount` (and `{MountLink`), or none, per item.
        let m = round_trip(
            "GEO {Type Sonar} {Name F1} {Location 0.19,-0.12,0.00} {Orientation 0.00,0.00,-0.87} {Mount P3AT} {Name F2} {Location 0.19,0.12,0.00} {Orientation 0.00,0.00,0.87}{Mount cam}{MountLink 2} {Name F3} {Location 0.19,0.12,0.00} {Orientation 0.00,0.00,0.87} {Mount cam}{MountLink 3} {Name F4} {Location 0.19,0.12,0.00} {Orientation 0.00,0.00,0.87} {Mount cam} {MountLink 4}",
        );
        let ServerMessage::Geo(Geo::Items { items, .. }) = m else {
            panic!()
        };
        let layouts: Vec<GeoLayout> = items.iter().map(|it| it.layout).collect();
        use GeoLayout::*;
        assert_eq!(layouts, [Spaced, Glued, Spaced, SpacedLink]);
        assert_eq!(items[1].mount_link, Some(2));
        assert_eq!(items[3].mount_link, Some(4));
        let m = ServerMessage::parse("GEO {Type Sonar} {Name F2 Location 0.1850,-0.1150,0.0000 Orientation 0.0000,0.0000,-0.8727 Mount HARD}").unwrap().message;
        assert_eq!(
            m.to_string(),
            "GEO {Type Sonar} {Name F2} {Location 0.18,-0.12,0.00} {Orientation 0.00,0.00,-0.87}{Mount HARD}"
        );
    }
}
