//! What one iteration leaves behind: its log lines and its trajectory, written as text and CSV.

use std::io::Write;
use std::path::Path;

use crate::geometry::Coordinates;
use crate::uav::UavState;

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
    /// A sample of the UAV's latest position reading; `None` before the first position.
    pub fn of(uav: &UavState) -> Option<Self> {
        let position = uav.position.as_ref()?;
        Some(Self {
            time: position.time,
            position: position.value,
            orientation: uav.orientation.as_ref().map(|r| r.value),
            velocity: uav.velocity.as_ref().map(|r| r.value),
            battery: uav.battery.as_ref().map(|r| r.value.level),
        })
    }
}

/// The CSV header of [`write_trajectory`].
pub const CSV_HEADER: &str = "time,x,y,z,roll,pitch,yaw,vx,vy,vz,battery";

/// Writes the trajectory as CSV: simulated time, position, orientation, velocity, battery
/// level (empty cells where unknown).
pub fn write_trajectory(path: &Path, points: &[TrajectoryPoint]) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(out, "{CSV_HEADER}")?;
    let triple = |v: Option<Coordinates>| {
        v.map_or_else(
            || ",,".to_owned(),
            |v| format!("{:.4},{:.4},{:.4}", v.x, v.y, v.z),
        )
    };
    for p in points {
        writeln!(
            out,
            "{:.4},{},{},{},{}",
            p.time,
            triple(Some(p.position)),
            triple(p.orientation),
            triple(p.velocity),
            p.battery.map_or(String::new(), |b| format!("{b:.4}")),
        )?;
    }
    out.flush()
}

/// Writes log lines, one per line.
pub fn write_log(path: &Path, lines: &[String]) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for line in lines {
        writeln!(out, "{line}")?;
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_has_header_and_empty_cells() {
        let dir = std::env::temp_dir().join(format!("ucc-record-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.csv");
        write_trajectory(
            &path,
            &[TrajectoryPoint {
                time: 1.5,
                position: Coordinates::new(1.0, 2.0, -3.0),
                orientation: None,
                velocity: Some(Coordinates::new(0.5, 0.0, 0.0)),
                battery: Some(1.0),
            }],
        )
        .unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            format!("{CSV_HEADER}\n1.5000,1.0000,2.0000,-3.0000,,,,0.5000,0.0000,0.0000,1.0000\n")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
