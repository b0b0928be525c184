//! What the side servers (the image server on 5003, USARTruth on 3989, the robot monitor on
//! 7435, the WSS on 50000) share: questions to the simulation thread, the accept loop with
//! its connection limit, and bounded line reading.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::oneshot;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{info, warn};
use usar_proto::shown::Repeats;

use super::request::{Ask, Request};
use crate::sim::World;

/// Connections each side server serves at once; more are closed on accept.
pub(super) const MAX_CONNECTIONS: usize = 64;

/// The longest request line a side server reads (bytes); a longer one closes the connection.
pub(super) const MAX_LINE: usize = 4096;

/// Asks the simulation thread `question`; `None` when the simulation has stopped.
pub(super) async fn ask<T: Send + 'static>(
    requests: &Sender<Request>,
    question: impl FnOnce(&World) -> T + Send + 'static,
) -> Option<T> {
    let (reply, answer) = oneshot::channel();
    let ask = Ask(Box::new(move |world: &World| {
        let _ = reply.send(question(world));
    }));
    requests.send(Request::Ask(ask)).ok()?;
    answer.await.ok()
}

/// The connections a side server serves, oldest first: at its limit, the oldest connection
/// that has not completed a request is closed to make room for a new one (the Gamebots
/// port's rule, docs/limits.md), so that idle or slow clients cannot lock the port.
#[derive(Default)]
pub(super) struct Slots {
    next: u64,
    live: BTreeMap<u64, (Arc<AtomicBool>, CancellationToken)>,
}

/// A connection's place in [`Slots`], given back when dropped.
pub(super) struct Slot {
    slots: Arc<Mutex<Slots>>,
    id: u64,
    /// Set by the session once the client has completed a request.
    pub(super) spoke: Arc<AtomicBool>,
}

impl Drop for Slot {
    fn drop(&mut self) {
        lock(&self.slots).live.remove(&self.id);
    }
}

fn lock(slots: &Mutex<Slots>) -> std::sync::MutexGuard<'_, Slots> {
    slots.lock().unwrap_or_else(|e| e.into_inner())
}

impl Slots {
    /// A place for a new connection, at most `max` at once: a free one, or the oldest
    /// connection's that has not completed a request (its `stop` is cancelled; then the
    /// flag is true); `None` when every connection has. `stop` ends the new connection's
    /// session.
    pub(super) fn take(
        slots: &Arc<Mutex<Self>>,
        max: usize,
        stop: CancellationToken,
    ) -> Option<(Slot, bool)> {
        let mut s = lock(slots);
        let full = s.live.len() >= max.max(1);
        if full {
            let quiet = s
                .live
                .iter()
                .find(|(_, (spoke, _))| !spoke.load(Ordering::Relaxed))
                .map(|(id, _)| *id)?;
            if let Some((_, evicted)) = s.live.remove(&quiet) {
                evicted.cancel();
            }
        }
        let id = s.next;
        s.next += 1;
        let spoke = Arc::new(AtomicBool::new(false));
        s.live.insert(id, (spoke.clone(), stop));
        let slot = Slot {
            slots: slots.clone(),
            id,
            spoke,
        };
        Some((slot, full))
    }
}

/// Accepts connections on `listener` until `shutdown`, at most `max` at once (see [`Slots`]), and serves each with `serve` on `tracker`: `serve` gets the connection,
/// the token that ends it (shutdown, or closed to make room) and the flag to set once the
/// client has completed a request.
pub(super) async fn accept<F, Fut>(
    service: &'static str,
    listener: TcpListener,
    max: usize,
    tracker: TaskTracker,
    shutdown: CancellationToken,
    serve: F,
) where
    F: Fn(TcpStream, CancellationToken, Arc<AtomicBool>) -> Fut + Send + 'static,
    Fut: std::future::Future<Output = ()> + Send + 'static,
{
    let slots: Arc<Mutex<Slots>> = Arc::default();
    let (mut refused, mut evictions) = (Repeats::default(), Repeats::default());
    loop {
        let (stream, peer) = tokio::select! {
            _ = shutdown.cancelled() => return,
            accepted = listener.accept() => match accepted {
                Ok(x) => x,
                Err(error) => {
                    warn!(service, %error, "accept failed");
                    tokio::time::sleep(std::time::Duration::from_millis(10)).await;
                    continue;
                }
            },
        };
        let stop = shutdown.child_token();
        let Some((slot, evicted)) = Slots::take(&slots, max, stop.clone()) else {
            if let Some(count) = refused.note() {
                warn!(service, %peer, max, count,
                    "too many connections, each has completed a request; closing");
            }
            continue;
        };
        if evicted && let Some(count) = evictions.note() {
            warn!(service, %peer, max, count,
                "too many connections: closed the oldest that had not completed a request");
        }
        info!(service, %peer, "connected");
        let _ = stream.set_nodelay(true);
        let done = serve(stream, stop.clone(), slot.spoke.clone());
        tracker.spawn(async move {
            done.await;
            drop(slot);
            info!(service, %peer, "disconnected");
        });
    }
}

/// Serves a service of one answer per request line on `listener` until `shutdown` (see
/// [`accept`]): `answer` turns each line into the text to send back (with its line ends),
/// on the simulation thread; `None` sends nothing. A line longer than [`MAX_LINE`] closes its
/// connection; a client that does not read holds only its own connection.
pub(super) async fn serve_lines(
    service: &'static str,
    listener: TcpListener,
    requests: Sender<Request>,
    tracker: TaskTracker,
    shutdown: CancellationToken,
    answer: fn(&World, &str) -> Option<String>,
) {
    accept(
        service,
        listener,
        MAX_CONNECTIONS,
        tracker.clone(),
        shutdown,
        move |stream, stop, spoke| {
            answer_lines(service, stream, requests.clone(), stop, spoke, answer)
        },
    )
    .await;
}

