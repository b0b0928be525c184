//! One connection's recording (`--record`, docs/recording.md).
//!
//! A write error (a full disk) is reported once, naming the file; the recording of that
//! connection stops there, and the file is cut back to its last whole line so that what was
//! written stays readable. The driver counts such files, and the server says at exit that
//! the recording is incomplete.

use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use tracing::warn;
use usar_proto::record::{Direction, RecordWriter};

/// A connection's recording file.
#[derive(Debug)]
pub(super) struct Recording {
    writer: Option<RecordWriter>,
    path: PathBuf,
}

impl Recording {
    /// Creates the file and writes the header; an error is reported (naming the file) and
    /// `Err(path)` says that this connection goes unrecorded.
    pub(super) fn create(path: PathBuf) -> Result<Self, PathBuf> {
        match RecordWriter::create(&path) {
            Ok(writer) => Ok(Self {
                writer: Some(writer),
                path,
            }),
            Err(error) => {
                warn!(path = %path.display(), %error, "cannot record this connection");
                Err(path)
            }
        }
    }

    /// Writes one entry (after a write error: nothing).
    pub(super) fn write(&mut self, time: f64, direction: Direction, text: &str) {
        if let Some(writer) = &mut self.writer
            && let Err(error) = writer.write_at(time, direction, text)
        {
            self.fail(&error);
        }
    }

    /// Writes what is buffered; `false` when this failed (reported here, once).
    pub(super) fn flush(&mut self) -> bool {
        if let Some(writer) = &mut self.writer
            && let Err(error) = writer.flush()
        {
            self.fail(&error);
        }
        self.complete()
    }

    /// Whether every entry so far was written.
    pub(super) fn complete(&self) -> bool {
        self.writer.is_some()
    }

    /// The file.
    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// Stops recording after `error` and cuts the file back to whole lines.
    fn fail(&mut self, error: &std::io::Error) {
        // Dropping the writer tries to write its buffer once more; the cut comes after.
        drop(self.writer.take());
        let kept = cut_to_whole_lines(&self.path);
        warn!(path = %self.path.display(), %error,
            kept_bytes = kept.as_ref().ok().copied(),
            "cannot write the recording; it ends here (whole lines kept)");
        if let Err(error) = kept {
            warn!(path = %self.path.display(), %error, "cannot cut the recording to whole lines");
        }
    }
}

/// Truncates the file at `path` after its last `\n`; returns its new length.
fn cut_to_whole_lines(path: &Path) -> std::io::Result<u64> {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
