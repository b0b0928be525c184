//! Camera frames from an image server (USARSim's UPIS, TCP 5003; docs/camera.md).
//!
//! [`decode`] turns a frame (usar-proto's sans-I/O [`FrameParser`] reassembles them) into
//! R, G, B pixels; [`ImageClient`] is the small socket wrapper: it asks for a frame (`OK`)
//! after each one it receives — and once on connecting, so that servers with and without
//! legacy mode both answer — and keeps the latest.

use std::sync::Arc;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::sync::watch;
use usar_proto::image::{FrameParser, ImageRequest, decode_raw};

pub use usar_proto::image::Frame;

/// The largest frame accepted (bytes): 64 MiB, far above a 4096 × 4096 raw frame.
pub const MAX_FRAME: usize = 64 << 20;

/// A decoded camera frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CameraImage {
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// R, G, B, row by row from the top.
    pub rgb: Vec<u8>,
    /// Frames received on the connection before this one.
    pub index: u64,
}

impl CameraImage {
    /// The image as a PNG file's bytes.
    pub fn to_png(&self) -> Vec<u8> {
        let mut out = std::io::Cursor::new(Vec::new());
        image::write_buffer_with_format(
            &mut out,
            &self.rgb,
            self.width,
            self.height,
            image::ColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .expect("an RGB image of its own size encodes as PNG in memory");
        out.into_inner()
    }
}

/// A frame that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// A raw frame of the wrong size, or a frame past [`MAX_FRAME`].
    #[error("image server frame: {0}")]
    Frame(#[from] usar_proto::image::FrameError),
    /// A JPEG frame that does not decode.
    #[error("image server frame: bad JPEG: {0}")]
    Jpeg(String),
    /// The connection failed.
    #[error("image server: {0}")]
    Io(#[from] std::io::Error),
}

/// The pixels of a frame: raw (pixels B, G, R when `bgr`, as USARSim sends them) or JPEG.
pub fn decode(frame: &Frame, bgr: bool, index: u64) -> Result<CameraImage, CameraError> {
    if frame.kind == usar_proto::image::RAW {
        let (width, height, rgb) = decode_raw(&frame.payload, bgr)?;
        return Ok(CameraImage {
            width: u32::from(width),
            height: u32::from(height),
            rgb,
            index,
        });
    }
    let image = image::load_from_memory_with_format(&frame.payload, image::ImageFormat::Jpeg)
        .map_err(|e| CameraError::Jpeg(e.to_string()))?
        .to_rgb8();
    Ok(CameraImage {
        width: image.width(),
        height: image.height(),
        rgb: image.into_raw(),
        index,
    })
}

/// A connection to an image server that keeps the latest frame.
#[derive(Debug)]
pub struct ImageClient {
    latest: watch::Receiver<Option<Arc<CameraImage>>>,
    task: tokio::task::JoinHandle<Result<(), CameraError>>,
}

impl ImageClient {
    /// Connects and starts asking for frames (`bgr`: raw pixels come as B, G, R).
    pub async fn connect(addr: std::net::SocketAddr, bgr: bool) -> Result<Self, CameraError> {
        Self::connect_with(addr, bgr, ImageRequest::Full).await
    }

    /// Connects and asks `request` after each frame (a rectangle: one robot's tile).
    pub async fn connect_with(
        addr: std::net::SocketAddr,
        bgr: bool,
        request: ImageRequest,
    ) -> Result<Self, CameraError> {
        let ask = request.to_bytes();
        let mut stream = TcpStream::connect(addr).await?;
        let _ = stream.set_nodelay(true);
        let (tx, latest) = watch::channel(None);
        let task = tokio::spawn(async move {
            stream.write_all(&ask).await?;
            let mut parser = FrameParser::new(MAX_FRAME);
            let (mut buf, mut index) = (vec![0u8; 1 << 16], 0u64);
            loop {
                while let Some(frame) = parser.next_frame()? {
                    let image = decode(&frame, bgr, index)?;
                    index += 1;
                    tx.send_replace(Some(Arc::new(image)));
                    stream.write_all(&ask).await?;
                }
                let n = stream.read(&mut buf).await?;
                if n == 0 {
                    return Ok(());
                }
                parser.push(&buf[..n]);
            }
        });
        Ok(Self { latest, task })
    }

    /// The latest frame received, if any.
    pub fn latest(&self) -> Option<Arc<CameraImage>> {
        self.latest.borrow().clone()
    }

    /// Waits for a frame after the one numbered `after` (`None`: any frame); `None` when the
    /// connection has ended.
    pub async fn next(&mut self, after: Option<u64>) -> Option<Arc<CameraImage>> {
        let newer = |f: &Option<Arc<CameraImage>>| {
            f.as_ref()
                .is_some_and(|f| after.is_none_or(|a| f.index > a))
        };
        self.latest
            .wait_for(newer)
            .await
            .ok()
            .and_then(|f| f.clone())
    }

    /// Closes the connection; returns why it ended if it failed.
    pub async fn close(self) -> Result<(), CameraError> {
        self.task.abort();
        match self.task.await {
            Ok(result) => result,
            Err(_) => Ok(()),
        }
    }
}
