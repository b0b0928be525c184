//! `INS`: location and orientation (normalised to [0, 2π)), without a time stamp.

use usar_proto::{ConfItem, SenData};

use super::{NoSettings, Reading, Sensor, interval_conf, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

/// INS settings: none (drift is modelled by the part's `noise`).
pub type InsConfig = NoSettings;

#[derive(Debug, Clone)]
struct Ins;

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let _: InsConfig = settings(part)?;
    Ok(Box::new(Ins))
}

impl Sensor for Ins {
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        SenData::Ins {
            name: at.name.to_string(),
            location: at.position.map(|v| noise.apply(v)).into(),
            orientation: at
                .rotation
                .map(|a| a.rem_euclid(std::f64::consts::TAU))
                .into(),
        }
    }

    fn conf(&self, name: &str, interval: f64) -> ConfItem {
        interval_conf(name, interval)
    }

    fn timestamped(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    #[test]
    fn orientation_is_normalised() {
        let (scene, me) = scene_with_wall(2.0);
        let at = Reading {
            rotation: [0.0, -0.5, 7.0],
            ..reading(&scene, me, 0.2)
        };
        let mut ins = make("INS", "");
        assert!(!ins.timestamped());
        let SenData::Ins { orientation, .. } = ins.read(&at, &mut quiet()) else {
            panic!()
        };
        assert!((orientation.y - (std::f64::consts::TAU - 0.5)).abs() < 1e-12);
        assert!((orientation.z - (7.0 - std::f64::consts::TAU)).abs() < 1e-12);
    }
}
