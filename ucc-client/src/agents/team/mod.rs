//! Team agents: the baseline agents of the scenarios (docs/scenarios.md). Like the mission
//! agents they do no I/O and read no clock: at the start a [`Brief`] tells one what the
//! scenario asks of it, then every period it gets its own [`UavState`], the shared [`Board`]
//! and the simulated time, and answers a [`TeamStep`].
//!
//! A new team agent is one file here and one line in [`TEAM_AGENTS`].

pub mod delivery;
pub mod follow;
pub mod lanes;
pub mod perimeter;
pub mod random;
pub mod relay;
pub mod searcher;
pub mod spiral;

use std::collections::BTreeMap;

use crate::geometry::{Coordinates, world_to_heading};
use crate::scenario::model::{Delivery, Fire, Pad, Radio, Relay, Search};
use crate::speed::SpeedCommand;
use crate::uav::UavState;

/// What the scenario tells one agent before the start.
#[derive(Debug, Clone, PartialEq)]
pub struct Brief {
    /// This UAV's index among all the scenario's UAVs (spawn order).
    pub index: usize,
    /// The indices of the UAVs flown by the same agent, this one included, ascending.
    pub group: Vec<usize>,
    /// UAVs in all.
    pub team: usize,
    /// The scenario's seed for this iteration (for agents that draw at random).
    pub seed: u64,
    /// Cruise height above the ground, metres.
    pub altitude: f64,
    /// The radius of the downward sensor's footprint at the cruise height, metres.
    pub footprint: f64,
    /// The UAV's top horizontal speed, m/s (its class's).
    pub speed: f64,
    /// The base station's pad.
    pub base: Option<Pad>,
    /// Where this UAV started.
    pub start: [f64; 3],
    /// Its own landing spot on the base pad (its start when that is on the pad, else a
    /// place on a ring around the pad's centre), so that UAVs do not land on each other.
    pub spot: [f64; 3],
    /// The area to search.
    pub search: Option<Search>,
    /// The endpoints to connect.
    pub relay: Option<Relay>,
    /// The radio model.
    pub radio: Radio,
    /// The fire (its centre is known; its radius is sensed: [`Board::fire_radius`]).
    pub fire: Option<Fire>,
    /// The targets' starts.
    pub targets: Vec<[f64; 3]>,
    /// The delivery job.
    pub delivery: Option<Delivery>,
    /// Simulated seconds of the iteration.
    pub time_limit: f64,
}

impl Brief {
    /// This UAV's rank in its group (0 for the first).
    pub fn rank(&self) -> usize {
        self.group
            .iter()
            .position(|&i| i == self.index)
            .unwrap_or(0)
    }

    /// The height it flies home at: the cruise height plus a layer of its own (1 m apart,
    /// five layers), so that UAVs converging on the base from all sides pass over each
    /// other instead of meeting head-on at one height.
    pub fn home_altitude(&self) -> f64 {
        self.altitude + (self.index % 5) as f64
    }
}

/// What every agent knows each period: the scenario's shared facts and, when the scenario
/// has a blackboard, what the other UAVs report and post.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Board {
    /// Simulated seconds.
    pub time: f64,
    /// Each UAV's reported position (only this UAV's without a blackboard).
    pub positions: Vec<Option<[f64; 3]>>,
    /// Each UAV's battery level, 0..=1 (only this UAV's without a blackboard).
    pub batteries: Vec<Option<f64>>,
    /// Each UAV is landed on the base pad and charging.
    pub charging: Vec<bool>,
    /// Each UAV carries a payload.
    pub carrying: Vec<bool>,
    /// Victims found so far, where.
    pub found: Vec<[f64; 3]>,
    /// Each target's last sighting: where and when.
    pub targets: Vec<Option<([f64; 3], f64)>>,
    /// The fire's radius, once a UAV's footprint has reached its edge (then updated each
    /// period a footprint touches it).
    pub fire_radius: Option<f64>,
    /// Notes the agents posted: key → (poster's index, value).
    pub notes: BTreeMap<String, (usize, f64)>,
}

