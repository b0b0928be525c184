//! `base`: the waypoint agent of the original control program.
//!
//! In the horizontal plane, α is the angle from the UAV's right axis to the direction of the
//! target, counted towards the forward axis (target on the right: 0°, ahead: 90°, on the
//! left: 180°, behind: 270°). The command is
//!
//! * forward = 100·sin α when the target is ahead (0° ≤ α ≤ 180°), 0 otherwise;
//! * yaw = 100·cos α (+ = turn right);
//! * up = 100·sin β, β the elevation of the target seen from the UAV;
//! * no lateral speed.
//!
//! One tie is broken on purpose: a target exactly behind (cos α = 0, sin α < 0) would leave
//! the UAV still forever, so it turns right at full speed.
//!
//! The thesis's law flies arcs: it moves forward while it turns, so even with imposed
//! velocities (stsAirRobot) a 2 m square strays 0.35 m from its sides; and at full speed up to
//! the waypoint it makes a vehicle with momentum (the stsQuadrotor, a real AR-100B) overshoot
//! and orbit its waypoints. So `base` keeps the law's heading (the yaw command above: it turns
//! to face the target) but moves as an autopilot's position loop does ([`hold_law`]): a
//! straight line to the target, sideways as needed, at a speed proportional to the distance
//! ([`WaypointConfig::gain`]) and at most full speed; within [`WaypointConfig::near`] of the
//! target it holds its heading too. The `thesis` agent flies the law alone
//! ([`WaypointConfig::original`]), as the original program did.
//!
//! A GotoXyz mission is reached when the UAV is within [`WaypointConfig::tolerance`] (default
//! 0.3 m, 3D distance); then the next mission is taken. A Hover mission holds, for its
//! duration, the waypoint of the GotoXyz before it (or where it starts, when it comes first).

use super::AgentInfo;
use crate::agent::{Agent, AgentEvent, MissionRefused, SpeedCommand, Step};
use crate::geometry::{Coordinates, world_to_heading};
use crate::mission::Mission;
use crate::speed::{FULL_SPEED, FULL_TURN};
use crate::uav::UavState;

/// The registry entry.
pub const INFO: AgentInfo = AgentInfo {
    name: "base",
    description: "waypoint flight: straight lines, turning to face each waypoint as the original law does, holding the point near it (no obstacle avoidance)",
    create: || Box::new(Base::new(WaypointConfig::default())),
};

/// The registry entry of the original law alone.
pub const THESIS: AgentInfo = AgentInfo {
    name: "thesis",
    description: "the original control law alone, as the thesis flew it (arcs; a vehicle with momentum orbits its waypoints)",
    create: || {
        Box::new(Base::new(WaypointConfig {
            original: true,
            ..WaypointConfig::default()
        }))
    },
};

/// Tunables of the waypoint flight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaypointConfig {
    /// A waypoint counts as reached within this distance, metres. At full speed (2 m/s) and
    /// 10 position readings per second the UAV moves 0.2 m between readings, so this must
    /// stay above about 0.15 m.
    pub tolerance: f64,
    /// Metres: within this distance of the target the agent holds the point ([`hold_law`])
    /// instead of flying the thesis's law.
    pub near: f64,
    /// 1/s: the hold's speed per metre of distance (the position loop's gain).
    pub gain: f64,
    /// Fly the thesis's law alone, as the original program did (the `thesis` agent).
    pub original: bool,
}

impl Default for WaypointConfig {
    fn default() -> Self {
        Self {
            tolerance: 0.3,
            near: 1.5,
            gain: 1.5,
            original: false,
        }
    }
}

/// The position loop: the speed command that takes a UAV at `position` with heading `yaw`
/// towards `target` (world frame, z down) at `gain` metres per second per metre of distance,
/// at most full speed, in a straight line (sideways and backwards as needed), heading held.
pub fn hold_law(position: &Coordinates, yaw: f64, target: &Coordinates, gain: f64) -> SpeedCommand {
    let d = world_to_heading(&(target - position), yaw);
    let distance = d.norm();
    if distance < 1e-9 {
        return SpeedCommand::STOP;
    }
    let percent = 100.0 * (gain * distance).min(FULL_SPEED) / FULL_SPEED;
    SpeedCommand {
        forward: percent * d.x / distance,
        right: percent * d.y / distance,
        up: -percent * d.z / distance,
        yaw: 0.0,
    }
}

