//! The program's output (the log on stderr, the ready lines on stdout), written so that
//! output nobody reads never stops the server (docs/limits.md).
//!
//! Log lines go into a bounded queue ([`QUEUE_LINES`]) that one thread of their own writes to
//! stderr. When the queue is full (stderr is a pipe nobody reads, or a slow terminal) or a
//! write fails (stderr closed), lines are dropped and counted; the count is reported on
//! stderr when a write works again, and in all at exit ([`Log::finish`]). So logging never
//! blocks a thread that serves, and the program ends on a signal whatever the state of its
//! output. The ready lines go to stdout from a thread of their own
//! ([`announce`]): a full stdout does not hold up serving, a closed one is logged.

use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
use std::time::{Duration, Instant};

use tracing_subscriber::fmt::MakeWriter;

/// Log lines waiting for stderr at most; more are dropped (counted).
pub const QUEUE_LINES: usize = 1024;

/// How long [`Log::finish`] waits at most for the queued lines to be written.
pub const FINISH_WAIT: Duration = Duration::from_millis(500);

/// Counts shared by the queue's senders and its writer thread.
#[derive(Debug, Default)]
struct Counts {
    /// Lines lost: the queue was full, or their write failed.
    dropped: AtomicU64,
    /// Lines put in the queue.
    queued: AtomicU64,
    /// Lines the writer has taken from the queue and written (or failed to).
    done: AtomicU64,
}

/// The program's log: a bounded queue of lines that a thread of its own writes out.
/// Cloned into the `tracing` subscriber as its writer.
#[derive(Debug, Clone)]
pub struct Log {
    queue: SyncSender<Vec<u8>>,
    counts: Arc<Counts>,
}

impl Log {
    /// A log whose lines a new thread writes to `out` (stderr in the program).
    pub fn new(out: impl Write + Send + 'static) -> std::io::Result<Self> {
        let (queue, lines) = std::sync::mpsc::sync_channel(QUEUE_LINES);
        let counts = Arc::new(Counts::default());
        let shared = counts.clone();
        std::thread::Builder::new()
            .name("usar-log".into())
            .spawn(move || write_out(lines, out, &shared))?;
        Ok(Self { queue, counts })
    }

    /// Queues `text` (a line with its newline) without ever waiting; dropped and counted if
    /// the queue is full.
    pub fn say(&self, text: impl Into<Vec<u8>>) {
        match self.queue.try_send(text.into()) {
            Ok(()) => {
                self.counts.queued.fetch_add(1, Ordering::SeqCst);
            }
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.counts.dropped.fetch_add(1, Ordering::SeqCst);
            }
        }
    }

    /// Lines dropped so far.
    pub fn dropped(&self) -> u64 {
        self.counts.dropped.load(Ordering::SeqCst)
    }

    /// At exit: says how many lines were dropped in all (if any), and waits at most
    /// [`FINISH_WAIT`] for the queue to be written out (not longer: the output may never
    /// take it).
    pub fn finish(&self) {
        let deadline = Instant::now() + FINISH_WAIT;
        self.wait_until(deadline);
        let dropped = self.dropped();
        if dropped > 0 {
            self.say(dropped_line(dropped, "in all"));
            self.wait_until(deadline);
        }
    }

    /// Waits until every queued line is done, or `deadline`.
    fn wait_until(&self, deadline: Instant) {
        while self.counts.done.load(Ordering::SeqCst) < self.counts.queued.load(Ordering::SeqCst)
            && Instant::now() < deadline
        {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

/// The line that reports `n` dropped log lines.
fn dropped_line(n: u64, when: &str) -> String {
    format!(
        "usar-server: {n} log lines dropped {when} (the log output was full or closed: \
         read the server's stderr)\n"
    )
}

/// The writer thread: writes each line; after a write that works, reports the lines dropped
/// since the last report.
fn write_out(lines: Receiver<Vec<u8>>, mut out: impl Write, counts: &Counts) {
    let mut reported = 0;
    for line in lines {
        if out.write_all(&line).and_then(|()| out.flush()).is_ok() {
            let dropped = counts.dropped.load(Ordering::SeqCst);
            if dropped > reported {
                let note = dropped_line(dropped - reported, "meanwhile");
                if out
                    .write_all(note.as_bytes())
                    .and_then(|()| out.flush())
                    .is_ok()
                {
                    reported = dropped;
                }
            }
        } else {
            counts.dropped.fetch_add(1, Ordering::SeqCst);
        }
        counts.done.fetch_add(1, Ordering::SeqCst);
    }
}

/// One log line being formatted; queued whole when dropped.
#[derive(Debug)]
pub struct LogLine<'a> {
    log: &'a Log,
    text: Vec<u8>,
}

impl Write for LogLine<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.text.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Drop for LogLine<'_> {
    fn drop(&mut self) {
        if !self.text.is_empty() {
            self.log.say(std::mem::take(&mut self.text));
        }
    }
}

