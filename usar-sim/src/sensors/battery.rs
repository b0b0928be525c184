//! `Battery` (ours, docs/quadrotor.md#energy): the voltage, current, charge and time left of
//! a robot with an energy model, `SEN {Time t} {Type Battery} {Name n} {Voltage v}
//! {Current a} {Charge c} {TimeLeft s}`. A robot without one (USARSim's battery timer)
//! reports nothing but its name.

use usar_proto::{Group, Pair, SenData};

use super::{NoSettings, Reading, Sensor, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

#[derive(Debug, Clone)]
struct Battery;

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let _: NoSettings = settings(part)?;
    Ok(Box::new(Battery))
}

/// `{key value}` with 4 decimals.
pub(super) fn pair(key: &str, value: String) -> Group {
    Group {
        pairs: vec![Pair {
            key: key.into(),
            value,
        }],
    }
}

impl Sensor for Battery {
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let mut groups = vec![pair("Name", at.name.to_string())];
        if let Some(g) = at.gauge {
            let time_left = if g.time_left.is_finite() {
                g.time_left.min(1e9)
            } else {
                1e9
            };
            groups.extend([
                pair("Voltage", format!("{:.4}", noise.apply(g.voltage).max(0.0))),
                pair("Current", format!("{:.4}", noise.apply(g.current).max(0.0))),
                pair("Charge", format!("{:.4}", g.charge)),
                pair("TimeLeft", format!("{time_left:.1}")),
            ]);
        }
        SenData::Other {
            kind: "Battery".into(),
            groups,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;
    use crate::power::Gauge;

    #[test]
    fn reports_the_gauge() {
        let (scene, me) = scene_with_wall(2.0);
        let at = Reading {
            gauge: Some(Gauge {
                voltage: 12.1,
                current: 9.5,
                charge: 0.75,
                time_left: 812.34,
            }),
            ..reading(&scene, me, 0.1)
        };
        let data = make("Battery", "").read(&at, &mut quiet());
        let line = usar_proto::ServerMessage::Sen(usar_proto::Sen { time: None, data }).to_string();
        assert!(
            line.contains(
                "{Type Battery} {Name S} {Voltage 12.1000} {Current 9.5000} {Charge 0.7500} {TimeLeft 812.3}"
            ),
            "{line}"
        );
    }
}
