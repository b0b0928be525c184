//! The image server (port 5003) with real client behaviour: UsarCommander (waits for the
//! frame sent on connect, then sends `OK` after each frame), the LCM proxy (`OK` first),
//! `U` rectangles, JPEG frames, bad requests and a client that never reads.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use tokio_util::sync::CancellationToken;
use usar_proto::image::{FrameParser, ImageRequest, decode_raw};
use usar_server::{ImageConfig, ServerConfig, SideListeners, TimeScale};

/// A server with an image server; returns the Gamebots and image addresses.
fn start(
    image: ImageConfig,
) -> (
    std::net::SocketAddr,
    std::net::SocketAddr,
    CancellationToken,
) {
    start_with(ServerConfig {
        image,
        time_scale: TimeScale::Factor(1.0),
        ..ServerConfig::default()
    })
}

/// [`start`] with any configuration.
fn start_with(
    config: ServerConfig,
) -> (
    std::net::SocketAddr,
    std::net::SocketAddr,
    CancellationToken,
) {
    let (tx, rx) = std::sync::mpsc::channel();
    let shutdown = CancellationToken::new();
    let token = shutdown.clone();
    std::thread::spawn(move || {
        let runtime = tokio::runtime::Runtime::new().unwrap();
        runtime.block_on(async move {
            let main = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
            let side = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
            tx.send((main.local_addr().unwrap(), side.local_addr().unwrap()))
                .unwrap();
            let side = SideListeners {
                image: Some(side),
                ..SideListeners::default()
            };
            usar_server::run_with(main, side, config, token)
                .await
                .unwrap();
        });
    });
    let (main, image) = rx.recv().unwrap();
    (main, image, shutdown)
}

/// Spawns an AirRobot at `start` over the Gamebots port (the connection keeps it).
fn air_robot(addr: std::net::SocketAddr, start: &str) -> TcpStream {
    let mut s = TcpStream::connect(addr).unwrap();
    s.write_all(format!("INIT {{ClassName USARBot.AirRobot}} {{Start {start}}}\r\n").as_bytes())
        .unwrap();
    // Wait for its first STA: the robot exists.
    let mut seen = Vec::new();
    let mut buf = [0u8; 4096];
    while !String::from_utf8_lossy(&seen).contains("STA {") {
        let n = s.read(&mut buf).unwrap();
        assert!(n > 0);
        seen.extend_from_slice(&buf[..n]);
    }
    s
}

struct Client {
    stream: TcpStream,
    parser: FrameParser,
}

impl Client {
    fn connect(addr: std::net::SocketAddr) -> Self {
        let stream = TcpStream::connect(addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(30)))
            .unwrap();
        Self {
            stream,
            parser: FrameParser::new(64 << 20),
        }
    }

    fn send(&mut self, bytes: &[u8]) {
        self.stream.write_all(bytes).unwrap();
    }

    fn frame(&mut self) -> usar_proto::image::Frame {
        let mut buf = vec![0u8; 65536];
        loop {
            if let Some(frame) = self.parser.next_frame().unwrap() {
                return frame;
            }
            let n = self.stream.read(&mut buf).expect("a frame in time");
            assert!(n > 0, "the server closed the connection");
            self.parser.push(&buf[..n]);
        }
    }

    /// No frame within `wait`.
    fn nothing_for(&mut self, wait: Duration) -> bool {
        self.stream.set_read_timeout(Some(wait)).unwrap();
        let mut buf = [0u8; 16];
        let quiet = matches!(self.stream.read(&mut buf), Err(e)
            if e.kind() == std::io::ErrorKind::WouldBlock || e.kind() == std::io::ErrorKind::TimedOut);
        self.stream
            .set_read_timeout(Some(Duration::from_secs(30)))
            .unwrap();
        quiet
    }
}

/// The latest `STA {Time t}` among the lines a Gamebots connection sends within `wait`.
fn latest_sta(s: &mut TcpStream, wait: Duration) -> f64 {
    s.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
    let end = std::time::Instant::now() + wait;
    let (mut text, mut buf) = (String::new(), vec![0u8; 1 << 16]);
    while std::time::Instant::now() < end {
        if let Ok(n) = s.read(&mut buf) {
            assert!(n > 0, "the robot's connection closed");
            text.push_str(&String::from_utf8_lossy(&buf[..n]));
        }
    }
    text.match_indices("STA {Time ")
        .filter_map(|(i, m)| {
            let rest = &text[i + m.len()..];
            rest[..rest.find('}')?].parse::<f64>().ok()
        })
        .fold(f64::NAN, f64::max)
}

fn pixel(rgb: &[u8], width: usize, x: usize, y: usize) -> [u8; 3] {
    let i = 3 * (y * width + x);
    [rgb[i], rgb[i + 1], rgb[i + 2]]
}