impl<'a> MakeWriter<'a> for Log {
    type Writer = LogLine<'a>;

    fn make_writer(&'a self) -> Self::Writer {
        LogLine {
            log: self,
            text: Vec::new(),
        }
    }
}

/// Sets up the program's log: `RUST_LOG` (default `info`) on stderr through a [`Log`],
/// colours only on a terminal. Call [`Log::finish`] before exiting.
pub fn init() -> Log {
    let log = Log::new(std::io::stderr()).unwrap_or_else(|_| {
        // No thread for the log (out of resources): lines are dropped, counted, never block.
        let (queue, _) = std::sync::mpsc::sync_channel(0);
        Log {
            queue,
            counts: Arc::default(),
        }
    });
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(log.clone())
        // Colours only on a terminal: a log file gets no escape sequences at all.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    log
}

/// Prints `text` on stdout (the ready lines: scripts wait for them) in one write, from a
/// thread of its own: a stdout nobody reads does not hold up serving, and one that is
/// closed (the reader took the line it wanted and left) is logged, never a panic.
pub fn announce(text: String) {
    let print = move || {
        let mut stdout = std::io::stdout().lock();
        if let Err(error) = stdout
            .write_all(text.as_bytes())
            .and_then(|()| stdout.flush())
        {
            tracing::warn!(%error, "cannot print the ready lines on stdout; serving anyway");
        }
    };
    if let Err(error) = std::thread::Builder::new()
        .name("usar-ready".into())
        .spawn(print)
    {
        tracing::warn!(%error, "cannot print the ready lines on stdout; serving anyway");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// An output that blocks until opened, then keeps what it is given.
    #[derive(Clone, Default)]
    struct Gate {
        open: Arc<(Mutex<bool>, std::sync::Condvar)>,
        text: Arc<Mutex<Vec<u8>>>,
    }

    impl Write for Gate {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            let (open, changed) = &*self.open;
            let mut open = open.lock().unwrap();
            while !*open {
                open = changed.wait(open).unwrap();
            }
            self.text.lock().unwrap().extend_from_slice(buf);
            Ok(buf.len())
        }

        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_blocked_output_drops_lines_without_waiting_and_reports_them_once_it_works() {
        let gate = Gate::default();
        let log = Log::new(gate.clone()).unwrap();
        let started = Instant::now();
        for n in 0..QUEUE_LINES + 500 {
            log.say(format!("line {n}\n"));
        }
        assert!(started.elapsed() < Duration::from_secs(5), "never waits");
        // The writer holds one line, the queue QUEUE_LINES; the rest were dropped.
        let dropped = log.dropped();
        assert!((499..=500).contains(&dropped), "{dropped}");
        *gate.open.0.lock().unwrap() = true;
        gate.open.1.notify_all();
        log.finish();
        let text = String::from_utf8(gate.text.lock().unwrap().clone()).unwrap();
        assert!(text.starts_with("line 0\n"), "{text}");
        assert!(
            text.contains(&format!("{dropped} log lines dropped meanwhile")),
            "{text}"
        );
        assert!(text.ends_with(&dropped_line(dropped, "in all")), "{text}");
    }

    #[test]
    fn a_closed_output_counts_its_lines_as_dropped() {
        struct Closed;
        impl Write for Closed {
            fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
                Err(std::io::ErrorKind::BrokenPipe.into())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let log = Log::new(Closed).unwrap();
        for _ in 0..10 {
            log.say("x\n");
        }
        let started = Instant::now();
        log.finish();
        assert!(started.elapsed() <= FINISH_WAIT + Duration::from_secs(1));
        assert!(log.dropped() >= 10, "{}", log.dropped());
    }
}
