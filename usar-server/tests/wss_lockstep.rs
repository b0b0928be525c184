//! The WSS in lockstep (issue 20, docs/wss.md "In lockstep"): a radio session is a function
//! of the simulated run only — the same links break and resume at the same simulated times,
//! and the same bytes get through, whatever the wall-clock delays of the clients.

use std::io::{ErrorKind, Read, Write};
use std::net::SocketAddr;
use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::{TcpListener, TcpStream};
use tokio_util::sync::CancellationToken;
use usar_server::sim::Map;
use usar_server::{ServerConfig, SideListeners, TimeScale};

/// Eight thin walls side by side, 3 m high, between y = 2 and y = 4.1 (as side_servers.rs).
fn walls_map() -> Map {
    let mut text = String::from(
        "level = \"Walls\"\n[[box]]\ncenter = [0.0, 0.0, 0.1]\nsize = [60.0, 60.0, 0.2]\n",
    );
    for i in 0..8 {
        let y = 2.0 + 0.3 * f64::from(i);
        text.push_str(&format!(
            "[[box]]\ncenter = [0.0, {y}, -1.5]\nsize = [20.0, 0.1, 3.0]\n"
        ));
    }
    Map::from_toml(&text, std::path::Path::new("walls.toml")).unwrap()
}

/// A line-based connection (Gamebots or the WSS's control port).
struct Lines {
    read: BufReader<OwnedReadHalf>,
    write: OwnedWriteHalf,
}

impl Lines {
    async fn connect(at: SocketAddr) -> Self {
        let (read, write) = TcpStream::connect(at).await.unwrap().into_split();
        Self {
            read: BufReader::new(read),
            write,
        }
    }

    async fn send(&mut self, line: &str) {
        self.write
            .write_all(format!("{line}\r\n").as_bytes())
            .await
            .unwrap();
    }

    async fn line(&mut self) -> String {
        let mut line = String::new();
        let n = tokio::time::timeout(Duration::from_secs(30), self.read.read_line(&mut line))
            .await
            .expect("a line in time")
            .unwrap();
        assert!(n > 0, "closed");
        line.trim_end().to_owned()
    }

    /// A WSS request and its reply.
    async fn ask(&mut self, request: &str) -> String {
        self.send(request).await;
        self.line().await
    }

    /// Sends `SYNC {Time t}` (Gamebots).
    async fn sync(&mut self, time: f64) {
        self.send(&format!("SYNC {{Time {time:.1}}}")).await;
    }

    /// Reads up to the `SYNC` answer.
    async fn answered(&mut self) {
        while !self.line().await.starts_with("SYNC ") {}
    }
}

/// Artificial wall-clock delays of the clients (milliseconds, by barrier number).
#[derive(Clone, Copy)]
enum Delays {
    None,
    /// Varying delays everywhere, and the two robots' `SYNC`s in the other order.
    Jitter,
    /// A long pause between the sender's write and its `SYNC` at every barrier.
    AfterWrite(u64),
}

impl Delays {
    async fn pause(self, barrier: u32, place: u32) {
        let ms = match self {
            Self::None => 0,
            Self::Jitter => u64::from((barrier * 7 + place * 13) % 9),
            Self::AfterWrite(ms) if place == 1 => ms,
            Self::AfterWrite(_) => 0,
        };
        if ms > 0 {
            tokio::time::sleep(Duration::from_millis(ms)).await;
        }
    }
}