#[test]
fn a_usarcommander_style_client_gets_a_frame_on_connect_then_one_per_ok() {
    let (main, addr, shutdown) = start(ImageConfig::default());
    let _robot = air_robot(main, "Start1");
    let mut client = Client::connect(addr);
    // It never sends first: the frame on connect (legacy mode) starts the exchange.
    let first = client.frame();
    assert_eq!(first.kind, 0, "raw by default (USARSim's ImageType=0)");
    let (w, h, rgb) = decode_raw(&first.payload, true).unwrap();
    assert_eq!((w, h), (640, 480), "a 2 x 2 grid of 320 x 240 tiles");
    // Tile 0 is the robot's camera: the room's walls and floor, no black; tile 3 is empty.
    assert_ne!(pixel(&rgb, 640, 160, 120), [0, 0, 0]);
    assert_ne!(pixel(&rgb, 640, 160, 120), pixel(&rgb, 640, 160, 235));
    assert_eq!(pixel(&rgb, 640, 480, 360), [0, 0, 0]);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    image::save_buffer(
        dir.join("image-server-frame.png"),
        &rgb,
        640,
        480,
        image::ColorType::Rgb8,
    )
    .unwrap();
    for _ in 0..3 {
        client.send(b"OK");
        let frame = client.frame();
        assert_eq!(frame.payload.len(), first.payload.len());
    }
    // The B, G, R order of the original server: read as R, G, B the colours swap.
    let (_, _, swapped) = decode_raw(&first.payload, false).unwrap();
    let [r, g, b] = pixel(&rgb, 640, 160, 120);
    assert_eq!(pixel(&swapped, 640, 160, 120), [b, g, r]);
    shutdown.cancel();
}

#[test]
fn an_lcm_proxy_style_client_sends_ok_first_and_gets_jpeg_frames() {
    let config = ImageConfig {
        legacy: false,
        kind: 3,
        ..ImageConfig::default()
    };
    let (main, addr, shutdown) = start(config);
    let _robot = air_robot(main, "Start1");
    let mut client = Client::connect(addr);
    assert!(
        client.nothing_for(Duration::from_millis(300)),
        "no frame on connect"
    );
    client.send(b"OK\r\n");
    for _ in 0..3 {
        let frame = client.frame();
        assert_eq!(frame.kind, 3, "NORMAL JPEG");
        let decoded = image::load_from_memory(&frame.payload).unwrap().to_rgb8();
        assert_eq!(decoded.dimensions(), (640, 480));
        client.send(b"OK");
    }
    // A rectangle: the robot's own tile, as UsarCommander would crop it.
    client.frame();
    let rect = ImageRequest::Rect {
        x: 0,
        y: 0,
        width: 320,
        height: 240,
    };
    client.send(&rect.to_bytes());
    let tile = client.frame();
    let decoded = image::load_from_memory(&tile.payload).unwrap().to_rgb8();
    assert_eq!(decoded.dimensions(), (320, 240));
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    decoded.save(dir.join("image-server-tile.png")).unwrap();
    shutdown.cancel();
}

#[test]
fn bad_requests_get_no_frame_and_do_not_hurt_the_connection_or_others() {
    let (main, addr, shutdown) = start(ImageConfig {
        legacy: false,
        ..ImageConfig::default()
    });
    let mut robot = air_robot(main, "Start1");
    // A client that asks for frames and never reads them.
    let mut hog = TcpStream::connect(addr).unwrap();
    hog.set_write_timeout(Some(Duration::from_secs(2))).unwrap();
    let mut client = Client::connect(addr);
    // Outside the frame, zero-sized, absurd: no answer; garbage is skipped.
    for rect in [
        (640, 0, 10, 10),
        (0, 0, 0, 10),
        (u32::MAX, u32::MAX, u32::MAX, u32::MAX),
    ] {
        let request = ImageRequest::Rect {
            x: rect.0,
            y: rect.1,
            width: rect.2,
            height: rect.3,
        };
        client.send(&request.to_bytes());
    }
    client.send(b"\x00\xffgarbage OX");
    assert!(client.nothing_for(Duration::from_millis(500)));
    // Partly outside: clipped to the frame.
    let request = ImageRequest::Rect {
        x: 600,
        y: 470,
        width: 1000,
        height: 1000,
    };
    client.send(&request.to_bytes());
    let (w, h, _) = decode_raw(&client.frame().payload, true).unwrap();
    assert_eq!((w, h), (40, 10));
    // The hog floods OKs without reading; the other client still gets frame after frame,
    // and the world goes on (the robot's STA lines keep coming, their time increasing).
    let before = latest_sta(&mut robot, Duration::from_millis(300));
    for _ in 0..2000 {
        if hog.write_all(b"OK").is_err() {
            break;
        }
    }
    let start = std::time::Instant::now();
    for _ in 0..5 {
        client.send(b"OK");
        client.frame();
    }
    assert!(start.elapsed() < Duration::from_secs(20));
    let after = latest_sta(&mut robot, Duration::from_secs(1));
    assert!(
        after > before + 0.5,
        "the world stalled: STA time {before} then {after}"
    );
    // A truncated U, then the client leaves: the server serves the next client.
    client.send(&request.to_bytes()[..7]);
    drop(client);
    let mut next = Client::connect(addr);
    next.send(b"OK");
    next.frame();
    shutdown.cancel();
}

