//! A state estimator for agents that fly from their sensors (issue #54): a loosely coupled
//! position fix / inertial Kalman filter, one per world axis, with the state position,
//! velocity and accelerometer bias.
//!
//! * **Predict** at every new IMU reading: the accelerometer's specific force (body frame, z
//!   reported + up as USARSim does: docs/quadrotor.md#sensors-on-a-quadrotor) turned into the
//!   world frame with the IMU's attitude, gravity added back, less the bias estimate, drives
//!   the position and velocity over the interval since the last reading; the process noise
//!   is the accelerometer's noise and the bias's random walk.
//! * **Correct** at every new position reading (a Position line, a GPS-like fix) with its
//!   noise.
//!
//! The attitude is the IMU's reading as it comes (exact, or with the noise the robot's
//! error model gives it). Without IMU readings the filter still smooths the fixes (a
//! constant-velocity model). [`FromEstimate`] wraps any agent so that it sees the estimate in
//! place of the position and velocity readings; the truth stays on the server (GroundTruth,
//! USARTruth) for scoring.

use crate::agent::{Agent, MissionRefused, Step};
use crate::geometry::{Coordinates, body_to_world};
use crate::mission::Mission;
use crate::uav::{Reading, UavState};

/// m/s², gravity (USARSim's).
const GRAVITY: f64 = 9.8066;

/// The filter's noise figures (standard deviations).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorConfig {
    /// m, of a position reading.
    pub position_noise: f64,
    /// m/s², the process noise: the accelerometer's own noise and what a reading misses of
    /// an acceleration that changes between readings (a vehicle under control changes it
    /// every few milliseconds).
    pub accel_noise: f64,
    /// m/s²/√s, the accelerometer bias's random walk.
    pub bias_walk: f64,
    /// m/s², the turn-on bias's standard deviation (the bias's first uncertainty).
    pub bias: f64,
}

impl Default for EstimatorConfig {
    /// A GPS-class fix (0.5 m) and an MPU-6000-class accelerometer (docs/robots.md) read at
    /// about 100 Hz.
    fn default() -> Self {
        Self {
            position_noise: 0.5,
            accel_noise: 0.3,
            bias_walk: 0.001,
            bias: 0.16,
        }
    }
}

/// One axis: x = (position, velocity, accelerometer bias) and its covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Axis {
    x: [f64; 3],
    p: [[f64; 3]; 3],
}

impl Axis {
    fn new(position: f64, config: &EstimatorConfig) -> Self {
        let mut p = [[0.0; 3]; 3];
        p[0][0] = config.position_noise.powi(2);
        p[1][1] = 1.0; // (1 m/s)²: unknown at the start
        p[2][2] = config.bias.powi(2);
        Self {
            x: [position, 0.0, 0.0],
            p,
        }
    }

    /// Over `dt` with the measured acceleration `a` (bias not yet removed; `None`: no IMU,
    /// constant velocity with `q` as its acceleration noise).
    fn predict(&mut self, dt: f64, a: Option<f64>, config: &EstimatorConfig) {
        let use_imu = a.is_some();
        let u = a.map_or(0.0, |a| a - self.x[2]);
        let [p, v, b] = self.x;
        self.x = [p + v * dt + 0.5 * u * dt * dt, v + u * dt, b];
        // F = [[1, dt, -dt²/2], [0, 1, -dt], [0, 0, 1]] (the bias only with the IMU).
        let k = if use_imu { 1.0 } else { 0.0 };
        let f = [
            [1.0, dt, -0.5 * dt * dt * k],
            [0.0, 1.0, -dt * k],
            [0.0, 0.0, 1.0],
        ];
        let fp = mul(&f, &self.p);
        let mut next = mul_t(&fp, &f);
        // Acceleration noise as white noise over the interval; without the IMU, a wider one
        // (the vehicle's own accelerations are unknown).
        let q = if use_imu {
            config.accel_noise.powi(2)
        } else {
            4.0
        };
        next[0][0] += q * dt.powi(4) / 4.0;
        next[0][1] += q * dt.powi(3) / 2.0;
        next[1][0] += q * dt.powi(3) / 2.0;
        next[1][1] += q * dt * dt;
        next[2][2] += config.bias_walk.powi(2) * dt;
        self.p = next;
    }

    /// With a position reading `z` of variance `r`.
    fn correct(&mut self, z: f64, r: f64) {
        let s = self.p[0][0] + r;
        if s.is_nan() || s <= 0.0 {
            return;
        }
        let k: [f64; 3] = std::array::from_fn(|i| self.p[i][0] / s);
        let innovation = z - self.x[0];
        for (x, k) in self.x.iter_mut().zip(k) {
            *x += k * innovation;
        }
        let row = self.p[0];
        for (i, ki) in k.iter().enumerate() {
            for (j, rj) in row.iter().enumerate() {
                self.p[i][j] -= ki * rj;
            }
        }
    }
}

fn mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// `a · bᵀ`.
fn mul_t(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[j][k]).sum()))
}

/// What the filter believes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Simulated seconds of the last reading used.
    pub time: f64,
    /// World frame, metres, z down.
    pub position: Coordinates,
    /// World frame, m/s.
    pub velocity: Coordinates,
    /// The accelerometer's bias, world frame, m/s².
    pub accel_bias: Coordinates,
    /// The position's standard deviation per axis, m.
    pub position_std: Coordinates,
}

