//! What one flight recorded ([`FlightRecord`]): its log, its trajectory, the laser's hits.

use crate::geometry::Coordinates;
use crate::uav::{LaserScan, UavState};

/// At most this many laser hit points are kept per iteration (for the map picture when the
/// map's geometry is unknown).
const MAX_LASER_HITS: usize = 50_000;

/// What one flight recorded.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FlightRecord {
    /// 1-based.
    pub iteration: usize,
    /// The log lines.
    pub log: Vec<String>,
    /// One row per time stamp with a position.
    pub trajectory: Vec<TrajectoryPoint>,
    /// Where the laser hit something (world frame), thinned: every fourth beam.
    pub laser_hits: Vec<Coordinates>,
    /// Missions completed.
    pub missions_done: usize,
    /// Simulated time of the spawn.
    pub start_time: Option<f64>,
    /// Simulated time the last mission was done.
    pub end_time: Option<f64>,
    /// The start location, when known (a start pose, or the PlayerStart the server reported).
    pub start: Option<Coordinates>,
    /// The map name the server reported.
    pub map: Option<String>,
    /// Whether the connection was made (nothing worth a file happened otherwise).
    pub connected: bool,
    /// Faults the server applied during the flight (`usar-server --faults`).
    pub faults: usize,
    /// The parameters the server drew for the robot (`--randomize`), as `mass 1.3021 ..`.
    pub randomized: Option<String>,
}

impl FlightRecord {
    /// Metres flown along the trajectory.
    pub fn distance(&self) -> f64 {
        self.trajectory
            .windows(2)
            .map(|w| (w[1].position - w[0].position).norm())
            .sum::<f64>()
            + 0.0 // an empty sum is -0.0: no "-0.0000" in the tables
    }

    /// Simulated seconds from the first to the last trajectory sample.
    pub fn simulated_seconds(&self) -> f64 {
        match (self.trajectory.first(), self.trajectory.last()) {
            (Some(a), Some(b)) => b.time - a.time,
            _ => 0.0,
        }
    }

    /// Simulated seconds from the spawn to the last mission done.
    pub fn duration(&self) -> f64 {
        match (self.start_time, self.end_time) {
            (Some(s), Some(e)) => e - s,
            _ => 0.0,
        }
    }

    /// Adds the hit points of a scan taken at `position` with heading `yaw`.
    /// Every fourth beam (`LaserScan::hits`), up to `MAX_LASER_HITS` in all.
    pub fn add_laser_hits(&mut self, position: &Coordinates, yaw: f64, scan: &LaserScan) {
        let room = MAX_LASER_HITS.saturating_sub(self.laser_hits.len());
        let hits = scan.hits(position, yaw).filter(|(i, _)| i % 4 == 0);
        self.laser_hits.extend(hits.map(|(_, p)| p).take(room));
    }
}

/// One sample of the trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryPoint {
    /// Simulated seconds.
    pub time: f64,
    /// World frame, metres, z down.
    pub position: Coordinates,
    /// Roll, pitch, yaw, radians.
    pub orientation: Option<Coordinates>,
    /// World frame, m/s.
    pub velocity: Option<Coordinates>,
    /// Battery level, fraction of the first value seen.
    pub battery: Option<f64>,
}

impl TrajectoryPoint {
    /// The row of time stamp `time`: `None` unless the position is of that time stamp; every
    /// other reading as of it.
    pub fn of(uav: &UavState, time: f64) -> Option<Self> {
        let position = uav
            .position
            .as_ref()
            .filter(|p| (p.time - time).abs() < 1e-9)?;
        Some(Self {
            time,
            position: position.value,
            orientation: uav.orientation.as_ref().map(|r| r.value),
            velocity: uav.velocity.as_ref().map(|r| r.value),
            battery: uav.battery.as_ref().map(|r| r.value.level),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_noisy_miss_is_no_laser_hit_on_the_map() {
        // Every fourth beam: 0 misses at 4 m, 4 misses with noise (3.99), 8 hits at 2 m.
        let mut ranges = vec![4.0; 9];
        ranges[4] = 3.99;
        ranges[8] = 2.0;
        let scan = LaserScan {
            ranges,
            resolution: 0.1,
            fov: 0.8,
        };
        let mut record = FlightRecord::default();
        record.add_laser_hits(&Coordinates::new(1.0, 2.0, -1.0), 0.0, &scan);
        assert_eq!(record.laser_hits.len(), 1, "{:?}", record.laser_hits);
        let hit = record.laser_hits[0];
        let bearing: f64 = -0.4; // the leftmost beam
        assert!(
            (hit - Coordinates::new(1.0 + 2.0 * bearing.cos(), 2.0 + 2.0 * bearing.sin(), -1.0))
                .norm()
                < 1e-12
        );
    }
}