/// The waypoint law: the speed command that takes a UAV at `position` with heading `yaw`
/// towards `target` (world frame, z down). See the module documentation.
pub fn waypoint_law(position: &Coordinates, yaw: f64, target: &Coordinates) -> SpeedCommand {
    let d = world_to_heading(&(target - position), yaw);
    let horizontal = d.x.hypot(d.y);
    let (forward, turn) = if horizontal < 1e-9 {
        (0.0, 0.0)
    } else {
        let alpha = d.x.atan2(d.y);
        let (sin, cos) = alpha.sin_cos();
        let turn = if sin < 0.0 && cos.abs() < 1e-9 {
            100.0
        } else {
            100.0 * cos
        };
        (100.0 * sin.max(0.0), turn)
    };
    let beta = (-d.z).atan2(horizontal);
    SpeedCommand {
        forward,
        right: 0.0,
        up: 100.0 * beta.sin(),
        yaw: turn,
    }
}

/// The progress through a mission list; shared by the agents that fly waypoints.
#[derive(Debug, Clone, Default)]
pub struct Base {
    config: WaypointConfig,
    missions: Vec<Mission>,
    current: usize,
    running: bool,
    /// Time and position at which the current mission started.
    mission_start: Option<(f64, Coordinates)>,
    /// The waypoint of the last GotoXyz reached (where a Hover after it holds).
    last_waypoint: Option<Coordinates>,
    /// Time of the last step that sent a command.
    last_step: Option<f64>,
}

impl Base {
    /// An agent with no missions yet.
    pub fn new(config: WaypointConfig) -> Self {
        Self {
            config,
            ..Self::default()
        }
    }

    /// The missions, in order.
    pub fn missions(&self) -> &[Mission] {
        &self.missions
    }

    /// Index of the mission being flown (equal to the count when all are done).
    pub fn current(&self) -> usize {
        self.current
    }
}

impl Agent for Base {
    fn name(&self) -> &str {
        if self.config.original {
            THESIS.name
        } else {
            INFO.name
        }
    }

    fn add_mission(&mut self, mission: Mission) -> Result<(), MissionRefused> {
        self.missions.push(mission);
        Ok(())
    }

    fn start(&mut self, _time: f64) {
        self.running = true;
    }

    fn stop(&mut self) {
        self.running = false;
    }

