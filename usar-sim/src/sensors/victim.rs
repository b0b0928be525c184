//! `VictSensor` (UT2004 USARSim, RoboCup 2007+; side-servers.md §4.1): the body parts of the
//! victims in view, located relative to the sensor.
//!
//! `SEN {Time t} {Type VictSensor} {Name n} {PartName Chest} {Location 2.05,0.33,0.46} ...`,
//! or `{Status NoVictims}`. Rays over `HorizontalFOV` × `VerticalFOV` in `step` degree steps
//! up to `max_range`; a ray that ends on a victim sees the part at that point of the body
//! (along its length: head, chest, pelvis, legs, feet; off to the side of the chest: arms
//! and hands). The hits on one part of one victim are averaged; each coordinate gets
//! `d · N(0, noise_factor)`, d the distance. Our choice: the whole pattern every reading
//! (UT2004 interleaved four patterns and sent every fourth update, 1.25 Hz: hence the
//! default interval of 0.8 s).

use serde::Deserialize;
use usar_proto::{SenData, VictimPart};

use super::{Reading, Sensor, settings};
use crate::noise::Noise;
use crate::part::PartConfig;
use crate::scene::{V3, direction, yaw_rotate};

/// VictSensor settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VictSensorConfig {
    /// Metres (UT2004 CONF: `MaxRange 6.0`).
    pub max_range: f64,
    /// Degrees.
    pub horizontal_fov: f64,
    /// Degrees.
    pub vertical_fov: f64,
    /// Degrees between rays.
    pub step: f64,
    /// Each coordinate gets `d · N(0, noise_factor)`.
    pub noise_factor: f64,
}

impl Default for VictSensorConfig {
    fn default() -> Self {
        Self {
            max_range: 6.0,
            horizontal_fov: 40.0,
            vertical_fov: 40.0,
            step: 4.0,
            noise_factor: 0.05,
        }
    }
}

/// The most rays one reading may cast (a field of view that would need more is refused).
const MAX_RAYS: f64 = 10_000.0;

#[derive(Debug, Clone)]
struct VictSensor {
    config: VictSensorConfig,
    /// (yaw, pitch) offsets of the rays from the sensor's axis, rad.
    rays: Vec<(f64, f64)>,
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let config: VictSensorConfig = settings(part)?;
    let c = &config;
    let ok = |v: f64, lo: f64, hi: f64| v.is_finite() && v >= lo && v <= hi;
    if !(ok(c.max_range, 0.01, 1000.0)
        && ok(c.horizontal_fov, 0.0, 360.0)
        && ok(c.vertical_fov, 0.0, 180.0)
        && ok(c.step, 0.01, 90.0)
        && ok(c.noise_factor, 0.0, 10.0))
    {
        return Err(format!(
            "part `{}`: VictSensor needs max_range 0.01..1000 m, horizontal_fov 0..360, vertical_fov 0..180, step 0.01..90 degrees, noise_factor 0..10",
            part.name
        ));
    }
    let across = |fov: f64| (fov / c.step).floor() + 1.0;
    if across(c.horizontal_fov) * across(c.vertical_fov) > MAX_RAYS {
        return Err(format!(
            "part `{}`: VictSensor of {} x {} degrees in {} degree steps casts more than {MAX_RAYS} rays",
            part.name, c.horizontal_fov, c.vertical_fov, c.step
        ));
    }
    let offsets = |fov: f64| -> Vec<f64> {
        let n = across(fov) as usize;
        (0..n)
            .map(|i| (-fov / 2.0 + fov * i as f64 / (n.max(2) - 1) as f64).to_radians())
            .map(|a| if n == 1 { 0.0 } else { a })
            .collect()
    };
    let mut rays = Vec::new();
    for pitch in offsets(c.vertical_fov) {
        for yaw in offsets(c.horizontal_fov) {
            rays.push((yaw, pitch));
        }
    }
    Ok(Box::new(VictSensor { config, rays }))
}

/// The part of a lying body at `along` (0 = head end, 1 = feet) and `side` (0 = the middle
/// line, 1 = the edge).
fn body_part(along: f64, side: f64) -> &'static str {
    match along {
        a if a < 0.13 => "Head",
        a if a < 0.42 && side > 0.6 => {
            if a < 0.3 {
                "Arm"
            } else {
                "Hand"
            }
        }
        a if a < 0.38 => "Chest",
        a if a < 0.52 => "Pelvis",
        a if a < 0.9 => "Leg",
        _ => "Foot",
    }
}