/// Issue 20: in lockstep, a frame asked for at a barrier shows the world at the barrier's
/// simulated time. A camera robot flies towards the empty room's far wall; the frame taken
/// at the barrier of t = 1 s equals the picture a fresh world renders with the robot where
/// its Position sensor says it was at t = 1 s, and not the one of a step (0.1 s) before.
#[test]
fn a_frame_at_a_lockstep_barrier_shows_the_barriers_time() {
    use usar_server::sim::{RobotCatalog, SimConfig, World};
    // The stsAirRobot (Position sensor, kinematic, level) with the AirRobot's camera.
    let mut robots = RobotCatalog::embedded();
    let mut camera = robots
        .get("USARBot.AirRobot")
        .unwrap()
        .parts
        .iter()
        .find(|p| p.kind == "Camera")
        .unwrap()
        .clone();
    camera.settings.remove("mount");
    robots
        .get_mut("USARBot.stsAirRobot")
        .unwrap()
        .parts
        .push(camera);
    let config = ServerConfig {
        robots: robots.clone(),
        lockstep: true,
        time_scale: TimeScale::Max,
        image: ImageConfig {
            legacy: false,
            ..ImageConfig::default()
        },
        ..ServerConfig::default()
    };
    let map = config.map.clone();
    let (main, image, shutdown) = start_with(config);
    let mut images = Client::connect(image);
    let mut robot = TcpStream::connect(main).unwrap();
    robot
        .set_read_timeout(Some(Duration::from_secs(30)))
        .unwrap();
    let mut lines = std::io::BufReader::new(robot.try_clone().unwrap());
    // Reads up to the answer of the SYNC just sent; the Position readings by time.
    let mut positions = std::collections::BTreeMap::new();
    let mut until_sync = |positions: &mut std::collections::BTreeMap<String, [f64; 3]>| loop {
        let mut line = String::new();
        assert!(std::io::BufRead::read_line(&mut lines, &mut line).unwrap() > 0);
        if line.starts_with("SYNC {Time") {
            return;
        }
        if let Ok(p) = usar_proto::ServerMessage::parse(line.trim_end())
            && let usar_proto::ServerMessage::Sen(sen) = p.message
            && let usar_proto::SenData::Position { location, .. } = sen.data
        {
            let time = format!("{:.1}", sen.time.unwrap().seconds);
            positions.insert(time, [location.x, location.y, location.z]);
        }
    };
    robot.write_all(b"SYNC {Time 0}\r\n").unwrap();
    until_sync(&mut positions);
    robot
        .write_all(
            b"INIT {ClassName USARBot.stsAirRobot} {Location 0,0,-1.5} {Rotation 0,0,0}\r\n\
              DRIVE {LinearVelocity 1.5}\r\nSYNC {Time 1.0}\r\n",
        )
        .unwrap();
    until_sync(&mut positions);
    // The world stands at t = 1 s: the frame asked for now.
    images.send(b"OK");
    let (w, h, rgb) = decode_raw(&images.frame().payload, true).unwrap();
    assert_eq!((w, h), (640, 480));
    let tile: Vec<u8> = (0..240)
        .flat_map(|y| rgb[3 * y * 640..3 * (y * 640 + 320)].to_vec())
        .collect();
    // What the camera sees with the robot at `at`, in a world of its own.
    let render = |at: [f64; 3]| {
        let mut world = World::new(map.clone(), robots.clone(), SimConfig::default());
        let client = world.connect();
        let init = format!(
            "INIT {{ClassName USARBot.stsAirRobot}} {{Location {},{},{}}} {{Rotation 0,0,0}}",
            at[0], at[1], at[2]
        );
        world.command(client, usar_proto::Command::parse(&init).unwrap().message);
        let mut frames = Vec::new();
        world.render_cameras(&mut frames);
        frames.remove(0).image.rgb
    };
    let same = |a: &[u8], b: &[u8]| {
        a.chunks(3).zip(b.chunks(3)).filter(|(p, q)| p == q).count() as f64 / (320.0 * 240.0)
    };
    let (now, earlier) = (positions["1.0"], positions["0.9"]);
    assert!(now[0] - earlier[0] > 0.1, "the robot moved: {positions:?}");
    let at_barrier = same(&tile, &render(now));
    let a_step_before = same(&tile, &render(earlier));
    // Pixel for pixel the world at the barrier (the renderer is deterministic and the
    // positions exact); the world one lockstep step (0.1 s, 0.15 m) before differs.
    assert!(
        at_barrier == 1.0 && a_step_before < 0.995,
        "pixels equal to the world at t = 1 s: {at_barrier}, at t = 0.9 s: {a_step_before}"
    );
    shutdown.cancel();
}