async fn answer_lines(
    service: &'static str,
    stream: TcpStream,
    requests: Sender<Request>,
    stop: CancellationToken,
    spoke: Arc<AtomicBool>,
    answer: fn(&World, &str) -> Option<String>,
) {
    let peer = stream
        .peer_addr()
        .map(|a| a.to_string())
        .unwrap_or_default();
    let (read, mut write) = stream.into_split();
    let mut lines = Lines::new(read);
    loop {
        let line = tokio::select! {
            _ = stop.cancelled() => return,
            line = lines.next() => line,
        };
        let line = match line {
            Ok(line) => {
                spoke.store(true, Ordering::Relaxed);
                String::from_utf8_lossy(&line).into_owned()
            }
            Err(LineError::Closed) => return,
            Err(LineError::TooLong) => {
                warn!(service, %peer, max = MAX_LINE, "request line too long; closing");
                return;
            }
        };
        let Some(text) = ask(&requests, move |world| answer(world, &line)).await else {
            return;
        };
        if let Some(text) = text
            && write.write_all(text.as_bytes()).await.is_err()
        {
            return;
        }
    }
}

/// Reads lines ended by CR, LF or CR LF (one end each), at most [`MAX_LINE`] bytes each.
pub(super) struct Lines<R> {
    read: R,
    buffer: Vec<u8>,
    /// The last byte ended a line with CR: a LF right after it belongs to that end.
    after_cr: bool,
}

/// Why [`Lines::next`] gave no line.
#[derive(Debug)]
pub(super) enum LineError {
    /// The peer closed the connection (or it failed).
    Closed,
    /// A line longer than [`MAX_LINE`].
    TooLong,
}

impl<R: AsyncRead + Unpin> Lines<R> {
    pub(super) fn new(read: R) -> Self {
        Self {
            read,
            buffer: Vec::new(),
            after_cr: false,
        }
    }

    /// The next line, without its end; not necessarily UTF-8.
    pub(super) async fn next(&mut self) -> Result<Vec<u8>, LineError> {
        let mut start = 0;
        loop {
            if self.after_cr && self.buffer.first() == Some(&b'\n') {
                self.buffer.remove(0);
            }
            if !self.buffer.is_empty() {
                self.after_cr = false;
            }
            if let Some(at) = self.buffer[start..]
                .iter()
                .position(|&b| b == b'\n' || b == b'\r')
            {
                let at = start + at;
                self.after_cr = self.buffer[at] == b'\r';
                let line = self.buffer[..at].to_vec();
                self.buffer.drain(..=at);
                return Ok(line);
            }
            start = self.buffer.len();
            if self.buffer.len() > MAX_LINE {
                return Err(LineError::TooLong);
            }
            let mut chunk = [0u8; 2048];
            match self.read.read(&mut chunk).await {
                Ok(0) | Err(_) => return Err(LineError::Closed),
                Ok(n) => self.buffer.extend_from_slice(&chunk[..n]),
            }
        }
    }
}

/// The `{key value}` blocks of a line (an optional leading word is skipped): each block's
/// key and the rest after its first space, trimmed. Text outside blocks is ignored.
pub(super) fn blocks(line: &str) -> Vec<(&str, &str)> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(open) = rest.find('{') {
        let Some(close) = rest[open..].find('}') else {
            break;
        };
        let inner = rest[open + 1..open + close].trim();
        let (key, value) = inner.split_once(' ').unwrap_or((inner, ""));
        out.push((key, value.trim()));
        rest = &rest[open + close + 1..];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn lines_end_at_cr_lf_or_crlf_and_are_bounded() {
        let data: &[u8] = b"a\r\nb\nc\r\r\nd";
        let mut lines = Lines::new(data);
        for want in ["a", "b", "c", ""] {
            assert_eq!(lines.next().await.unwrap(), want.as_bytes());
        }
        assert!(matches!(lines.next().await, Err(LineError::Closed)));
        let long = vec![b'x'; MAX_LINE * 2];
        let mut lines = Lines::new(&long[..]);
        assert!(matches!(lines.next().await, Err(LineError::TooLong)));
    }

    #[test]
    fn at_the_limit_the_oldest_quiet_connection_makes_room() {
        let slots: Arc<Mutex<Slots>> = Arc::default();
        let stops: Vec<CancellationToken> = (0..4).map(|_| CancellationToken::new()).collect();
        let taken: Vec<Slot> = stops
            .iter()
            .take(3)
            .map(|stop| Slots::take(&slots, 3, stop.clone()).unwrap().0)
            .collect();
        taken[0].spoke.store(true, Ordering::Relaxed);
        // Full: the second (the oldest that has not completed a request) is closed.
        let (fourth, evicted) = Slots::take(&slots, 3, stops[3].clone()).unwrap();
        assert!(evicted);
        assert!(!stops[0].is_cancelled() && stops[1].is_cancelled());
        // Every connection has completed a request: the next one is refused.
        taken[2].spoke.store(true, Ordering::Relaxed);
        fourth.spoke.store(true, Ordering::Relaxed);
        assert!(Slots::take(&slots, 3, CancellationToken::new()).is_none());
        drop(taken);
        assert!(Slots::take(&slots, 3, CancellationToken::new()).is_some());
    }

    #[test]
    fn blocks_skip_a_leading_word_and_trim() {
        assert_eq!(
            blocks("GETOBS {From  A } {To B C}"),
            vec![("From", "A"), ("To", "B C")]
        );
        assert_eq!(blocks("\u{0}\u{ff}garbage{"), vec![]);
    }
}
