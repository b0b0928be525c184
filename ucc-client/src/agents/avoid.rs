//! `avoid`: the waypoint flight of [`base`](super::base), going around obstacles in the way.
//!
//! The clearance in eight directions (ahead, then every 45° clockwise) is the smaller of the
//! matching horizontal sonar and the laser beams within ±22.5° of that direction. On top of
//! the waypoint law:
//!
//! * every direction closer than [`AvoidConfig::influence`] pushes the UAV away from it, the
//!   harder the closer (up to 100 % at contact);
//! * when the UAV wants to go forward and the way ahead is closer than
//!   [`AvoidConfig::blocked`], it stops going forward and sidesteps at
//!   [`AvoidConfig::sidestep`] % towards the freer side, keeping its heading on the target,
//!   until the way ahead is clear again (the side is kept meanwhile, so it does not dither);
//! * it does not climb when the free space above is below [`AvoidConfig::vertical_margin`],
//!   nor descend when the free space below is.

use super::AgentInfo;
use super::base::{Base, WaypointConfig};
use crate::agent::{Agent, AgentEvent, MissionRefused, SpeedCommand, Step};
use crate::mission::Mission;
use crate::uav::{HORIZONTAL_SONARS, UavState};

/// The registry entry.
pub const INFO: AgentInfo = AgentInfo {
    name: "avoid",
    description: "waypoint flight that sidesteps obstacles seen by the sonars and the laser",
    create: || {
        Box::new(Avoid::new(
            WaypointConfig::default(),
            AvoidConfig::default(),
        ))
    },
};

/// Tunables of the avoidance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AvoidConfig {
    /// Obstacles closer than this push the UAV away, metres.
    pub influence: f64,
    /// The way ahead is blocked below this clearance, metres.
    pub blocked: f64,
    /// Lateral speed while going around, percent.
    pub sidestep: f64,
    /// No climbing (descending) with less free space above (below), metres.
    pub vertical_margin: f64,
    /// Clearance assumed when no sensor reports a direction (the sonars' maximum range).
    pub unknown: f64,
}

impl Default for AvoidConfig {
    fn default() -> Self {
        Self {
            influence: 1.0,
            blocked: 1.2,
            sidestep: 60.0,
            vertical_margin: 0.6,
            unknown: 5.0,
        }
    }
}

/// The avoiding waypoint agent.
#[derive(Debug, Clone)]
pub struct Avoid {
    base: Base,
    config: AvoidConfig,
    /// +1 = sidestepping right, -1 = left, `None` = not avoiding.
    side: Option<f64>,
}

impl Avoid {
    /// An agent with no missions yet.
    pub fn new(waypoints: WaypointConfig, config: AvoidConfig) -> Self {
        Self {
            base: Base::new(waypoints),
            config,
            side: None,
        }
    }

    /// Clearance in the eight directions (0 = ahead, then 45° steps clockwise), metres.
    pub fn clearances(&self, uav: &UavState) -> [f64; HORIZONTAL_SONARS] {
        let sector = std::f64::consts::TAU / HORIZONTAL_SONARS as f64;
        std::array::from_fn(|i| {
            let sonar = uav.sonars[i].as_ref().map(|r| r.value);
            let laser = uav.laser.as_ref().and_then(|scan| {
                let scan = &scan.value;
                let direction = i as f64 * sector;
                scan.ranges
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| {
                        crate::geometry::wrap_angle(scan.bearing(*j) - direction).abs()
                            <= sector / 2.0
                    })
                    .map(|(_, r)| *r)
                    .filter(|r| *r > 0.0)
                    .reduce(f64::min)
            });
            [sonar, laser]
                .into_iter()
                .flatten()
                .reduce(f64::min)
                .unwrap_or(self.config.unknown)
        })
    }

    fn adjust(
        &mut self,
        mut command: SpeedCommand,
        uav: &UavState,
        step: &mut Step,
    ) -> SpeedCommand {
        let c = self.config;
        let clear = self.clearances(uav);
        let sector = std::f64::consts::TAU / HORIZONTAL_SONARS as f64;

        let (mut push_forward, mut push_right) = (0.0, 0.0);
        if clear.iter().any(|range| *range < c.influence) {
            // The way back to the straight line (the waypoint law's sideways part) waits
            // until nothing is near: it would lead into what is being avoided.
            command.right = 0.0;
        }
        for (i, range) in clear.iter().enumerate() {
            if *range < c.influence {
                let strength = 100.0 * (c.influence - range.max(0.0)) / c.influence;
                let (sin, cos) = (i as f64 * sector).sin_cos();
                push_forward -= strength * cos;
                push_right -= strength * sin;
            }
        }

        let ahead = clear[0];
        if command.forward > 0.0 && ahead < c.blocked {
            let side = *self.side.get_or_insert_with(|| {
                let right = clear[1] + clear[2];
                let left = clear[7] + clear[6];
                let side = if right > left { 1.0 } else { -1.0 };
                step.events.push(AgentEvent::Log(format!(
                    "obstacle ahead at {ahead:.2} m: going around on the {}",
                    if side > 0.0 { "right" } else { "left" }
                )));
                side
            });
            command.forward = 0.0;
            command.right = side * c.sidestep;
        } else if ahead > c.blocked * 1.5 {
            self.side = None;
        }
        command.forward += push_forward;
        command.right += push_right;

        let near = |r: &Option<crate::uav::Reading<f64>>| {
            r.as_ref().is_some_and(|r| r.value < c.vertical_margin)
        };
        if (command.up > 0.0 && near(&uav.free_above))
            || (command.up < 0.0 && near(&uav.free_below))
        {
            command.up = 0.0;
        }
        command.clamped()
    }
}

