//! The recording format shared by `usar-server --record`, `ucc run --record` and `ucc tap`
//! (docs/recording.md): a header line, then one line per protocol line,
//! `<time> <C|S> <line>`, time in simulated seconds with 4 decimals.

use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

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

/// A recording being written (the one writer of `usar-server --record`, `ucc run --record`
/// and `ucc tap`): the [`HEADER`], then one entry per line. Entries are stamped with the
/// latest simulated time the caller has seen ([`RecordWriter::set_time`]) unless given one.
#[derive(Debug)]
pub struct RecordWriter<W: Write = std::io::BufWriter<std::fs::File>> {
    out: W,
    time: f64,
}

impl RecordWriter {
    /// Creates (or truncates) the file at `path` and writes the header.
    pub fn create(path: &std::path::Path) -> std::io::Result<Self> {
        Self::new(std::io::BufWriter::new(std::fs::File::create(path)?))
    }
}

impl<W: Write> RecordWriter<W> {
    /// Starts a recording on `out`: writes the header.
    pub fn new(mut out: W) -> std::io::Result<Self> {
        writeln!(out, "{HEADER}")?;
        Ok(Self { out, time: 0.0 })
    }

    /// The time stamp of the next entries written with [`RecordWriter::write`].
    pub fn set_time(&mut self, time: f64) {
        self.time = time;
    }

    /// The time stamp of the next entries.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Writes one entry at the current time stamp.
    pub fn write(&mut self, direction: Direction, text: &str) -> std::io::Result<()> {
        write_entry(&mut self.out, self.time, direction, text)
    }

    /// Writes one entry at `time` (which becomes the current time stamp).
    pub fn write_at(&mut self, time: f64, direction: Direction, text: &str) -> std::io::Result<()> {
        self.time = time;
        self.write(direction, text)
    }

    /// Writes what is buffered to the file.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }

    /// The output, flushed.
    pub fn into_inner(mut self) -> std::io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// A recording file that stops at its first write error (a full disk) and cuts the file back
/// to its last whole line, so that what was written stays readable; `usar-server --record`,
/// `ucc run --record` and `ucc tap` each say so in their own words.
#[derive(Debug)]
pub struct RecordFile {
    writer: Option<RecordWriter>,
    path: PathBuf,
}

/// Why a [`RecordFile`] stopped.
#[derive(Debug)]
pub struct RecordStopped {
    /// The write error.
    pub error: std::io::Error,
    /// The bytes of whole lines kept, or why the file could not be cut.
    pub kept: std::io::Result<u64>,
}

impl RecordFile {
    /// Creates (or truncates) the file at `path` and writes the header.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        Ok(Self::new(RecordWriter::create(path)?, path))
    }

    /// A recording already started on the file at `path`.
    pub fn new(writer: RecordWriter, path: &Path) -> Self {
        Self {
            writer: Some(writer),
            path: path.to_owned(),
        }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether every entry so far was written.
    pub fn is_complete(&self) -> bool {
        self.writer.is_some()
    }

    /// Runs `write` on the writer (after a failure: nothing). On the first failure the
    /// recording stops, the file is cut back to its last whole line, and the error is
    /// returned, once.
    pub fn with(
        &mut self,
        write: impl FnOnce(&mut RecordWriter) -> std::io::Result<()>,
    ) -> Result<(), RecordStopped> {
        let Some(writer) = &mut self.writer else {
            return Ok(());
        };
        write(writer).map_err(|error| {
            // Dropping the writer tries to write its buffer once more; the cut comes after.
            drop(self.writer.take());
            RecordStopped {
                error,
                kept: cut_to_whole_lines(&self.path),
            }
        })
    }
}

/// Truncates the file at `path` after its last `\n`; returns its new length.
pub fn cut_to_whole_lines(path: &Path) -> std::io::Result<u64> {
    const BLOCK: u64 = 64 * 1024;
    let mut file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)?;
    let mut end = file.metadata()?.len();
    let mut block = vec![0; BLOCK as usize];
    while end > 0 {
        let start = end.saturating_sub(BLOCK);
        let len = (end - start) as usize;
        file.seek(SeekFrom::Start(start))?;
        file.read_exact(&mut block[..len])?;
        if let Some(i) = block[..len].iter().rposition(|&b| b == b'\n') {
            let keep = start + i as u64 + 1;
            if keep != file.metadata()?.len() {
                file.set_len(keep)?;
            }
            return Ok(keep);
        }
        end = start;
    }
    file.set_len(0)?;
    Ok(0)
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
    #[test]
    fn a_cut_keeps_whole_lines() {
        let dir = std::env::temp_dir().join(format!("usar-cut-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("r.usarlog");
        let mut text = "# usar-record 1\n".to_owned();
        text.push_str(&"0.1000 S STA {Time 0.1000}\n".repeat(5000));
        text.push_str("0.2000 S STA {Ti");
        std::fs::write(&path, &text).unwrap();
        let kept = cut_to_whole_lines(&path).unwrap();
        let after = std::fs::read_to_string(&path).unwrap();
        assert_eq!(kept as usize, after.len());
        assert!(after.ends_with("{Time 0.1000}\n"));
        assert_eq!(after.lines().count(), 5001);
        std::fs::write(&path, "no newline at all").unwrap();
        assert_eq!(cut_to_whole_lines(&path).unwrap(), 0);
        std::fs::remove_dir_all(&dir).unwrap();
    }

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
    fn the_writer_stamps_entries_with_the_latest_time() {
        let mut w = RecordWriter::new(Vec::new()).unwrap();
        w.write(Direction::Client, "SYNC {Time 0.1000}").unwrap();
        w.write_at(0.1, Direction::Server, "STA {Time 0.1000} {Battery 9}")
            .unwrap();
        w.write(Direction::Client, "DRIVE {LinearVelocity 1}")
            .unwrap();
        let text = String::from_utf8(w.into_inner().unwrap()).unwrap();
        assert_eq!(
            text,
            "# usar-record 1\n0.0000 C SYNC {Time 0.1000}\n0.1000 S STA {Time 0.1000} {Battery 9}\n\
             0.1000 C DRIVE {LinearVelocity 1}\n"
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
