//! One connection's recording (`--record`, docs/recording.md).
//!
//! A write error (a full disk) is reported once, naming the file; the recording of that
//! connection stops there, and the file is cut back to its last whole line so that what was
//! written stays readable. The driver counts such files, and the server says at exit that
//! the recording is incomplete.

use std::path::{Path, PathBuf};

use tracing::warn;
use usar_proto::record::{Direction, RecordFile, RecordStopped, RecordWriter};

/// A connection's recording file.
#[derive(Debug)]
pub(super) struct Recording(RecordFile);

impl Recording {
    /// Creates the file and writes the header; an error is reported (naming the file) and
    /// `Err(path)` says that this connection goes unrecorded.
    pub(super) fn create(path: PathBuf) -> Result<Self, PathBuf> {
        match RecordFile::create(&path) {
            Ok(file) => Ok(Self(file)),
            Err(error) => {
                warn!(path = %path.display(), %error, "cannot record this connection");
                Err(path)
            }
        }
    }

    /// Writes one entry (after a write error: nothing).
    pub(super) fn write(&mut self, time: f64, direction: Direction, text: &str) {
        if let Err(stopped) = self.0.with(|w| w.write_at(time, direction, text)) {
            self.report(stopped);
        }
    }

    /// Writes what is buffered; `false` when this failed (reported here, once).
    pub(super) fn flush(&mut self) -> bool {
        if let Err(stopped) = self.0.with(RecordWriter::flush) {
            self.report(stopped);
        }
        self.complete()
    }

    /// Whether every entry so far was written.
    pub(super) fn complete(&self) -> bool {
        self.0.is_complete()
    }

    /// The file.
    pub(super) fn path(&self) -> &Path {
        self.0.path()
    }

    fn report(&self, RecordStopped { error, kept }: RecordStopped) {
        let path = self.0.path().display();
        warn!(%path, %error, kept_bytes = kept.as_ref().ok().copied(),
            "cannot write the recording; it ends here (whole lines kept)");
        if let Err(error) = kept {
            warn!(%path, %error, "cannot cut the recording to whole lines");
        }
    }
}
