//! The image server (UPIS, TCP 5003; docs/camera.md): the robots' camera pictures as one
//! frame of tiles, raw or JPEG, one frame per `OK` (a rectangle of it per `U`), and one on
//! connect in legacy mode.
//!
//! Capture: the driver renders every camera (`World::render_cameras`) only when a client
//! waits for a frame ([`Feed::wanted`]), at most once per [`ImageConfig::interval`] of
//! simulated time while the world runs, and while it stands still (a lockstep barrier,
//! an empty world) at most every [`STILL_INTERVAL`] of wall time — so a frame asked for
//! at a barrier shows the world at the barrier's time. The frame is composed and encoded
//! once and shared by every client ([`Captured`], through a `watch` channel). A client
//! gets each frame at most once: a request waits for the first frame newer than the last
//! one it got.
//!
//! Clients never slow the world or each other: the driver only publishes the latest frame;
//! each session writes to its own socket, one frame at a time, and reads the next request
//! only after answering the last (a client that does not read holds only itself up, with
//! one frame in flight: TCP back-pressure bounds the rest).

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use bytes::Bytes;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use tracing::{debug, info, warn};
use usar_proto::image::{self, ImageRequest, RequestParser};
use usar_proto::shown::Repeats;

use super::request::Request;
use super::side::{Activity, Limits};
use crate::sim::{CameraFrame, Tiles, World};

/// While the world stands still, the least wall time between two captures.
pub const STILL_INTERVAL: Duration = Duration::from_millis(66);

/// How the image server sends its frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageConfig {
    /// The type byte of every frame: 0 raw, 1..=5 JPEG of quality SUPER, GOOD, NORMAL,
    /// FAIR, BAD (USARSim's `ImageType`; its ini sets 0).
    pub kind: u8,
    /// Send one frame as soon as a client connects (USARSim's `LegacyMode`; on by default
    /// here, so that both real client styles work: docs/camera.md).
    pub legacy: bool,
    /// Raw pixels as B, G, R (as the original server sent them); `false`: R, G, B.
    pub bgr: bool,
    /// Simulated seconds between captures while the world runs (USARSim's cameras: 15 Hz).
    pub interval: f64,
}

impl Default for ImageConfig {
    fn default() -> Self {
        Self {
            kind: image::RAW,
            legacy: true,
            bgr: true,
            interval: 1.0 / 15.0,
        }
    }
}

/// One captured frame, shared by every client.
#[derive(Debug)]
pub(super) struct Captured {
    /// Captures so far (1 for the first).
    seq: u64,
    width: u16,
    height: u16,
    /// The whole frame, R, G, B.
    rgb: Vec<u8>,
    /// The whole frame as sent for `OK`: header and payload.
    full: Bytes,
}

/// What the driver and the image sessions share.
#[derive(Debug)]
pub(super) struct Feed {
    /// A client waits for a frame newer than the latest.
    wanted: AtomicBool,
    frames: watch::Sender<Option<Arc<Captured>>>,
}

impl Feed {
    pub(super) fn new() -> Arc<Self> {
        Arc::new(Self {
            wanted: AtomicBool::new(false),
            frames: watch::Sender::new(None),
        })
    }
}

/// The driver's side: renders, composes and encodes frames when asked.
pub(super) struct Capture {
    feed: Arc<Feed>,
    config: ImageConfig,
    tiles: Tiles,
    /// Simulated and wall time of the last capture.
    last: Option<(f64, Instant)>,
    seq: u64,
    cameras: Vec<CameraFrame>,
}

impl Capture {
    pub(super) fn new(feed: Arc<Feed>, config: ImageConfig, tiles: Tiles) -> Self {
        Self {
            feed,
            config,
            tiles,
            last: None,
            seq: 0,
            cameras: Vec::new(),
        }
    }

    /// Captures a frame if a client waits for one and it is time (`running`: the world is
    /// stepping; otherwise it stands still).
    pub(super) fn poll(&mut self, world: &World, running: bool) {
        if !self.feed.wanted.load(Ordering::SeqCst) {
            return;
        }
        let now = world.time();
        let due = match self.last {
            None => true,
            Some((time, at)) => {
                if running {
                    now - time >= self.config.interval - 1e-9
                } else {
                    now != time || at.elapsed() >= STILL_INTERVAL
                }
            }
        };
        if !due {
            return;
        }
        self.feed.wanted.store(false, Ordering::SeqCst);
        self.last = Some((now, Instant::now()));
        world.render_cameras(&mut self.cameras);
        let (width, height, rgb) = compose(&self.cameras, self.tiles);
        let full = encode(&self.config, width, height, &rgb);
        self.seq += 1;
        self.feed.frames.send_replace(Some(Arc::new(Captured {
            seq: self.seq,
            width,
            height,
            rgb,
            full,
        })));
    }
}

