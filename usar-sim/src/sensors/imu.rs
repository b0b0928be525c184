//! `IMU`: finite differences over the scan interval (USARSim `IMU.uc`); gravity excluded.
//! On a robot with physics (the quadrotor) it measures the truth instead: specific force
//! (gravity included) and body rates.

use usar_proto::{SenData, Vec3};

use serde::Deserialize;

use super::{Reading, Sensor, settings};
use crate::dynamics::{ImuTruth, wrap_angle};
use crate::noise::{ErrorModel, Errors, Noise};
use crate::part::PartConfig;
use crate::scene::V3;

/// IMU settings: the error models of the accelerometer (m/s²) and the gyro (rad/s), off by
/// default (the engine adds no noise to the IMU either).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuConfig {
    /// Accelerometer errors (on `XYZAcceleration`).
    pub accel: ErrorModel,
    /// Gyro errors (on `AngularVel`).
    pub gyro: ErrorModel,
    /// Attitude errors, rad (on `Rotation`: roll, pitch, yaw as an attitude estimator would
    /// give them; GroundTruth keeps the truth).
    pub attitude: ErrorModel,
}

#[derive(Debug, Clone)]
struct Imu {
    /// The previous reading: time, world velocity, attitude, angular rates.
    last: Option<(f64, V3, V3, V3)>,
    accel: Errors<3>,
    gyro: Errors<3>,
    attitude: Errors<3>,
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let c: ImuConfig = settings(part)?;
    c.accel.check(&format!("part `{}`: accel", part.name))?;
    c.gyro.check(&format!("part `{}`: gyro", part.name))?;
    c.attitude
        .check(&format!("part `{}`: attitude", part.name))?;
    Ok(Box::new(Imu {
        last: None,
        accel: Errors::new(c.accel),
        gyro: Errors::new(c.gyro),
        attitude: Errors::new(c.attitude),
    }))
}

impl Imu {
    /// A model with physics: specific force (gravity included, as an accelerometer measures
    /// it; hovering reads +g on z) and body rates; the angular acceleration is the rates'
    /// difference over the interval.
    fn read_truth(&mut self, at: &Reading<'_>, truth: ImuTruth) -> SenData {
        let f = truth.specific_force;
        let rates = truth.body_rates;
        let rate_accel = match self.last {
            Some((t, _, _, w)) if at.time > t => {
                std::array::from_fn(|i| (rates[i] - w[i]) / (at.time - t))
            }
            _ => [0.0; 3],
        };
        self.last = Some((at.time, at.velocity, at.rotation, rates));
        SenData::Imu {
            name: at.name.to_string(),
            // Body frame, z negated as the engine reports it (+ = up).
            acceleration: [f[0], f[1], -f[2]].into(),
            angular_vel: rates.into(),
            angular_accel: rate_accel.into(),
            rotation: Vec3::from(at.rotation),
        }
    }
}

impl Sensor for Imu {
    fn scale_noise(&mut self, k: f64) {
        self.accel.scale(k);
        self.gyro.scale(k);
        self.attitude.scale(k);
    }

    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let mut data = self.read_exact(at);
        if let SenData::Imu {
            acceleration,
            angular_vel,
            rotation,
            ..
        } = &mut data
        {
            let a = self.accel.apply(
                [acceleration.x, acceleration.y, acceleration.z],
                at.time,
                noise,
            );
            let w = self.gyro.apply(
                [angular_vel.x, angular_vel.y, angular_vel.z],
                at.time,
                noise,
            );
            *acceleration = a.into();
            *angular_vel = w.into();
            // Off by default: no draws, the line stays byte-identical.
            *rotation = self
                .attitude
                .apply([rotation.x, rotation.y, rotation.z], at.time, noise)
                .into();
        }
        data
    }
}

impl Imu {
    /// The reading without errors.
    fn read_exact(&mut self, at: &Reading<'_>) -> SenData {
        if let Some(truth) = at.imu {
            return self.read_truth(at, truth);
        }
        let (accel, rates, rate_accel) = match self.last {
            Some((t, v, r, w)) if at.time > t => {
                let dt = at.time - t;
                let dv = [
                    (at.velocity[0] - v[0]) / dt,
                    (at.velocity[1] - v[1]) / dt,
                    (at.velocity[2] - v[2]) / dt,
                ];
                // Into the body frame (yaw only), then z negated as the engine does (+ = up).
                let b = at.yaw_to_body(dv);
                let rates: V3 = std::array::from_fn(|i| wrap_angle(at.rotation[i] - r[i]) / dt);
                let rate_accel: V3 = std::array::from_fn(|i| (rates[i] - w[i]) / dt);
                ([b[0], b[1], -b[2]], rates, rate_accel)
            }
            _ => ([0.0; 3], [0.0; 3], [0.0; 3]),
        };
        self.last = Some((at.time, at.velocity, at.rotation, rates));
        SenData::Imu {
            name: at.name.to_string(),
            acceleration: accel.into(),
            angular_vel: rates.into(),
            angular_accel: rate_accel.into(),
            rotation: Vec3::from(at.rotation),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    #[test]
    fn an_attitude_error_model_makes_the_rotation_noisy() {
        let (scene, me) = scene_with_wall(2.0);
        let mut imu = make("IMU", "attitude = { noise = 0.01 }");
        let mut rng = crate::noise::Noise::new(5, 1, 2, 0.0);
        let n = 2000;
        let rolls: Vec<f64> = (0..n)
            .map(
                |i| match imu.read(&reading(&scene, me, 0.1 * f64::from(i)), &mut rng) {
                    SenData::Imu { rotation, .. } => rotation.x,
                    other => panic!("{other:?}"),
                },
            )
            .collect();
        let sd = (rolls.iter().map(|x| x * x).sum::<f64>() / f64::from(n)).sqrt();
        assert!((sd - 0.01).abs() < 0.001, "{sd}");
        // Off by default: the truth.
        let SenData::Imu { rotation, .. } = make("IMU", "").read(
            &Reading {
                rotation: [0.1, 0.2, 0.3],
                ..reading(&scene, me, 0.1)
            },
            &mut rng,
        ) else {
            panic!()
        };
        assert_eq!(rotation, Vec3::new(0.1, 0.2, 0.3));
    }

    #[test]
    fn differences_over_the_interval() {
        let (scene, me) = scene_with_wall(2.0);
        let mut imu = make("IMU", "");
        let first = imu.read(&reading(&scene, me, 0.1), &mut quiet());
        let SenData::Imu { acceleration, .. } = first else {
            panic!()
        };
        assert_eq!(acceleration, Vec3::default());
        // 0.1 s later: climbing at 1 m/s (z down → -1) and yawed by 0.1 rad.
        let at = Reading {
            velocity: [0.0, 0.0, -1.0],
            rotation: [0.0, 0.0, 0.1],
            ..reading(&scene, me, 0.2)
        };
        let SenData::Imu {
            acceleration,
            angular_vel,
            rotation,
            ..
        } = imu.read(&at, &mut quiet())
        else {
            panic!()
        };
        assert!((acceleration.z - 10.0).abs() < 1e-9, "{acceleration:?}");
        assert!((angular_vel.z - 1.0).abs() < 1e-9);
        assert_eq!(rotation, Vec3::new(0.0, 0.0, 0.1));
    }

    #[test]
    fn yaw_rate_wraps() {
        assert!((wrap_angle(-3.1 - 3.1) - (std::f64::consts::TAU - 6.2)).abs() < 1e-12);
    }
}
