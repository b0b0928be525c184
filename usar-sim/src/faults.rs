//! A faults file (`usar-server --faults FILE`, docs/quadrotor.md#faults): `FAULT` lines
//! scheduled in simulated time for robots by spawn number, at a fixed time or at a random
//! one drawn from the world's seed.
//!
//! ```toml
//! [[fault]]
//! time = 5.0                           # simulated seconds
//! robot = 1                            # the first robot spawned
//! line = "FAULT {Motor 1} {Thrust 0}"
//!
//! [[random]]
//! probability = 0.02                   # per second
//! robot = 1
//! line = "FAULT {Sensor Position} {Mode Silent} {Duration 3}"
//! ```
//!
//! `robot = "each"` gives every robot spawned the fault, its `time` (`from`, `until`) counted
//! from the robot's spawn: every iteration of a loop (a new spawn each) gets its fault.
//!
//! A recording (docs/recording.md) is a faults file too: the `FAULT` lines the server sent
//! when it applied its faults are read back as fixed-time faults, so a faulty run is
//! reproducible from its recording alone.

use serde::Deserialize;
use usar_proto::Message;

use super::dynamics::{Fault, parse_fault};
use super::noise::Noise;

/// The faults of a run: fixed-time ones in time order and random ones.
#[derive(Debug, Clone, Default)]
pub struct FaultPlan {
    pub(crate) faults: Vec<PlannedFault>,
    random: Vec<RandomFault>,
    /// `robot = "each"`: times from each robot's spawn (`serial` unused).
    each: Vec<PlannedFault>,
    each_random: Vec<RandomFault>,
}

/// Whom an entry's fault is for: a robot by spawn number (from 1), or each robot spawned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Whom {
    Number(u64),
    Each,
}

impl<'de> Deserialize<'de> for Whom {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(u64),
            Word(String),
        }
        match Raw::deserialize(d)? {
            Raw::Number(n) => Ok(Self::Number(n)),
            Raw::Word(w) if w.eq_ignore_ascii_case("each") => Ok(Self::Each),
            Raw::Word(w) => Err(serde::de::Error::custom(format!(
                "robot must be a spawn number (1 = the first spawned) or \"each\", got {w:?}"
            ))),
        }
    }
}

/// One fault: when, to whom, what.
#[derive(Debug, Clone)]
pub(crate) struct PlannedFault {
    pub(crate) time: f64,
    /// Spawn number from 0 (the file counts from 1).
    pub(crate) serial: u64,
    pub(crate) fault: Fault,
    /// The `FAULT` line (its groups go into the notice to the robot's connection).
    pub(crate) line: Message,
}

/// A fault that happens with a probability per second, at most once.
#[derive(Debug, Clone)]
struct RandomFault {
    probability: f64,
    from: f64,
    until: f64,
    serial: u64,
    fault: Fault,
    line: Message,
}

/// Stream numbers of the random faults' draws (apart from every part's).
const RANDOM_STREAM: u64 = 1 << 40;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    fault: Vec<Entry>,
    #[serde(default)]
    random: Vec<RandomEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    time: f64,
    robot: Whom,
    line: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RandomEntry {
    probability: f64,
    robot: Whom,
    line: String,
    #[serde(default)]
    from: f64,
    until: Option<f64>,
}

/// The `FAULT` line's message and fault; the error names `at`.
fn fault_line(at: &str, robot: Whom, line: &str) -> Result<(Message, Fault), String> {
    if robot == Whom::Number(0) {
        return Err(format!("{at}: robot counts from 1 (the first spawned)"));
    }
    let message = match usar_proto::Command::parse(line) {
        Ok(c) => match c.message {
            usar_proto::Command::Other(m) if m.kind.eq_ignore_ascii_case("FAULT") => m,
            _ => return Err(format!("{at}: not a FAULT line")),
        },
        Err(error) => return Err(format!("{at}: {error}")),
    };
    let fault = parse_fault(&message).map_err(|error| format!("{at}: {error}"))?;
    Ok((message, fault))
}

impl FaultPlan {
    /// Parses a faults file; the error names the entry and the problem.
    pub fn from_toml(text: &str) -> Result<Self, String> {
        let file: File = toml::from_str(text).map_err(|e| e.to_string())?;
        let (mut faults, mut each) = (Vec::new(), Vec::new());
        for (i, e) in file.fault.iter().enumerate() {
            let at = format!("fault {} (line {:?})", i + 1, e.line);
            if !(e.time.is_finite() && e.time >= 0.0) {
                return Err(format!("{at}: time must be >= 0 s, got {}", e.time));
            }
            let (line, fault) = fault_line(&at, e.robot, &e.line)?;
            let (list, serial) = match e.robot {
                Whom::Number(n) => (&mut faults, n - 1),
                Whom::Each => (&mut each, 0),
            };
            list.push(PlannedFault {
                time: e.time,
                serial,
                fault,
                line,
            });
        }
        faults.sort_by(|a, b| a.time.total_cmp(&b.time));
        each.sort_by(|a, b| a.time.total_cmp(&b.time));
        let (mut random, mut each_random) = (Vec::new(), Vec::new());
        for (i, e) in file.random.iter().enumerate() {
            let at = format!("random {} (line {:?})", i + 1, e.line);
            if !(e.probability.is_finite() && (0.0..=1.0).contains(&e.probability)) {
                return Err(format!(
                    "{at}: probability (per second) must be within [0, 1], got {}",
                    e.probability
                ));
            }
            let until = e.until.unwrap_or(f64::INFINITY);
            if !(e.from.is_finite() && e.from >= 0.0 && until >= e.from) {
                return Err(format!(
                    "{at}: from must be >= 0 s and until >= from, got {} and {until}",
                    e.from
                ));
            }
            let (line, fault) = fault_line(&at, e.robot, &e.line)?;
            let (list, serial) = match e.robot {
                Whom::Number(n) => (&mut random, n - 1),
                Whom::Each => (&mut each_random, 0),
            };
            list.push(RandomFault {
                probability: e.probability,
                from: e.from,
                until,
                serial,
                fault,
                line,
            });
        }
        Ok(Self {
            faults,
            random,
            each,
            each_random,
        })
    }

