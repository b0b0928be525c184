//! The attack suite (docs/limits.md): each attack of issue #14, on loopback, against a fresh
//! `usar-server` process at real time, while a healthy client flies. Asserts that the healthy
//! client keeps at least 90 % of its baseline message rate (in one of [`ATTEMPTS`]) and that
//! the server's peak memory stays under [`MEMORY_BOUND_MIB`]; prints the figures.
//!
//! Bounded: every attack runs for [`ATTACK`] wall seconds (the whole suite takes about half a
//! minute), with bounded counts of connections and bytes.

use std::io::BufRead;
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;
use tokio_util::sync::CancellationToken;

/// How long the healthy client's rate is measured during each attack.
const ATTACK: Duration = Duration::from_secs(3);

/// Head start of the attack before the measurement begins (the attack goes on until the
/// measurement ends, which is at most `2 × ATTACK + 1 s` later).
const HEAD_START: Duration = Duration::from_millis(700);

/// The healthy client must keep this share of its baseline rate.
const MIN_SHARE: f64 = 0.9;

/// Attempts per attack: an attack that starves the healthy client does so every time; one
/// share under [`MIN_SHARE`] (a 2-core machine busy with other tests) is measured again on
/// a fresh server, and only a share under it in every attempt fails.
const ATTEMPTS: usize = 3;

/// Runs one attack on a fresh server (`start` starts it; with `side_ports`, each side port
/// must also answer a new client during it) up to [`ATTEMPTS`] times, until the healthy
/// client keeps [`MIN_SHARE`] of `baseline`; prints each attempt and adds to `failures` what
/// went wrong (memory, death and the side ports at every attempt, the share only when every
/// attempt was under).
async fn judge(
    name: &str,
    baseline: f64,
    failures: &mut Vec<String>,
    start: impl Fn(&Server, CancellationToken) -> tokio::task::JoinHandle<String>,
    (side_ports, args): (bool, &[&str]),
) {
    let mut shares = Vec::new();
    for _ in 0..ATTEMPTS {
        let mut server = Server::start(args);
        let stop = CancellationToken::new();
        let attacker = start(&server, stop.clone());
        tokio::time::sleep(Duration::from_millis(100)).await;
        let rate = healthy_rate(server.addr).await;
        // Under attack still, each side port answers a new client.
        let silent = if side_ports {
            unanswered(server.side).await
        } else {
            Vec::new()
        };
        let peak = server.peak_mib();
        stop.cancel();
        let what = attacker.await.unwrap();
        let share = rate / baseline;
        println!(
            "{name:<22} {rate:>10.1} {:>7.0}% {peak:>12.1}  {what}{}",
            share * 100.0,
            if silent.is_empty() {
                String::new()
            } else {
                format!("; not answering: {}", silent.join(", "))
            }
        );
        // NaN (no /proc) fails too.
        if peak.partial_cmp(&MEMORY_BOUND_MIB) != Some(std::cmp::Ordering::Less) {
            failures.push(format!("{name}: server peak memory {peak:.1} MiB"));
        }
        if !silent.is_empty() {
            failures.push(format!("{name}: {silent:?} did not answer a new client"));
        }
        if !server.alive() {
            failures.push(format!("{name}: the server died"));
        }
        shares.push(share);
        if share >= MIN_SHARE {
            return;
        }
    }
    let shown: Vec<String> = shares
        .iter()
        .map(|s| format!("{:.0} %", s * 100.0))
        .collect();
    failures.push(format!("{name}: healthy client at {}", shown.join(", ")));
}

/// The server's peak resident memory (VmHWM) during any attack, MiB (docs/limits.md).
const MEMORY_BOUND_MIB: f64 = 64.0;

struct Server {
    child: Child,
    addr: SocketAddr,
    side: Side,
}

/// The side ports of a server (each on a free port).
#[derive(Debug, Clone, Copy)]
struct Side {
    image: SocketAddr,
    truth: SocketAddr,
    monitor: SocketAddr,
    wss: SocketAddr,
}

