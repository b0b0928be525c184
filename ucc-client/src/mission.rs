//! Missions: what a UAV is asked to do, from a TOML file or the command line.
//!
//! A mission file is a list of `[[mission]]` tables, flown in order (see `docs/missions.md`):
//!
//! ```toml
//! [[mission]]
//! type = "GotoXyz"      # fly to a point: world frame, metres, z down (negative = up)
//! x = 2.0
//! y = 1.5
//! z = -2.0
//!
//! [[mission]]
//! type = "Hover"        # hold the current position for a while (simulated seconds)
//! seconds = 3.0
//! ```

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::geometry::{Coordinates, Num, triple};

/// One mission.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "type", deny_unknown_fields)]
pub enum Mission {
    /// Fly to a point (world frame, metres, z down).
    GotoXyz {
        /// North, metres.
        x: f64,
        /// East, metres.
        y: f64,
        /// Down, metres (a negative value is above the origin).
        z: f64,
    },
    /// Hold the position where the mission starts, for this many simulated seconds.
    Hover {
        /// Simulated seconds.
        seconds: f64,
    },
}

impl Mission {
    /// A GotoXyz mission to this point.
    pub fn goto(target: Coordinates) -> Self {
        Self::GotoXyz {
            x: target.x,
            y: target.y,
            z: target.z,
        }
    }

    /// The mission type's name, as written in a mission file.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::GotoXyz { .. } => "GotoXyz",
            Self::Hover { .. } => "Hover",
        }
    }

    /// The target point of a GotoXyz mission.
    pub fn target(&self) -> Option<Coordinates> {
        match self {
            Self::GotoXyz { x, y, z } => Some(Coordinates::new(*x, *y, *z)),
            Self::Hover { .. } => None,
        }
    }
}

impl fmt::Display for Mission {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::GotoXyz { x, y, z } => {
                write!(f, "GotoXyz {}", triple(&Coordinates::new(*x, *y, *z), 2))
            }
            Self::Hover { seconds } => write!(f, "Hover {} s", Num(*seconds, 1)),
        }
    }
}

/// A mission file or a command-line mission that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum MissionError {
    /// The file could not be read.
    #[error("cannot read mission file {path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why (part of the message, so not a `source`).
        error: std::io::Error,
    },
    /// The file is not a valid mission list.
    #[error("{path}:{line}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// 1-based line of the error (1 when unknown).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A `--goto` argument that is not `x,y,z`.
    #[error("invalid point {text:?}: {reason} (expected x,y,z in metres, z down, e.g. 2,1.5,-2)")]
    Point {
        /// The argument.
        text: String,
        /// Why.
        reason: String,
    },
}

/// One `[[mission]]` table as written, every key and value with its place in the file.
type RawMission = BTreeMap<toml::Spanned<String>, toml::Spanned<toml::Value>>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MissionFile {
    #[serde(default)]
    mission: Vec<toml::Spanned<RawMission>>,
}

/// The largest mission file [`load_missions`] reads (bytes): 1 MiB, like a robot file.
pub const MAX_MISSION_FILE: u64 = 1024 * 1024;

/// The most missions a file or a run may hold.
pub const MAX_MISSIONS: usize = 10_000;

/// Reads a mission file (at most [`MAX_MISSION_FILE`] bytes of UTF-8, at most
/// [`MAX_MISSIONS`] missions).
pub fn load_missions(path: &Path) -> Result<Vec<Mission>, MissionError> {
    use std::io::Read;
    let io = |error| MissionError::Io {
        path: path.to_owned(),
        error,
    };
    let invalid = |line, message| MissionError::Invalid {
        path: path.to_owned(),
        line,
        message,
    };
    let mut bytes = Vec::new();
    // `take` bounds what has no size too (a pipe, /dev/zero).
    std::fs::File::open(path)
        .map_err(io)?
        .take(MAX_MISSION_FILE + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_MISSION_FILE {
        return Err(invalid(
            1,
            format!("larger than the limit of {MAX_MISSION_FILE} bytes (1 MiB)"),
        ));
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        let good = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = good.iter().filter(|&&b| b == b'\n').count() + 1;
        invalid(line, "not a text file (bytes that are not UTF-8)".into())
    })?;
    parse_missions(&text, path)
}

/// Parses the text of a mission file; `path` names it in errors, which point at the line of
/// the bad key or value (at the `[[mission]]` header only for a missing key).
pub fn parse_missions(text: &str, path: &Path) -> Result<Vec<Mission>, MissionError> {
    let invalid = |offset: Option<usize>, message: String| MissionError::Invalid {
        path: path.to_owned(),
        line: offset.map_or(1, |o| line_of(text, o)),
        message,
    };
    let file: MissionFile = toml::from_str(text)
        .map_err(|e| invalid(e.span().map(|s| s.start), e.message().trim().to_owned()))?;
    if file.mission.is_empty() {
        return Err(invalid(None, "no [[mission]] entries".into()));
    }
    if let Some(extra) = file.mission.get(MAX_MISSIONS) {
        return Err(invalid(
            Some(extra.span().start),
            format!(
                "more than {MAX_MISSIONS} missions ({} in the file)",
                file.mission.len()
            ),
        ));
    }
    file.mission
        .iter()
        .map(|table| {
            read_mission(table).map_err(|(offset, message)| invalid(Some(offset), message))
        })
        .collect()
}

