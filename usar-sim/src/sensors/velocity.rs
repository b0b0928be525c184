//! `Velocity` (stsVelocitySensor, §9): world velocity and body-frame velocity.

use usar_proto::{ConfItem, SenData};

use super::{NoSettings, Reading, Sensor, interval_conf, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

/// Velocity settings: none.
pub type VelocityConfig = NoSettings;

#[derive(Debug, Clone)]
struct Velocity;

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let _: VelocityConfig = settings(part)?;
    Ok(Box::new(Velocity))
}

impl Sensor for Velocity {
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let absolute = at.velocity.map(|v| noise.apply(v));
        SenData::Velocity {
            name: at.name.to_string(),
            absolute: absolute.into(),
            relative: at.to_body(absolute).into(),
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
    fn relative_is_in_the_body_frame() {
        let (scene, me) = scene_with_wall(2.0);
        // Heading east, flying east at 1 m/s and climbing at 0.5 m/s.
        let at = Reading {
            velocity: [0.0, 1.0, -0.5],
            rotation: [0.0, 0.0, std::f64::consts::FRAC_PI_2],
            ..reading(&scene, me, 0.1)
        };
        let SenData::Velocity {
            absolute, relative, ..
        } = make("Velocity", "").read(&at, &mut quiet())
        else {
            panic!()
        };
        assert_eq!(absolute, [0.0, 1.0, -0.5].into());
        assert!((relative.x - 1.0).abs() < 1e-12 && relative.y.abs() < 1e-12);
        assert_eq!(relative.z, -0.5);
    }
}
