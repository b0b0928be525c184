//! `Position` (stsPositionSensor, §9): the robot's world location, z down.

use usar_proto::{ConfItem, SenData};

use super::{NoSettings, Reading, Sensor, interval_conf, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

/// Position settings: none.
pub type PositionConfig = NoSettings;

#[derive(Debug, Clone)]
struct Position;

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let _: PositionConfig = settings(part)?;
    Ok(Box::new(Position))
}

impl Sensor for Position {
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        SenData::Position {
            name: at.name.to_string(),
            location: at.position.map(|v| noise.apply(v)).into(),
        }
    }

    fn conf(&self, name: &str, interval: f64) -> ConfItem {
        interval_conf(name, interval)
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    #[test]
    fn reports_the_world_location() {
        let (scene, me) = scene_with_wall(2.0);
        let at = Reading {
            position: [1.0, 2.0, -3.0],
            ..reading(&scene, me, 0.1)
        };
        let data = make("Position", "").read(&at, &mut quiet());
        assert_eq!(
            data,
            SenData::Position {
                name: "S".into(),
                location: [1.0, 2.0, -3.0].into()
            }
        );
    }
}
