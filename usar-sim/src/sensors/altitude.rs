//! `AltitudeSensor`: height above the spawn point (+ up) and that plus 111 m ASL.

use serde::Deserialize;
use usar_proto::SenData;

use super::{Reading, Sensor, settings};
use crate::noise::{ErrorModel, Errors, Noise};
use crate::part::PartConfig;

/// Altitude settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AltitudeConfig {
    /// Height of the spawn point above sea level, m (`ASL`).
    pub sea_level: f64,
    /// Barometric altimeter errors (m, on the relative altitude); off by default.
    pub error: ErrorModel,
}

impl Default for AltitudeConfig {
    fn default() -> Self {
        Self {
            sea_level: 111.0,
            error: ErrorModel::default(),
        }
    }
}

#[derive(Debug, Clone)]
struct Altitude(AltitudeConfig, Errors<1>);

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let c: AltitudeConfig = settings(part)?;
    c.error.check(&format!("part `{}`: error", part.name))?;
    let errors = Errors::new(c.error.clone());
    Ok(Box::new(Altitude(c, errors)))
}

impl Sensor for Altitude {
    fn scale_noise(&mut self, k: f64) {
        self.1.scale(k);
    }

    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let [truth] = self.1.apply([at.spawn_z - at.position[2]], at.time, noise);
        let relative = noise.apply(truth);
        SenData::AltitudeSensor {
            name: at.name.to_string(),
            relative,
            absolute: (relative + self.0.sea_level).max(0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    #[test]
    fn up_is_positive() {
        let (scene, me) = scene_with_wall(2.0);
        let mut sensor = make("AltitudeSensor", "");
        let at = Reading {
            position: [0.0, 0.0, -3.5],
            spawn_z: -1.0,
            ..reading(&scene, me, 1.0)
        };
        let SenData::AltitudeSensor {
            relative, absolute, ..
        } = sensor.read(&at, &mut quiet())
        else {
            panic!()
        };
        assert_eq!((relative, absolute), (2.5, 113.5));
        let deep = Reading {
            position: [0.0, 0.0, 200.0],
            ..reading(&scene, me, 1.0)
        };
        let SenData::AltitudeSensor { absolute, .. } = sensor.read(&deep, &mut quiet()) else {
            panic!()
        };
        assert_eq!(absolute, 0.0);
    }
}
