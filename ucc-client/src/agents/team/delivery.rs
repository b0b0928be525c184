//! `delivery`: takes off, flies to the pickup pad at cruise height, lands and takes the
//! payload, climbs, flies the scenario's waypoints past the obstacles (pushed away from
//! anything its horizontal sonars see closer than [`CLEARANCE`]), lands on the drop-off pad
//! and releases the payload (or drops it from above the pad when the scenario says not to
//! land), then goes back to the base and lands.

use super::{
    Act, Board, Brief, Route, TeamAgent, TeamAgentInfo, TeamStep, distance2, fly_to, position,
};
use crate::speed::SpeedCommand;
use crate::uav::{HORIZONTAL_SONARS, UavState};

/// The registry entry.
pub const INFO: TeamAgentInfo = TeamAgentInfo {
    name: "delivery",
    description: "picks up a payload, flies waypoints past obstacles, lands on the pad and sets it down",
    create: || Box::new(Courier::default()),
};

/// Metres: closer than this, a sonar's obstacle pushes the UAV away.
pub const CLEARANCE: f64 = 1.5;

#[derive(Debug, Clone, Copy, Default, PartialEq)]
enum Phase {
    #[default]
    ToPickup,
    LandPickup,
    Climb,
    Carry,
    LandDrop,
    Leave,
    Home,
    LandHome,
    Done,
}

/// The courier.
#[derive(Debug, Clone, Default)]
pub struct Courier {
    brief: Option<Brief>,
    phase: Phase,
    route: Route,
}

/// A push away from obstacles the horizontal sonars see within [`CLEARANCE`], in percent
/// of the top speed, body frame (forward, right).
pub fn repulsion(uav: &UavState) -> (f64, f64) {
    let mut push = (0.0, 0.0);
    for (i, s) in uav.sonars.iter().enumerate() {
        let Some(r) = s else { continue };
        if r.value > 0.0 && r.value < CLEARANCE {
            // Sonar i points at i·45° clockwise from ahead.
            let a = i as f64 * std::f64::consts::TAU / HORIZONTAL_SONARS as f64;
            let strength = 100.0 * (CLEARANCE - r.value) / CLEARANCE;
            push.0 -= strength * a.cos();
            push.1 -= strength * a.sin();
        }
    }
    push
}

/// `command` with the sonars' [`repulsion`] added.
fn clear_of_obstacles(mut command: SpeedCommand, uav: &UavState) -> SpeedCommand {
    let (f, r) = repulsion(uav);
    command.forward += f;
    command.right += r;
    command.clamped()
}

fn landed(uav: &UavState, pad_z: f64, pos: [f64; 3]) -> bool {
    let low = uav
        .free_below
        .as_ref()
        .map_or(pad_z - pos[2] < 0.45, |r| r.value < 0.35);
    let still = uav.velocity.as_ref().is_none_or(|v| v.value.norm() < 0.3);
    low && still
}

impl TeamAgent for Courier {
    fn name(&self) -> &str {
        INFO.name
    }

    fn start(&mut self, brief: &Brief) {
        self.brief = Some(brief.clone());
    }