    fn step(&mut self, uav: &UavState, time: f64) -> Step {
        let mut step = Step::default();
        if !self.running {
            step.command = Some(SpeedCommand::STOP);
            return step;
        }
        let Some(position) = uav.position.as_ref().map(|p| p.value) else {
            return step; // nothing to steer by yet
        };
        while let Some(mission) = self.missions.get(self.current) {
            let (start_time, start_position) = *self.mission_start.get_or_insert_with(|| {
                step.events.push(AgentEvent::MissionStarted {
                    index: self.current,
                    mission: mission.clone(),
                    time,
                });
                (time, position)
            });
            let (target, done) = match mission {
                Mission::GotoXyz { .. } => {
                    let target = mission.target().unwrap_or(position);
                    (target, (target - position).norm() <= self.config.tolerance)
                }
                Mission::Hover { seconds } => (
                    self.last_waypoint.unwrap_or(start_position),
                    time - start_time >= *seconds,
                ),
            };
            if !done {
                let distance = (target - position).norm();
                let (yaw, c) = (uav.yaw(), &self.config);
                step.command = Some(if c.original {
                    waypoint_law(&position, yaw, &target)
                } else if distance <= c.near {
                    hold_law(&position, yaw, &target, c.gain)
                } else {
                    // The command holds until the next step while the heading turns: the
                    // straight line is aimed from the heading halfway there.
                    let turn = waypoint_law(&position, yaw, &target).yaw;
                    let period = self.last_step.map_or(0.1, |t| (time - t).clamp(0.0, 0.5));
                    let lead = if turn.abs() < 0.01 {
                        0.0 // below what a DRIVE line resolves
                    } else {
                        (turn / 100.0 * FULL_TURN).to_radians() * period / 2.0
                    };
                    SpeedCommand {
                        yaw: turn,
                        ..hold_law(&position, yaw + lead, &target, c.gain)
                    }
                });
                self.last_step = Some(time);
                return step;
            }
            if let Some(target) = mission.target() {
                self.last_waypoint = Some(target);
            }
            let distance = mission.target().map(|t| (t - position).norm());
            step.events.push(AgentEvent::MissionDone {
                index: self.current,
                mission: mission.clone(),
                time,
                distance,
            });
            self.current += 1;
            self.mission_start = None;
        }
        step.all_done = true;
        step.command = Some(SpeedCommand::STOP);
        step
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::uav::Reading;
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    /// A UAV at `position` with heading `yaw`.
    pub(crate) fn uav_at(position: Coordinates, yaw: f64) -> UavState {
        let mut uav = UavState::new();
        uav.position = Some(Reading {
            value: position,
            time: 0.0,
        });
        uav.orientation = Some(Reading {
            value: Coordinates::new(0.0, 0.0, yaw),
            time: 0.0,
        });
        uav
    }

    fn law(target: (f64, f64, f64), yaw: f64) -> SpeedCommand {
        waypoint_law(
            &Coordinates::zeros(),
            yaw,
            &Coordinates::new(target.0, target.1, target.2),
        )
    }

    fn assert_command(c: SpeedCommand, forward: f64, yaw: f64, up: f64) {
        let ok = (c.forward - forward).abs() < 1e-6
            && (c.yaw - yaw).abs() < 1e-6
            && (c.up - up).abs() < 1e-6
            && c.right == 0.0;
        assert!(
            ok,
            "got {c:?}, expected forward {forward} yaw {yaw} up {up}"
        );
    }

    #[test]
    fn target_ahead_right_left_behind() {
        // Heading north (yaw 0): x ahead, y right.
        assert_command(law((5.0, 0.0, 0.0), 0.0), 100.0, 0.0, 0.0); // α = 90°
        assert_command(law((0.0, 5.0, 0.0), 0.0), 0.0, 100.0, 0.0); // α = 0°
        assert_command(law((0.0, -5.0, 0.0), 0.0), 0.0, -100.0, 0.0); // α = 180°
        assert_command(law((-5.0, 0.0, 0.0), 0.0), 0.0, 100.0, 0.0); // α = 270°, tie broken
    }

    #[test]
    fn diagonal_angles() {
        let s = FRAC_PI_4.sin() * 100.0;
        // Ahead-right: α = 45°.
        assert_command(law((3.0, 3.0, 0.0), 0.0), s, s, 0.0);
        // Ahead-left: α = 135°.
        assert_command(law((3.0, -3.0, 0.0), 0.0), s, -s, 0.0);
        // Behind-left: α = 225°: no forward speed, turn left.
        assert_command(law((-3.0, -3.0, 0.0), 0.0), 0.0, -s, 0.0);
        // Behind-right: α = 315°: turn right.
        assert_command(law((-3.0, 3.0, 0.0), 0.0), 0.0, s, 0.0);
        // α = 60°: forward 100·sin 60° = 86.6, yaw 100·cos 60° = 50.
        let a = 60f64.to_radians();
        assert_command(law((a.sin(), a.cos(), 0.0), 0.0), 86.602540378, 50.0, 0.0);
    }

    #[test]
    fn heading_is_taken_into_account() {
        // Heading east (yaw +90°): a target to the east is ahead, one to the north is left.
        assert_command(law((0.0, 5.0, 0.0), FRAC_PI_2), 100.0, 0.0, 0.0);
        assert_command(law((5.0, 0.0, 0.0), FRAC_PI_2), 0.0, -100.0, 0.0);
        // Heading south: a target to the north is behind.
        assert_command(law((5.0, 0.0, 0.0), PI), 0.0, 100.0, 0.0);
    }

    #[test]
    fn elevation() {
        // z is down: a target 3 m ahead and 3 m up is at β = 45°.
        let s = FRAC_PI_4.sin() * 100.0;
        assert_command(law((3.0, 0.0, -3.0), 0.0), 100.0, 0.0, s);
        assert_command(law((3.0, 0.0, 3.0), 0.0), 100.0, 0.0, -s);
        // Straight above: climb only.
        assert_command(law((0.0, 0.0, -2.0), 0.0), 0.0, 0.0, 100.0);
    }

    #[test]
    fn flies_missions_in_order() {
        let mut agent = Base::new(WaypointConfig::default());
        agent
            .add_mission(Mission::goto(Coordinates::new(2.0, 0.0, 0.0)))
            .unwrap();
        agent.add_mission(Mission::Hover { seconds: 1.0 }).unwrap();

        // Not started: stop.
        let step = agent.step(&uav_at(Coordinates::zeros(), 0.0), 0.0);
        assert_eq!(step.command, Some(SpeedCommand::STOP));

        agent.start(0.0);
        let step = agent.step(&uav_at(Coordinates::zeros(), 0.0), 0.0);
        assert_command(step.command.unwrap(), 100.0, 0.0, 0.0);
        assert!(matches!(
            step.events[..],
            [AgentEvent::MissionStarted { index: 0, .. }]
        ));

        // Within tolerance: waypoint reached, hover starts.
        let step = agent.step(&uav_at(Coordinates::new(1.8, 0.0, 0.0), 0.0), 1.0);
        assert!(!step.all_done);
        match &step.events[..] {
            [
                AgentEvent::MissionDone {
                    index: 0,
                    time,
                    distance: Some(d),
                    ..
                },
                AgentEvent::MissionStarted { index: 1, .. },
            ] => {
                assert_eq!(*time, 1.0);
                assert!((d - 0.2).abs() < 1e-9);
            }
            other => panic!("unexpected events {other:?}"),
        }
        // The hover holds the waypoint, not where the mission was reached: 0.2 m short, it
        // moves on at 1.5 m/s per metre (0.3 m/s, 15 %).
        assert_command(step.command.unwrap(), 15.0, 0.0, 0.0);

        // Drifted while hovering: flies back straight, backwards, heading held.
        let step = agent.step(&uav_at(Coordinates::new(2.8, 0.0, 0.0), 0.0), 1.5);
        assert_command(step.command.unwrap(), -60.0, 0.0, 0.0);

        let step = agent.step(&uav_at(Coordinates::new(1.8, 0.0, 0.0), 0.0), 2.0);
        assert!(step.all_done);
        assert_eq!(step.command, Some(SpeedCommand::STOP));
        assert_eq!(agent.current(), 2);
    }

    /// Flies `agent` in a kinematic AirRobot (2 m/s, 100 deg/s, integer deg/s) sampled at
    /// 10 Hz; returns the simulated seconds until all missions are done.
    pub(crate) fn fly(agent: &mut dyn Agent, max_seconds: f64) -> Option<f64> {
        let (mut p, mut yaw, dt) = (Coordinates::zeros(), 0.0f64, 0.1);
        let mut command = SpeedCommand::STOP;
        agent.start(0.0);
        for tick in 0..(max_seconds / dt) as usize {
            let t = tick as f64 * dt;
            let step = agent.step(&uav_at(p, yaw), t);
            if step.all_done {
                return Some(t);
            }
            command = step.command.unwrap_or(command).clamped();
            yaw += (command.yaw.trunc()).to_radians() * dt;
            let (s, c) = yaw.sin_cos();
            let (f, r) = (command.forward * 0.02, command.right * 0.02);
            p += Coordinates::new(f * c - r * s, f * s + r * c, -command.up * 0.02) * dt;
        }
        None
    }

    #[test]
    fn closed_loop_reaches_every_waypoint() {
        let mut agent = Base::new(WaypointConfig::default());
        for (x, y, z) in [
            (0.0, 0.0, -1.5),
            (2.5, 0.0, -1.5),
            (2.5, 2.5, -2.0),
            (0.0, 2.5, -1.5),
            (-3.0, -1.0, -1.0),
        ] {
            agent
                .add_mission(Mission::goto(Coordinates::new(x, y, z)))
                .unwrap();
        }
        let seconds = fly(&mut agent, 120.0).expect("all waypoints reached");
        assert!(seconds < 40.0, "took {seconds} s");
    }

    #[test]
    fn waits_for_a_position() {
        let mut agent = Base::new(WaypointConfig::default());
        agent
            .add_mission(Mission::goto(Coordinates::zeros()))
            .unwrap();
        agent.start(0.0);
        let step = agent.step(&UavState::default(), 0.0);
        assert_eq!(step, Step::default());
    }
}
