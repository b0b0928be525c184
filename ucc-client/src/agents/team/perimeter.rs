//! `perimeter-track`: n UAVs circle a spreading fire's perimeter evenly spaced, so that any
//! point of the perimeter is seen every t_r / n seconds (t_r: one UAV's lap time), as the
//! thesis describes. Each UAV flies at a fixed fraction of its top speed on a circle of the
//! fire's radius (sensed, [`Board::fire_radius`]); its place on the circle is its slot's
//! angle 2πk/n plus the angle all UAVs have flown, which each integrates the same way.

use super::{Board, Brief, TeamAgent, TeamAgentInfo, TeamStep, distance2, fly_to, position};
use crate::speed::SpeedCommand;
use crate::uav::UavState;

/// The registry entry.
pub const INFO: TeamAgentInfo = TeamAgentInfo {
    name: "perimeter-track",
    description: "circles a spreading fire's perimeter, n UAVs evenly spaced (update time t_r/n)",
    create: || Box::new(Perimeter::default()),
};

/// Fraction of the top speed flown along the circle (the rest catches up the slot).
const CRUISE: f64 = 0.7;

/// The perimeter tracker.
#[derive(Debug, Clone, Default)]
pub struct Perimeter {
    brief: Option<Brief>,
    /// Angle flown by the formation, rad.
    angle: f64,
    last: Option<f64>,
    on_station: bool,
}

impl TeamAgent for Perimeter {
    fn name(&self) -> &str {
        INFO.name
    }

    fn start(&mut self, brief: &Brief) {
        self.brief = Some(brief.clone());
    }

    fn step(&mut self, uav: &UavState, board: &Board, time: f64) -> TeamStep {
        let mut out = TeamStep::default();
        let (Some(pos), Some(brief)) = (position(uav), self.brief.as_ref()) else {
            out.command = Some(SpeedCommand::STOP);
            return out;
        };
        let Some(fire) = brief.fire else {
            out.command = Some(SpeedCommand::STOP);
            return out;
        };
        let radius = board.fire_radius.unwrap_or(fire.radius).max(0.5);
        let dt = self.last.map_or(0.0, |t| (time - t).max(0.0));
        self.last = Some(time);
        self.angle += brief.speed * CRUISE / radius * dt;
        let n = brief.group.len().max(1) as f64;
        let theta = self.angle + std::f64::consts::TAU * brief.rank() as f64 / n;
        let goal = [
            fire.center[0] + radius * theta.cos(),
            fire.center[1] + radius * theta.sin(),
            -brief.altitude,
        ];
        if !self.on_station && distance2(pos, goal) < 2.0 {
            self.on_station = true;
            out.log.push(format!(
                "on station on the perimeter (radius {radius:.1} m)"
            ));
        }
        out.command = Some(fly_to(pos, uav.yaw(), goal, 1.0, 3.0));
        out
    }
}
