//! `lane-search` and `partition-search`: lane by lane (boustrophedon) over the search area,
//! lanes two footprint radii apart less 10 % overlap. With several UAVs of the same agent
//! the area is cut into strips along y, one per UAV: equal strips for `lane-search`; for
//! `partition-search` each strip's width is weighted by its distance to the base (the
//! thesis's figure 3.3: a UAV that flies farther to its strip spends more of its battery
//! getting there, so it gets less to search). Both go home to recharge when the battery
//! would not last the flight home, and resume where they left.

use super::TeamAgentInfo;
use super::searcher::{Pattern, Searcher};

/// The registry entry of `lane-search`.
pub const INFO: TeamAgentInfo = TeamAgentInfo {
    name: LANES.name,
    description: "searches the area lane by lane (equal strips for several UAVs), recharging at the base",
    create: || Box::new(Searcher::new(LANES)),
};

/// The registry entry of `partition-search`.
pub const PARTITION_INFO: TeamAgentInfo = TeamAgentInfo {
    name: PARTITION.name,
    description: "splits the area into strips weighted by distance to the base (thesis fig. 3.3), lanes each, recharging at the base",
    create: || Box::new(Searcher::new(PARTITION)),
};

/// The pattern of `lane-search`: lanes over equal strips.
pub const LANES: Pattern = Pattern {
    name: "lane-search",
    weighted: false,
    route: |strip, spacing, z, _| lanes(strip, spacing, z),
};

/// The pattern of `partition-search`: lanes over strips weighted by distance to the base.
pub const PARTITION: Pattern = Pattern {
    name: "partition-search",
    weighted: true,
    route: |strip, spacing, z, _| lanes(strip, spacing, z),
};

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
}
