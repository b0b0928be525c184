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

/// Reads a mission file.
pub fn load_missions(path: &Path) -> Result<Vec<Mission>, MissionError> {
    let text = std::fs::read_to_string(path).map_err(|error| MissionError::Io {
        path: path.to_owned(),
        error,
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
                .find(|(v, _)| !v.is_finite())
                .map(|(_, at)| *at)
            {
                return Err((at, "GotoXyz coordinates must be finite numbers".into()));
            }
            Mission::GotoXyz { x, y, z }
        }
        _ => {
            let (seconds, at) = number("seconds")?;
            if !(seconds.is_finite() && seconds >= 0.0) {
                return Err((at, "Hover seconds must be a number >= 0".into()));
            }
            Mission::Hover { seconds }
        }
    };
    Ok(mission)
}

fn line_of(text: &str, offset: usize) -> usize {
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
        [x, y, z] => Ok(Coordinates::new(x, y, z)),
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