impl Server {
    fn start(args: &[&str]) -> Self {
        // USAR_SERVER_BIN runs the suite against another build (an older one, to compare).
        let bin = std::env::var_os("USAR_SERVER_BIN")
            .unwrap_or_else(|| env!("CARGO_BIN_EXE_usar-server").into());
        let mut child = Command::new(bin)
            .args([
                "--port",
                "0",
                "--truth-port",
                "0",
                "--monitor-port",
                "0",
                "--wss-port",
                "0",
            ])
            .args(args)
            .env("RUST_LOG", "error")
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // The ready lines: the Gamebots port first, then each side port.
        let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
        let mut ready = String::new();
        for _ in 0..5 {
            stdout.read_line(&mut ready).unwrap();
        }
        let at = |service: &str| -> SocketAddr {
            let line = ready
                .lines()
                .find(|l| l.starts_with(&format!("usar-server {service}")))
                .unwrap_or_else(|| panic!("no {service} in {ready:?}"));
            line.rsplit(' ').next().unwrap().parse().unwrap()
        };
        let addr = ready.split_whitespace().nth(3).unwrap().parse().unwrap();
        let side = Side {
            image: at("image server listening"),
            truth: at("USARTruth listening"),
            monitor: at("robot monitor listening"),
            wss: at("WSS listening"),
        };
        Self { child, addr, side }
    }

    /// Peak resident memory, MiB.
    fn peak_mib(&self) -> f64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id()))
            .unwrap_or_default();
        status
            .lines()
            .find_map(|l| l.strip_prefix("VmHWM:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
            .map_or(f64::NAN, |kib| kib / 1024.0)
    }

    /// Whether the process is still running.
    fn alive(&mut self) -> bool {
        self.child.try_wait().unwrap().is_none()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Connects from loopback address `127.0.0.n`.
async fn connect(addr: SocketAddr, n: u8) -> std::io::Result<TcpStream> {
    let socket = tokio::net::TcpSocket::new_v4()?;
    socket.bind(SocketAddr::from(([127, 0, 0, n], 0)))?;
    socket.connect(addr).await
}

/// The healthy client: an stsAirRobot at the first start, reading everything. Returns its
/// rate in lines per wall second over [`ATTACK`], after [`HEAD_START`].
async fn healthy_rate(addr: SocketAddr) -> f64 {
    let stream = connect(addr, 1).await.expect("the healthy client connects");
    let (read, mut write) = stream.into_split();
    let mut lines = BufReader::new(read);
    let mut line = String::new();
    if !matches!(read_line(&mut lines, &mut line).await, Ok(Ok(n)) if n > 0)
        || !line.starts_with("NFO")
    {
        return 0.0; // locked out
    }
    write
        .write_all(b"INIT {ClassName USARBot.stsAirRobot} {Name Healthy} {Start Start1}\r\n")
        .await
        .unwrap();
    // Whole simulated seconds (from one STA to the STA ATTACK later), so that the sensors'
    // different intervals do not change the count per period.
    let sta_time = |line: &str| {
        line.strip_prefix("STA {Time ")
            .and_then(|rest| rest.split('}').next())
            .and_then(|t| t.parse::<f64>().ok())
    };
    // The attack goes on until the measurement ends; a world that stalls is measured as
    // such: the measurement ends at `deadline` whatever happens.
    let begin = Instant::now() + HEAD_START;
    let deadline = begin + 2 * ATTACK + Duration::from_secs(1);
    let next = async |lines: &mut BufReader<_>, line: &mut String| {
        line.clear();
        let wait = deadline.saturating_duration_since(Instant::now());
        matches!(
            tokio::time::timeout(wait, lines.read_line(line)).await,
            Ok(Ok(n)) if n > 0
        )
    };
    let (first, t0) = loop {
        if !next(&mut lines, &mut line).await {
            return 0.0;
        }
        if let Some(t) = sta_time(&line).filter(|_| Instant::now() >= begin) {
            break (Instant::now(), t);
        }
    };
    let mut count = 1u64;
    loop {
        if !next(&mut lines, &mut line).await {
            break; // past the deadline (or the server closed)
        }
        if sta_time(&line).is_some_and(|t| t >= t0 + ATTACK.as_secs_f64() - 1e-3) {
            break;
        }
        count += 1;
    }
    count as f64 / (Instant::now() - first).as_secs_f64()
}

/// Reads one line (cleared first), failing after 30 s.
async fn read_line(
    lines: &mut BufReader<tokio::net::tcp::OwnedReadHalf>,
    line: &mut String,
) -> Result<std::io::Result<usize>, tokio::time::error::Elapsed> {
    line.clear();
    tokio::time::timeout(Duration::from_secs(30), lines.read_line(line)).await
}

/// Writes `chunk` again and again until stopped, never reading.
async fn flood(mut stream: TcpStream, chunk: Vec<u8>, stop: CancellationToken) {
    while !stop.is_cancelled() {
        let write = tokio::time::timeout(Duration::from_millis(200), stream.write_all(&chunk));
        if let Ok(Err(_)) = write.await {
            return;
        }
    }
}

/// Reads and discards everything until stopped.
async fn drain(mut read: tokio::net::tcp::OwnedReadHalf, stop: CancellationToken) {
    let mut buf = vec![0u8; 64 * 1024];
    while !stop.is_cancelled() {
        let read = tokio::time::timeout(Duration::from_millis(200), read.read(&mut buf));
        if let Ok(Ok(0) | Err(_)) = read.await {
            return;
        }
    }
}

/// One attack: its name, the server's extra flags and what it does until the deadline.
type Attack = (
    &'static str,
    fn(SocketAddr, CancellationToken) -> tokio::task::JoinHandle<String>,
);

fn valid_command_flood(
    addr: SocketAddr,
    stop: CancellationToken,
) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut s = connect(addr, 2).await.unwrap();
        s.write_all(b"INIT {ClassName USARBot.stsAirRobot} {Location 3,3,-1}\r\n")
            .await
            .unwrap();
        let chunk = "DRIVE {LinearVelocity 0.1}\r\nGETCONF {Type Sonar}\r\nGETGEO {Type Sonar}\r\n"
            .repeat(1000)
            .into_bytes();
        flood(s, chunk, stop).await;
        "valid commands as fast as possible, never reading".into()
    })
}

