//! Wind: a constant mean wind plus seeded gusts, per map (`[wind]`, docs/maps.md) or per run
//! (`usar-server --wind`, [`super::SimConfig::wind`]). Only models with physics feel it
//! (the quadrotor); the kinematic model imposes its velocities.
//!
//! Gusts follow the Dryden model's first-order form (MIL-F-8785C, MIL-HDBK-1797): each
//! component is white noise through `σ·sqrt(2L/(πV)) / (1 + (L/V)s)`, which for a step `h` is
//! the exact recursion `u ← a·u + σ·sqrt(1-a²)·n`, `a = exp(-V·h/L)`, `n ~ N(0,1)`. `V` is the
//! vehicle's airspeed (at least 1 m/s). Low-altitude proportions: the vertical component has
//! half the intensity and a quarter of the length scale of the horizontal ones. Every robot
//! draws from its own stream, seeded from the world seed and its spawn number.

use serde::Deserialize;

use super::noise::Noise;
use super::scene::V3;

/// Wind settings.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WindConfig {
    /// Mean wind, world frame (x north, y east, z down): where the air moves to, m/s.
    pub velocity: [f64; 3],
    /// Standard deviation of the horizontal gust components, m/s (0 = no gusts).
    pub gusts: f64,
    /// Horizontal turbulence length scale, m.
    pub gust_length: f64,
}

impl Default for WindConfig {
    fn default() -> Self {
        Self {
            velocity: [0.0; 3],
            gusts: 0.0,
            gust_length: 20.0,
        }
    }
}

impl WindConfig {
    /// Checks the numbers; the message names the bad one.
    pub fn check(&self) -> Result<(), String> {
        if !self.velocity.iter().all(|v| v.is_finite()) {
            return Err("wind velocity must be finite".into());
        }
        if !(self.gusts.is_finite() && self.gusts >= 0.0) {
            return Err(format!("wind gusts must be >= 0, got {}", self.gusts));
        }
        if !(self.gust_length.is_finite() && self.gust_length > 0.0) {
            return Err(format!(
                "wind gust_length must be a positive number of metres, got {}",
                self.gust_length
            ));
        }
        Ok(())
    }
}

/// The gust state of one robot.
#[derive(Debug, Clone)]
pub(crate) struct Gusts {
    config: WindConfig,
    state: V3,
    noise: Noise,
}

/// The noise stream index of the gusts (parts use 0, 1, 2, ...).
const GUST_STREAM: u64 = 0x5749_4E44; // "WIND"

impl Gusts {
    pub(crate) fn new(config: WindConfig, seed: u64, serial: u64) -> Self {
        Self {
            config,
            state: [0.0; 3],
            noise: Noise::new(seed, serial, GUST_STREAM, 1.0),
        }
    }

    /// The mean wind.
    pub(crate) fn mean(&self) -> V3 {
        self.config.velocity
    }

    /// Advances by `h` seconds at `airspeed`; returns the wind now (mean + gust).
    pub(crate) fn step(&mut self, h: f64, airspeed: f64) -> V3 {
        let c = self.config;
        if c.gusts > 0.0 {
            let v = airspeed.max(1.0);
            for (i, (sigma, length)) in [
                (c.gusts, c.gust_length),
                (c.gusts, c.gust_length),
                (c.gusts * 0.5, c.gust_length * 0.25),
            ]
            .into_iter()
            .enumerate()
            {
                let a = (-v * h / length).exp();
                self.state[i] =
                    a * self.state[i] + sigma * (1.0 - a * a).sqrt() * self.noise.draw();
            }
        }
        std::array::from_fn(|i| c.velocity[i] + self.state[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gusts_have_the_configured_intensity_and_repeat() {
        let config = WindConfig {
            velocity: [2.0, 0.0, 0.0],
            gusts: 1.5,
            gust_length: 20.0,
        };
        let mut a = Gusts::new(config, 7, 3);
        let mut b = Gusts::new(config, 7, 3);
        let xs: Vec<V3> = (0..200_000).map(|_| a.step(0.005, 3.0)).collect();
        let ys: Vec<V3> = (0..200_000).map(|_| b.step(0.005, 3.0)).collect();
        assert_eq!(xs, ys);
        let n = xs.len() as f64;
        let mean = xs.iter().map(|w| w[0]).sum::<f64>() / n;
        let var = xs.iter().map(|w| (w[0] - mean).powi(2)).sum::<f64>() / n;
        assert!((mean - 2.0).abs() < 0.3, "mean {mean}");
        assert!((var.sqrt() - 1.5).abs() < 0.3, "std {}", var.sqrt());
        let still = Gusts::new(WindConfig::default(), 7, 3).step(0.005, 0.0);
        assert_eq!(still, [0.0; 3]);
    }
}
