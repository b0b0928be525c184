//! `target-follow`: flies over a moving target at cruise height, to where it is predicted
//! to be: its last sighting (the board's, by any UAV's footprint sensor) moved on at the
//! velocity of its last two sightings; before the first sighting it goes to the target's
//! known start. With several targets, UAV k of the group follows target k mod n.

use super::{Board, Brief, TeamAgent, TeamAgentInfo, TeamStep, fly_to, position};
use crate::speed::SpeedCommand;
use crate::uav::UavState;

/// The registry entry.
pub const INFO: TeamAgentInfo = TeamAgentInfo {
    name: "target-follow",
    description: "flies over a moving target where it was last seen",
    create: || Box::new(Follow::default()),
};

/// The follower.
#[derive(Debug, Clone, Default)]
pub struct Follow {
    brief: Option<Brief>,
    seen: bool,
    /// The last two different sightings (position, time).
    sightings: [Option<([f64; 3], f64)>; 2],
}

impl TeamAgent for Follow {
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
        if brief.targets.is_empty() {
            out.command = Some(SpeedCommand::STOP);
            return out;
        }
        let k = brief.rank() % brief.targets.len();
        let sighting = board.targets.get(k).copied().flatten();
        if sighting.is_some() && !self.seen {
            self.seen = true;
            out.log.push(format!("target {} in sight", k + 1));
        }
        if let Some(s) = sighting
            && self.sightings[1].is_none_or(|(_, t)| t < s.1)
        {
            self.sightings = [self.sightings[1], Some(s)];
        }
        let at = match self.sightings {
            [Some((p0, t0)), Some((p1, t1))] if t1 > t0 => {
                // Predict for at most 5 s (a target may turn).
                let ahead = (board.time - t1).clamp(0.0, 5.0);
                std::array::from_fn(|i| p1[i] + (p1[i] - p0[i]) / (t1 - t0) * ahead)
            }
            [_, Some((p, _))] => p,
            _ => brief.targets[k],
        };
        out.command = Some(fly_to(
            pos,
            uav.yaw(),
            [at[0], at[1], -brief.altitude],
            1.0,
            1.5,
        ));
        out
    }
}
