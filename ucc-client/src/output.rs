//! The files one iteration ([`FlightRecord`]) is written to: the log, the trajectory CSV,
//! the map picture and the plots ([`write_iteration`]).

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::RunError;
use crate::geometry::Coordinates;
use crate::picture::{MapPicture, Plots};
pub use crate::record::{FlightRecord, TrajectoryPoint};
use crate::settings::{Pictures, RunSettings};

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
            |v| format!("{},{},{}", fixed4(v.x), fixed4(v.y), fixed4(v.z)),
        )
    };
    for p in points {
        writeln!(
            out,
            "{},{},{},{},{}",
            fixed4(p.time),
            triple(Some(p.position)),
            triple(p.orientation),
            triple(p.velocity),
            p.battery.map_or(String::new(), fixed4),
        )?;
    }
    out.flush()
}

/// A number of a CSV file, with 4 decimals as UDK prints it (`usar_proto::format::push_fixed`:
/// a value beyond UDK's 32-bit range, `1e308` from a hostile server, is never 309 digits).
pub(crate) fn fixed4(v: f64) -> String {
    let mut s = String::new();
    usar_proto::format::push_fixed(&mut s, v, 4);
    s
}

/// Writes log lines, one per line.
pub fn write_log(path: &Path, lines: &[String]) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for line in lines {
        writeln!(out, "{line}")?;
    }
    out.flush()
}

/// The files of one iteration in the log directory (none without one, or when the connection
/// was never made): the log, the trajectory CSV and, with [`Pictures::All`], the bases of the
/// map picture and of the plots (each written as SVG and PNG).
struct IterationFiles {
    log: PathBuf,
    csv: PathBuf,
    pictures: Option<(PathBuf, PathBuf)>,
}

impl IterationFiles {
    fn of(settings: &RunSettings, record: &FlightRecord) -> Option<Self> {
        if !record.connected {
            return None;
        }
        let name = |suffix: &str| settings.file(&format!("{:02}{suffix}", record.iteration));
        let pictures = match (settings.pictures, name("-map"), name("-plots")) {
            (Pictures::All, Some(map), Some(plots)) => Some((map, plots)),
            _ => None,
        };
        Some(Self {
            log: name(".log")?,
            csv: name("-trajectory.csv")?,
            pictures,
        })
    }

    /// Every path, in the order [`write_iteration`] returns them.
    fn paths(&self) -> Vec<PathBuf> {
        let mut files = vec![self.log.clone(), self.csv.clone()];
        for base in self.pictures.iter().flat_map(|(map, plots)| [map, plots]) {
            files.extend(["svg", "png"].map(|ext| base.with_extension(ext)));
        }
        files
    }
}

/// The files [`write_iteration`] writes for `record`, named before they are written.
pub fn iteration_files(settings: &RunSettings, record: &FlightRecord) -> Vec<PathBuf> {
    IterationFiles::of(settings, record).map_or_else(Vec::new, |f| f.paths())
}

/// Writes the files of one iteration into the log directory (nothing without one): the log
/// (with `last_line` at its end), the trajectory CSV and, with [`Pictures::All`], the map
/// picture and the plots. Returns the files written ([`iteration_files`]).
pub fn write_iteration(
    settings: &RunSettings,
    record: &FlightRecord,
    last_line: &str,
) -> Result<Vec<PathBuf>, RunError> {
    let Some(files) = IterationFiles::of(settings, record) else {
        return Ok(Vec::new());
    };
    let output = |path: &Path| {
        let path = path.to_owned();
        move |error| RunError::Output { path, error }
    };
    let mut lines = record.log.clone();
    lines.push(last_line.to_owned());
    write_log(&files.log, &lines).map_err(output(&files.log))?;
    write_trajectory(&files.csv, &record.trajectory).map_err(output(&files.csv))?;
    if let Some((map, plots)) = &files.pictures {
        let picture = MapPicture {
            title: format!("{} — iteration {}", settings.prefix, record.iteration),
            paths: vec![record.trajectory.iter().map(|p| p.position).collect()],
            repeats: Vec::new(),
            waypoints: settings.waypoints(),
            start: record
                .start
                .or_else(|| record.trajectory.first().map(|p| p.position)),
            geometry: settings.map.clone(),
            laser_hits: record.laser_hits.clone(),
        };
        picture.write(map)?;
        let plots_picture = Plots {
            title: format!("{} — iteration {}", settings.prefix, record.iteration),
            trajectory: record.trajectory.clone(),
            waypoints: settings.waypoints(),
        };
        plots_picture.write(plots)?;
    }
    Ok(files.paths())
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