/// An agent's request to the scenario's world.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Act {
    /// Take the payload (granted when landed on the pickup pad).
    PickUp,
    /// Release the payload (it falls if the UAV is flying).
    Drop,
}

/// What a team agent answers to one step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TeamStep {
    /// The speed command (`None`: keep the last).
    pub command: Option<SpeedCommand>,
    /// Lines for the log.
    pub log: Vec<String>,
    /// Notes to post (`Some` value) or take down (`None`) on the blackboard.
    pub notes: Vec<(String, Option<f64>)>,
    /// A request.
    pub act: Option<Act>,
    /// This agent has nothing left to do.
    pub done: bool,
}

/// A team agent.
pub trait TeamAgent: Send {
    /// The registry name.
    fn name(&self) -> &str;
    /// Called once before the first step.
    fn start(&mut self, brief: &Brief);
    /// Called every period with this UAV's state, the board and the simulated time.
    fn step(&mut self, uav: &UavState, board: &Board, time: f64) -> TeamStep;
}

/// A registry entry.
#[derive(Debug, Clone, Copy)]
pub struct TeamAgentInfo {
    /// The name scenario files use.
    pub name: &'static str,
    /// One line for `--list`.
    pub description: &'static str,
    /// A fresh agent.
    pub create: fn() -> Box<dyn TeamAgent>,
}

/// Every team agent by name.
pub const TEAM_AGENTS: &[TeamAgentInfo] = &[
    random::INFO,
    lanes::INFO,
    lanes::PARTITION_INFO,
    spiral::INFO,
    relay::INFO,
    perimeter::INFO,
    follow::INFO,
    delivery::INFO,
];

/// The entry named `name`.
pub fn info(name: &str) -> Option<&'static TeamAgentInfo> {
    TEAM_AGENTS.iter().find(|a| a.name == name)
}