/// The filter (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Estimator {
    config: EstimatorConfig,
    axes: Option<[Axis; 3]>,
    /// Time of the state.
    time: f64,
    /// Times of the last IMU and position readings used.
    last_imu: Option<f64>,
    last_fix: Option<f64>,
}

impl Estimator {
    /// A filter that starts at the first position reading.
    pub fn new(config: EstimatorConfig) -> Self {
        Self {
            config,
            axes: None,
            time: 0.0,
            last_imu: None,
            last_fix: None,
        }
    }

    /// Takes the readings of `uav` that are new since the last call; the estimate (`None`
    /// before the first position reading).
    pub fn update(&mut self, uav: &UavState) -> Option<Estimate> {
        let config = self.config;
        let fix = uav
            .position
            .as_ref()
            .filter(|p| p.value.iter().all(|v| v.is_finite()));
        let axes = match &mut self.axes {
            Some(axes) => axes,
            None => {
                let fix = fix?;
                self.time = fix.time;
                self.last_fix = Some(fix.time);
                self.axes = Some(std::array::from_fn(|i| Axis::new(fix.value[i], &config)));
                self.axes.as_mut()?
            }
        };
        // The IMU: the world-frame acceleration it measured, over the time since the state.
        let imu = match (&uav.acceleration, &uav.orientation) {
            (Some(f), Some(o)) if Some(f.time) != self.last_imu && f.time > self.time => {
                let frd = Coordinates::new(f.value.x, f.value.y, -f.value.z);
                let a = body_to_world(&o.value) * frd + Coordinates::new(0.0, 0.0, GRAVITY);
                Some((f.time, a))
            }
            _ => None,
        };
        if let Some((t, a)) = imu {
            let dt = t - self.time;
            for (i, axis) in axes.iter_mut().enumerate() {
                axis.predict(dt, Some(a[i]), &config);
            }
            self.time = t;
            self.last_imu = Some(t);
        }
        if let Some(fix) = fix.filter(|f| Some(f.time) != self.last_fix) {
            if fix.time > self.time && self.last_imu.is_none() {
                let dt = fix.time - self.time;
                for axis in axes.iter_mut() {
                    axis.predict(dt, None, &config);
                }
                self.time = fix.time;
            }
            let r = config.position_noise.powi(2);
            for (i, axis) in axes.iter_mut().enumerate() {
                axis.correct(fix.value[i], r);
            }
            self.last_fix = Some(fix.time);
        }
        let v = |k: usize| Coordinates::from_fn(|i, _| axes[i].x[k]);
        Some(Estimate {
            time: self.time,
            position: v(0),
            velocity: v(1),
            accel_bias: v(2),
            position_std: Coordinates::from_fn(|i, _| axes[i].p[0][0].max(0.0).sqrt()),
        })
    }
}

/// An agent that flies from the [`Estimator`]'s estimate: it sees the estimated position and
/// velocity in place of the readings (the other readings as they come).
pub struct FromEstimate {
    inner: Box<dyn Agent>,
    estimator: Estimator,
    /// The last estimate (for a caller that scores it).
    pub last: Option<Estimate>,
}

impl FromEstimate {
    /// `inner` flying from a filter with `config`.
    pub fn new(inner: Box<dyn Agent>, config: EstimatorConfig) -> Self {
        Self {
            inner,
            estimator: Estimator::new(config),
            last: None,
        }
    }
}

impl Agent for FromEstimate {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn add_mission(&mut self, mission: Mission) -> Result<(), MissionRefused> {
        self.inner.add_mission(mission)
    }

    fn start(&mut self, time: f64) {
        self.inner.start(time);
    }

    fn stop(&mut self) {
        self.inner.stop();
    }

    fn step(&mut self, uav: &UavState, time: f64) -> Step {
        self.last = self.estimator.update(uav);
        let Some(estimate) = self.last else {
            return self.inner.step(uav, time);
        };
        let mut seen = uav.clone();
        seen.position = Some(Reading {
            value: estimate.position,
            time: estimate.time,
        });
        seen.velocity = Some(Reading {
            value: estimate.velocity,
            time: estimate.time,
        });
        self.inner.step(&seen, time)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UAV accelerating north at 1 m/s² from rest, level: IMU at 100 Hz, exact fixes at
    /// 10 Hz; the estimate follows within a centimetre.
    #[test]
    fn follows_a_constant_acceleration() {
        let mut e = Estimator::new(EstimatorConfig::default());
        let mut uav = UavState::new();
        let mut worst = 0.0f64;
        for k in 0..=300 {
            let t = k as f64 * 0.01;
            let x = 0.5 * t * t;
            uav.acceleration = Some(Reading {
                value: Coordinates::new(1.0, 0.0, GRAVITY),
                time: t,
            });
            uav.orientation = Some(Reading {
                value: Coordinates::zeros(),
                time: t,
            });
            if k % 10 == 0 {
                uav.position = Some(Reading {
                    value: Coordinates::new(x, 0.0, -1.0),
                    time: t,
                });
            }
            let est = e.update(&uav).unwrap();
            worst = worst.max((est.position - Coordinates::new(x, 0.0, -1.0)).norm());
        }
        assert!(worst < 0.01, "worst {worst}");
    }
}
