//! `MagneticCompass`. The engine converts the yaw to radians twice and keeps an `int` in
//! between, so it reports `int(yaw_rad) / 10430.378` (always within ±0.0003 for yaws in
//! (-π, π]); `usarsim_quirk = false` reports the plain heading in [0, 2π) instead.

use serde::Deserialize;
use usar_proto::SenData;

use super::{Reading, Sensor, settings};
use crate::noise::{ErrorModel, Errors, Noise};
use crate::part::PartConfig;

/// Compass settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CompassConfig {
    /// Reproduce the engine's double conversion (default `true`).
    pub usarsim_quirk: bool,
    /// Heading errors (rad, on the yaw before the conversion); off by default.
    pub error: ErrorModel,
}

impl Default for CompassConfig {
    fn default() -> Self {
        Self {
            usarsim_quirk: true,
            error: ErrorModel::default(),
        }
    }
}

#[derive(Debug, Clone)]
struct Compass(CompassConfig, Errors<1>);

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let c: CompassConfig = settings(part)?;
    c.error.check(&format!("part `{}`: error", part.name))?;
    let errors = Errors::new(c.error.clone());
    Ok(Box::new(Compass(c, errors)))
}

impl Sensor for Compass {
    fn scale_noise(&mut self, k: f64) {
        self.1.scale(k);
    }

    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let [yaw] = self.1.apply([at.rotation[2]], at.time, noise);
        let angle = if self.0.usarsim_quirk {
            f64::from(yaw.trunc() as f32 / 10_430.378)
        } else {
            yaw.rem_euclid(std::f64::consts::TAU)
        };
        SenData::MagneticCompass {
            name: at.name.to_string(),
            angle,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    fn angle(sensor: &mut Box<dyn Sensor>, yaw: f64) -> f64 {
        let (scene, me) = scene_with_wall(2.0);
        let at = Reading {
            rotation: [0.0, 0.0, yaw],
            ..reading(&scene, me, 0.1)
        };
        match sensor.read(&at, &mut quiet()) {
            SenData::MagneticCompass { angle, .. } => angle,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    #[allow(clippy::approx_constant)] // a yaw as the engine would hold it
    fn quirk_and_plain() {
        let mut quirky = make("MagneticCompass", "");
        assert_eq!(format!("{:.4}", angle(&mut quirky, 1.5707)), "0.0001");
        assert_eq!(angle(&mut quirky, 0.5), 0.0);
        let mut plain = make("MagneticCompass", "usarsim_quirk = false");
        assert!((angle(&mut plain, -1.0) - (std::f64::consts::TAU - 1.0)).abs() < 1e-12);
    }
}
