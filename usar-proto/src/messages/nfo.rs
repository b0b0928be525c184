//! `NFO`: game info on connect (§3.1) and the GETSTARTPOSES reply (§2.2), in the UDK layout
//! `{StartPoses n} {name x,y,z r,p,y name ...}` (4 decimals) or the old one
//! `{StartPoses n} {Name n Location x,y,z Orientation r,p,y} ...` (2 decimals).

use super::line::Line;
use super::server::{Nfo, StartPose};
use crate::error::ParseError;
use crate::format::{self, WireBuf};
use crate::primitive::Vec3;
use crate::value::Reader;

impl Nfo {
    /// `None` for NFO forms without a typed model (PathNodes, Pathnode).
    pub(crate) fn read(r: Reader<'_, '_>) -> Result<Option<Self>, ParseError> {
        if r.has("Gametype") {
            return Ok(Some(Self::GameInfo {
                gametype: r.string("Gametype")?,
                level: r.string("Level")?,
                time_limit: r.i64("TimeLimit")?,
            }));
        }
        let Some(at) = r
            .pairs
            .iter()
            .position(|p| p.key.eq_ignore_ascii_case("StartPoses"))
        else {
            return Ok(None);
        };
        r.i64("StartPoses")?;
        let rest = r.sub("start poses", &r.pairs[at + 1..]);
        if rest.has("Location") && rest.has("Orientation") {
            let poses = rest
                .items()
                .map(|it| {
                    Ok(StartPose {
                        name: it.string("Name")?,
                        location: it.vec3("Location")?,
                        rotation: it.vec3("Orientation")?,
                    })
                })
                .collect::<Result<_, ParseError>>()?;
            return Ok(Some(Self::StartPoses {
                poses,
                old_layout: true,
            }));
        }
        let tokens: Vec<&str> = rest
            .pairs
            .iter()
            .flat_map(|p| std::iter::once(p.key).chain(p.value.split_whitespace()))
            .filter(|t| !t.is_empty())
            .collect();
        if !tokens.len().is_multiple_of(3) {
            return Err(rest.error("expected name, location and rotation for each pose"));
        }
        let poses = tokens
            .chunks(3)
            .map(|c| {
                Ok(StartPose {
                    name: c[0].to_owned(),
                    location: rest.vec3_in(c[0], c[1])?,
                    rotation: rest.vec3_in(c[0], c[2])?,
                })
            })
            .collect::<Result<_, ParseError>>()?;
        Ok(Some(Self::StartPoses {
            poses,
            old_layout: false,
        }))
    }

    pub(crate) fn write(&self, out: &mut impl WireBuf) {
        let mut w = Line::new(out, "NFO");
        match self {
            Self::GameInfo {
                gametype,
                level,
                time_limit,
            } => {
                w.text("Gametype", gametype)
                    .text("Level", level)
                    .int("TimeLimit", *time_limit);
            }
            Self::StartPoses { poses, old_layout } => {
                w.int("StartPoses", poses.len() as i64);
                if *old_layout {
                    for p in poses {
                        w.raw(" {Name ").raw(&p.name).raw(" Location ");
                        vector(&mut w, p.location, 2);
                        w.raw(" Orientation ");
                        vector(&mut w, p.rotation, 2);
                        w.raw("}");
                    }
                } else if !poses.is_empty() {
                    w.raw(" {");
                    for (i, p) in poses.iter().enumerate() {
                        if i > 0 {
                            w.raw(" ");
                        }
                        w.raw(&p.name).raw(" ");
                        vector(&mut w, p.location, 4);
                        w.raw(" ");
                        vector(&mut w, p.rotation, 4);
                    }
                    w.raw("}");
                }
            }
        }
    }
}

/// Three implicit floats joined by commas.
fn vector<B: WireBuf>(w: &mut Line<'_, B>, v: Vec3, decimals: u8) {
    let mut s = String::with_capacity(32);
    format::push_fixed_list(&mut s, &[v.x, v.y, v.z], decimals);
    w.raw(&s);
}

#[cfg(test)]
mod tests {
    use crate::messages::testutil::round_trip;
    use crate::{Nfo, ServerMessage, StartPose, Vec3};

    #[test]
    fn game_info() {
        assert_eq!(
            round_trip("NFO {Gametype BotDeathMatch} {Level EmptyRoom} {TimeLimit 20}"),
            ServerMessage::Nfo(Nfo::GameInfo {
                gametype: "BotDeathMatch".into(),
                level: "EmptyRoom".into(),
                time_limit: 20
            })
        );
    }

    #[test]
    fn start_poses_all_layouts() {
        round_trip("NFO {StartPoses 0}");
        let m =
            round_trip("NFO {StartPoses 1} {Start1 -5.4734,27.8247,1.4720 0.0000,0.0000,-3.4361}");
        assert_eq!(
            m,
            ServerMessage::Nfo(Nfo::StartPoses {
                poses: vec![StartPose {
                    name: "Start1".into(),
                    location: Vec3::new(-5.4734, 27.8247, 1.472),
                    rotation: Vec3::new(0.0, 0.0, -3.4361)
                }],
                old_layout: false
            })
        );
        let m = round_trip(
            "NFO {StartPoses 2} {A 1.0000,2.0000,3.0000 0.0000,0.0000,0.0000 B 4.0000,5.0000,6.0000 0.0000,0.0000,1.5708}",
        );
        let ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) = m else {
            panic!()
        };
        assert_eq!(poses[1].name, "B");
        let m = round_trip(
            "NFO {StartPoses 2} {Name UnitLoader1 Location 10.24,3.54,10.05 Orientation 0.00,0.00,1.60} {Name UnitLoader2 Location 1.00,2.00,3.00 Orientation 0.00,0.00,0.00}",
        );
        let ServerMessage::Nfo(Nfo::StartPoses { poses, old_layout }) = m else {
            panic!()
        };
        assert!(old_layout);
        assert_eq!(poses[0].location, Vec3::new(10.24, 3.54, 10.05));
    }

    #[test]
    fn other_nfo_is_kept() {
        let m = round_trip("NFO {PathNodes 0}");
        assert!(matches!(m, ServerMessage::Other(_)));
    }
}
