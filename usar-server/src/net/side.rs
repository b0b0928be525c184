//! What the side servers (the image server on 5003, USARTruth on 3989, the robot monitor on
//! 7435, the WSS on 50000) share: questions to the simulation thread, the accept loop with
//! its connection limit and timeouts, and bounded line reading.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::oneshot;
use tokio::time::Instant;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{info, warn};
use usar_proto::shown::{Repeats, Shown};

use super::request::{Ask, Request};
use crate::sim::World;

/// The longest request line a side server reads (bytes); a longer one closes the connection.
pub(super) const MAX_LINE: usize = 4096;

/// A side service's limits (docs/limits.md; `ServerConfig::side_connections`,
/// `idle_timeout`, `line_timeout`).
#[derive(Debug, Clone, Copy)]
pub(super) struct Limits {
    /// Connections served at once (see [`Slots`]).
    pub(super) max: usize,
    /// A connection that has not completed a request this long after connecting is closed
    /// (`None`: never; the image server, whose clients may only read the frame sent on
    /// connect).
    pub(super) idle: Option<Duration>,
    /// A connection that has begun a request and not ended it within this time is closed
    /// (a slow sender).
    pub(super) line: Duration,
}

/// How a side connection is doing, shared by its session (which tells) and the accept loop
/// (which picks the connection to close at the limit).
#[derive(Debug)]
pub(super) struct Activity {
    connected: Instant,
    /// The client has completed a request.
    spoke: AtomicBool,
    /// When the request not yet ended began: milliseconds after `connected`, plus one;
    /// 0: no request is unfinished.
    unfinished: AtomicU64,
    idle: Option<Duration>,
    line: Duration,
}

/// Why a side connection stopped waiting for its client.
pub(super) type TimedOut = &'static str;

impl Activity {
    pub(super) fn new(limits: Limits) -> Self {
        Self {
            connected: Instant::now(),
            spoke: AtomicBool::new(false),
            unfinished: AtomicU64::new(0),
            idle: limits.idle,
            line: limits.line,
        }
    }

    /// The client has completed a request.
    pub(super) fn completed(&self) {
        self.spoke.store(true, Ordering::Relaxed);
    }

    fn spoke(&self) -> bool {
        self.spoke.load(Ordering::Relaxed)
    }

    /// Whether bytes of a request not yet ended wait (told before each read).
    pub(super) fn unfinished(&self, unfinished: bool) {
        if !unfinished {
            self.unfinished.store(0, Ordering::Relaxed);
        } else if self.unfinished.load(Ordering::Relaxed) == 0 {
            let ms = u64::try_from(self.connected.elapsed().as_millis()).unwrap_or(u64::MAX - 1);
            self.unfinished.store(ms + 1, Ordering::Relaxed);
        }
    }

    /// When the request not yet ended began.
    fn unfinished_since(&self) -> Option<Instant> {
        match self.unfinished.load(Ordering::Relaxed) {
            0 => None,
            ms => Some(self.connected + Duration::from_millis(ms - 1)),
        }
    }

    /// Reads from the client, as long as the limits allow: until `idle` after connecting
    /// while no request was completed, until `line` after a request began while it is
    /// unfinished, else without end. `unfinished`: bytes of a request wait already.
    pub(super) async fn read<R: AsyncRead + Unpin>(
        &self,
        read: &mut R,
        buf: &mut [u8],
        unfinished: bool,
    ) -> Result<std::io::Result<usize>, TimedOut> {
        self.unfinished(unfinished);
        let idle = self
            .idle
            .filter(|_| !self.spoke())
            .map(|idle| (self.connected + idle, "no complete request in time"));
        let line = self
            .unfinished_since()
            .map(|since| (since + self.line, "request not finished in time"));
        let deadline = match (idle, line) {
            (Some(a), Some(b)) => Some(if a.0 <= b.0 { a } else { b }),
            (a, b) => a.or(b),
        };
        match deadline {
            None => Ok(read.read(buf).await),
            Some((at, why)) => tokio::time::timeout_at(at, read.read(buf))
                .await
                .map_err(|_| why),
        }
    }
}

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

/// The connections a side server serves, oldest first. At its limit a new connection takes
/// the place of one that holds it without using it: the oldest that has not completed a
/// request, else the one whose unfinished request began first (a slow sender); only when
/// every connection has completed a request and has none unfinished is the new one closed
/// (docs/limits.md). So idle or slow clients cannot lock the port.
#[derive(Default)]
pub(super) struct Slots {
    next: u64,
    live: BTreeMap<u64, (Arc<Activity>, CancellationToken)>,
}

