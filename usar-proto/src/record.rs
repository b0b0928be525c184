//! The recording format shared by `usar-server --record`, `ucc run --record` and `ucc tap`
//! (docs/recording.md): a header line, then one line per protocol line,
//! `<time> <C|S> <line>`, time in simulated seconds with 4 decimals.

use std::io::Write;

/// The first line of every recording.
pub const HEADER: &str = "# usar-record 1";

/// Which way a recorded line went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Client → server (`C`).
    Client,
    /// Server → client (`S`).
    Server,
}

impl Direction {
    fn letter(self) -> char {
        match self {
            Self::Client => 'C',
            Self::Server => 'S',
        }
    }
}

/// One recorded line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry<'a> {
    /// Simulated seconds.
    pub time: f64,
    /// Which way it went.
    pub direction: Direction,
    /// The protocol line, without terminator.
    pub text: &'a str,
}

/// A recording line that is not `<time> <C|S> <line>`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RecordError {
    /// The line has no time stamp or no direction.
    #[error("expected `<time> <C|S> <line>`")]
    Shape,
    /// The time stamp is not a finite number.
    #[error("bad time stamp '{0}'")]
    Time(String),
    /// The direction is neither `C` nor `S`.
    #[error("direction must be C or S, not '{0}'")]
    Direction(String),
}

/// Writes one entry.
pub fn write_entry(
    out: &mut impl Write,
    time: f64,
    direction: Direction,
    text: &str,
) -> std::io::Result<()> {
    writeln!(out, "{time:.4} {} {text}", direction.letter())
}

/// Reads one line of a recording; `Ok(None)` for blank lines and `#` comments.
pub fn parse_entry(line: &str) -> Result<Option<Entry<'_>>, RecordError> {
    let line = line.trim_end_matches(['\r', '\n']);
    if line.trim().is_empty() || line.starts_with('#') {
        return Ok(None);
    }
    let (time, rest) = line.split_once(' ').ok_or(RecordError::Shape)?;
    let time: f64 = time
        .parse()
        .ok()
        .filter(|t: &f64| t.is_finite())
        .ok_or_else(|| RecordError::Time(time.to_owned()))?;
    let (direction, text) = rest.split_once(' ').unwrap_or((rest, ""));
    let direction = match direction {
        "C" => Direction::Client,
        "S" => Direction::Server,
        other => return Err(RecordError::Direction(other.to_owned())),
    };
    Ok(Some(Entry {
        time,
        direction,
        text,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_round_trip() {
        let mut out = Vec::new();
        write_entry(
            &mut out,
            0.1,
            Direction::Server,
            "STA {Time 0.1000} {Battery 99999}",
        )
        .unwrap();
        let text = String::from_utf8(out).unwrap();
        assert_eq!(text, "0.1000 S STA {Time 0.1000} {Battery 99999}\n");
        let entry = parse_entry(&text).unwrap().unwrap();
        assert_eq!(
            entry,
            Entry {
                time: 0.1,
                direction: Direction::Server,
                text: "STA {Time 0.1000} {Battery 99999}"
            }
        );
    }

    #[test]
    fn comments_are_skipped_and_bad_lines_explained() {
        assert_eq!(parse_entry(HEADER), Ok(None));
        assert_eq!(parse_entry("x S STA"), Err(RecordError::Time("x".into())));
        for t in ["NaN", "inf", "-inf", "1e999"] {
            let line = format!("{t} S STA");
            assert_eq!(parse_entry(&line), Err(RecordError::Time(t.into())), "{t}");
        }
        assert_eq!(
            parse_entry("1.0 X STA"),
            Err(RecordError::Direction("X".into()))
        );
        assert_eq!(parse_entry("1.0"), Err(RecordError::Shape));
    }
}