impl Agent for Avoid {
    fn name(&self) -> &str {
        INFO.name
    }

    fn add_mission(&mut self, mission: Mission) -> Result<(), MissionRefused> {
        match mission {
            Mission::GotoXyz { .. } => self.base.add_mission(mission),
            Mission::Hover { .. } => Err(MissionRefused {
                agent: INFO.name.into(),
                kind: mission.kind(),
                reason: "it only flies to points (use the base agent to hover)".into(),
            }),
        }
    }

    fn start(&mut self, time: f64) {
        self.side = None;
        self.base.start(time);
    }

    fn stop(&mut self) {
        self.base.stop();
    }

    fn step(&mut self, uav: &UavState, time: f64) -> Step {
        let mut step = self.base.step(uav, time);
        if let Some(command) = step.command.filter(|_| !step.all_done)
            && command != SpeedCommand::STOP
        {
            step.command = Some(self.adjust(command, uav, &mut step));
        }
        step
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::agents::base::tests::uav_at;
    use crate::geometry::Coordinates;
    use crate::uav::{LaserScan, Reading};

    fn agent_to(target: Coordinates) -> Avoid {
        let mut agent = Avoid::new(WaypointConfig::default(), AvoidConfig::default());
        agent.add_mission(Mission::goto(target)).unwrap();
        agent.start(0.0);
        agent
    }

    fn with_sonar(mut uav: UavState, index: usize, range: f64) -> UavState {
        uav.sonars[index] = Some(Reading {
            value: range,
            time: 0.0,
        });
        uav
    }

    #[test]
    fn free_way_is_the_waypoint_law() {
        let mut agent = agent_to(Coordinates::new(5.0, 0.0, 0.0));
        let uav = with_sonar(uav_at(Coordinates::zeros(), 0.0), 4, 3.0);
        let step = agent.step(&uav, 0.0);
        let c = step.command.unwrap();
        assert_eq!((c.forward, c.right), (100.0, 0.0));
        assert!(c.yaw.abs() < 1e-9);
    }

    #[test]
    fn turns_away_from_a_close_sonar_reading() {
        let mut agent = agent_to(Coordinates::new(5.0, 0.0, 0.0));
        // Something 0.6 m ahead and 0.7 m ahead-right: go around on the left, back off.
        let uav = with_sonar(uav_at(Coordinates::zeros(), 0.0), 0, 0.6);
        let uav = with_sonar(uav, 1, 0.7);
        let step = agent.step(&uav, 0.0);
        let c = step.command.unwrap();
        assert!(c.forward < 0.0, "{c:?}");
        assert!(c.right < -50.0, "{c:?}");
        assert!(
            step.events
                .iter()
                .any(|e| matches!(e, AgentEvent::Log(l) if l.contains("left"))),
            "{:?}",
            step.events
        );
        // Still blocked with the right now freer: keeps the side it chose.
        let uav = with_sonar(
            with_sonar(uav_at(Coordinates::zeros(), 0.0), 0, 0.9),
            7,
            1.1,
        );
        let c = agent.step(&uav, 0.1).command.unwrap();
        assert!(c.right < 0.0, "{c:?}");
    }

    #[test]
    fn close_wall_on_the_right_pushes_left() {
        let mut agent = agent_to(Coordinates::new(5.0, 0.0, 0.0));
        let uav = with_sonar(uav_at(Coordinates::zeros(), 0.0), 2, 0.5);
        let c = agent.step(&uav, 0.0).command.unwrap();
        assert!((c.right + 50.0).abs() < 1e-9, "{c:?}");
        assert!((c.forward - 100.0).abs() < 1e-9, "{c:?}");
    }

    #[test]
    fn laser_sees_the_way_ahead() {
        let mut agent = agent_to(Coordinates::new(5.0, 0.0, 0.0));
        let mut ranges = vec![4.0; 228];
        // Beams right of the centre (lower indices) see a wall at 0.8 m.
        for r in &mut ranges[100..114] {
            *r = 0.8;
        }
        let mut uav = uav_at(Coordinates::zeros(), 0.0);
        uav.laser = Some(Reading {
            value: LaserScan {
                ranges,
                resolution: 0.0184,
                fov: 4.1889,
            },
            time: 0.0,
        });
        assert!((agent.clearances(&uav)[0] - 0.8).abs() < 1e-9);
        let c = agent.step(&uav, 0.0).command.unwrap();
        assert!(c.forward < 0.0 && c.right.abs() > 50.0, "{c:?}");
    }

    #[test]
    fn no_climb_under_a_ceiling() {
        let mut agent = agent_to(Coordinates::new(5.0, 0.0, -3.0));
        let mut uav = uav_at(Coordinates::zeros(), 0.0);
        uav.free_above = Some(Reading {
            value: 0.3,
            time: 0.0,
        });
        let c = agent.step(&uav, 0.0).command.unwrap();
        assert_eq!(c.up, 0.0);
        // The straight line's horizontal part: 5 m of its 5.83.
        assert!(
            (c.forward - 100.0 * 5.0 / 34f64.sqrt()).abs() < 1e-9,
            "{c:?}"
        );
    }

    /// Distance along a horizontal ray from `p` to an axis-aligned box (x0, x1, y0, y1).
    fn ray_to_box(p: Coordinates, angle: f64, b: (f64, f64, f64, f64)) -> Option<f64> {
        let (dx, dy) = (angle.cos(), angle.sin());
        let slab = |o: f64, d: f64, lo: f64, hi: f64| {
            if d.abs() < 1e-12 {
                if o >= lo && o <= hi {
                    Some((f64::MIN, f64::MAX))
                } else {
                    None
                }
            } else {
                let (a, b) = ((lo - o) / d, (hi - o) / d);
                Some((a.min(b), a.max(b)))
            }
        };
        let (ax, bx) = slab(p.x, dx, b.0, b.1)?;
        let (ay, by) = slab(p.y, dy, b.2, b.3)?;
        let (near, far) = (ax.max(ay), bx.min(by));
        (near <= far && far >= 0.0).then_some(near.max(0.0))
    }

    #[test]
    fn closed_loop_goes_around_a_pillar() {
        // A 1 m pillar 3 m north, the target 6 m north; the UAV must not touch it.
        let pillar = (2.5, 3.5, -0.5, 0.5);
        let target = Coordinates::new(6.0, 0.0, 0.0);
        let mut agent = agent_to(target);
        let (mut p, mut yaw, dt) = (Coordinates::zeros(), 0.0f64, 0.1);
        let mut closest = f64::MAX;
        let mut reached = false;
        for tick in 0..600 {
            let mut uav = uav_at(p, yaw);
            for i in 0..HORIZONTAL_SONARS {
                let range = ray_to_box(p, yaw + i as f64 * std::f64::consts::FRAC_PI_4, pillar)
                    .unwrap_or(5.0)
                    .clamp(0.1, 5.0);
                closest = closest.min(range);
                uav.sonars[i] = Some(Reading {
                    value: range,
                    time: 0.0,
                });
            }
            let step = agent.step(&uav, tick as f64 * dt);
            if step.all_done {
                reached = true;
                break;
            }
            let c = step.command.unwrap_or(SpeedCommand::STOP);
            yaw += c.yaw.trunc().to_radians() * dt;
            let (s, co) = yaw.sin_cos();
            let (f, r) = (c.forward * 0.02, c.right * 0.02);
            p += Coordinates::new(f * co - r * s, f * s + r * co, 0.0) * dt;
        }
        assert!(reached, "stuck at {p:?}");
        assert!(closest > 0.3, "came within {closest} m of the pillar");
    }

    #[test]
    fn refuses_hover() {
        let mut agent = Avoid::new(WaypointConfig::default(), AvoidConfig::default());
        let err = agent
            .add_mission(Mission::Hover { seconds: 1.0 })
            .unwrap_err();
        assert_eq!(err.kind, "Hover");
        assert!(err.to_string().contains("avoid"));
    }
}