/// A connection's place in [`Slots`], given back when dropped.
pub(super) struct Slot {
    slots: Arc<Mutex<Slots>>,
    id: u64,
    /// What the session tells of its client.
    pub(super) activity: Arc<Activity>,
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
    /// A place for a new connection, at most `limits.max` at once: a free one, or the place
    /// of a connection that holds it without using it (see [`Slots`]; its `stop` is
    /// cancelled, and then the flag is true); `None` when there is none. `stop` ends the
    /// new connection's session.
    pub(super) fn take(
        slots: &Arc<Mutex<Self>>,
        limits: Limits,
        stop: CancellationToken,
    ) -> Option<(Slot, bool)> {
        let mut s = lock(slots);
        let full = s.live.len() >= limits.max.max(1);
        if full {
            let quiet = s
                .live
                .iter()
                .find(|(_, (a, _))| !a.spoke())
                .map(|(id, _)| *id);
            let slow = || {
                s.live
                    .iter()
                    .filter_map(|(id, (a, _))| Some((a.unfinished_since()?, *id)))
                    .min()
                    .map(|(_, id)| id)
            };
            let id = quiet.or_else(slow)?;
            if let Some((_, evicted)) = s.live.remove(&id) {
                evicted.cancel();
            }
        }
        let id = s.next;
        s.next += 1;
        let activity = Arc::new(Activity::new(limits));
        s.live.insert(id, (activity.clone(), stop));
        let slot = Slot {
            slots: slots.clone(),
            id,
            activity,
        };
        Some((slot, full))
    }
}

/// Accepts connections on `listener` until `shutdown`, at most `limits.max` at once (see
/// [`Slots`]), and serves each with `serve` on `tracker`: `serve` gets the connection, the
/// token that ends it (shutdown, or closed to make room) and the [`Activity`] to tell and
/// read through.
pub(super) async fn accept<F, Fut>(
    service: &'static str,
    listener: TcpListener,
    limits: Limits,
    tracker: TaskTracker,
    shutdown: CancellationToken,
    serve: F,
) where
    F: Fn(TcpStream, CancellationToken, Arc<Activity>) -> Fut + Send + 'static,
    Fut: std::future::Future<Output = ()> + Send + 'static,
{
    let slots: Arc<Mutex<Slots>> = Arc::default();
    let (mut refused, mut evictions) = (Repeats::default(), Repeats::default());
    let max = limits.max;
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
        let Some((slot, evicted)) = Slots::take(&slots, limits, stop.clone()) else {
            if let Some(count) = refused.note() {
                warn!(service, %peer, max, count,
                    "too many connections, each has completed a request and has none \
                     unfinished; closing");
            }
            continue;
        };
        if evicted && let Some(count) = evictions.note() {
            warn!(service, %peer, max, count,
                "too many connections: closed the oldest that had not completed a request \
                 (or the slowest sender)");
        }
        info!(service, %peer, "connected");
        let _ = stream.set_nodelay(true);
        let done = serve(stream, stop.clone(), slot.activity.clone());
        tracker.spawn(async move {
            done.await;
            drop(slot);
            info!(service, %peer, "disconnected");
        });
    }
}

/// Closes a connection whose first line is HTTP (`usar_proto::http`, docs/security.md):
/// `true` (and a warning) if `line` is the first and looks like HTTP.
pub(super) fn refuse_http(service: &str, peer: &str, first: bool, line: &[u8]) -> bool {
    if !first || !usar_proto::http::looks_like_http(line) {
        return false;
    }
    let text = String::from_utf8_lossy(line);
    warn!(service, %peer, line = %Shown(&text),
        "closing: the first line is HTTP (a web page's request?), not this port's protocol");
    true
}

/// Serves a service of one answer per request line on `listener` until `shutdown` (see
/// [`accept`]): `answer` turns each line into the text to send back (with its line ends),
/// on the simulation thread; `None` sends nothing. A line longer than [`MAX_LINE`], a first
/// line that is HTTP, or a timeout of `limits` closes its connection; a client that does
/// not read holds only its own connection.
pub(super) async fn serve_lines(
    service: &'static str,
    listener: TcpListener,
    requests: Sender<Request>,
    (tracker, limits): (TaskTracker, Limits),
    shutdown: CancellationToken,
    answer: fn(&World, &str) -> Option<String>,
) {
    accept(
        service,
        listener,
        limits,
        tracker.clone(),
        shutdown,
        move |stream, stop, activity| {
            answer_lines(service, stream, requests.clone(), stop, activity, answer)
        },
    )
    .await;
}

