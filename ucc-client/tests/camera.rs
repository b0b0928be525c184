//! The image client against a real image server: the latest frame, raw and JPEG.

use std::io::{Read, Write};

use tokio_util::sync::CancellationToken;
use ucc_client::camera::ImageClient;
use usar_server::{ImageConfig, ServerConfig, SideListeners};

async fn server(
    image: ImageConfig,
    map: &str,
) -> (
    std::net::SocketAddr,
    std::net::SocketAddr,
    CancellationToken,
) {
    let main = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let side = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addrs = (main.local_addr().unwrap(), side.local_addr().unwrap());
    let shutdown = CancellationToken::new();
    let config = ServerConfig {
        image,
        map: usar_server::sim::Map::embedded(map).unwrap(),
        ..ServerConfig::default()
    };
    let token = shutdown.clone();
    tokio::spawn(async move {
        let side = SideListeners {
            image: Some(side),
            ..SideListeners::default()
        };
        usar_server::run_with(main, side, config, token)
            .await
            .unwrap();
    });
    (addrs.0, addrs.1, shutdown)
}

/// An AirRobot at `start`, spawned over the Gamebots port on a blocking thread.
fn air_robot(addr: std::net::SocketAddr, start: &str) -> std::net::TcpStream {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.write_all(format!("INIT {{ClassName USARBot.AirRobot}} {{Start {start}}}\r\n").as_bytes())
        .unwrap();
    let (mut seen, mut buf) = (Vec::new(), [0u8; 4096]);
    while !String::from_utf8_lossy(&seen).contains("STA {") {
        let n = s.read(&mut buf).unwrap();
        assert!(n > 0);
        seen.extend_from_slice(&buf[..n]);
    }
    s
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_client_keeps_the_latest_frame_raw_or_jpeg() {
    for (kind, map) in [(0u8, "city"), (2, "empty_room")] {
        let config = ImageConfig {
            kind,
            ..ImageConfig::default()
        };
        let (main, image, shutdown) = server(config, map).await;
        let robot = tokio::task::spawn_blocking(move || air_robot(main, "Start1"))
            .await
            .unwrap();
        let mut client = ImageClient::connect(image, true).await.unwrap();
        let first = client.next(None).await.expect("a frame");
        let later = client
            .next(Some(first.index + 1))
            .await
            .expect("more frames");
        assert!(later.index > first.index + 1);
        assert_eq!((later.width, later.height), (640, 480));
        let sky = usar_server::sim::render::SKY;
        let px = |x: usize, y: usize| {
            let i = 3 * (y * 640 + x);
            [later.rgb[i], later.rgb[i + 1], later.rgb[i + 2]]
        };
        if kind == 0 {
            // Raw: exact colours. In the city, the sky above, the ground below; tile 3 black.
            assert_eq!(px(160, 2), sky);
            assert_ne!(px(160, 238), sky);
            assert_eq!(px(480, 360), [0, 0, 0]);
        }
        let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
        image::save_buffer(
            dir.join(format!("image-client-{map}-type{kind}.png")),
            &later.rgb,
            later.width,
            later.height,
            image::ColorType::Rgb8,
        )
        .unwrap();
        assert!(client.latest().is_some());
        client.close().await.unwrap();
        drop(robot);
        shutdown.cancel();
    }
}