/// One mission from its table; an error is the byte offset to blame and what is wrong.
fn read_mission(table: &toml::Spanned<RawMission>) -> Result<Mission, (usize, String)> {
    let header = table.span().start;
    let find = |key: &str| table.get_ref().iter().find(|(k, _)| k.get_ref() == key);
    let (_, kind) = find("type").ok_or((
        header,
        "a [[mission]] needs a type (GotoXyz or Hover)".to_owned(),
    ))?;
    let (name, keys): (&str, &[&str]) = match kind.get_ref().as_str() {
        Some("GotoXyz") => ("GotoXyz", &["x", "y", "z"]),
        Some("Hover") => ("Hover", &["seconds"]),
        Some(other) => {
            return Err((
                kind.span().start,
                format!("unknown mission type {other:?} (known: GotoXyz, Hover)"),
            ));
        }
        None => return Err((kind.span().start, "type must be a string".into())),
    };
    if let Some((key, _)) = table
        .get_ref()
        .iter()
        .find(|(k, _)| k.get_ref() != "type" && !keys.contains(&k.get_ref().as_str()))
    {
        return Err((
            key.span().start,
            format!(
                "unknown key `{}` in a {name} mission (its keys: {})",
                key.get_ref(),
                keys.join(", ")
            ),
        ));
    }
    let number = |key: &str| -> Result<(f64, usize), (usize, String)> {
        let (_, value) = find(key).ok_or((header, format!("{name} mission without `{key}`")))?;
        let at = value.span().start;
        let v = match value.get_ref() {
            toml::Value::Float(v) => *v,
            toml::Value::Integer(v) => *v as f64,
            _ => return Err((at, format!("`{key}` must be a number"))),
        };
        Ok((v, at))
    };
    let mission = match name {
        "GotoXyz" => {
            let [(x, ax), (y, ay), (z, az)] = [number("x")?, number("y")?, number("z")?];
            if let Some(at) = [(x, ax), (y, ay), (z, az)]
                .iter()
                .find(|(v, _)| v.is_nan() || v.abs() > MAX_COORDINATE)
                .map(|(_, at)| *at)
            {
                return Err((
                    at,
                    format!(
                        "GotoXyz coordinates must be numbers within ±{MAX_COORDINATE} m (the world's size)"
                    ),
                ));
            }
            Mission::GotoXyz { x, y, z }
        }
        _ => {
            let (seconds, at) = number("seconds")?;
            if !(0.0..=MAX_HOVER).contains(&seconds) {
                return Err((
                    at,
                    format!("Hover seconds must be a number >= 0 and <= {MAX_HOVER}"),
                ));
            }
            Mission::Hover { seconds }
        }
    };
    Ok(mission)
}

/// The largest coordinate of a waypoint, metres: the server's world ends at ±100 000 m
/// (docs/limits.md).
pub const MAX_COORDINATE: f64 = 100_000.0;

/// The longest hover, simulated seconds (as `--mission-timeout`'s limit).
const MAX_HOVER: f64 = 1e6;

/// The 1-based line of byte `offset` in `text` (for errors that name the line).
pub(crate) fn line_of(text: &str, offset: usize) -> usize {
    text.as_bytes()[..offset.min(text.len())]
        .iter()
        .filter(|b| **b == b'\n')
        .count()
        + 1
}

/// Parses `x,y,z` (metres, z down) as written after `--goto`.
pub fn parse_point(text: &str) -> Result<Coordinates, MissionError> {
    let numbers = parse_numbers(text).map_err(|reason| MissionError::Point {
        text: text.to_owned(),
        reason,
    })?;
    match numbers[..] {
        [x, y, z] if [x, y, z].iter().all(|v| v.abs() <= MAX_COORDINATE) => {
            Ok(Coordinates::new(x, y, z))
        }
        [_, _, _] => Err(MissionError::Point {
            text: text.to_owned(),
            reason: format!("a coordinate beyond ±{MAX_COORDINATE} m (the world's size)"),
        }),
        _ => Err(MissionError::Point {
            text: text.to_owned(),
            reason: format!("{} numbers instead of 3", numbers.len()),
        }),
    }
}

