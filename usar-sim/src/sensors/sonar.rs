//! `Sonar` (USARSim SonarSensor): one range per reading, clamped to [MinRange, MaxRange].

use std::sync::Arc;

use serde::Deserialize;
use usar_proto::{ConfItem, NamedRange, SenData};

use super::{Reading, Sensor, f32ish, from_uu, settings, to_uu};
use crate::noise::Noise;
use crate::part::PartConfig;
use crate::scene::direction;

/// How a reading is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SonarModel {
    /// What the engine does in effect: only the central ray counts.
    #[default]
    Usarsim,
    /// The minimum over all traces inside the cone of `beam_angle`.
    Cone,
}

/// Sonar settings (defaults: `[USARSensor.SonarSensor]`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SonarConfig {
    /// Metres; also the reading when nothing is hit.
    pub max_range: f64,
    /// Metres.
    pub min_range: f64,
    /// Full cone angle, rad.
    pub beam_angle: f64,
    /// rad (reported in CONF).
    pub max_angle_of_incidence: f64,
    /// Cones between the axis and the beam edge (cone model).
    pub number_of_cones: u32,
    /// Traces on each cone (cone model).
    pub traces_per_cone: u32,
    /// Central ray only (`usarsim`) or the whole cone (`cone`).
    pub model: SonarModel,
}

impl Default for SonarConfig {
    fn default() -> Self {
        Self {
            max_range: 5.0,
            min_range: 0.1,
            beam_angle: 0.349,
            max_angle_of_incidence: 0.174_532_925_2,
            number_of_cones: 10,
            traces_per_cone: 16,
            model: SonarModel::Usarsim,
        }
    }
}

/// A sonar: its settings and the trace directions as (pitch, yaw) offsets from its axis.
#[derive(Debug, Clone)]
struct Sonar {
    config: SonarConfig,
    /// (pitch, yaw) offsets of the traces; the first is the axis.
    traces: Arc<[(f64, f64)]>,
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let config: SonarConfig = settings(part)?;
    if !(config.min_range >= 0.0 && config.max_range > config.min_range) {
        return Err(format!(
            "part `{}`: need 0 <= min_range < max_range",
            part.name
        ));
    }
    if config.max_range > crate::map::LIMIT {
        return Err(format!(
            "part `{}`: max_range must be at most {} m",
            part.name,
            crate::map::LIMIT
        ));
    }
    if !((0.0..=std::f64::consts::PI).contains(&config.beam_angle)
        && config.max_angle_of_incidence.is_finite())
    {
        return Err(format!(
            "part `{}`: need 0 <= beam_angle <= π and a finite max_angle_of_incidence",
            part.name
        ));
    }
    let mut traces = vec![(0.0, 0.0)];
    if config.model == SonarModel::Cone {
        let cones = config.number_of_cones.min(100);
        let per_cone = config.traces_per_cone.min(100);
        for c in 1..=cones {
            let half = config.beam_angle / 2.0 * f64::from(c) / f64::from(cones);
            for t in 0..per_cone {
                let around = std::f64::consts::TAU * f64::from(t) / f64::from(per_cone);
                traces.push((half * around.sin(), half * around.cos()));
            }
        }
    }
    Ok(Box::new(Sonar {
        config,
        traces: traces.into(),
    }))
}