/// An in-process server in lockstep at full speed on the walls map, with its robot monitor
/// and WSS: (Gamebots address, WSS address, its shutdown, its task).
async fn lockstep_server() -> (
    SocketAddr,
    SocketAddr,
    CancellationToken,
    tokio::task::JoinHandle<Result<(), usar_server::ServerError>>,
) {
    let bind = async || TcpListener::bind("127.0.0.1:0").await.unwrap();
    let (main, monitor, wss) = (bind().await, bind().await, bind().await);
    let (gamebots, wss_at) = (main.local_addr().unwrap(), wss.local_addr().unwrap());
    let shutdown = CancellationToken::new();
    let config = ServerConfig {
        map: walls_map(),
        lockstep: true,
        time_scale: TimeScale::Max,
        ..ServerConfig::default()
    };
    let side = SideListeners {
        image: None,
        truth: None,
        monitor: Some(monitor),
        wss: Some(wss),
    };
    let server = tokio::spawn(usar_server::run_with(main, side, config, shutdown.clone()));
    (gamebots, wss_at, shutdown, server)
}

/// Robot1 on the near side of the walls and BaseStation 6 m east above their tops, each
/// joining the barrier at 0 s, then spawning.
async fn two_robots(gamebots: SocketAddr) -> (Lines, Lines) {
    let mut robot1 = Lines::connect(gamebots).await;
    let mut base = Lines::connect(gamebots).await;
    for (c, name, at) in [
        (&mut robot1, "Robot1", "0,0,-1"),
        (&mut base, "BaseStation", "0,6,-5"),
    ] {
        c.line().await; // NFO
        c.sync(0.0).await;
        c.answered().await;
        c.send(&format!(
            "INIT {{ClassName USARBot.AirRobot}} {{Name {name}}} {{Location {at}}}"
        ))
        .await;
    }
    (robot1, base)
}

/// The port of a `DNSREPLY {Robot BaseStation} {Port p}` reply.
fn dns_port(reply: &str) -> u16 {
    reply
        .strip_prefix("DNSREPLY {Robot BaseStation} {Port ")
        .and_then(|r| r.strip_suffix('}'))
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("{reply}"))
}

/// Robot1 and BaseStation (whose own listener is on `base_port`) register with the WSS:
/// their control connections.
async fn register(wss_at: SocketAddr, base_port: u16) -> (Lines, Lines) {
    let (mut a, mut b) = (Lines::connect(wss_at).await, Lines::connect(wss_at).await);
    assert_eq!(
        a.ask("INIT {Robot Robot1} {Port 8001}").await,
        "INITREPLY {Status OK}"
    );
    assert_eq!(
        b.ask(&format!("INIT {{Robot BaseStation}} {{Port {base_port}}}"))
            .await,
        "INITREPLY {Status OK}"
    );
    (a, b)
}

/// What a run shows: Robot1's view at each barrier after it asked for the relay port
/// (`"<time> <signal> <what happened>"`), every byte the BaseStation received, and what
/// Robot1 is told of a registration no robot has (`"<time> <GETSS reply>"`, barriers 3 to
/// 11).
#[derive(Debug, PartialEq)]
struct Outcome {
    log: Vec<String>,
    received: String,
    ghost: Vec<String>,
}

impl Outcome {
    /// The simulated times at which Robot1 found its relayed connection closed (breaks) and
    /// could connect again (resumes).
    fn times(&self, what: &str) -> Vec<String> {
        self.log
            .iter()
            .filter(|l| l.contains(what))
            .map(|l| l.split(' ').next().unwrap().to_owned())
            .collect()
    }
}