fn start_poses_flood(addr: SocketAddr, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let s = connect(addr, 2).await.unwrap();
        let (read, mut write) = s.into_split();
        let reader = tokio::spawn(drain(read, stop.clone()));
        let chunk = "GETSTARTPOSES\r\n".repeat(1000);
        while !stop.is_cancelled() {
            let sent = tokio::time::timeout(
                Duration::from_millis(200),
                write.write_all(chunk.as_bytes()),
            );
            if let Ok(Err(_)) = sent.await {
                break;
            }
        }
        let _ = reader.await;
        "GETSTARTPOSES as fast as possible, reading".into()
    })
}

fn idle_connections(addr: SocketAddr, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut held = Vec::new();
        for _ in 0..64 {
            if let Ok(mut s) = connect(addr, 2).await {
                let mut nfo = [0u8; 3];
                let greeted = tokio::time::timeout(Duration::from_secs(1), s.read_exact(&mut nfo));
                if matches!(greeted.await, Ok(Ok(_))) {
                    held.push(s);
                }
            }
        }
        stop.cancelled().await;
        format!(
            "64 idle connections from one address ({} served)",
            held.len()
        )
    })
}

fn init_flood(addr: SocketAddr, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let s = connect(addr, 2).await.unwrap();
        let chunk: String = (0..20_000)
            .map(|i| {
                // A grid of free places outside the room, 1 m apart.
                format!(
                    "INIT {{ClassName USARBot.stsAirRobot}} {{Location {},{},{}}}\r\n",
                    20 + i % 28,
                    i / 28 % 28,
                    -(i / 784) - 1
                )
            })
            .collect();
        let (read, mut write) = s.into_split();
        let reader = tokio::spawn(drain(read, stop.clone()));
        let _ = write.write_all(chunk.as_bytes()).await;
        let _ = reader.await;
        "20,000 INITs on one connection".into()
    })
}