    fn step(&mut self, uav: &UavState, board: &Board, _time: f64) -> TeamStep {
        let mut out = TeamStep::default();
        let (Some(pos), Some(brief)) = (position(uav), self.brief.as_ref()) else {
            out.command = Some(SpeedCommand::STOP);
            return out;
        };
        let Some(job) = brief.delivery.clone() else {
            out.command = Some(SpeedCommand::STOP);
            out.done = true;
            return out;
        };
        let yaw = uav.yaw();
        let z = -brief.altitude;
        let carrying = board.carrying.get(brief.index).copied().unwrap_or(false);
        let over = |pad: [f64; 3]| [pad[0], pad[1], pad[2] + z];
        let descend = |target: [f64; 3]| {
            let mut c = fly_to(pos, yaw, [target[0], target[1], pos[2]], 0.4, 1.0);
            c.up = if target[2] - pos[2] > 1.0 {
                -80.0
            } else {
                -35.0
            };
            c
        };
        let next = |phase: Phase, out: &mut TeamStep, line: &str| {
            out.log.push(line.to_owned());
            phase
        };
        let command = match self.phase {
            Phase::ToPickup => {
                let goal = over(job.pickup.location);
                if pos[2] > goal[2] + 0.5 && distance2(pos, goal) > 1.0 {
                    SpeedCommand {
                        up: 100.0,
                        ..SpeedCommand::STOP
                    }
                } else {
                    if distance2(pos, goal) < 0.3 {
                        self.phase =
                            next(Phase::LandPickup, &mut out, "over the pickup pad: landing");
                    }
                    fly_to(pos, yaw, goal, 1.0, 2.0)
                }
            }
            Phase::LandPickup => {
                if carrying {
                    self.phase = next(Phase::Climb, &mut out, "payload on board: taking off");
                    let mut pts = job.waypoints.clone();
                    pts.push(over(job.dropoff.location));
                    self.route = Route::new(pts, 0.5);
                } else if landed(uav, job.pickup.location[2], pos) {
                    out.act = Some(Act::PickUp);
                }
                descend(job.pickup.location)
            }
            Phase::Climb => {
                if pos[2] <= z + 0.3 {
                    self.phase = Phase::Carry;
                }
                SpeedCommand {
                    up: 100.0,
                    ..SpeedCommand::STOP
                }
            }
            Phase::Carry => match self.route.steer(pos, yaw) {
                Some(c) => clear_of_obstacles(c, uav),
                None => {
                    self.phase = next(
                        Phase::LandDrop,
                        &mut out,
                        if job.land {
                            "over the drop-off pad: landing"
                        } else {
                            "over the drop-off pad: dropping"
                        },
                    );
                    SpeedCommand::STOP
                }
            },
            Phase::LandDrop => {
                if !carrying {
                    self.phase = next(Phase::Leave, &mut out, "payload delivered: taking off");
                    SpeedCommand::STOP
                } else if !job.land || landed(uav, job.dropoff.location[2], pos) {
                    out.act = Some(Act::Drop);
                    SpeedCommand::STOP
                } else {
                    descend(job.dropoff.location)
                }
            }
            Phase::Leave => {
                if pos[2] <= z + 0.3 {
                    self.phase = Phase::Home;
                    let mut back: Vec<[f64; 3]> = job.waypoints.iter().rev().copied().collect();
                    if let Some(base) = brief.base {
                        back.push(over(base.location));
                    } else {
                        back.clear();
                    }
                    self.route = Route::new(back, 0.5);
                }
                SpeedCommand {
                    up: 100.0,
                    ..SpeedCommand::STOP
                }
            }
            Phase::Home => match self.route.steer(pos, yaw) {
                Some(c) => clear_of_obstacles(c, uav),
                None => {
                    self.phase = if brief.base.is_some() {
                        next(Phase::LandHome, &mut out, "back at the base: landing")
                    } else {
                        Phase::Done
                    };
                    SpeedCommand::STOP
                }
            },
            Phase::LandHome => {
                let base = brief.base.map_or(pos, |b| b.location);
                if landed(uav, base[2], pos) {
                    self.phase = next(Phase::Done, &mut out, "landed at the base");
                }
                descend(base)
            }
            Phase::Done => {
                out.done = true;
                SpeedCommand {
                    up: -30.0,
                    ..SpeedCommand::STOP
                }
            }
        };
        out.command = Some(command);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uav::Reading;

    #[test]
    fn an_obstacle_ahead_pushes_back_and_one_on_the_right_pushes_left() {
        let mut uav = UavState::new();
        uav.sonars[0] = Some(Reading {
            value: 0.5,
            time: 0.0,
        });
        let (f, r) = repulsion(&uav);
        assert!(f < -50.0 && r.abs() < 1e-9, "{f} {r}");
        uav.sonars[0] = None;
        uav.sonars[2] = Some(Reading {
            value: 0.75,
            time: 0.0,
        });
        let (f, r) = repulsion(&uav);
        assert!(r < -40.0 && f.abs() < 1e-6, "{f} {r}");
    }
}