/// Two robots in lockstep (0.1 s barriers) talk through the in-process WSS: Robot1 on the
/// near side of eight walls writes `t=<time>;` at every barrier to the BaseStation, which
/// flies down behind the walls (out of range) and climbs back.
async fn session(delays: Delays) -> Outcome {
    let (gamebots, wss_at, shutdown, server) = lockstep_server().await;

    let (mut robot1, mut base) = two_robots(gamebots).await;
    // The BaseStation's own listener (non-blocking: read at barriers).
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    listener.set_nonblocking(true).unwrap();
    let base_port = listener.local_addr().unwrap().port();
    let mut accepted: Vec<std::net::TcpStream> = Vec::new();
    let mut received = Vec::new();
    let read_all = |accepted: &mut Vec<std::net::TcpStream>, received: &mut Vec<u8>| {
        while let Ok((s, _)) = listener.accept() {
            s.set_nonblocking(true).unwrap();
            accepted.push(s);
        }
        for s in accepted.iter_mut() {
            let mut chunk = [0u8; 4096];
            while let Ok(n @ 1..) = s.read(&mut chunk) {
                received.extend_from_slice(&chunk[..n]);
            }
        }
    };

    let (mut control1, mut control2) = (None, None);
    let mut relay_port = None;
    let mut link: Option<std::net::TcpStream> = None;
    let mut log = Vec::new();
    let mut ghost = Vec::new();
    let mut ghost_control = None;
    for barrier in 1..=90u32 {
        let time = f64::from(barrier) / 10.0;
        // The BaseStation's flight: down behind the walls at 2 s, back up at 5 s.
        let drive = match barrier {
            20 => Some(-2),
            40 | 70 => Some(0),
            50 => Some(2),
            _ => None,
        };
        if let Some(v) = drive {
            base.send(&format!("DRIVE {{AltitudeVelocity {v}}}")).await;
        }
        if matches!(delays, Delays::Jitter) && barrier % 2 == 0 {
            base.sync(time).await;
            delays.pause(barrier, 0).await;
            robot1.sync(time).await;
        } else {
            robot1.sync(time).await;
            delays.pause(barrier, 0).await;
            base.sync(time).await;
        }
        robot1.answered().await;
        base.answered().await;
        // The world stands at `time` until both sync again.
        if barrier == 2 {
            let (a, b) = register(wss_at, base_port).await;
            (control1, control2) = (Some(a), Some(b));
            // A name the simulation does not have: kicked at the next evaluation.
            let mut g = Lines::connect(wss_at).await;
            assert_eq!(
                g.ask("INIT {Robot Ghost} {Port 1}").await,
                "INITREPLY {Status OK}"
            );
            ghost_control = Some(g);
        }
        if (3..=11).contains(&barrier) {
            let reply = control1.as_mut().unwrap().ask("GETSS {Robot Ghost}").await;
            ghost.push(format!("{time:.1} {reply}"));
        }
        if barrier == 12 {
            let reply = control1
                .as_mut()
                .unwrap()
                .ask("DNS {Robot BaseStation}")
                .await;
            let port = dns_port(&reply);
            relay_port = Some(port);
        }
        if let Some(port) = relay_port {
            let signal = control1
                .as_mut()
                .unwrap()
                .ask("GETSS {Robot BaseStation}")
                .await;
            let signal = signal.rsplit("{Strength ").next().unwrap();
            let signal = signal.trim_end_matches('}').to_owned();
            let mut what = Vec::new();
            if link.is_none() {
                match std::net::TcpStream::connect(("127.0.0.1", port)) {
                    Ok(s) => {
                        s.set_nodelay(true).unwrap();
                        what.push("connected");
                        link = Some(s);
                    }
                    Err(_) => what.push("refused"),
                }
            }
            if let Some(s) = &mut link {
                let message = format!("t={time:.1};");
                match s.write_all(message.as_bytes()) {
                    Ok(()) => what.push("sent"),
                    Err(_) => what.push("write-failed"),
                }
                delays.pause(barrier, 1).await;
                // Closed by the WSS (the link broke)?
                s.set_nonblocking(true).unwrap();
                let mut probe = [0u8; 16];
                match s.read(&mut probe) {
                    Err(e) if e.kind() == ErrorKind::WouldBlock => {}
                    _ => {
                        what.push("closed");
                        link = None;
                    }
                }
                if let Some(s) = &link {
                    s.set_nonblocking(false).unwrap();
                }
            }
            log.push(format!("{time:.1} {signal} {}", what.join(" ")));
        }
        delays.pause(barrier, 2).await;
        read_all(&mut accepted, &mut received);
    }
    // The last bytes: Robot1 closes its end; the BaseStation reads each relayed connection
    // to its end.
    drop(link);
    let mut last = 91.0;
    for _ in 0..3 {
        robot1.sync(last / 10.0).await;
        base.sync(last / 10.0).await;
        robot1.answered().await;
        base.answered().await;
        last += 1.0;
    }
    read_all(&mut accepted, &mut received);
    for s in &mut accepted {
        s.set_nonblocking(false).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let mut rest = Vec::new();
        s.read_to_end(&mut rest)
            .expect("the relayed connection ends");
        received.extend_from_slice(&rest);
    }
    // The ghost's control connection was closed by the kick.
    let mut g = ghost_control.unwrap();
    let mut rest = String::new();
    let closed = tokio::time::timeout(Duration::from_secs(10), g.read.read_line(&mut rest)).await;
    assert!(matches!(closed, Ok(Ok(0))), "the ghost is kicked");
    drop((control1, control2));
    shutdown.cancel();
    let _ = server.await;
    Outcome {
        log,
        received: String::from_utf8(received).unwrap(),
        ghost,
    }
}