fn huge_numbers(addr: SocketAddr, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let s = connect(addr, 2).await.unwrap();
        let (read, mut write) = s.into_split();
        let reader = tokio::spawn(drain(read, stop.clone()));
        let _ = write
            .write_all(
                b"INIT {ClassName USARBot.stsAirRobot} {Location 1e308,1e308,-1e308}\r\n\
                  DRIVE {LinearVelocity 1.5e308} {LateralVelocity -1.5e308} {RotationalVelocity 1e308}\r\n",
            )
            .await;
        let _ = reader.await;
        "DRIVE and INIT numbers of 1e308".into()
    })
}

fn garbage(addr: SocketAddr, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let s = connect(addr, 2).await.unwrap();
        let mut chunk = Vec::new();
        let mut x: u32 = 12345;
        for i in 0..(256 * 1024) {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            chunk.push(if i % 97 == 0 { b'\n' } else { x as u8 });
        }
        chunk.extend_from_slice(&[b'A'; 200 * 1024]); // a line past the length limit
        chunk.push(b'\n');
        flood(s, chunk, stop).await;
        "random bytes and over-long lines as fast as possible".into()
    })
}

fn long_lines(addr: SocketAddr, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut s = connect(addr, 2).await.unwrap();
        s.write_all(b"INIT {ClassName USARBot.stsAirRobot} {Location 3,3,-1}\r\n")
            .await
            .unwrap();
        let line = format!("GETCONF {{Type {}}}\r\n", "Sonar".repeat(12_000));
        flood(s, line.repeat(16).into_bytes(), stop).await;
        "60 KB commands (just under the line limit) as fast as possible, never reading".into()
    })
}

fn sync_zero(addr: SocketAddr, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut s = connect(addr, 2).await.unwrap();
        s.write_all(b"SYNC {Time 0}\r\nINIT {ClassName USARBot.AirRobot} {Location 3,-3,-1}\r\n")
            .await
            .unwrap();
        let (read, _write) = s.into_split();
        drain(read, stop).await;
        "SYNC {Time 0}, then silence".into()
    })
}

/// `n` connections from the healthy client's own address (loopback), each active: it has
/// sent a line and reads its answers (issue #56: 16 locked every local client out).
fn active_connections(
    addr: SocketAddr,
    n: usize,
    stop: CancellationToken,
) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut readers = Vec::new();
        let mut writers = Vec::new();
        for _ in 0..n {
            let Ok(s) = connect(addr, 1).await else {
                continue;
            };
            let (read, mut write) = s.into_split();
            if write.write_all(b"GETSTARTPOSES\r\n").await.is_ok() {
                readers.push(tokio::spawn(drain(read, stop.clone())));
                writers.push(write);
            }
        }
        let held = readers.len();
        for r in readers {
            let _ = r.await;
        }
        format!("{n} active connections from the healthy client's address ({held} opened)")
    })
}

fn active_16(addr: SocketAddr, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    active_connections(addr, 16, stop)
}

fn active_40(addr: SocketAddr, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    active_connections(addr, 40, stop)
}

/// 80 connections to each side port that each complete a request, then hold the
/// connection without reading (issue #56: 64 locked each port).
fn side_active(side: Side, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut held = Vec::new();
        for (_, addr, request) in side_ports(side) {
            for _ in 0..80 {
                if let Ok(mut s) = connect(addr, 2).await
                    && s.write_all(request).await.is_ok()
                {
                    held.push(s);
                }
            }
        }
        let opened = held.len();
        stop.cancelled().await;
        format!("side ports: 80 active connections each ({opened} opened), not reading")
    })
}

