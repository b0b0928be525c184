//! Test harness: a real server on port 0 and raw-line clients.
#![allow(dead_code, unreachable_pub)]

use std::net::SocketAddr;
use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use usar_proto::{SenData, ServerMessage, Vec3};
use usar_server::{LocalServer, ServerConfig, TimeScale};

/// Wall-clock limit for any single wait in a test (a hang fails instead of blocking CI).
pub const PATIENCE: Duration = Duration::from_secs(60);

pub struct TestServer {
    pub addr: SocketAddr,
    server: LocalServer,
}

impl TestServer {
    /// The embedded defaults, simulated 10× faster than real time.
    pub async fn start() -> Self {
        Self::with(ServerConfig {
            time_scale: TimeScale::Factor(10.0),
            ..ServerConfig::default()
        })
        .await
    }

    pub async fn with(config: ServerConfig) -> Self {
        let server = LocalServer::start(config).await.unwrap();
        Self {
            addr: server.addr(),
            server,
        }
    }

    pub async fn client(&self) -> Client {
        Client::connect(self.addr).await
    }

    /// Stops the server and checks that it exits cleanly.
    pub async fn stop(self) {
        self.server.stop().await.expect("the server stops cleanly");
    }
}

pub struct Client {
    pub reader: BufReader<OwnedReadHalf>,
    pub writer: OwnedWriteHalf,
}

impl Client {
    pub async fn connect(addr: SocketAddr) -> Self {
        let stream = TcpStream::connect(addr).await.unwrap();
        // A line and its CR LF go in two writes: without this, Nagle holds the second until
        // the server's delayed ACK (40 ms a line).
        stream.set_nodelay(true).unwrap();
        let (r, w) = stream.into_split();
        Self {
            reader: BufReader::new(r),
            writer: w,
        }
    }

    /// Connects from another loopback address (`127.0.0.N`): the per-address limit counts
    /// each separately.
    pub async fn connect_from(addr: SocketAddr, n: u8) -> Self {
        let socket = tokio::net::TcpSocket::new_v4().unwrap();
        socket.bind(SocketAddr::from(([127, 0, 0, n], 0))).unwrap();
        let stream = socket.connect(addr).await.unwrap();
        stream.set_nodelay(true).unwrap();
        let (r, w) = stream.into_split();
        Self {
            reader: BufReader::new(r),
            writer: w,
        }
    }

    pub async fn send(&mut self, line: &str) {
        self.writer.write_all(line.as_bytes()).await.unwrap();
        self.writer.write_all(b"\r\n").await.unwrap();
    }

    /// The next raw line with its terminator, or `None` at EOF.
    pub async fn raw_line(&mut self) -> Option<String> {
        let mut line = String::new();
        let n = tokio::time::timeout(PATIENCE, self.reader.read_line(&mut line))
            .await
            .expect("no line from the server in time")
            .unwrap();
        (n > 0).then_some(line)
    }

    /// The next line, checked to end with CR LF, and parsed.
    pub async fn message(&mut self) -> (String, ServerMessage) {
        let line = self.raw_line().await.expect("unexpected EOF");
        assert!(
            line.ends_with("\r\n"),
            "line not terminated by CR LF: {line:?}"
        );
        let text = line.trim_end_matches("\r\n").to_owned();
        let parsed = ServerMessage::parse(&text)
            .unwrap_or_else(|e| panic!("server sent an unreadable line {text:?}: {e}"));
        (text, parsed.message)
    }

    /// Reads until `pick` returns `Some`, skipping everything else.
    pub async fn until<T>(&mut self, mut pick: impl FnMut(&ServerMessage) -> Option<T>) -> T {
        loop {
            let (_, m) = self.message().await;
            if let Some(t) = pick(&m) {
                return t;
            }
        }
    }

    /// The next Position reading: (time, location).
    pub async fn position(&mut self) -> (f64, Vec3) {
        self.until(|m| match m {
            ServerMessage::Sen(s) => match &s.data {
                SenData::Position { location, .. } => Some((s.time.unwrap().seconds, *location)),
                _ => None,
            },
            _ => None,
        })
        .await
    }

    /// The next IMU reading: (time, rotation).
    pub async fn rotation(&mut self) -> (f64, Vec3) {
        self.until(|m| match m {
            ServerMessage::Sen(s) => match &s.data {
                SenData::Imu { rotation, .. } => Some((s.time.unwrap().seconds, *rotation)),
                _ => None,
            },
            _ => None,
        })
        .await
    }

    /// The next reading of the sonar called `name`: (time, range).
    pub async fn sonar(&mut self, name: &str) -> (f64, f64) {
        self.until(|m| match m {
            ServerMessage::Sen(s) => match &s.data {
                SenData::Sonar { readings, .. } => readings
                    .iter()
                    .find(|r| r.name == name)
                    .map(|r| (s.time.unwrap().seconds, r.range)),
                _ => None,
            },
            _ => None,
        })
        .await
    }

    /// The next laser scan's ranges.
    pub async fn scan(&mut self) -> Vec<f64> {
        self.until(|m| match m {
            ServerMessage::Sen(s) => match &s.data {
                SenData::RangeScanner(scan) => Some(scan.ranges.clone()),
                _ => None,
            },
            _ => None,
        })
        .await
    }

    /// Reads the NFO, sends INIT for an stsAirRobot at `location` (yaw `yaw`) and waits for
    /// the first STA.
    pub async fn spawn_at(&mut self, location: [f64; 3], yaw: f64) {
        let [x, y, z] = location;
        self.send(&format!(
            "INIT {{ClassName USARBot.stsAirRobot}} {{Name UAV}} {{Location {x},{y},{z}}} {{Rotation 0,0,{yaw}}}"
        ))
        .await;
        self.until(|m| matches!(m, ServerMessage::Sta(_)).then_some(()))
            .await;
    }
}

pub fn distance(a: Vec3, b: Vec3) -> f64 {
    ((a.x - b.x).powi(2) + (a.y - b.y).powi(2) + (a.z - b.z).powi(2)).sqrt()
}

/// The `usar-server` program (`USAR_SERVER_BIN=path` tests another build).
pub fn program() -> std::process::Command {
    std::process::Command::new(
        std::env::var_os("USAR_SERVER_BIN")
            .unwrap_or_else(|| env!("CARGO_BIN_EXE_usar-server").into()),
    )
}

/// Starts the program with `args`, its stderr into `stderr`; returns it and the first line
/// it printed (its ready line).
pub fn start_program<S: AsRef<std::ffi::OsStr>>(
    args: &[S],
    stderr: std::process::Stdio,
) -> (std::process::Child, String) {
    use std::io::BufRead;
    let mut child = program()
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(stderr)
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    (child, line)
}

/// Sends the program SIGTERM.
pub fn terminate(child: &std::process::Child) {
    std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
}