impl Sensor for VictSensor {
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        // (victim index, part) → sum of hit points (sensor frame), count.
        let mut seen: Vec<(usize, &'static str, V3, f64)> = Vec::new();
        for &(dyaw, dpitch) in &self.rays {
            let dir = direction(at.pitch + dpitch, at.yaw + dyaw);
            let Some((d, handle)) =
                at.scene
                    .cast_ray_hit(at.origin, dir, self.config.max_range, Some(at.me))
            else {
                continue;
            };
            let Some(v) = at.scene.victims.iter().position(|v| v.handle == handle) else {
                continue;
            };
            let body = &at.scene.victims[v];
            let hit = [
                at.origin[0] + dir[0] * d,
                at.origin[1] + dir[1] * d,
                at.origin[2] + dir[2] * d,
            ];
            // In the body's frame: x along its length (head at -x/2), y across.
            let local = yaw_rotate(
                -body.yaw,
                [hit[0] - body.center[0], hit[1] - body.center[1], 0.0],
            );
            let along = (local[0] / body.size[0] + 0.5).clamp(0.0, 1.0);
            let side = (local[1].abs() / (body.size[1] / 2.0)).clamp(0.0, 1.0);
            let part = body_part(along, side);
            let rel = yaw_rotate(
                -at.yaw,
                [
                    hit[0] - at.origin[0],
                    hit[1] - at.origin[1],
                    hit[2] - at.origin[2],
                ],
            );
            match seen.iter_mut().find(|s| s.0 == v && s.1 == part) {
                Some(s) => {
                    s.2 = [s.2[0] + rel[0], s.2[1] + rel[1], s.2[2] + rel[2]];
                    s.3 += 1.0;
                }
                None => seen.push((v, part, rel, 1.0)),
            }
        }
        if seen.is_empty() {
            return SenData::VictSensor {
                name: None,
                parts: Vec::new(),
            };
        }
        let sigma = self.config.noise_factor;
        let parts = seen
            .into_iter()
            .map(|(_, part, sum, n)| {
                let p = sum.map(|s| s / n);
                let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                let p = p.map(|x| x + d * sigma * noise.draw());
                VictimPart {
                    part: part.to_owned(),
                    location: p.into(),
                }
            })
            .collect();
        SenData::VictSensor {
            name: Some(at.name.to_owned()),
            parts,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;
    use crate::map::Placed;
    use rapier3d::math::Pose;
    use rapier3d::prelude::ColliderBuilder;

    #[test]
    fn sees_the_parts_of_a_victim_ahead_and_nothing_elsewhere() {
        let (mut scene, me) = scene_with_wall(20.0);
        let victim = Placed {
            name: "V".into(),
            class: "FemaleVictim".into(),
            victim: true,
            // Lying across the view 3 m ahead, 1 m down: head to the west (-y).
            center: [3.0, 0.0, 1.0],
            size: [1.7, 0.5, 0.3],
            yaw: std::f64::consts::FRAC_PI_2,
            color: None,
        };
        let handle = scene.insert(
            ColliderBuilder::cuboid(0.85, 0.25, 0.15).position(Pose::new(
                rapier3d::math::Vector::new(3.0, 0.0, 1.0),
                rapier3d::math::Vector::new(0.0, 0.0, std::f32::consts::FRAC_PI_2),
            )),
        );
        scene.add_victim(handle, victim.center, victim.size, victim.yaw);
        scene.refit();
        let config = part("VictSensor", "noise_factor = 0.0\nvertical_fov = 60.0");
        let mut sensor = build(&config).unwrap();
        let mut noise = Noise::new(1, 0, 0, 0.0);
        let mut at = reading(&scene, me, 1.0);
        at.pitch = -0.3; // looking down
        let SenData::VictSensor { name, parts } = sensor.read(&at, &mut noise) else {
            panic!()
        };
        assert_eq!(name.as_deref(), Some("S"));
        let names: Vec<&str> = parts.iter().map(|p| p.part.as_str()).collect();
        assert!(
            names.contains(&"Chest") && names.contains(&"Leg"),
            "{names:?}"
        );
        for p in &parts {
            assert!((2.5..3.5).contains(&p.location.x), "{p:?}");
        }
        // Turned away: nothing.
        at.yaw = std::f64::consts::PI;
        assert_eq!(
            sensor.read(&at, &mut noise),
            SenData::VictSensor {
                name: None,
                parts: vec![]
            }
        );
        let huge = part("VictSensor", "step = 0.01\nhorizontal_fov = 360.0");
        assert!(build(&huge).unwrap_err().contains("more than"));
    }
}
