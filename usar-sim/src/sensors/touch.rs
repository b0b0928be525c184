//! `Touch` (USARSim `Touch.uc`): `{Name n} {Touch True|False}`. Two kinds of event:
//! `contact` (the body touched something during the last tick, a bumper) and `crash`
//! (latched: the robot has crashed, docs/quadrotor.md). A stock client reads either as a
//! bumper line.

use serde::Deserialize;
use usar_proto::SenData;

use super::{Reading, Sensor, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

/// What makes the sensor read `True`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TouchEvent {
    /// Any contact in the last tick.
    #[default]
    Contact,
    /// The robot has crashed (stays `True`).
    Crash,
}

/// Touch settings.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TouchConfig {
    /// `"contact"` (default) or `"crash"`.
    pub event: TouchEvent,
}

#[derive(Debug, Clone)]
struct Touch {
    event: TouchEvent,
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let config: TouchConfig = settings(part)?;
    Ok(Box::new(Touch {
        event: config.event,
    }))
}

impl Sensor for Touch {
    fn read(&mut self, at: &Reading<'_>, _noise: &mut Noise) -> SenData {
        SenData::Touch {
            name: at.name.to_string(),
            touch: match self.event {
                TouchEvent::Contact => at.contact || at.crashed,
                TouchEvent::Crash => at.crashed,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    #[test]
    fn crash_and_contact_lines() {
        let (scene, me) = scene_with_wall(2.0);
        let mut crash = make("Touch", "event = \"crash\"");
        let mut bumper = make("Touch", "");
        let touching = Reading {
            contact: true,
            ..reading(&scene, me, 0.1)
        };
        let line = |data| {
            usar_proto::ServerMessage::Sen(usar_proto::Sen {
                time: Some(usar_proto::Time::udk(0.1)),
                data,
            })
            .to_string()
        };
        assert_eq!(
            line(crash.read(&touching, &mut quiet())),
            "SEN {Time 0.1000} {Type Touch} {Name S} {Touch False}"
        );
        assert_eq!(
            line(bumper.read(&touching, &mut quiet())),
            "SEN {Time 0.1000} {Type Touch} {Name S} {Touch True}"
        );
        let crashed = Reading {
            crashed: true,
            ..reading(&scene, me, 0.1)
        };
        assert!(line(crash.read(&crashed, &mut quiet())).ends_with("{Touch True}"));
        assert!(
            (super::super::find("touch").unwrap().build)(&part("Touch", "event = \"bump\""))
                .unwrap_err()
                .contains("bump")
        );
    }
}