/// 100 connections to each side port that each complete a request, read every answer, then
/// send a byte each 0.5 s that never ends a request (the image server: `U` and its
/// rectangle, 16 bytes, a byte each 0.5 s).
fn side_slow_after_a_request(
    side: Side,
    stop: CancellationToken,
) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut held = Vec::new();
        let mut readers = Vec::new();
        for (name, addr, request) in side_ports(side) {
            for _ in 0..100 {
                let Ok(s) = connect(addr, 2).await else {
                    continue;
                };
                let (read, mut write) = s.into_split();
                readers.push(tokio::spawn(drain(read, stop.clone())));
                if name == "image" {
                    // After the frame sent on connect.
                    tokio::time::sleep(Duration::from_millis(5)).await;
                }
                if write.write_all(request).await.is_ok() {
                    held.push((name, write));
                }
            }
        }
        let opened = held.len();
        tokio::time::sleep(Duration::from_millis(300)).await;
        let mut sent = 0usize;
        while !stop.is_cancelled() {
            for (name, s) in &mut held {
                // The image server: `U`, 15 bytes of its rectangle, then the 16th and the
                // next `U` at once, so that a request is always unfinished.
                let byte: &[u8] = match (*name, sent % 15) {
                    ("image", 0) if sent == 0 => b"U",
                    ("image", 0) => b"\x7fU",
                    ("image", _) => b"\x7f",
                    _ => b"x",
                };
                let _ = tokio::time::timeout(Duration::from_millis(10), s.write_all(byte)).await;
            }
            sent += 1;
            tokio::select! {
                _ = stop.cancelled() => {}
                _ = tokio::time::sleep(Duration::from_millis(500)) => {}
            }
        }
        for r in readers {
            let _ = r.await;
        }
        format!(
            "side ports (64 places each): 100 connections each ({opened} opened) complete a \
             request, then a byte each 0.5 s, never a whole request"
        )
    })
}

/// An attack on the four side ports at once.
type SideAttack = (
    &'static str,
    fn(Side, CancellationToken) -> tokio::task::JoinHandle<String>,
);

/// Each side port with a valid request for it (the WSS's after an `INIT`).
fn side_ports(side: Side) -> [(&'static str, SocketAddr, &'static [u8]); 4] {
    [
        ("image", side.image, b"OK"),
        ("USARTruth", side.truth, b"\r\n"),
        (
            "monitor",
            side.monitor,
            b"GETPOS\r\nGETOBS {Start -100,0,-1} {End 100,0,-1}\r\n",
        ),
        ("WSS", side.wss, b"GETSS {Robot Nobody}\r\n"),
    ]
}

/// Valid requests as fast as possible on 4 connections to each side port; `reading`:
/// reading every answer, otherwise never reading.
fn side_flood(
    side: Side,
    stop: CancellationToken,
    reading: bool,
) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut tasks = Vec::new();
        for (i, (_, addr, request)) in side_ports(side).into_iter().enumerate() {
            for j in 0..4 {
                let stop = stop.clone();
                tasks.push(tokio::spawn(async move {
                    let Ok(mut s) = connect(addr, 2).await else {
                        return;
                    };
                    if i == 3 {
                        let init = format!("INIT {{Robot Flood{j}}} {{Port 9}}\r\n");
                        let _ = s.write_all(init.as_bytes()).await;
                    }
                    let chunk = request.repeat(500);
                    if reading {
                        let (read, mut write) = s.into_split();
                        let reader = tokio::spawn(drain(read, stop.clone()));
                        while !stop.is_cancelled() {
                            let sent = tokio::time::timeout(
                                Duration::from_millis(200),
                                write.write_all(&chunk),
                            );
                            if let Ok(Err(_)) = sent.await {
                                break;
                            }
                        }
                        let _ = reader.await;
                    } else {
                        flood(s, chunk, stop).await;
                    }
                }));
            }
        }
        for t in tasks {
            let _ = t.await;
        }
        format!(
            "side ports: valid requests as fast as possible, 4 connections each, {}",
            if reading { "reading" } else { "never reading" }
        )
    })
}

