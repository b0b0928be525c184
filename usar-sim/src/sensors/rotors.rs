//! `Rotors` (ours, docs/quadrotor.md): the rotor speeds of a quadrotor in rotor order, rad/s,
//! `SEN {Time t} {Type Rotors} {Name n} {Speeds w1,w2,w3,w4}` (nothing but the name on a
//! kinematic robot).

use usar_proto::SenData;

use super::battery::pair;
use super::{NoSettings, Reading, Sensor, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

#[derive(Debug, Clone)]
struct Rotors;

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let _: NoSettings = settings(part)?;
    Ok(Box::new(Rotors))
}

impl Sensor for Rotors {
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let mut groups = vec![pair("Name", at.name.to_string())];
        if let Some(w) = at.rotors {
            let w = w.map(|w| format!("{:.2}", noise.apply(w)));
            groups.push(pair("Speeds", w.join(",")));
        }
        SenData::Other {
            kind: "Rotors".into(),
            groups,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    #[test]
    fn reports_the_speeds_in_rotor_order() {
        let (scene, me) = scene_with_wall(2.0);
        let at = Reading {
            rotors: Some([700.0, 701.5, 702.25, 703.125]),
            ..reading(&scene, me, 0.1)
        };
        let data = make("Rotors", "").read(&at, &mut quiet());
        let line = usar_proto::ServerMessage::Sen(usar_proto::Sen { time: None, data }).to_string();
        assert!(
            line.ends_with("{Type Rotors} {Name S} {Speeds 700.00,701.50,702.25,703.12}"),
            "{line}"
        );
    }
}
