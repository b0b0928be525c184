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

/// The strongest wind component or gust intensity accepted, m/s (a hurricane is 70).
const MAX_WIND: f64 = 100.0;

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
        if !self
            .velocity
            .iter()
            .all(|v| v.is_finite() && v.abs() <= MAX_WIND)
        {
            return Err(format!(
                "wind velocity components must be numbers within ±{MAX_WIND} m/s, got {:?}",
                self.velocity
            ));
        }
        if !(self.gusts.is_finite() && (0.0..=MAX_WIND).contains(&self.gusts)) {
            return Err(format!(
                "wind gusts must be between 0 and {MAX_WIND} m/s, got {}",
                usar_proto::shown::Number(self.gusts)
            ));
        }
        if !(self.gust_length.is_finite() && self.gust_length > 0.0) {
            return Err(format!(
                "wind gust_length must be a positive number of metres, got {}",
                usar_proto::shown::Number(self.gust_length)
            ));
        }
        Ok(())
    }
}

/// A wind velocity from the command line: `vx,vy` or `vx,vy,vz` (m/s, x north, y east,
/// z down: where the air moves to).
pub fn parse_velocity(text: &str) -> Result<[f64; 3], String> {
    let numbers: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("wind `{text}`: expected vx,vy[,vz] in m/s"))?;
    match numbers[..] {
        [x, y] => Ok([x, y, 0.0]),
        [x, y, z] => Ok([x, y, z]),
        _ => Err(format!("wind `{text}`: expected two or three numbers")),
    }
}

impl WindConfig {
    /// The run's wind: `base` (the map's, or calm) with the fields the command line gives;
    /// `None` when it gives none (the map's wind then applies).
    pub fn overridden(
        base: Option<Self>,
        velocity: Option<[f64; 3]>,
        gusts: Option<f64>,
        gust_length: Option<f64>,
    ) -> Result<Option<Self>, String> {
        if velocity.is_none() && gusts.is_none() && gust_length.is_none() {
            return Ok(None);
        }
        let mut wind = base.unwrap_or_default();
        if let Some(v) = velocity {
            wind.velocity = v;
        }
        if let Some(g) = gusts {
            wind.gusts = g;
        }
        if let Some(l) = gust_length {
            wind.gust_length = l;
        }
        wind.check()?;
        Ok(Some(wind))
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
    fn command_line_wind() {
        assert_eq!(parse_velocity("1,-2"), Ok([1.0, -2.0, 0.0]));
        assert_eq!(parse_velocity(" 1, 2, 0.5"), Ok([1.0, 2.0, 0.5]));
        assert!(parse_velocity("1").unwrap_err().contains("two or three"));
        assert!(parse_velocity("1,x").unwrap_err().contains("vx,vy"));
        let map = WindConfig {
            velocity: [3.0, 0.0, 0.0],
            gusts: 0.5,
            gust_length: 20.0,
        };
        assert_eq!(
            WindConfig::overridden(Some(map), None, None, None),
            Ok(None)
        );
        let run = WindConfig::overridden(Some(map), None, Some(1.0), None).unwrap();
        assert_eq!(
            run.map(|w| (w.velocity, w.gusts)),
            Some(([3.0, 0.0, 0.0], 1.0))
        );
        assert!(WindConfig::overridden(None, None, Some(-1.0), None).is_err());
        let e = WindConfig::overridden(None, Some([1e300, 0.0, 0.0]), None, None).unwrap_err();
        assert!(e.contains("±100 m/s"), "{e}");
    }

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