async fn answer_lines(
    service: &'static str,
    stream: TcpStream,
    requests: Sender<Request>,
    stop: CancellationToken,
    activity: Arc<Activity>,
    answer: fn(&World, &str) -> Option<String>,
) {
    let peer = stream
        .peer_addr()
        .map(|a| a.to_string())
        .unwrap_or_default();
    let (read, mut write) = stream.into_split();
    let mut lines = Lines::new(read);
    let mut first = true;
    loop {
        let line = tokio::select! {
            _ = stop.cancelled() => return,
            line = lines.next(&activity) => line,
        };
        let line = match line {
            Ok(line) => {
                if refuse_http(service, &peer, std::mem::take(&mut first), &line) {
                    return;
                }
                activity.completed();
                String::from_utf8_lossy(&line).into_owned()
            }
            Err(LineError::Closed) => return,
            Err(LineError::TooLong) => {
                warn!(service, %peer, max = MAX_LINE, "request line too long; closing");
                return;
            }
            Err(LineError::TimedOut(why)) => {
                info!(service, %peer, "closing: {why}");
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
    /// A limit of [`Limits`] ran out.
    TimedOut(TimedOut),
}

impl<R: AsyncRead + Unpin> Lines<R> {
    pub(super) fn new(read: R) -> Self {
        Self {
            read,
            buffer: Vec::new(),
            after_cr: false,
        }
    }

    /// The next line, without its end; not necessarily UTF-8. Reads through `activity`
    /// (its timeouts; it is told whether a line is unfinished).
    pub(super) async fn next(&mut self, activity: &Activity) -> Result<Vec<u8>, LineError> {
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
            let unfinished = !self.buffer.is_empty();
            match activity.read(&mut self.read, &mut chunk, unfinished).await {
                Err(why) => return Err(LineError::TimedOut(why)),
                Ok(Ok(0) | Err(_)) => return Err(LineError::Closed),
                Ok(Ok(n)) => self.buffer.extend_from_slice(&chunk[..n]),
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

    const LIMITS: Limits = Limits {
        max: 3,
        idle: None,
        line: Duration::from_secs(3600),
    };

    #[tokio::test]
    async fn lines_end_at_cr_lf_or_crlf_and_are_bounded() {
        let activity = Activity::new(LIMITS);
        let data: &[u8] = b"a\r\nb\nc\r\r\nd";
        let mut lines = Lines::new(data);
        for want in ["a", "b", "c", ""] {
            assert_eq!(lines.next(&activity).await.unwrap(), want.as_bytes());
        }
        assert!(matches!(
            lines.next(&activity).await,
            Err(LineError::Closed)
        ));
        let long = vec![b'x'; MAX_LINE * 2];
        let mut lines = Lines::new(&long[..]);
        assert!(matches!(
            lines.next(&activity).await,
            Err(LineError::TooLong)
        ));
    }

    #[tokio::test(start_paused = true)]
    async fn a_request_left_unfinished_or_never_sent_times_out() {
        let limits = Limits {
            idle: Some(Duration::from_secs(30)),
            line: Duration::from_secs(5),
            ..LIMITS
        };
        // Never a complete request: closed after the idle time.
        let (client, server) = tokio::io::duplex(64);
        let activity = Activity::new(limits);
        let mut lines = Lines::new(server);
        let begin = tokio::time::Instant::now();
        assert!(matches!(
            lines.next(&activity).await,
            Err(LineError::TimedOut("no complete request in time"))
        ));
        assert_eq!(begin.elapsed(), Duration::from_secs(30));
        drop(client);
        // A request, then a second one begun and never ended: closed `line` after it began,
        // however slowly its bytes come; waiting between requests is fine.
        let (mut client, server) = tokio::io::duplex(64);
        let activity = Activity::new(limits);
        let mut lines = Lines::new(server);
        client.write_all(b"GETPOS\r\n").await.unwrap();
        assert_eq!(lines.next(&activity).await.unwrap(), b"GETPOS");
        activity.completed();
        let sender = tokio::spawn(async move {
            tokio::time::sleep(Duration::from_secs(100)).await;
            for _ in 0..100 {
                if client.write_all(b"x").await.is_err() {
                    return;
                }
                tokio::time::sleep(Duration::from_millis(500)).await;
            }
        });
        let begin = tokio::time::Instant::now();
        assert!(matches!(
            lines.next(&activity).await,
            Err(LineError::TimedOut("request not finished in time"))
        ));
        let waited = begin.elapsed();
        assert!(
            waited >= Duration::from_secs(105) && waited < Duration::from_secs(106),
            "{waited:?}"
        );
        drop(lines);
        sender.await.unwrap();
    }

    #[test]
    fn at_the_limit_the_oldest_quiet_connection_makes_room() {
        let slots: Arc<Mutex<Slots>> = Arc::default();
        let stops: Vec<CancellationToken> = (0..4).map(|_| CancellationToken::new()).collect();
        let taken: Vec<Slot> = stops
            .iter()
            .take(3)
            .map(|stop| Slots::take(&slots, LIMITS, stop.clone()).unwrap().0)
            .collect();
        taken[0].activity.completed();
        // Full: the second (the oldest that has not completed a request) is closed.
        let (fourth, evicted) = Slots::take(&slots, LIMITS, stops[3].clone()).unwrap();
        assert!(evicted);
        assert!(!stops[0].is_cancelled() && stops[1].is_cancelled());
        // Every connection has completed a request: the next one is refused.
        taken[2].activity.completed();
        fourth.activity.completed();
        assert!(Slots::take(&slots, LIMITS, CancellationToken::new()).is_none());
        // Unless one has begun a request and not ended it (a slow sender): the one whose
        // request began first makes room.
        taken[2].activity.unfinished(true);
        std::thread::sleep(Duration::from_millis(5));
        fourth.activity.unfinished(true);
        let (_fifth, evicted) = Slots::take(&slots, LIMITS, CancellationToken::new()).unwrap();
        assert!(evicted && stops[2].is_cancelled() && !stops[3].is_cancelled());
        drop(taken);
        assert!(Slots::take(&slots, LIMITS, CancellationToken::new()).is_some());
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