/// The same session twice, the second with varying wall-clock delays and the two robots'
/// `SYNC`s in the other order: the same breaks and resumes at the same simulated times, and
/// the same bytes received.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lockstep_radio_session_is_the_same_whatever_the_wall_clock() {
    let first = session(Delays::None).await;
    let breaks = first.times("closed");
    let resumes = first.times("connected");
    assert!(
        !breaks.is_empty() && resumes.len() >= 2,
        "the link breaks behind the walls and resumes: {:#?}",
        first.log
    );
    assert!(!first.received.is_empty());
    let second = session(Delays::Jitter).await;
    assert_eq!(first, second, "the radio depends on the wall clock");
}

/// The rule (docs/wss.md): a byte written at a barrier is taken at that barrier's simulated
/// time and delivered if and only if the link held at the last evaluation (every second of
/// simulated time); a break at T closes the relayed connection before the clients see T. So
/// the message written at the barrier just before T is delivered — even when the sender
/// waits long on the wall clock before its next `SYNC` — and the one written at T is refused,
/// as are all until the link resumes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_byte_sent_just_before_a_break_is_delivered_by_the_rule() {
    let run = session(Delays::AfterWrite(30)).await;
    let breaks = run.times("closed");
    let resumes = run.times("connected");
    assert!(!breaks.is_empty() && resumes.len() >= 2, "{:#?}", run.log);
    let break_at: f64 = breaks[0].parse().unwrap();
    let resume_at: f64 = resumes[1].parse().unwrap();
    assert!(
        (break_at - break_at.round()).abs() < 1e-9 && (resume_at - resume_at.round()).abs() < 1e-9,
        "links change at evaluations, whole seconds of simulated time: {:#?}",
        run.log
    );
    for line in &run.log {
        let t: f64 = line.split(' ').next().unwrap().parse().unwrap();
        let message = format!("t={t:.1};");
        let delivered = run.received.contains(&message);
        let sent = line.contains("sent");
        let held = t < break_at - 1e-9 || t > resume_at - 1e-9;
        assert_eq!(
            delivered,
            sent && held,
            "{message} (break at {break_at}, resume at {resume_at}): {line}\n{:#?}",
            run.log
        );
    }
    // The ghost is kicked at the first evaluation after it registered (1 s).
    assert_eq!(
        run.ghost[6..8],
        [
            "0.9 SS {Robot Ghost} {Strength NaN} {Error Model.Returned.NaN}",
            "1.0 SS {Robot Ghost} {Strength NaN} {Error Robot.Does.Not.Exist}"
        ]
    );
    let before = format!("t={:.1};", break_at - 0.1);
    assert!(run.received.contains(&before), "{before} is delivered");
    let at = format!("t={break_at:.1};");
    assert!(
        run.log
            .iter()
            .any(|l| l.starts_with(&format!("{break_at:.1} ")) && l.contains("sent closed")),
        "Robot1 wrote at the break and then found the connection closed: {:#?}",
        run.log
    );
    assert!(!run.received.contains(&at), "{at} is refused");
    // The same as without delays.
    assert_eq!(run, session(Delays::None).await);
}

