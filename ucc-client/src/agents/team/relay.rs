//! `relay-chain`: UAVs hold evenly spaced points on the straight line between the two
//! endpoints, so each hop is as short as the chain allows. UAVs beyond the chain's length
//! are spares: they wait charged on the base pad. With a blackboard the chain rotates: a
//! holder whose battery would soon not last the flight home posts `relieve:K` for its slot
//! K; ready spares (each posts `ready:I`) take the open requests in order (lowest spare
//! index to lowest slot) and post `take:K`; once the spare is in place it posts `held:K`,
//! and the relieved holder goes home to recharge and becomes a spare. Without a blackboard
//! a holder stays until its battery only lasts the flight home.

use super::{
    Board, Brief, Homing, TeamAgent, TeamAgentInfo, TeamStep, battery_level, battery_seconds,
    distance2, fly_to, position,
};
use crate::speed::SpeedCommand;
use crate::uav::UavState;

/// The registry entry.
pub const INFO: TeamAgentInfo = TeamAgentInfo {
    name: "relay-chain",
    description: "holds evenly spaced points between two endpoints; spares rotate in via the blackboard",
    create: || Box::new(RelayChain::default()),
};

/// Seconds of margin a holder asks for its relief before it must leave.
const RELIEF_MARGIN: f64 = 40.0;
/// Metres a relieved holder climbs above the chain before it flies home.
const LEAVE_CLIMB: f64 = 2.5;

/// What the UAV is doing.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
enum Role {
    /// Holding slot K (flying there or there).
    Hold(usize),
    /// Waiting at the base, ready or charging.
    #[default]
    Spare,
}

/// The relay agent.
#[derive(Debug, Clone, Default)]
pub struct RelayChain {
    brief: Option<Brief>,
    role: Role,
    homing: Homing,
    asked: bool,
    announced: bool,
    /// This UAV has posted `held:K` for its slot (it is in place).
    placed: bool,
    /// Relieved: climbing clear of the UAV that took the slot before flying home.
    leaving: bool,
}

/// Slot `k`'s point of a chain of `n` between `a` and `b`, at height `z`.
pub fn slot_point(a: [f64; 3], b: [f64; 3], n: usize, k: usize, z: f64) -> [f64; 3] {
    let f = (k + 1) as f64 / (n + 1) as f64;
    [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), z]
}

impl TeamAgent for RelayChain {
    fn name(&self) -> &str {
        INFO.name
    }

    fn start(&mut self, brief: &Brief) {
        let chain = brief.relay.map_or(1, |r| r.chain);
        self.role = if brief.rank() < chain {
            Role::Hold(brief.rank())
        } else {
            Role::Spare
        };
        self.brief = Some(brief.clone());
    }