/// The names, comma separated.
pub fn names() -> String {
    TEAM_AGENTS
        .iter()
        .map(|a| a.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The command that flies a UAV at `position` with heading `yaw` to `target` (world frame,
/// z down) sideways as needed, at most `fraction` of its top speed, slowing within `slow`
/// metres so that it stops there instead of overshooting. Heading is held.
pub fn fly_to(
    position: [f64; 3],
    yaw: f64,
    target: [f64; 3],
    fraction: f64,
    slow: f64,
) -> SpeedCommand {
    let d = world_to_heading(
        &Coordinates::new(
            target[0] - position[0],
            target[1] - position[1],
            target[2] - position[2],
        ),
        yaw,
    );
    let horizontal = d.x.hypot(d.y);
    let top = 100.0 * fraction.clamp(0.0, 1.0);
    let speed = top * (horizontal / slow.max(1e-3)).min(1.0);
    let (forward, right) = if horizontal < 1e-6 {
        (0.0, 0.0)
    } else {
        (speed * d.x / horizontal, speed * d.y / horizontal)
    };
    SpeedCommand {
        forward,
        right,
        up: (-d.z / 0.5 * 100.0).clamp(-100.0, 100.0),
        yaw: 0.0,
    }
}

/// The UAV's position as an array (`None` before the first reading).
pub fn position(uav: &UavState) -> Option<[f64; 3]> {
    uav.position
        .as_ref()
        .map(|p| [p.value.x, p.value.y, p.value.z])
}

/// Horizontal distance.
pub fn distance2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Metres: a route point higher than this above the UAV is climbed to before flying on.
pub const CLIMB_FIRST: f64 = 2.0;

/// Follows a list of points: which one is next, and the command towards it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Route {
    /// The points, world frame, z down.
    pub points: Vec<[f64; 3]>,
    /// The next one.
    pub next: usize,
    /// A point counts as reached within this distance (3D), metres.
    pub tolerance: f64,
}

impl Route {
    /// A route through `points`.
    pub fn new(points: Vec<[f64; 3]>, tolerance: f64) -> Self {
        Self {
            points,
            next: 0,
            tolerance,
        }
    }

    /// Whether every point was reached.
    pub fn finished(&self) -> bool {
        self.next >= self.points.len()
    }

    /// Moves past reached points; the command to the next (`None` when finished). A point
    /// more than [`CLIMB_FIRST`] above the UAV is climbed to straight up first, so that a
    /// take-off to cruise height does not fly into the side of a building on the way.
    pub fn steer(&mut self, position: [f64; 3], yaw: f64) -> Option<SpeedCommand> {
        while let Some(&p) = self.points.get(self.next) {
            let d = (0..3)
                .map(|i| (p[i] - position[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            if d > self.tolerance {
                // z is down: the point is above when its z is smaller.
                let to = if position[2] - p[2] > CLIMB_FIRST {
                    [position[0], position[1], p[2]]
                } else {
                    p
                };
                return Some(fly_to(position, yaw, to, 1.0, 1.5));
            }
            self.next += 1;
        }
        None
    }
}

/// Going home to recharge: the shared behaviour of the searchers (and of relays that rotate
/// out): fly to the base at cruise height, descend onto the pad, wait until charged, climb.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub enum Homing {
    /// Not homing.
    #[default]
    Away,
    /// On the way to the base.
    Going,
    /// Descending onto the pad.
    Landing,
    /// On the pad.
    Charging,
    /// Back up to cruise height.
    Climbing,
}

impl Homing {
    /// The command for this phase, moving to the next phase when it is over. `charged`: the
    /// board says the battery is full again (or there is no charging to wait for).
    pub fn steer(
        &mut self,
        spot: [f64; 3],
        altitude: f64,
        pos: [f64; 3],
        yaw: f64,
        charging: bool,
        level: f64,
    ) -> SpeedCommand {
        let cruise = [spot[0], spot[1], spot[2] - altitude];
        match self {
            Self::Away => SpeedCommand::STOP,
            Self::Going => {
                if distance2(pos, cruise) < 0.3 {
                    *self = Self::Landing;
                }
                fly_to(pos, yaw, cruise, 1.0, 2.0)
            }
            Self::Landing => {
                if charging {
                    *self = Self::Charging;
                }
                let mut c = fly_to(pos, yaw, [cruise[0], cruise[1], pos[2]], 0.3, 0.5);
                c.up = -60.0;
                c
            }
            Self::Charging => {
                if level >= CHARGED {
                    *self = Self::Climbing;
                }
                SpeedCommand {
                    up: -30.0,
                    ..SpeedCommand::STOP
                }
            }
            Self::Climbing => {
                if pos[2] <= cruise[2] + 0.3 {
                    *self = Self::Away;
                }
                SpeedCommand {
                    up: 100.0,
                    ..SpeedCommand::STOP
                }
            }
        }
    }

    /// Seconds the flight home takes from `pos` at `speed`: 20 % over the straight line, and
    /// the descent onto the pad at 1.2 m/s with 3 s to spare.
    pub fn time_home(base: &Pad, pos: [f64; 3], speed: f64) -> f64 {
        distance2(pos, base.location) / speed.max(0.1) * 1.2
            + (base.location[2] - pos[2]).max(0.0) / 1.2
            + 3.0
    }
}

/// A battery at this level or above counts as charged.
pub const CHARGED: f64 = 0.95;

/// Metres: the scale of the landing spots' sunflower on a base pad ([`landing_spot`]).
const SPOT_SCALE: f64 = 1.25;

/// The landing spot of UAV `index` starting at `start` on a base pad (see [`Brief::spot`]):
/// its start when that is on the pad, else spot `index` of a sunflower (Vogel's spiral)
/// around the pad's centre, neighbours about 1.9 m apart, so that UAVs of 0.9 m landing
/// together do not land on each other: the first ten spots lie within 3.9 m of the
/// centre, sixteen within 4.9 m.
pub fn landing_spot(base: &Pad, start: [f64; 3], index: usize) -> [f64; 3] {
    if distance2(start, base.location) <= base.radius * 0.8 {
        return [start[0], start[1], base.location[2]];
    }
    let k = index as f64;
    let a = k * 2.399_963; // the golden angle
    let r = SPOT_SCALE * (k + 0.5).sqrt();
    [
        base.location[0] + r * a.cos(),
        base.location[1] + r * a.sin(),
        base.location[2],
    ]
}

/// The battery level a UAV reports (1 when it reports none).
pub fn battery_level(uav: &UavState) -> f64 {
    uav.battery.as_ref().map_or(1.0, |b| b.value.level)
}

/// Seconds of battery left as reported (`f64::INFINITY` without a battery).
pub fn battery_seconds(uav: &UavState) -> f64 {
    match uav.battery.as_ref() {
        Some(b) if b.value.remaining < 99_999 => b.value.remaining as f64,
        _ => f64::INFINITY,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn landing_spots_leave_room_between_uavs_and_a_start_on_the_pad_is_kept() {
        let base = Pad {
            location: [10.0, -5.0, 0.0],
            radius: 5.0,
            charge_time: 10.0,
        };
        let far = [40.0, 40.0, -0.5];
        let spots: Vec<[f64; 3]> = (0..16).map(|i| landing_spot(&base, far, i)).collect();
        for (i, a) in spots.iter().enumerate() {
            assert!(distance2(*a, base.location) <= 4.95, "spot {i} off the pad");
            for b in &spots[i + 1..] {
                assert!(distance2(*a, *b) >= 1.8, "spots {a:?} and {b:?} too close");
            }
        }
        assert_eq!(
            landing_spot(&base, [11.0, -5.0, -0.5], 3),
            [11.0, -5.0, 0.0]
        );
    }

    #[test]
    fn a_route_climbs_straight_up_to_a_high_point_before_flying_towards_it() {
        let mut route = Route::new(vec![[50.0, 0.0, -40.0]], 0.5);
        let c = route.steer([0.0, 0.0, -0.5], 0.0).unwrap();
        assert_eq!((c.forward, c.right), (0.0, 0.0));
        assert!(c.up > 99.0);
        let c = route.steer([0.0, 0.0, -39.0], 0.0).unwrap();
        assert!(c.forward > 99.0, "{c:?}");
    }

    #[test]
    fn registry_names_match_agents() {
        for info in TEAM_AGENTS {
            assert_eq!((info.create)().name(), info.name);
        }
        assert!(info("nope").is_none());
    }

    #[test]
    fn fly_to_moves_towards_the_target_and_stops_on_it() {
        let c = fly_to([0.0, 0.0, -3.0], 0.0, [10.0, 0.0, -3.0], 1.0, 2.0);
        assert!((c.forward - 100.0).abs() < 1e-9 && c.right.abs() < 1e-9);
        // Facing east (yaw +90°), a target to the north is on the left.
        let c = fly_to(
            [0.0, 0.0, -3.0],
            std::f64::consts::FRAC_PI_2,
            [10.0, 0.0, -3.0],
            1.0,
            2.0,
        );
        assert!(c.right < -99.0, "{c:?}");
        let c = fly_to([0.0, 0.0, -3.0], 0.0, [0.0, 0.0, -3.0], 1.0, 2.0);
        assert_eq!((c.forward, c.right, c.up), (0.0, 0.0, 0.0));
        // Below the target: climb.
        assert!(fly_to([0.0, 0.0, -1.0], 0.0, [0.0, 0.0, -3.0], 1.0, 2.0).up > 99.0);
    }
}