fn side_flood_reading(side: Side, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    side_flood(side, stop, true)
}

fn side_flood_not_reading(side: Side, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    side_flood(side, stop, false)
}

/// Sends `chunk` again and again to `addr`, reconnecting when the server closes, until
/// `limit` bytes are sent or `stop`; returns the bytes sent.
async fn pour(addr: SocketAddr, chunk: Vec<u8>, limit: usize, stop: CancellationToken) -> usize {
    let mut sent = 0;
    while sent < limit && !stop.is_cancelled() {
        let Ok(mut s) = connect(addr, 2).await else {
            tokio::time::sleep(Duration::from_millis(10)).await;
            continue;
        };
        while sent < limit && !stop.is_cancelled() {
            let write = tokio::time::timeout(Duration::from_millis(200), s.write_all(&chunk));
            match write.await {
                Ok(Ok(())) => sent += chunk.len(),
                Ok(Err(_)) => break,
                Err(_) => {}
            }
        }
    }
    sent
}

fn side_long_lines(side: Side, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let tasks: Vec<_> = side_ports(side)
            .into_iter()
            .map(|(name, addr, _)| {
                let stop = stop.clone();
                tokio::spawn(async move {
                    let sent = pour(addr, vec![b'A'; 64 * 1024], 100 << 20, stop).await;
                    format!("{name} {} MB", sent >> 20)
                })
            })
            .collect();
        let mut sent = Vec::new();
        for t in tasks {
            sent.push(t.await.unwrap());
        }
        format!(
            "side ports: 100 MB lines (no line end), reconnecting ({})",
            sent.join(", ")
        )
    })
}

fn side_garbage(side: Side, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut chunk = Vec::new();
        let mut x: u32 = 987_654_321;
        for i in 0..(256 * 1024) {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            if i % 101 == 0 {
                chunk.extend_from_slice(b"\r\n");
            } else {
                chunk.push(x as u8);
            }
        }
        let tasks: Vec<_> = side_ports(side)
            .into_iter()
            .map(|(_, addr, _)| tokio::spawn(pour(addr, chunk.clone(), usize::MAX, stop.clone())))
            .collect();
        let mut total = 0;
        for t in tasks {
            total += t.await.unwrap();
        }
        format!(
            "side ports: random bytes as fast as possible, reconnecting ({} MB in all)",
            total >> 20
        )
    })
}

fn side_slowloris(side: Side, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        let mut held = Vec::new();
        for (_, addr, _) in side_ports(side) {
            for _ in 0..100 {
                if let Ok(s) = connect(addr, 2).await {
                    held.push(s);
                }
            }
        }
        let opened = held.len();
        // One byte each half second, never a whole request.
        while !stop.is_cancelled() {
            for s in &mut held {
                let _ = tokio::time::timeout(Duration::from_millis(10), s.write_all(b"x")).await;
            }
            tokio::select! {
                _ = stop.cancelled() => {}
                _ = tokio::time::sleep(Duration::from_millis(500)) => {}
            }
        }
        format!("side ports: slowloris, 100 connections each ({opened} opened), a byte each 0.5 s")
    })
}

fn side_churn(side: Side, stop: CancellationToken) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move {
        // 10,000 connections (issue #14's churn), at most 2,000 a second: faster, the
        // attacker's own connects would take the 2 cores (what is measured is the server).
        let begin = Instant::now();
        let mut churned = 0u32;
        'outer: while churned < 10_000 {
            for (_, addr, _) in side_ports(side) {
                if stop.is_cancelled() {
                    break 'outer;
                }
                // From 50 addresses: one address's ephemeral ports would run out (TIME_WAIT).
                if connect(addr, 10 + (churned % 50) as u8).await.is_ok() {
                    churned += 1;
                }
            }
            let due = begin + Duration::from_secs_f64(f64::from(churned) / 2000.0);
            tokio::time::sleep_until(due.into()).await;
        }
        format!("side ports: connection churn ({churned} connections opened and closed, 2,000/s)")
    })
}