    fn step(&mut self, uav: &UavState, board: &Board, _time: f64) -> TeamStep {
        let mut out = TeamStep::default();
        let (Some(pos), Some(brief), Some(relay)) = (
            position(uav),
            self.brief.as_ref(),
            self.brief.as_ref().and_then(|b| b.relay),
        ) else {
            out.command = Some(SpeedCommand::STOP);
            return out;
        };
        let me = brief.index;
        let yaw = uav.yaw();
        let level = battery_level(uav);
        let charging = board.charging.get(me).copied().unwrap_or(false);
        let [a, b] = relay.endpoints;
        if self.leaving {
            if pos[2] > -(brief.altitude + LEAVE_CLIMB) {
                out.command = Some(SpeedCommand {
                    up: 100.0,
                    ..SpeedCommand::STOP
                });
                return out;
            }
            self.leaving = false;
            self.homing = Homing::Going;
        }
        if self.homing != Homing::Away && brief.base.is_some() {
            let command = self
                .homing
                .steer(brief.spot, brief.altitude, pos, yaw, charging, level);
            out.command = Some(command);
            if matches!(self.homing, Homing::Charging | Homing::Climbing) {
                // Stay on the pad as a spare rather than climbing back.
                self.homing = Homing::Away;
                self.role = Role::Spare;
                self.announced = false;
            }
            return out;
        }
        match self.role {
            Role::Hold(k) => {
                let key = format!("held:{k}");
                let relieved =
                    self.placed && board.notes.get(&key).is_some_and(|&(by, _)| by != me);
                let home_time = brief.base.map_or(0.0, |base| {
                    super::Homing::time_home(&base, pos, brief.speed)
                });
                let left = battery_seconds(uav);
                if relieved || (brief.base.is_some() && left < home_time + 5.0) {
                    out.log.push(format!(
                        "slot {k}: {} — going home with {:.0} s of battery",
                        if relieved {
                            "relieved"
                        } else {
                            "no relief came"
                        },
                        left
                    ));
                    out.notes.push((format!("relieve:{k}"), None));
                    if !relieved {
                        out.notes.push((key, None));
                    }
                    self.asked = false;
                    self.placed = false;
                    // Up and clear of the UAV that took the slot (it stands where this one
                    // is), then home.
                    self.leaving = brief.base.is_some();
                    self.role = Role::Spare;
                    out.command = Some(SpeedCommand::STOP);
                    return out;
                }
                let goal = slot_point(a, b, relay.chain, k, -brief.altitude);
                if !self.placed && distance2(pos, goal) < 1.5 {
                    self.placed = true;
                    out.notes.push((key, Some(me as f64)));
                    out.notes.push((format!("take:{k}"), None));
                    out.notes.push((format!("relieve:{k}"), None));
                }
                if !self.asked && brief.base.is_some() && left < home_time + RELIEF_MARGIN + 30.0 {
                    self.asked = true;
                    out.log.push(format!(
                        "slot {k}: battery low ({left:.0} s), asking for relief"
                    ));
                    out.notes.push((format!("relieve:{k}"), Some(me as f64)));
                }
                out.command = Some(fly_to(pos, yaw, goal, 1.0, 2.0));
            }
            Role::Spare => {
                let ready = level >= super::CHARGED || brief.base.is_none();
                let ready_key = format!("ready:{me}");
                if ready && !self.announced {
                    self.announced = true;
                    out.notes.push((ready_key.clone(), Some(1.0)));
                }
                if ready {
                    // Open requests and ready spares, both in order: the i-th ready spare
                    // takes the i-th open request.
                    let open: Vec<usize> = board
                        .notes
                        .keys()
                        .filter_map(|k| k.strip_prefix("relieve:")?.parse().ok())
                        .filter(|k| !board.notes.contains_key(&format!("take:{k}")))
                        .collect::<std::collections::BTreeSet<usize>>()
                        .into_iter()
                        .collect();
                    let spares: Vec<usize> = board
                        .notes
                        .keys()
                        .filter_map(|k| k.strip_prefix("ready:")?.parse().ok())
                        .collect::<std::collections::BTreeSet<usize>>()
                        .into_iter()
                        .collect();
                    if let Some(i) = spares.iter().position(|&s| s == me)
                        && let Some(&k) = open.get(i)
                    {
                        out.log.push(format!("taking over slot {k}"));
                        out.notes.push((format!("take:{k}"), Some(me as f64)));
                        out.notes.push((ready_key, None));
                        self.announced = false;
                        self.role = Role::Hold(k);
                        out.command = Some(SpeedCommand {
                            up: 100.0,
                            ..SpeedCommand::STOP
                        });
                        return out;
                    }
                }
                // Wait on the ground (keep pressing down onto the pad).
                out.command = Some(SpeedCommand {
                    up: -30.0,
                    ..SpeedCommand::STOP
                });
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn slots_split_the_line_evenly() {
        let a = [0.0, 0.0, -1.0];
        let b = [100.0, 0.0, -1.0];
        let p: Vec<f64> = (0..3)
            .map(|k| super::slot_point(a, b, 3, k, -5.0)[0])
            .collect();
        assert_eq!(p, vec![25.0, 50.0, 75.0]);
    }
}
