//! A faults file (`usar-server --faults FILE`, docs/quadrotor.md#faults): `FAULT` lines
//! scheduled in simulated time for robots by spawn number.
//!
//! ```toml
//! [[fault]]
//! time = 5.0                           # simulated seconds
//! robot = 1                            # the first robot spawned
//! line = "FAULT {Motor 1} {Thrust 0}"
//! ```

use serde::Deserialize;

use super::dynamics::{Fault, parse_fault};

/// The faults of a run, in time order.
#[derive(Debug, Clone, Default)]
pub struct FaultPlan {
    pub(crate) faults: Vec<PlannedFault>,
}

/// One fault: when, to whom, what.
#[derive(Debug, Clone)]
pub(crate) struct PlannedFault {
    pub(crate) time: f64,
    /// Spawn number from 0 (the file counts from 1).
    pub(crate) serial: u64,
    pub(crate) fault: Fault,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    fault: Vec<Entry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    time: f64,
    robot: u64,
    line: String,
}

impl FaultPlan {
    /// Parses a faults file; the error names the entry and the problem.
    pub fn from_toml(text: &str) -> Result<Self, String> {
        let file: File = toml::from_str(text).map_err(|e| e.to_string())?;
        let mut faults = Vec::new();
        for (i, e) in file.fault.iter().enumerate() {
            let at = format!("fault {} (line {:?})", i + 1, e.line);
            if !(e.time.is_finite() && e.time >= 0.0) {
                return Err(format!("{at}: time must be >= 0 s, got {}", e.time));
            }
            if e.robot == 0 {
                return Err(format!("{at}: robot counts from 1 (the first spawned)"));
            }
            let message = match usar_proto::Command::parse(&e.line) {
                Ok(c) => match c.message {
                    usar_proto::Command::Other(m) if m.kind.eq_ignore_ascii_case("FAULT") => m,
                    _ => return Err(format!("{at}: not a FAULT line")),
                },
                Err(error) => return Err(format!("{at}: {error}")),
            };
            let fault = parse_fault(&message).map_err(|error| format!("{at}: {error}"))?;
            faults.push(PlannedFault {
                time: e.time,
                serial: e.robot - 1,
                fault,
            });
        }
        faults.sort_by(|a, b| a.time.total_cmp(&b.time));
        Ok(Self { faults })
    }

    /// Reads and parses a faults file.
    pub fn from_file(path: &std::path::Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::from_toml(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.faults.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_entries_are_named() {
        let ok = FaultPlan::from_toml(
            "[[fault]]\ntime = 2.0\nrobot = 1\nline = \"FAULT {Battery 0.5}\"\n\
             [[fault]]\ntime = 1.0\nrobot = 2\nline = \"FAULT {Motor 3}\"\n",
        )
        .unwrap();
        assert_eq!(ok.faults[0].time, 1.0);
        assert_eq!(ok.faults[0].serial, 1);
        let e =
            FaultPlan::from_toml("[[fault]]\ntime = 1.0\nrobot = 1\nline = \"FAULT {Motor 9}\"\n")
                .unwrap_err();
        assert!(e.contains("fault 1") && e.contains("1 to 4"), "{e}");
        let e =
            FaultPlan::from_toml("[[fault]]\ntime = -1.0\nrobot = 1\nline = \"FAULT {Motor 1}\"\n")
                .unwrap_err();
        assert!(e.contains("time"), "{e}");
        let e =
            FaultPlan::from_toml("[[fault]]\ntime = 1.0\nrobot = 0\nline = \"FAULT {Motor 1}\"\n")
                .unwrap_err();
        assert!(e.contains("from 1"), "{e}");
        let e =
            FaultPlan::from_toml("[[fault]]\ntime = 1.0\nrobot = 1\nline = \"DRIVE {Linear 1}\"\n")
                .unwrap_err();
        assert!(e.contains("not a FAULT"), "{e}");
    }
}
