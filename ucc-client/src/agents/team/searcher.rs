//! The search agents' shared machinery: a [`Searcher`] flies the route its [`Pattern`] lays
//! over this UAV's strip of the search area, at cruise height, going home to recharge when
//! the battery would not last the flight home and resuming where it left. The patterns
//! themselves are in `lanes`, `spiral` and `random`.

use super::{
    Brief, Homing, Route, TeamAgent, TeamStep, battery_level, battery_seconds, distance2, position,
};
use crate::speed::SpeedCommand;
use crate::uav::UavState;

/// The route over `strip`, legs `spacing` apart, at height `z`, for the UAV of `brief`.
pub type Layout = fn(strip: [[f64; 2]; 2], spacing: f64, z: f64, brief: &Brief) -> Vec<[f64; 3]>;

/// How a searcher lays out its route over its strip of the area: one per search agent.
#[derive(Debug, Clone, Copy)]
pub struct Pattern {
    /// The agent's name (its registry entry's).
    pub name: &'static str,
    /// Whether the strips are weighted by distance to the base (`partition-search`) rather
    /// than equal.
    pub weighted: bool,
    /// The route over `strip`, legs `spacing` apart, at height `z`, for this UAV (`brief`).
    pub route: Layout,
}

/// The searchers: a route over this UAV's strip of the area by [`Pattern`], flown at cruise
/// height, going home to recharge and back (the shared behaviour of the search agents).
#[derive(Debug, Clone)]
pub struct Searcher {
    pattern: Pattern,
    brief: Option<Brief>,
    route: Route,
    homing: Homing,
    reserve: f64,
    done: bool,
}

/// Cuts `area` into `n` strips along y; with `base`, each strip's width is weighted by
/// 1 / (1 + d / L), d the distance from the base to the strip's centre and L the area's
/// diagonal (ten rounds of fixed-point iteration).
pub fn strips(area: [[f64; 2]; 2], n: usize, base: Option<[f64; 3]>) -> Vec<[[f64; 2]; 2]> {
    let [[x0, y0], [x1, y1]] = area;
    let n = n.max(1);
    let width = y1 - y0;
    let mut widths = vec![width / n as f64; n];
    if let Some(b) = base {
        let diagonal = (x1 - x0).hypot(y1 - y0);
        for _ in 0..10 {
            let mut y = y0;
            let weights: Vec<f64> = widths
                .iter()
                .map(|w| {
                    let centre = [(x0 + x1) / 2.0, y + w / 2.0];
                    y += w;
                    1.0 / (1.0 + (centre[0] - b[0]).hypot(centre[1] - b[1]) / diagonal)
                })
                .collect();
            let total: f64 = weights.iter().sum();
            widths = weights.iter().map(|w| width * w / total).collect();
        }
    }
    let mut y = y0;
    widths
        .iter()
        .map(|w| {
            let strip = [[x0, y], [x1, y + w]];
            y += w;
            strip
        })
        .collect()
}

impl Searcher {
    /// A searcher flying `pattern`.
    pub fn new(pattern: Pattern) -> Self {
        Self {
            pattern,
            brief: None,
            route: Route::default(),
            homing: Homing::Away,
            reserve: 0.25,
            done: false,
        }
    }
}

impl TeamAgent for Searcher {
    fn name(&self) -> &str {
        self.pattern.name
    }

    fn start(&mut self, brief: &Brief) {
        if let Some(search) = &brief.search {
            let base = brief
                .base
                .map(|b| b.location)
                .filter(|_| self.pattern.weighted);
            let strip = strips(search.area, brief.group.len(), base)[brief.rank()];
            let spacing = 2.0 * brief.footprint * 0.9;
            let z = -brief.altitude;
            let points = (self.pattern.route)(strip, spacing, z, brief);
            self.route = Route::new(points, 0.5);
            self.reserve = search.reserve;
        }
        self.brief = Some(brief.clone());
    }

    fn step(&mut self, uav: &UavState, board: &super::Board, _time: f64) -> TeamStep {
        sweep_step(
            &mut self.route,
            &mut self.homing,
            &mut self.done,
            self.reserve,
            self.brief.as_ref(),
            uav,
            board,
        )
    }
}

/// One step of a route-following searcher that goes home to recharge.
fn sweep_step(
    route: &mut Route,
    homing: &mut Homing,
    done: &mut bool,
    reserve: f64,
    brief: Option<&Brief>,
    uav: &UavState,
    board: &super::Board,
) -> TeamStep {
    let mut out = TeamStep {
        done: *done,
        ..TeamStep::default()
    };
    let (Some(pos), Some(brief)) = (position(uav), brief) else {
        out.command = Some(SpeedCommand::STOP);
        return out;
    };
    let yaw = uav.yaw();
    if *done && matches!(*homing, Homing::Charging) {
        // Home for good: stay on the pad.
        out.command = Some(SpeedCommand {
            up: -30.0,
            ..SpeedCommand::STOP
        });
        return out;
    }
    let level = battery_level(uav);
    let charging = board.charging.get(brief.index).copied().unwrap_or(false);
    if let Some(base) = &brief.base {
        if *homing == Homing::Away && !*done {
            let low =
                level < reserve || battery_seconds(uav) < Homing::time_home(base, pos, brief.speed);
            if low {
                *homing = Homing::Going;
                // Come back to this very point and go on from there.
                if !route.finished() {
                    route.points.insert(route.next, pos);
                }
                out.log.push(format!(
                    "battery at {:.0} %: going home to recharge ({:.0} m away)",
                    level * 100.0,
                    distance2(pos, base.location)
                ));
            }
        }
        if *homing != Homing::Away {
            out.command =
                Some(homing.steer(brief.spot, brief.home_altitude(), pos, yaw, charging, level));
            if *homing == Homing::Away {
                out.log.push("recharged: back to the search".into());
            }
            return out;
        }
    }
    match route.steer(pos, yaw) {
        Some(c) => out.command = Some(c),
        None => {
            if !*done {
                *done = true;
                out.log.push("search pattern finished".into());
                if let Some(base) = &brief.base
                    && distance2(pos, base.location) > base.radius
                {
                    *homing = Homing::Going;
                }
            }
            out.done = true;
            out.command = Some(SpeedCommand::STOP);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_far_from_the_base_are_narrower() {
        let equal = strips([[0.0, 0.0], [10.0, 30.0]], 3, None);
        assert!((equal[1][1][1] - equal[1][0][1] - 10.0).abs() < 1e-9);
        let weighted = strips([[0.0, 0.0], [10.0, 30.0]], 3, Some([5.0, -5.0, 0.0]));
        let w: Vec<f64> = weighted.iter().map(|s| s[1][1] - s[0][1]).collect();
        assert!(w[0] > w[1] && w[1] > w[2], "{w:?}");
        assert!((w.iter().sum::<f64>() - 30.0).abs() < 1e-9);
        assert!((weighted[2][1][1] - 30.0).abs() < 1e-9);
    }
}