/// Parses a comma-separated list of finite numbers.
pub(crate) fn parse_numbers(text: &str) -> Result<Vec<f64>, String> {
    text.split(',')
        .map(|part| match part.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!("{:?} is not a number", part.trim())),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<Mission>, MissionError> {
        parse_missions(text, Path::new("m.toml"))
    }

    #[test]
    fn good_file() {
        let missions = parse(
            "# a square\n[[mission]]\ntype = \"GotoXyz\"\nx = 1\ny = 2.5\nz = -2\n\n\
             [[mission]]\ntype = \"Hover\"\nseconds = 3\n",
        )
        .unwrap();
        assert_eq!(
            missions,
            vec![
                Mission::GotoXyz {
                    x: 1.0,
                    y: 2.5,
                    z: -2.0
                },
                Mission::Hover { seconds: 3.0 }
            ]
        );
    }

    fn error_line(text: &str) -> (usize, String) {
        match parse(text) {
            Err(MissionError::Invalid {
                line,
                message,
                path,
            }) => {
                assert_eq!(path, Path::new("m.toml"));
                (line, message)
            }
            other => panic!("expected an invalid-file error, got {other:?}"),
        }
    }

    #[test]
    fn unknown_type_names_the_line() {
        let (line, msg) = error_line(
            "[[mission]]\ntype = \"GotoXyz\"\nx = 1\ny = 2\nz = 3\n\n[[mission]]\ntype = \"Land\"\n",
        );
        assert_eq!(line, 8, "{msg}"); // the `type = "Land"` line
        assert!(msg.contains("Land"), "{msg}");
    }

    #[test]
    fn missing_coordinate_and_syntax_error() {
        let (line, msg) = error_line("[[mission]]\ntype = \"GotoXyz\"\nx = 1\ny = 2\n");
        assert_eq!(line, 1);
        assert!(msg.contains('z'), "{msg}");
        let (line, _) = error_line("[[mission]]\ntype = \"GotoXyz\"\nx = = 1\n");
        assert_eq!(line, 3);
        let (line, msg) = error_line("[[mission]]\ntype = \"Hover\"\nseconds = -1\n");
        assert_eq!(line, 3, "the bad value's line");
        assert!(msg.contains(">= 0"), "{msg}");
        let (_, msg) = error_line("# nothing\n");
        assert!(msg.contains("no [[mission]]"));
        let err = parse("[[mission]]\ntype = \"Hover\"\nseconds = 1\nspeed = 2\n").unwrap_err();
        assert!(
            err.to_string().starts_with("m.toml:4: unknown key `speed`"),
            "{err}"
        );
    }

    #[test]
    fn example_file() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/example.toml");
        let missions = load_missions(&path).unwrap();
        assert_eq!(missions.len(), 4);
        assert_eq!(missions[2], Mission::Hover { seconds: 3.0 });
    }

    #[test]
    fn absurd_files_and_numbers_are_refused_with_a_short_message() {
        let dir = std::env::temp_dir().join(format!("ucc-missions-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // A file past 1 MiB, read no further than the limit.
        let big = dir.join("big.toml");
        std::fs::write(&big, "#".repeat(MAX_MISSION_FILE as usize + 10)).unwrap();
        let err = load_missions(&big).unwrap_err().to_string();
        assert!(err.contains("big.toml:1: larger than the limit"), "{err}");
        // /dev/zero has no size and no end.
        if Path::new("/dev/zero").exists() {
            let err = load_missions(Path::new("/dev/zero"))
                .unwrap_err()
                .to_string();
            assert!(err.contains("larger than the limit"), "{err}");
        }
        let binary = dir.join("binary.toml");
        std::fs::write(&binary, b"# a\n\xff\xfe").unwrap();
        let err = load_missions(&binary).unwrap_err().to_string();
        assert!(
            err.ends_with("binary.toml:2: not a text file (bytes that are not UTF-8)"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
        // More missions than the limit: named at the first one too many.
        let one = "[[mission]]\ntype = \"Hover\"\nseconds = 1\n";
        let (line, msg) = error_line(&one.repeat(MAX_MISSIONS + 1));
        assert_eq!(line, 3 * MAX_MISSIONS + 1, "{msg}");
        assert!(msg.contains("more than 10000 missions (10001"), "{msg}");
        assert_eq!(
            parse(&one.repeat(MAX_MISSIONS)).unwrap().len(),
            MAX_MISSIONS
        );
        // 1e308 is refused, and no message prints its 309 digits.
        let (_, msg) = error_line("[[mission]]\ntype = \"GotoXyz\"\nx = 1e308\ny = 0\nz = 0\n");
        assert!(msg.contains("within ±100000 m"), "{msg}");
        let err = parse_point("1e308,0,0").unwrap_err().to_string();
        assert!(err.len() < 200 && err.contains("beyond"), "{err}");
        let (_, msg) = error_line("[[mission]]\ntype = \"Hover\"\nseconds = 1e308\n");
        assert!(msg.len() < 100, "{msg}");
        let far = Mission::GotoXyz {
            x: 1e308,
            y: 0.0,
            z: -1.0,
        };
        assert_eq!(far.to_string(), "GotoXyz 1.00e308,0.00,-1.00");
    }

    #[test]
    fn missing_file() {
        let err = load_missions(Path::new("/nonexistent/m.toml")).unwrap_err();
        assert!(err.to_string().contains("/nonexistent/m.toml"));
    }

    #[test]
    fn points() {
        assert_eq!(
            parse_point("1, 2.5,-3").unwrap(),
            Coordinates::new(1.0, 2.5, -3.0)
        );
        assert!(parse_point("1,2").is_err());
        assert!(
            parse_point("1,x,3")
                .unwrap_err()
                .to_string()
                .contains("\"x\"")
        );
        assert!(parse_point("1,2,inf").is_err());
    }
}
