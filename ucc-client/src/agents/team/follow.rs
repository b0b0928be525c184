//! `target-follow`: flies over a moving target at cruise height, to where it was last seen
//! (the board's sighting, by any UAV's footprint sensor); before the first sighting it goes
//! to the target's known start. With several targets, UAV k of the group follows target
//! k mod n.

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
        let at = sighting.map_or(brief.targets[k], |(p, _)| p);
        out.command = Some(fly_to(pos, uav.yaw(), [at[0], at[1], -brief.altitude], 1.0, 1.5));
        out
    }
}