/// Which side ports do not answer a fresh client's valid request within 10 s.
async fn unanswered(side: Side) -> Vec<&'static str> {
    let mut silent = Vec::new();
    for (name, addr, request) in side_ports(side) {
        let answered = tokio::time::timeout(Duration::from_secs(10), async {
            let mut s = connect(addr, 3).await.ok()?;
            if name == "WSS" {
                s.write_all(b"INIT {Robot Probe} {Port 9}\r\n").await.ok()?;
            } else {
                s.write_all(request).await.ok()?;
            }
            let mut first = [0u8; 5];
            s.read_exact(&mut first).await.ok()
        });
        if !matches!(answered.await, Ok(Some(_))) {
            silent.push(name);
        }
    }
    silent
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_attack_slows_a_healthy_client_or_grows_the_server() {
    let baseline = {
        let server = Server::start(&[]);
        healthy_rate(server.addr).await
    };
    println!("baseline: healthy client {baseline:.1} lines/s");
    assert!(baseline > 50.0, "the healthy client gets its readings");
    let attacks: &[Attack] = &[
        ("valid-command flood", valid_command_flood),
        ("GETSTARTPOSES flood", start_poses_flood),
        ("idle connections", idle_connections),
        ("INIT flood", init_flood),
        ("huge numbers", huge_numbers),
        ("garbage", garbage),
        ("long lines", long_lines),
        ("SYNC {Time 0}", sync_zero),
        ("16 active, same addr", active_16),
        ("40 active, same addr", active_40),
    ];
    let mut failures = Vec::new();
    println!(
        "{:<22} {:>10} {:>8} {:>12}  what",
        "attack", "lines/s", "share", "peak MiB"
    );
    for (name, attack) in attacks {
        let start = |server: &Server, stop| attack(server.addr, stop);
        judge(name, baseline, &mut failures, start, (false, &[])).await;
    }
    let side_attacks: &[SideAttack] = &[
        ("side: flood, reading", side_flood_reading),
        ("side: flood, no reads", side_flood_not_reading),
        ("side: 100 MB lines", side_long_lines),
        ("side: garbage", side_garbage),
        ("side: slowloris", side_slowloris),
        ("side: churn", side_churn),
        ("side: 80 active each", side_active),
    ];
    for (name, attack) in side_attacks {
        let start = |server: &Server, stop| attack(server.side, stop);
        judge(name, baseline, &mut failures, start, (true, &[])).await;
    }
    // Slow senders that completed a request first, 100 a port against 64 places: they make
    // room for a new client (issue #56).
    let start = |server: &Server, stop| side_slow_after_a_request(server.side, stop);
    let args: &[&str] = &["--max-side-connections", "64"];
    judge(
        "side: slow, after one",
        baseline,
        &mut failures,
        start,
        (true, args),
    )
    .await;
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A lockstep member from `127.0.0.n`: spawns, then syncs one step (0.05 s) ahead each time
/// it is answered, at once. Sends the simulated time of each answer until `stop`.
fn lockstep_member(
    addr: SocketAddr,
    n: u8,
    answers: tokio::sync::mpsc::UnboundedSender<(Instant, f64)>,
    stop: CancellationToken,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let stream = connect(addr, n).await.expect("the member connects");
        let (read, mut write) = stream.into_split();
        let mut lines = BufReader::new(read);
        let mut line = String::new();
        let init = format!(
            "INIT {{ClassName USARBot.stsAirRobot}} {{Name Member{n}}} {{Location {n},0,-1}}\r\n"
        );
        write.write_all(init.as_bytes()).await.unwrap();
        let mut barrier = 0.05;
        while !stop.is_cancelled() {
            let sync = format!("SYNC {{Time {barrier:.2}}}\r\n");
            if write.write_all(sync.as_bytes()).await.is_err() {
                return;
            }
            // Read up to the answer; its time is where the world stands.
            let answered = loop {
                match read_line(&mut lines, &mut line).await {
                    Ok(Ok(n)) if n > 0 => {}
                    _ => return,
                }
                if let Some(t) = line
                    .strip_prefix("SYNC {Time ")
                    .and_then(|rest| rest.split('}').next())
                    .and_then(|t| t.parse::<f64>().ok())
                {
                    break t;
                }
            };
            let _ = answers.send((Instant::now(), answered));
            barrier = answered + 0.05;
        }
    })
}

