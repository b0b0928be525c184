//! `lane-search` and `partition-search`: lane by lane (boustrophedon) over the search area,
//! lanes two footprint radii apart less 10 % overlap. With several UAVs of the same agent
//! the area is cut into strips along y, one per UAV: equal strips for `lane-search`; for
//! `partition-search` each strip's width is weighted by its distance to the base (the
//! thesis's figure 3.3: a UAV that flies farther to its strip spends more of its battery
//! getting there, so it gets less to search). Both go home to recharge when the battery
//! would not last the flight home, and resume where they left.

use super::{
    Brief, Homing, Route, TeamAgent, TeamAgentInfo, TeamStep, battery_level, battery_seconds,
    distance2, position,
};
use crate::speed::SpeedCommand;
use crate::uav::UavState;

/// The registry entry of `lane-search`.
pub const INFO: TeamAgentInfo = TeamAgentInfo {
    name: "lane-search",
    description: "searches the area lane by lane (equal strips for several UAVs), recharging at the base",
    create: || Box::new(Searcher::new(Pattern::Lanes)),
};

/// The registry entry of `partition-search`.
pub const PARTITION_INFO: TeamAgentInfo = TeamAgentInfo {
    name: "partition-search",
    description: "splits the area into strips weighted by distance to the base (thesis fig. 3.3), lanes each, recharging at the base",
    create: || Box::new(Searcher::new(Pattern::Partition)),
};

/// How a searcher lays out its route over its strip of the area.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    /// Lanes, equal strips (`lane-search`).
    Lanes,
    /// Lanes, strips weighted by distance to the base (`partition-search`).
    Partition,
    /// A square spiral from the strip's centre (`spiral-search`).
    Spiral,
    /// Random points, seeded (`random-search`).
    Random,
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

/// Lanes along x over `area` (`[[x_min, y_min], [x_max, y_max]]`), `spacing` apart, at
/// height `z`, alternating direction; the first and last lanes half a spacing inside the
/// edges, so that a footprint of radius `spacing / 2` covers the edges.
pub fn lanes(area: [[f64; 2]; 2], spacing: f64, z: f64) -> Vec<[f64; 3]> {
    let [[x0, y0], [x1, y1]] = area;
    let width = y1 - y0;
    let count = (width / spacing).ceil().max(1.0) as usize;
    let step = if count > 1 {
        (width - spacing).max(0.0) / (count - 1) as f64
    } else {
        0.0
    };
    let mut points = Vec::with_capacity(2 * count);
    for k in 0..count {
        let y = if count == 1 {
            (y0 + y1) / 2.0
        } else {
            y0 + spacing / 2.0 + k as f64 * step
        };
        let (a, b) = if k % 2 == 0 { (x0, x1) } else { (x1, x0) };
        points.push([a, y, z]);
        points.push([b, y, z]);
    }
    points
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
        match self.pattern {
            Pattern::Lanes => INFO.name,
            Pattern::Partition => PARTITION_INFO.name,
            Pattern::Spiral => super::spiral::INFO.name,
            Pattern::Random => super::random::INFO.name,
        }
    }

    fn start(&mut self, brief: &Brief) {
        if let Some(search) = &brief.search {
            let base = brief
                .base
                .map(|b| b.location)
                .filter(|_| self.pattern == Pattern::Partition);
            let strip = strips(search.area, brief.group.len(), base)[brief.rank()];
            let spacing = 2.0 * brief.footprint * 0.9;
            let z = -brief.altitude;
            let points = match self.pattern {
                Pattern::Lanes | Pattern::Partition => lanes(strip, spacing, z),
                Pattern::Spiral => super::spiral::spiral(strip, spacing, z),
                Pattern::Random => super::random::points(strip, brief.seed, brief.index, z),
            };
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
    fn lanes_cover_the_area_edge_to_edge() {
        let pts = lanes([[0.0, 0.0], [10.0, 9.0]], 3.0, -4.0);
        // 3 lanes: y = 1.5, 4.5, 7.5; alternating direction.
        assert_eq!(pts.len(), 6);
        assert_eq!(pts[0], [0.0, 1.5, -4.0]);
        assert_eq!(pts[1], [10.0, 1.5, -4.0]);
        assert_eq!(pts[2], [10.0, 4.5, -4.0]);
        assert_eq!(pts[5], [10.0, 7.5, -4.0]);
        // A width that is no multiple: the last lane still half a spacing from the edge.
        let pts = lanes([[0.0, 0.0], [10.0, 10.0]], 3.0, -4.0);
        assert_eq!(pts.last().unwrap()[1], 8.5);
    }

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
