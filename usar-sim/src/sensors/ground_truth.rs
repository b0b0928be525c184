//! `GroundTruth`: the robot's exact location and attitude (3 decimals, as since 2013-07-26).

use usar_proto::{ConfItem, SenData};

use super::{NoSettings, Reading, Sensor, interval_conf, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

/// GroundTruth settings: none.
pub type GroundTruthConfig = NoSettings;

#[derive(Debug, Clone)]
struct GroundTruth;

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let _: GroundTruthConfig = settings(part)?;
    Ok(Box::new(GroundTruth))
}

impl Sensor for GroundTruth {
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        SenData::GroundTruth {
            name: at.name.to_string(),
            location: at.position.map(|v| noise.apply(v)).into(),
            orientation: at.rotation.into(),
            decimals: 3,
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
    fn exact_pose() {
        let (scene, me) = scene_with_wall(2.0);
        let at = Reading {
            position: [1.0, -2.0, -0.5],
            rotation: [0.0, 0.1, 7.0],
            ..reading(&scene, me, 0.1)
        };
        assert_eq!(
            make("GroundTruth", "").read(&at, &mut quiet()),
            SenData::GroundTruth {
                name: "S".into(),
                location: [1.0, -2.0, -0.5].into(),
                orientation: [0.0, 0.1, 7.0].into(),
                decimals: 3,
            }
        );
    }
}