/// Simulated seconds per wall second seen by a member's answers over `span`.
async fn member_rate(
    answers: &mut tokio::sync::mpsc::UnboundedReceiver<(Instant, f64)>,
    span: Duration,
) -> f64 {
    while answers.try_recv().is_ok() {}
    let Some((t0, s0)) = answers.recv().await else {
        return 0.0;
    };
    let (mut t1, mut s1) = (t0, s0);
    let end = t0 + span;
    while let Ok(Some((t, s))) = tokio::time::timeout_at(end.into(), answers.recv()).await {
        (t1, s1) = (t, s);
    }
    // A world that stood still until the end: nothing was answered after t1.
    let wall = Instant::now().max(t1) - t0;
    (s1 - s0) / wall.as_secs_f64()
}

/// Issue #56: one client that reconnects again and again, each time joining the lockstep
/// barrier and then holding the world (here: `SYNC {Time 0}`, 300 ms of silence, close),
/// gave the established members 0-0.5 % of their rate. New members now hold the world
/// only within a budget (`--lockstep-join-share`, 5 % by default): the members keep at
/// least 90 % of the rate they had before the attack.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_reconnecting_into_the_lockstep_barrier_leaves_the_members_their_rate() {
    let server = Server::start(&["--lockstep"]);
    let stop = CancellationToken::new();
    let (tx, mut answers) = tokio::sync::mpsc::unbounded_channel();
    let members = [
        lockstep_member(server.addr, 1, tx.clone(), stop.clone()),
        lockstep_member(server.addr, 3, tx, stop.clone()),
    ];
    // Members are new for 10 s after they join; then they are the established ones.
    tokio::time::sleep(Duration::from_millis(10_500)).await;
    let baseline = member_rate(&mut answers, ATTACK).await;
    println!("lockstep members: {baseline:.3} simulated s per wall s before the attack");
    assert!(baseline > 0.5, "the members' world runs ({baseline:.3})");
    let attacker = {
        let (addr, stop) = (server.addr, stop.clone());
        tokio::spawn(async move {
            let mut connections = 0u32;
            while !stop.is_cancelled() {
                let Ok(mut s) = connect(addr, 2).await else {
                    continue;
                };
                connections += 1;
                let hold =
                    b"INIT {ClassName USARBot.AirRobot} {Location 5,5,-1}\r\nSYNC {Time 0}\r\n";
                if s.write_all(hold).await.is_ok() {
                    tokio::time::sleep(Duration::from_millis(300)).await;
                }
            }
            connections
        })
    };
    tokio::time::sleep(HEAD_START).await;
    let mut shares = Vec::new();
    for _ in 0..ATTEMPTS {
        let rate = member_rate(&mut answers, ATTACK).await;
        shares.push(rate / baseline);
        println!(
            "under attack: {rate:.3} simulated s per wall s ({:.0} %)",
            rate / baseline * 100.0
        );
        if rate / baseline >= MIN_SHARE {
            break;
        }
    }
    stop.cancel();
    let connections = attacker.await.unwrap();
    for m in members {
        m.await.unwrap();
    }
    assert!(connections >= 5, "the attacker reconnected ({connections})");
    assert!(
        shares.iter().any(|s| *s >= MIN_SHARE),
        "the members kept {shares:?} of their rate"
    );
}