/// The frame: each camera's picture scaled (nearest pixel) into its tile; tiles outside
/// the grid are not shown; the rest is black.
fn compose(cameras: &[CameraFrame], tiles: Tiles) -> (u16, u16, Vec<u8>) {
    let (tw, th) = (tiles.width as usize, tiles.height as usize);
    let (w, h) = (tw * tiles.columns as usize, th * tiles.rows as usize);
    let mut rgb = vec![0u8; 3 * w * h];
    let shown = tiles.columns as usize * tiles.rows as usize;
    for camera in cameras.iter().filter(|c| c.tile < shown) {
        let (ox, oy) = tiles.offset(camera.tile);
        let (ox, oy) = (ox as usize, oy as usize);
        let image = &camera.image;
        let (iw, ih) = (image.width as usize, image.height as usize);
        if iw == 0 || ih == 0 {
            continue;
        }
        for ty in 0..th {
            let sy = ty * ih / th;
            let row = 3 * ((oy + ty) * w + ox);
            if iw == tw && ih == th {
                rgb[row..row + 3 * tw].copy_from_slice(&image.rgb[3 * sy * iw..3 * (sy + 1) * iw]);
                continue;
            }
            for tx in 0..tw {
                let s = 3 * (sy * iw + tx * iw / tw);
                rgb[row + 3 * tx..row + 3 * tx + 3].copy_from_slice(&image.rgb[s..s + 3]);
            }
        }
    }
    (w as u16, h as u16, rgb)
}

/// A frame (header and payload) of `config.kind` from R, G, B pixels.
fn encode(config: &ImageConfig, width: u16, height: u16, rgb: &[u8]) -> Bytes {
    let mut payload = Vec::new();
    let kind = config.kind;
    if (1..=5).contains(&kind) {
        let quality = image::JPEG_QUALITY[usize::from(kind - 1)];
        let encoder = jpeg_encoder::Encoder::new(&mut payload, quality);
        if let Err(error) = encoder.encode(rgb, width, height, jpeg_encoder::ColorType::Rgb) {
            // Only for sizes the configuration refuses (more than 65535 pixels a side).
            warn!(%error, width, height, "JPEG encoding failed; sending an empty frame");
            payload.clear();
        }
    } else {
        image::raw_payload(width, height, rgb, config.bgr, &mut payload);
    }
    let mut out = Vec::with_capacity(5 + payload.len());
    out.extend_from_slice(&image::frame_header(kind, payload.len() as u32));
    out.extend_from_slice(&payload);
    Bytes::from(out)
}

/// Accepts image clients until `shutdown` (the side services' limits, without the idle
/// timeout: a client may only read the frame sent on connect); each is served on its own
/// task.
pub(super) async fn accept(
    listener: TcpListener,
    feed: Arc<Feed>,
    wake: std::sync::mpsc::Sender<Request>,
    (config, limits): (ImageConfig, Limits),
    shutdown: CancellationToken,
    tracker: TaskTracker,
) {
    let limits = Limits {
        idle: None,
        ..limits
    };
    super::side::accept(
        "image server",
        listener,
        limits,
        tracker,
        shutdown,
        move |stream, stop, activity| {
            serve(stream, feed.clone(), wake.clone(), config, stop, activity)
        },
    )
    .await;
}