/// A robot that floods its link while the other side never reads (bad input): the WSS on the
/// simulated clock holds at most 64 KiB of it, so the flooder's writes stop, and the world
/// keeps stepping for both robots.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_over_a_lockstep_link_is_bounded_and_does_not_hold_the_world() {
    let (gamebots, wss_at, shutdown, _server) = lockstep_server().await;
    let mut robot1 = Lines::connect(gamebots).await;
    robot1.line().await;
    robot1.sync(0.0).await;
    robot1.answered().await;
    robot1
        .send("INIT {ClassName USARBot.AirRobot} {Name Robot1} {Location 0,0,-1}")
        .await;
    let mut base = Lines::connect(gamebots).await;
    base.line().await;
    base.send("INIT {ClassName USARBot.AirRobot} {Name BaseStation} {Location 0,-3,-1}")
        .await;
    // A listener that accepts but never reads.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let base_port = listener.local_addr().unwrap().port();
    let (mut a, mut b) = (Lines::connect(wss_at).await, Lines::connect(wss_at).await);
    let mut time = 0.0;
    let barrier = async |robot1: &mut Lines, time: &mut f64| {
        *time += 0.1;
        robot1.sync(*time).await;
        robot1.answered().await;
    };
    barrier(&mut robot1, &mut time).await;
    a.ask("INIT {Robot Robot1} {Port 1}").await;
    b.ask(&format!("INIT {{Robot BaseStation}} {{Port {base_port}}}"))
        .await;
    while time < 1.05 {
        barrier(&mut robot1, &mut time).await;
    }
    let reply = a.ask("DNS {Robot BaseStation}").await;
    let port = dns_port(&reply);
    let mut link = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    let flood = std::thread::spawn(move || {
        let chunk = vec![0u8; 1 << 20];
        let mut sent = 0usize;
        while sent < 64 << 20 && link.write_all(&chunk).is_ok() {
            sent += chunk.len();
        }
        sent
    });
    // The world steps on while the flood waits: 3 s of simulated time.
    while time < 4.05 {
        barrier(&mut robot1, &mut time).await;
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    assert!(
        !flood.is_finished(),
        "the WSS took a 64 MiB flood that nobody reads"
    );
    let _accepted = listener.accept().unwrap();
    shutdown.cancel();
    drop((a, b, base));
}

/// Issue #55, in lockstep: robots that register with the WSS at a barrier between two
/// evaluations (here at 0.5 s; evaluations come at whole seconds) get a finite `GETSS` and
/// a relay port that accepts from their `INITREPLY` on (they waited for the next
/// evaluation).
#[tokio::test]
async fn in_lockstep_getss_and_dns_work_from_the_moment_init_is_answered() {
    let (gamebots, wss_at, shutdown, server) = lockstep_server().await;
    let (mut robot1, mut base) = two_robots(gamebots).await;
    robot1.sync(0.5).await;
    base.sync(0.5).await;
    robot1.answered().await;
    base.answered().await;
    // The world stands at 0.5 s.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let base_port = listener.local_addr().unwrap().port();
    let (mut a, _b) = register(wss_at, base_port).await;
    let reply = a.ask("GETSS {Robot BaseStation}").await;
    let s: f64 = reply
        .strip_prefix("SS {Robot BaseStation} {Strength ")
        .and_then(|r| r.strip_suffix('}'))
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("not a strength: {reply}"));
    assert!((-93.0..-70.0).contains(&s), "in range: {reply}");
    let reply = a.ask("DNS {Robot BaseStation}").await;
    let port = dns_port(&reply);
    // The relay port listens at once (its connection is taken at the next barrier).
    std::net::TcpStream::connect(("127.0.0.1", port)).expect("the relay port accepts");
    shutdown.cancel();
    let _ = server.await;
}
