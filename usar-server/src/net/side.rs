//! What the side servers (USARTruth on 3989, the robot monitor on 7435) share: questions to
//! the simulation thread, the accept loop with its connection limit, and bounded line reading.

use std::sync::Arc;
use std::sync::mpsc::Sender;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{Semaphore, oneshot};
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{info, warn};

use super::driver::{Ask, Request};
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

/// Accepts connections on `listener` until `shutdown`, at most [`MAX_CONNECTIONS`] at once,
/// and serves each with `serve` on `tracker`.
pub(super) async fn accept<F, Fut>(
    service: &'static str,
    listener: TcpListener,
    tracker: TaskTracker,
    shutdown: CancellationToken,
    serve: F,
) where
    F: Fn(TcpStream, CancellationToken) -> Fut + Send + 'static,
    Fut: std::future::Future<Output = ()> + Send + 'static,
{
    let slots = Arc::new(Semaphore::new(MAX_CONNECTIONS));
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
        let Ok(permit) = slots.clone().try_acquire_owned() else {
            warn!(service, %peer, max = MAX_CONNECTIONS, "too many connections; closing");
            continue;
        };
        info!(service, %peer, "connected");
        let _ = stream.set_nodelay(true);
        let done = serve(stream, shutdown.child_token());
        tracker.spawn(async move {
            done.await;
            drop(permit);
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
        tracker.clone(),
        shutdown,
        move |stream, stop| answer_lines(service, stream, requests.clone(), stop, answer),
    )
    .await;
}

async fn answer_lines(
    service: &'static str,
    stream: TcpStream,
    requests: Sender<Request>,
    stop: CancellationToken,
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
            Ok(line) => String::from_utf8_lossy(&line).into_owned(),
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
    fn blocks_skip_a_leading_word_and_trim() {
        assert_eq!(
            blocks("GETOBS {From  A } {To B C}"),
            vec![("From", "A"), ("To", "B C")]
        );
        assert_eq!(blocks("\u{0}\u{ff}garbage{"), vec![]);
    }
}
