//! `ASTA`, `EFF` and `DIE` (protocol.md §3.5).

use super::command::LinkValue;
use super::line::Line;
use super::server::{Asta, Die, Eff};
use crate::error::ParseError;
use crate::format::WireBuf;
use crate::value::Reader;
use crate::value::time;

impl Asta {
    pub(crate) fn read(r: Reader<'_, '_>) -> Result<Self, ParseError> {
        let mut links = Vec::new();
        let mut link = 0;
        for p in r.pairs {
            if p.key.eq_ignore_ascii_case("Link") {
                link = r.int_in("Link", p.value)?;
            } else if p.key.eq_ignore_ascii_case("Value") {
                let value = r.number_in("Value", p.value)?;
                links.push(LinkValue { link, value });
            }
        }
        Ok(Self {
            time: time(&r)?,
            name: r.string("Name")?,
            links,
        })
    }

    pub(crate) fn write(&self, out: &mut impl WireBuf) {
        let mut w = Line::new(out, "ASTA");
        w.time(self.time).text("Name", &self.name);
        for l in &self.links {
            w.int("Link", l.link).fixed("Value", l.value, 4);
        }
    }
}

impl Eff {
    pub(crate) fn read(r: Reader<'_, '_>) -> Result<Self, ParseError> {
        let on = match (r.has("On"), r.has("Off")) {
            (true, false) => true,
            (false, true) => false,
            _ => return Err(r.error("expected exactly one of {On} and {Off}")),
        };
        Ok(Self {
            time: time(&r)?,
            kind: r.string("Type")?,
            name: r.string("Name")?,
            on,
        })
    }

    pub(crate) fn write(&self, out: &mut impl WireBuf) {
        let mut w = Line::new(out, "EFF");
        w.time(self.time)
            .text("Type", &self.kind)
            .text("Name", &self.name)
            .bare(if self.on { "On" } else { "Off" });
    }
}

impl Die {
    pub(crate) fn read(r: Reader<'_, '_>) -> Result<Self, ParseError> {
        Ok(Self {
            killer: r.string("Killer")?,
            damage_type: r.string("DamageType")?,
        })
    }

    pub(crate) fn write(&self, out: &mut impl WireBuf) {
        Line::new(out, "DIE")
            .text("Killer", &self.killer)
            .text("DamageType", &self.damage_type);
    }
}

#[cfg(test)]
mod tests {
    use crate::messages::testutil::round_trip;
    use crate::{Asta, LinkValue, ServerMessage, Time};

    #[test]
    fn asta_eff_die() {
        assert_eq!(
            round_trip("ASTA {Time 12.3456} {Name cam} {Link 1} {Value 0.0000}"),
            ServerMessage::Asta(Asta {
                time: Time::udk(12.3456),
                name: "cam".into(),
                links: vec![LinkValue {
                    link: 1,
                    value: 0.0
                }]
            })
        );
        round_trip(
            "ASTA {Time 1.0000} {Name arm} {Link 1} {Value 0.5000} {Link 2} {Value -1.2500}",
        );
        round_trip("EFF {Time 1.0000} {Type Gripper} {Name g} {On}");
        round_trip("EFF {Time 1.0000} {Type Gripper} {Name g} {Off}");
        round_trip("DIE {Killer Robot2} {DamageType Crushed}");
    }
}
