//! `Magnetometer` (ours): a 3-axis magnetometer, `{Name n} {Field x,y,z}`: the map's
//! magnetic field (`[geo] magnetic_field`, docs/maps.md#geo; a mid-latitude default) in the
//! body frame (x forward, y right, z down), µT, through an error model (noise, turn-on bias
//! — the hard-iron offset of an uncalibrated sensor —, bias walk, scale, quantum, latency).

use serde::Deserialize;
use usar_proto::SenData;

use super::{Reading, Sensor, settings};
use crate::noise::{ErrorModel, Errors, Noise};
use crate::part::PartConfig;

/// Magnetometer settings: its error model in µT, off by default.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MagnetometerConfig {
    /// Errors on each axis, µT.
    pub error: ErrorModel,
}

#[derive(Debug, Clone)]
struct Magnetometer {
    errors: Errors<3>,
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let c: MagnetometerConfig = settings(part)?;
    c.error.check(&format!("part `{}`: error", part.name))?;
    Ok(Box::new(Magnetometer {
        errors: Errors::new(c.error),
    }))
}

impl Sensor for Magnetometer {
    fn scale_noise(&mut self, k: f64) {
        self.errors.scale(k);
    }

    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let field = at.to_body(at.scene.geo.magnetic_field);
        let field = self
            .errors
            .apply(field, at.time, noise)
            .map(|v| noise.apply(v));
        SenData::Magnetometer {
            name: at.name.to_string(),
            field: field.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    fn field(data: &SenData) -> [f64; 3] {
        match data {
            SenData::Magnetometer { field, .. } => [field.x, field.y, field.z],
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_field_turns_with_the_body() {
        let (scene, me) = scene_with_wall(2.0);
        // Facing north: the map's field (default 20 µT north, 45 down).
        let north = make("Magnetometer", "").read(&reading(&scene, me, 0.1), &mut quiet());
        let f = field(&north);
        assert!((f[0] - 20.0).abs() < 1e-9 && f[1].abs() < 1e-9 && (f[2] - 45.0).abs() < 1e-9);
        // Facing east (yaw +90°): north is to the left (−y).
        let east = Reading {
            rotation: [0.0, 0.0, std::f64::consts::FRAC_PI_2],
            yaw: std::f64::consts::FRAC_PI_2,
            ..reading(&scene, me, 0.1)
        };
        let f = field(&make("Magnetometer", "").read(&east, &mut quiet()));
        assert!(f[0].abs() < 1e-9 && (f[1] + 20.0).abs() < 1e-9, "{f:?}");
    }

    #[test]
    fn noise_and_bias_follow_the_error_model() {
        let (scene, me) = scene_with_wall(2.0);
        let mut sensor = make("Magnetometer", "error = { noise = 0.5, bias = 2.0 }");
        let mut rng = crate::noise::Noise::new(7, 1, 2, 0.0);
        let n = 4000;
        let xs: Vec<f64> = (0..n)
            .map(|i| {
                let at = reading(&scene, me, 0.01 * f64::from(i));
                field(&sensor.read(&at, &mut rng))[0]
            })
            .collect();
        let mean = xs.iter().sum::<f64>() / f64::from(n);
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / f64::from(n)).sqrt();
        assert!((sd - 0.5).abs() < 0.05, "noise {sd}");
        assert!((mean - 20.0).abs() > 1e-3, "a turn-on bias: {mean}");
        assert!(build(&part("Magnetometer", "error = { noise = -1.0 }")).is_err());
    }
}