    /// The `FAULT` lines a server sent in a recording (`FAULT {Time t} {Robot n} ...`, S
    /// lines), as fixed-time faults.
    pub fn from_recording(text: &str) -> Result<Self, String> {
        let mut faults = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let entry = usar_proto::record::parse_entry(line)
                .map_err(|e| format!("line {}: {e}", n + 1))?;
            let Some(entry) = entry.filter(|e| {
                e.direction == usar_proto::record::Direction::Server
                    && Message::word(e.text).eq_ignore_ascii_case("FAULT")
            }) else {
                continue;
            };
            let at = format!("line {}", n + 1);
            let message = Message::parse(entry.text)
                .map_err(|e| format!("{at}: {e}"))?
                .message;
            let number = |key: &str| {
                message
                    .get(key)
                    .and_then(|v| v.trim().parse::<f64>().ok())
                    .filter(|v| v.is_finite() && *v >= 0.0)
                    .ok_or_else(|| format!("{at}: a server FAULT line needs {{{key} ..}}"))
            };
            let (time, robot) = (number("Time")?, number("Robot")?);
            let mut line = message.clone();
            line.groups.retain(|g| {
                !g.pairs.iter().any(|p| {
                    p.key.eq_ignore_ascii_case("Time") || p.key.eq_ignore_ascii_case("Robot")
                })
            });
            let fault = parse_fault(&line).map_err(|e| format!("{at}: {e}"))?;
            faults.push(PlannedFault {
                time,
                serial: (robot as u64).saturating_sub(1),
                fault,
                line,
            });
        }
        faults.sort_by(|a, b| a.time.total_cmp(&b.time));
        Ok(Self {
            faults,
            ..Self::default()
        })
    }

    /// Reads and parses a faults file, or a recording (it starts with `# usar-record`).
    pub fn from_file(path: &std::path::Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        if text.starts_with("# usar-record") {
            return Self::from_recording(&text).map_err(|e| format!("{}: {e}", path.display()));
        }
        Self::from_toml(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.faults.is_empty()
            && self.random.is_empty()
            && self.each.is_empty()
            && self.each_random.is_empty()
    }

    /// Every fault at its time, the random ones drawn from `seed`: a random fault of
    /// probability `p` per second happens at `from + E`, `E` exponential with the rate
    /// `−ln(1 − p)` (so that it happens within a second with probability `p`), unless that
    /// is after `until`. The same seed gives the same times.
    pub(crate) fn schedule(&self, seed: u64) -> Vec<PlannedFault> {
        let mut out = self.faults.clone();
        for (i, r) in self.random.iter().enumerate() {
            out.extend(r.draw(seed, i, r.serial, 0.0));
        }
        out.sort_by(|a, b| a.time.total_cmp(&b.time));
        out
    }

    /// The `robot = "each"` faults of the robot `serial` spawned at `time`, drawn from
    /// `seed` and its serial, in time order.
    pub(crate) fn for_spawn(&self, seed: u64, serial: u64, time: f64) -> Vec<PlannedFault> {
        let mut out: Vec<_> = self
            .each
            .iter()
            .map(|f| PlannedFault {
                time: time + f.time,
                serial,
                ..f.clone()
            })
            .collect();
        for (i, r) in self.each_random.iter().enumerate() {
            // Streams apart from the numbered random faults'.
            out.extend(r.draw(seed, self.random.len() + i, serial, time));
        }
        out.sort_by(|a, b| a.time.total_cmp(&b.time));
        out
    }
}

impl RandomFault {
    /// When it happens to `serial` (times from `start`), if it does: with probability `p` per
    /// second at `from + E`, `E` exponential with the rate `−ln(1 − p)`, unless after `until`.
    fn draw(&self, seed: u64, index: usize, serial: u64, start: f64) -> Option<PlannedFault> {
        let mut rng = Noise::new(seed, serial, RANDOM_STREAM + index as u64, 0.0);
        let u = rng.uniform();
        let time = if self.probability >= 1.0 {
            self.from
        } else if self.probability <= 0.0 {
            return None;
        } else {
            self.from + (1.0 - u).ln() / (1.0 - self.probability).ln()
        };
        (time <= self.until).then(|| PlannedFault {
            time: start + time,
            serial,
            fault: self.fault.clone(),
            line: self.line.clone(),
        })
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
