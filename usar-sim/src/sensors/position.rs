//! `Position` (stsPositionSensor, §9): the robot's world location, z down.

use serde::Deserialize;
use usar_proto::{ConfItem, SenData};

use super::{Reading, Sensor, interval_conf, settings};
use crate::noise::{ErrorModel, Errors, Noise};
use crate::part::PartConfig;

/// Position settings: a GPS-like error model, off by default.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PositionConfig {
    /// Errors on each coordinate, m (`bias_walk` gives the slow drift of a GPS fix).
    pub error: ErrorModel,
    /// Fix losses per second (Poisson); during one the line repeats the last fix.
    pub dropout_rate: f64,
    /// s, how long a fix loss lasts.
    pub dropout_length: f64,
}

#[derive(Debug, Clone)]
struct Position {
    config: PositionConfig,
    errors: Errors<3>,
    /// The last fix, the time it was read, and the end of the current dropout.
    last: Option<([f64; 3], f64)>,
    lost_until: f64,
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let c: PositionConfig = settings(part)?;
    c.error.check(&format!("part `{}`: error", part.name))?;
    for (key, v) in [
        ("dropout_rate", c.dropout_rate),
        ("dropout_length", c.dropout_length),
    ] {
        if !(v.is_finite() && (0.0..=1e6).contains(&v)) {
            return Err(format!(
                "part `{}`: {key} must be within [0, 1e6], got {v}",
                part.name
            ));
        }
    }
    Ok(Box::new(Position {
        errors: Errors::new(c.error.clone()),
        config: c,
        last: None,
        lost_until: f64::MIN,
    }))
}

impl Sensor for Position {
    fn scale_noise(&mut self, k: f64) {
        self.errors.scale(k);
    }

    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let c = &self.config;
        if let Some((fix, t)) = self.last.filter(|_| c.dropout_rate > 0.0) {
            // A loss starts within the interval with probability 1 − e^(−rate·Δt).
            let p = 1.0 - (-c.dropout_rate * (at.time - t).max(0.0)).exp();
            if at.time >= self.lost_until && noise.uniform() < p {
                self.lost_until = at.time + c.dropout_length;
            }
            if at.time < self.lost_until {
                self.last = Some((fix, at.time));
                return SenData::Position {
                    name: at.name.to_string(),
                    location: fix.into(),
                };
            }
        }
        let fix = self
            .errors
            .apply(at.position, at.time, noise)
            .map(|v| noise.apply(v));
        self.last = Some((fix, at.time));
        SenData::Position {
            name: at.name.to_string(),
            location: fix.into(),
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
    fn reports_the_world_location() {
        let (scene, me) = scene_with_wall(2.0);
        let at = Reading {
            position: [1.0, 2.0, -3.0],
            ..reading(&scene, me, 0.1)
        };
        let data = make("Position", "").read(&at, &mut quiet());
        assert_eq!(
            data,
            SenData::Position {
                name: "S".into(),
                location: [1.0, 2.0, -3.0].into()
            }
        );
    }
}

#[cfg(test)]
mod dropout_tests {
    use super::super::testing::*;
    use super::*;

    #[test]
    fn a_dropout_repeats_the_last_fix_for_its_length() {
        let (scene, me) = scene_with_wall(2.0);
        let mut gps = make("Position", "dropout_rate = 0.5\ndropout_length = 1.0");
        let mut noise = Noise::new(3, 1, 0, 0.0);
        let mut frozen = 0;
        let mut previous: Option<SenData> = None;
        for k in 0..2000 {
            let t = f64::from(k) * 0.1;
            let at = Reading {
                position: [t, 0.0, 0.0],
                time: t,
                ..reading(&scene, me, t)
            };
            let data = gps.read(&at, &mut noise);
            if previous.as_ref().is_some_and(|p| *p == data) {
                frozen += 1;
            }
            previous = Some(data);
        }
        // Losses start at 0.5 per second and last 1 s: about a third of the time frozen.
        let share = f64::from(frozen) / 2000.0;
        assert!((0.2..0.45).contains(&share), "frozen {share}");
    }
}
