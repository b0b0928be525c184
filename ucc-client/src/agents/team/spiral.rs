//! `spiral-search`: a square spiral outwards from the centre of the area (or of this UAV's
//! strip when several fly it), legs two footprint radii apart less 10 % overlap, until the
//! spiral has passed every edge; it goes home to recharge like the lane searcher.

use super::TeamAgentInfo;
use super::searcher::{Pattern, Searcher};

/// The registry entry.
pub const INFO: TeamAgentInfo = TeamAgentInfo {
    name: PATTERN.name,
    description: "searches in a square spiral outwards from the area's centre, recharging at the base",
    create: || Box::new(Searcher::new(PATTERN)),
};

/// The pattern of `spiral-search`: a square spiral from the strip's centre.
pub const PATTERN: Pattern = Pattern {
    name: "spiral-search",
    weighted: false,
    route: |strip, spacing, z, _| spiral(strip, spacing, z),
};

/// The corners of a square spiral from the centre of `area`, `spacing` between legs, at
/// height `z`, clipped to the area, ending once it is larger than the area.
pub fn spiral(area: [[f64; 2]; 2], spacing: f64, z: f64) -> Vec<[f64; 3]> {
    let [[x0, y0], [x1, y1]] = area;
    let centre = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
    let reach = ((x1 - x0).max(y1 - y0)) / 2.0 + spacing;
    let clip = |p: [f64; 2]| {
        [
            p[0].clamp(
                x0 + spacing / 2.0,
                (x1 - spacing / 2.0).max(x0 + spacing / 2.0),
            ),
            p[1].clamp(
                y0 + spacing / 2.0,
                (y1 - spacing / 2.0).max(y0 + spacing / 2.0),
            ),
            z,
        ]
    };
    let mut points = vec![clip(centre)];
    let mut p = centre;
    let dirs = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]];
    let mut leg = spacing;
    let mut k = 0;
    while leg / 2.0 <= reach {
        for _ in 0..2 {
            let d = dirs[k % 4];
            p = [p[0] + d[0] * leg, p[1] + d[1] * leg];
            let c = clip(p);
            if points.last() != Some(&c) {
                points.push(c);
            }
            k += 1;
        }
        leg += spacing;
    }
    points
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_spiral_starts_at_the_centre_and_reaches_the_corners() {
        let pts = super::spiral([[0.0, 0.0], [20.0, 20.0]], 4.0, -3.0);
        assert_eq!(pts[0], [10.0, 10.0, -3.0]);
        for corner in [[2.0, 2.0], [18.0, 18.0], [2.0, 18.0], [18.0, 2.0]] {
            assert!(
                pts.iter().any(|p| p[0] == corner[0] && p[1] == corner[1]),
                "{corner:?} not in {pts:?}"
            );
        }
    }
}