impl Sensor for Sonar {
    fn single_ray(&self) -> Option<f64> {
        (self.traces[..] == [(0.0, 0.0)]).then_some(self.config.max_range)
    }

    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let max = self.config.max_range;
        let hit = if let [(dp, dy)] = self.traces[..] {
            at.ray_hit
                .unwrap_or_else(|| at.trace(direction(at.pitch + dp, at.yaw + dy), max))
                .unwrap_or(max)
        } else {
            let dirs: Vec<_> = self
                .traces
                .iter()
                .map(|&(dp, dy)| direction(at.pitch + dp, at.yaw + dy))
                .collect();
            let mut hits = Vec::with_capacity(dirs.len());
            at.trace_many(&dirs, max, &mut hits);
            hits.into_iter().flatten().fold(max, f64::min)
        };
        let range = noise.apply(hit).clamp(self.config.min_range, max);
        SenData::Sonar {
            readings: vec![NamedRange {
                name: at.name.to_string(),
                range,
            }],
            grouped: false,
        }
    }

    fn conf(&self, name: &str, interval: f64) -> ConfItem {
        ConfItem::Sonar {
            name: name.to_string(),
            max_range: f32ish(self.config.max_range),
            min_range: f32ish(self.config.min_range),
            scan_interval: f32ish(interval),
            // The engine keeps the cone angle in rotation units (→ `0.3489`), the incidence
            // limit as a float (→ `0.1745`).
            beam_angle: from_uu(to_uu(self.config.beam_angle)),
            max_angle_of_incidence: f32ish(self.config.max_angle_of_incidence),
            traces_per_cone: i64::from(self.config.traces_per_cone),
            number_of_cones: i64::from(self.config.number_of_cones),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    fn range(data: SenData) -> f64 {
        match data {
            SenData::Sonar { readings, .. } => readings[0].range,
            other => panic!("not a sonar reading: {other:?}"),
        }
    }

    #[test]
    fn box_at_known_distance() {
        let (scene, me) = scene_with_wall(2.0);
        let mut sonar = make("Sonar", "");
        let at = reading(&scene, me, 0.2);
        assert!((range(sonar.read(&at, &mut quiet())) - 2.0).abs() < 1e-4);
        // Pointing away: nothing within 5 m → MaxRange.
        let away = Reading {
            yaw: std::f64::consts::PI,
            ..reading(&scene, me, 0.2)
        };
        assert_eq!(range(sonar.read(&away, &mut quiet())), 5.0);
        // Pointing down: the floor at 2 m.
        let down = Reading {
            pitch: -std::f64::consts::FRAC_PI_2,
            ..reading(&scene, me, 0.2)
        };
        assert!((range(sonar.read(&down, &mut quiet())) - 2.0).abs() < 1e-4);
    }

    #[test]
    fn clamped_to_min_range_and_cone_sees_the_edge() {
        let (scene, me) = scene_with_wall(0.05);
        let mut sonar = make("Sonar", "");
        assert_eq!(
            range(sonar.read(&reading(&scene, me, 0.2), &mut quiet())),
            0.1
        );
        // A wall almost parallel to the axis: the central ray reaches it only after 20 m,
        // the cone's edge (0.22 rad off the wall) after 4.5 m.
        let (scene, me) = scene_with_wall(1.0);
        let skew = Reading {
            yaw: 0.5 * std::f64::consts::PI - 0.05,
            ..reading(&scene, me, 0.2)
        };
        let mut central = make("Sonar", "");
        let mut cone = make("Sonar", "model = \"cone\"");
        assert_eq!(range(central.read(&skew, &mut quiet())), 5.0);
        assert!(range(cone.read(&skew, &mut quiet())) < 5.0);
    }

    #[test]
    fn conf_prints_what_the_engine_printed() {
        let sonar = make("Sonar", "");
        let conf = usar_proto::ServerMessage::Conf(usar_proto::Conf::Items {
            kind: "Sonar".into(),
            items: vec![sonar.conf("S", 0.2)],
        });
        // protocol.md §3.4: the default sonar's CONF.
        assert_eq!(
            conf.to_string(),
            "CONF {Type Sonar} {Name S} {MaxRange 5.0000} {MinRange 0.1000} {ScanInterval 0.2000} \
             {beamAngle 0.3489} {maxAngleOfIncidence 0.1745} {tracesPerCone 16} {numberOfCones 10}"
        );
    }

    #[test]
    fn bad_settings_are_errors() {
        let part = part("Sonar", "max_rang = 3.0");
        assert!(
            (super::super::find("sonar").unwrap().build)(&part)
                .unwrap_err()
                .contains("max_rang")
        );
    }
}