/// Serves one image client until it leaves, the socket fails or the server shuts down.
async fn serve(
    mut stream: TcpStream,
    feed: Arc<Feed>,
    wake: std::sync::mpsc::Sender<Request>,
    config: ImageConfig,
    shutdown: CancellationToken,
    activity: Arc<Activity>,
) {
    let Ok(peer) = stream.peer_addr() else {
        return;
    };
    let mut frames = feed.frames.subscribe();
    let mut parser = RequestParser::default();
    let mut pending: VecDeque<ImageRequest> = VecDeque::new();
    if config.legacy {
        pending.push_back(ImageRequest::Full);
    }
    let (mut got, mut requests, mut buf) = (0u64, Vec::new(), vec![0u8; 4096]);
    let mut outside = Repeats::default();
    // The frame sent on connect was not asked for: a client that has already left (connection
    // churn) gets none rendered or written into its closed socket.
    let mut unasked = config.legacy;
    loop {
        while let Some(request) = pending.pop_front() {
            if std::mem::take(&mut unasked) {
                match stream.try_read(&mut buf) {
                    Ok(0) => {
                        debug!(%peer, "image client left before its first frame");
                        return;
                    }
                    Ok(n) => {
                        parser.push(&buf[..n], &mut requests);
                        if !requests.is_empty() {
                            activity.completed();
                        }
                        pending.extend(requests.drain(..));
                    }
                    Err(_) => {}
                }
            }
            // The first frame newer than the last one this client got.
            feed.wanted.store(true, Ordering::SeqCst);
            let _ = wake.send(Request::Wake);
            let frame = tokio::select! {
                _ = shutdown.cancelled() => return,
                frame = frames.wait_for(|f| f.as_ref().is_some_and(|f| f.seq > got)) => {
                    match frame {
                        Ok(frame) => frame.clone().expect("waited for a frame"),
                        Err(_) => return, // the server is gone
                    }
                }
            };
            got = frame.seq;
            let bytes = match request {
                ImageRequest::Full => frame.full.clone(),
                ImageRequest::Rect {
                    x,
                    y,
                    width,
                    height,
                } => {
                    match image::crop(frame.width, frame.height, &frame.rgb, x, y, width, height) {
                        Some((w, h, rgb)) => encode(&config, w, h, &rgb),
                        None => {
                            if let Some(count) = outside.note() {
                                warn!(%peer, x, y, width, height, frame_width = frame.width,
                                frame_height = frame.height, count,
                                "image request U: the rectangle has no pixel in the frame; \
                                 not answered");
                            }
                            continue;
                        }
                    }
                }
            };
            let written = tokio::select! {
                _ = shutdown.cancelled() => return,
                written = stream.write_all(&bytes) => written,
            };
            if let Err(error) = written {
                debug!(%peer, %error, "image client: write failed");
                return;
            }
        }
        let read = tokio::select! {
            _ = shutdown.cancelled() => return,
            read = activity.read(&mut stream, &mut buf, parser.is_partial()) => read,
        };
        let read = match read {
            Ok(read) => read,
            Err(why) => {
                info!(%peer, "image client: closing: {why}");
                return;
            }
        };
        match read {
            Ok(0) => {
                if parser.is_partial() {
                    debug!(%peer, "image client left in the middle of a request");
                }
                return;
            }
            Ok(n) => {
                requests.clear();
                parser.push(&buf[..n], &mut requests);
                if !requests.is_empty() {
                    activity.completed();
                }
                pending.extend(requests.drain(..));
            }
            Err(error) => {
                debug!(%peer, %error, "image client: read failed");
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::Image;

    fn camera(tile: usize, width: u32, height: u32, color: [u8; 3]) -> CameraFrame {
        let mut image = Image::new(width, height);
        for px in image.rgb.chunks_mut(3) {
            px.copy_from_slice(&color);
        }
        CameraFrame {
            tile,
            image,
            ..CameraFrame::default()
        }
    }

    #[test]
    fn cameras_go_to_their_tiles_scaled_and_beyond_the_grid_are_not_shown() {
        let tiles = Tiles::default();
        let cameras = [
            camera(0, 320, 240, [255, 0, 0]),
            camera(1, 64, 48, [0, 255, 0]),
            camera(3, 640, 480, [0, 0, 255]),
            camera(4, 320, 240, [9, 9, 9]),
        ];
        let (w, h, rgb) = compose(&cameras, tiles);
        assert_eq!((w, h), (640, 480));
        let px = |x: usize, y: usize| &rgb[3 * (y * 640 + x)..3 * (y * 640 + x) + 3];
        assert_eq!(px(0, 0), [255, 0, 0]);
        assert_eq!(px(319, 239), [255, 0, 0]);
        assert_eq!(px(320, 0), [0, 255, 0]);
        assert_eq!(px(639, 239), [0, 255, 0]);
        assert_eq!(px(0, 240), [0, 0, 0], "tile 2 has no camera");
        assert_eq!(px(320, 240), [0, 0, 255]);
        assert!(!rgb.chunks(3).any(|p| p == [9, 9, 9]));
    }
}
