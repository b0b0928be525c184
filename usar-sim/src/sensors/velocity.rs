//! `Velocity` (stsVelocitySensor, §9): world velocity and body-frame velocity.

use usar_proto::{ConfItem, SenData};

use serde::Deserialize;

use super::{Reading, Sensor, interval_conf, settings};
use crate::noise::{ErrorModel, Errors, Noise};
use crate::part::PartConfig;

/// Velocity settings: an error model on the world velocity, m/s, off by default (the
/// body-frame velocity is the noisy one turned into the body).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VelocityConfig {
    /// Errors on each component of the world velocity, m/s.
    pub error: ErrorModel,
}

#[derive(Debug, Clone)]
struct Velocity {
    errors: Errors<3>,
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let c: VelocityConfig = settings(part)?;
    c.error.check(&format!("part `{}`: error", part.name))?;
    Ok(Box::new(Velocity {
        errors: Errors::new(c.error),
    }))
}

impl Sensor for Velocity {
    fn scale_noise(&mut self, k: f64) {
        self.errors.scale(k);
    }

    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        // Off by default: no draws, the line stays byte-identical.
        let absolute = self
            .errors
            .apply(at.velocity, at.time, noise)
            .map(|v| noise.apply(v));
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

    #[test]
    fn an_error_model_makes_it_noisy() {
        let (scene, me) = scene_with_wall(2.0);
        let mut sensor = make("Velocity", "error = { noise = 0.1 }");
        let mut rng = crate::noise::Noise::new(3, 1, 1, 0.0);
        let n = 2000;
        let xs: Vec<f64> = (0..n)
            .map(|i| {
                let at = reading(&scene, me, 0.1 * f64::from(i));
                match sensor.read(&at, &mut rng) {
                    SenData::Velocity { absolute, .. } => absolute.x,
                    other => panic!("{other:?}"),
                }
            })
            .collect();
        let sd = (xs.iter().map(|x| x * x).sum::<f64>() / f64::from(n)).sqrt();
        assert!((sd - 0.1).abs() < 0.01, "{sd}");
        assert!(build(&part("Velocity", "error = { noise = -0.1 }")).is_err());
        assert!(build(&part("Velocity", "speed = 1.0")).is_err());
    }
}
