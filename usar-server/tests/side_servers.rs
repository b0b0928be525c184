//! USARTruth (3989) and the robot monitor (7435) as real clients use them (issue 20).

use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::{TcpListener, TcpStream};
use tokio_util::sync::CancellationToken;
use usar_server::sim::Map;
use usar_server::{ServerConfig, SideListeners};

struct Servers {
    gamebots: std::net::SocketAddr,
    truth: std::net::SocketAddr,
    monitor: std::net::SocketAddr,
    shutdown: CancellationToken,
}

async fn start(map: &str) -> Servers {
    let bind = async || TcpListener::bind("127.0.0.1:0").await.unwrap();
    let (main, truth, monitor) = (bind().await, bind().await, bind().await);
    let servers = Servers {
        gamebots: main.local_addr().unwrap(),
        truth: truth.local_addr().unwrap(),
        monitor: monitor.local_addr().unwrap(),
        shutdown: CancellationToken::new(),
    };
    let config = ServerConfig {
        map: Map::embedded(map).unwrap(),
        ..ServerConfig::default()
    };
    let side = SideListeners {
        image: None,
        truth: Some(truth),
        monitor: Some(monitor),
        wss: None,
    };
    tokio::spawn(usar_server::run_with(
        main,
        side,
        config,
        servers.shutdown.clone(),
    ));
    servers
}

/// A Gamebots client that spawned `class` named `name` at `start`.
async fn spawn(servers: &Servers, class: &str, name: &str, start: &str) -> TcpStream {
    let mut stream = TcpStream::connect(servers.gamebots).await.unwrap();
    let mut nfo = [0u8; 3];
    stream.read_exact(&mut nfo).await.unwrap();
    let init = format!("INIT {{ClassName USARBot.{class}}} {{Name {name}}} {{Start {start}}}\r\n");
    stream.write_all(init.as_bytes()).await.unwrap();
    stream
}

/// Sends `query` and reads the answer up to `{End}` (the lines before it).
async fn ask(
    read: &mut BufReader<tokio::net::tcp::OwnedReadHalf>,
    write: &mut tokio::net::tcp::OwnedWriteHalf,
    query: &[u8],
) -> Vec<String> {
    write.write_all(query).await.unwrap();
    let mut lines = Vec::new();
    loop {
        let mut line = String::new();
        let n = tokio::time::timeout(Duration::from_secs(30), read.read_line(&mut line))
            .await
            .expect("an answer")
            .unwrap();
        assert!(n > 0, "closed before {{End}}");
        assert!(line.ends_with("\r\n"), "{line:?}");
        let line = line.trim_end().to_owned();
        if line == "{End}" {
            return lines;
        }
        lines.push(line);
    }
}

/// The regex of RoboCupScore and MetricTool (side-servers.md §2.3).
fn scoring_regex() -> regex::Regex {
    regex::Regex::new(
        r"\{Name (.*)\} \{Class (.*)\} \{Time (.*)\} \{Location (.*),(.*),(.*)\} \{Rotation (.*),(.*),(.*)\}",
    )
    .unwrap()
}

#[tokio::test]
async fn a_scoring_tool_reads_robots_and_victims_with_its_regex() {
    let servers = start("rescue").await;
    let _robot = spawn(&servers, "AirRobot", "Robot1", "Start1").await;
    let stream = TcpStream::connect(servers.truth).await.unwrap();
    let (read, mut write) = stream.into_split();
    let mut read = BufReader::new(read);
    let re = scoring_regex();
    // MetricTool sends a bare CR LF: the default query, every robot and every victim.
    let mut answer = Vec::new();
    for _ in 0..300 {
        answer = ask(&mut read, &mut write, b"\r\n").await;
        if answer.iter().any(|l| l.contains("Robot1")) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let mut seen = Vec::new();
    for line in &answer {
        let c = re
            .captures(line)
            .unwrap_or_else(|| panic!("the scoring regex does not match {line:?}"));
        let numbers: Vec<f64> = (3..=9).map(|i| c[i].parse().unwrap()).collect();
        assert!(numbers.iter().all(|x| x.is_finite()), "{line}");
        seen.push((c[1].to_owned(), c[2].to_owned(), numbers));
    }
    let names: Vec<(&str, &str)> = seen.iter().map(|s| (s.0.as_str(), s.1.as_str())).collect();
    assert_eq!(
        names,
        [
            ("Robot1", "AirRobot"),
            ("Victim1", "FemaleVictim"),
            ("Victim2", "MaleVictim"),
            ("Victim3", "MaleVictim"),
            ("Victim4", "FemaleVictim"),
        ],
        "the default query lists robots and victims, not objects"
    );
    assert_eq!(&seen[1].2[1..4], &[-4.0, -3.5, -0.15], "Victim1's location");
    assert_eq!(&seen[0].2[1..3], &[-12.0, 0.0], "the robot at Start1");
    let victim1 = answer.iter().find(|l| l.contains("Victim1")).unwrap();
    assert!(
        victim1.ends_with("{Location -4.00,-3.50,-0.15} {Rotation 0.00,0.00,1.20}"),
        "2 decimals, no spaces: {victim1}"
    );
    // RoboCupScore's request (an unknown key: the default query too).
    assert_eq!(ask(&mut read, &mut write, b"{Actors}\r\n").await.len(), 5);
    // By class (with its package, any case of the key), and by name.
    let males = ask(&mut read, &mut write, b"{class USARVictim.MaleVictim}\r\n").await;
    assert_eq!(males.len(), 2, "{males:?}");
    assert!(males.iter().all(|l| l.contains("{Class MaleVictim}")));
    let car = ask(&mut read, &mut write, b"{Class Sedan}\r\n").await;
    assert!(
        car.len() == 1 && car[0].starts_with("{Name Car1} {Class Sedan}"),
        "{car:?}"
    );
    let one = ask(&mut read, &mut write, b"{Name Victim4}\n").await;
    assert!(
        one.len() == 1 && one[0].starts_with("{Name Victim4}"),
        "{one:?}"
    );
    assert!(
        ask(&mut read, &mut write, b"{class Nope.Nothing}\r\n")
            .await
            .is_empty()
    );
    // Binary garbage is a line without blocks: the default query, as USARSim answers it.
    assert_eq!(
        ask(&mut read, &mut write, b"\x00\xff\x1b[2J\r\n")
            .await
            .len(),
        5
    );
    servers.shutdown.cancel();
}

#[tokio::test]
async fn a_flood_without_line_ends_closes_only_that_connection() {
    let servers = start("rescue").await;
    let mut flood = TcpStream::connect(servers.truth).await.unwrap();
    let garbage = vec![b'{'; 64 * 1024];
    // The server closes the connection; the write may fail once it has.
    let _ = flood.write_all(&garbage).await;
    let mut rest = Vec::new();
    let closed = tokio::time::timeout(Duration::from_secs(30), flood.read_to_end(&mut rest)).await;
    assert!(matches!(closed, Ok(Ok(_)) | Ok(Err(_))), "closed in time");
    // Others are served as before.
    let stream = TcpStream::connect(servers.truth).await.unwrap();
    let (read, mut write) = stream.into_split();
    let mut read = BufReader::new(read);
    assert_eq!(ask(&mut read, &mut write, b"\r\n").await.len(), 4);
    servers.shutdown.cancel();
}

#[tokio::test]
async fn the_robot_monitor_reports_positions_and_wall_counts() {
    let servers = start("rescue").await;
    let _robot = spawn(&servers, "AirRobot", "Robot1", "Start1").await;
    let stream = TcpStream::connect(servers.monitor).await.unwrap();
    let (read, mut write) = stream.into_split();
    let mut read = BufReader::new(read);
    let mut line = String::new();
    let mut request = async |text: &str| {
        write.write_all(text.as_bytes()).await.unwrap();
        line.clear();
        tokio::time::timeout(Duration::from_secs(30), read.read_line(&mut line))
            .await
            .unwrap()
            .unwrap();
        line.clone()
    };
    let mut positions = String::new();
    for _ in 0..300 {
        positions = request("GETPOS\r\n").await;
        if positions.contains("Robot1") {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert_eq!(
        positions,
        "POSITIONS {Robots 1} {Name Robot1 Location -12.0000,0.0000,-1.5000 BatteryEmpty False}\r\n"
    );
    // Three walls between the west of the building and its east, 4 m south of the middle.
    assert_eq!(
        request("GETOBS {Start -12,-4,-1.5} {End 12,-4,-1.5}\n").await,
        "NUMOBS {Start -12,-4,-1.5} {End 12,-4,-1.5} {ObstCount 3.0000}\r\n"
    );
    assert_eq!(
        request("getobs {From Robot1} {To Nobody}\r").await,
        "NUMOBS {From Robot1} {To Nobody} {ObstCount -1.0000}\r\n"
    );
    assert_eq!(
        request("GETOBS\r\n").await,
        "\r\n",
        "neither pair: an empty line"
    );
    // Unknown commands and garbage get no reply: the next answer is GETPOS's.
    let answer = request("\x00\x01 HELLO {x}\r\nGETPOS\r\n").await;
    assert!(answer.starts_with("POSITIONS {Robots 1}"), "{answer:?}");
    servers.shutdown.cancel();
}

/// A WSS control connection: one request, one reply (CR LF).
struct Control {
    read: BufReader<tokio::net::tcp::OwnedReadHalf>,
    write: tokio::net::tcp::OwnedWriteHalf,
}

impl Control {
    async fn connect(at: std::net::SocketAddr) -> Self {
        let (read, write) = TcpStream::connect(at).await.unwrap().into_split();
        Self {
            read: BufReader::new(read),
            write,
        }
    }

    async fn ask(&mut self, request: &str) -> String {
        self.write
            .write_all(format!("{request}\r\n").as_bytes())
            .await
            .unwrap();
        let mut line = String::new();
        tokio::time::timeout(Duration::from_secs(30), self.read.read_line(&mut line))
            .await
            .expect("a reply")
            .unwrap();
        assert!(line.ends_with("\r\n"), "{line:?}");
        line.trim_end().to_owned()
    }
}

/// Eight thin walls side by side, 3 m high, between y = 2 and y = 4.1.
const WALLS: &str = r#"
level = "Walls"
[[box]]
center = [0.0, 0.0, 0.1]
size = [60.0, 60.0, 0.2]
"#;

fn walls_map() -> Map {
    let mut text = WALLS.to_owned();
    for i in 0..8 {
        let y = 2.0 + 0.3 * f64::from(i);
        text.push_str(&format!(
            "[[box]]\ncenter = [0.0, {y}, -1.5]\nsize = [20.0, 0.1, 3.0]\n"
        ));
    }
    Map::from_toml(&text, std::path::Path::new("walls.toml")).unwrap()
}

/// The reference's session set up: the walls map served with a robot monitor, the WSS as
/// its own server against the monitor (as `usar-server wss` runs it) polling every `poll`,
/// and two robots, Robot1 on the ground's near side and BaseStation 6 m east above the
/// walls' tops, in the simulation (the monitor lists both: the WSS kicks names it does not
/// have; UsarCommander waits 3 s after spawning for this reason).
struct WssRig {
    robot1: TcpStream,
    base: TcpStream,
    wss_at: std::net::SocketAddr,
    shutdown: CancellationToken,
}

async fn wss_rig(poll: Duration) -> WssRig {
    use usar_server::net::wss::{self, WssConfig};
    let bind = async || TcpListener::bind("127.0.0.1:0").await.unwrap();
    let (main, monitor, wss_listener) = (bind().await, bind().await, bind().await);
    let (gamebots, monitor_at, wss_at) = (
        main.local_addr().unwrap(),
        monitor.local_addr().unwrap(),
        wss_listener.local_addr().unwrap(),
    );
    let shutdown = CancellationToken::new();
    let config = ServerConfig {
        map: walls_map(),
        ..ServerConfig::default()
    };
    let side = SideListeners {
        image: None,
        truth: None,
        monitor: Some(monitor),
        wss: None,
    };
    tokio::spawn(usar_server::run_with(main, side, config, shutdown.clone()));
    let wss_config = WssConfig {
        poll,
        ..WssConfig::new(monitor_at)
    };
    tokio::spawn(wss::serve(wss_listener, wss_config, shutdown.clone()));
    let mut robots = Vec::new();
    for (name, at) in [("Robot1", "0,0,-1"), ("BaseStation", "0,6,-5")] {
        let mut s = TcpStream::connect(gamebots).await.unwrap();
        let init =
            format!("INIT {{ClassName USARBot.AirRobot}} {{Name {name}}} {{Location {at}}}\r\n");
        s.write_all(init.as_bytes()).await.unwrap();
        robots.push(s);
    }
    let (read, mut write) = TcpStream::connect(monitor_at).await.unwrap().into_split();
    let mut read = BufReader::new(read);
    for _ in 0..600 {
        write.write_all(b"GETPOS\r\n").await.unwrap();
        let mut line = String::new();
        read.read_line(&mut line).await.unwrap();
        if line.starts_with("POSITIONS {Robots 2}") {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let base = robots.pop().unwrap();
    WssRig {
        robot1: robots.pop().unwrap(),
        base,
        wss_at,
        shutdown,
    }
}

/// The strength of a `GETSS {Robot other}` reply (NaN when it gives none).
fn strength_of(reply: &str, other: &str) -> f64 {
    reply
        .strip_prefix(&format!("SS {{Robot {other}}} {{Strength "))
        .and_then(|r| r.strip_suffix('}'))
        .and_then(|s| s.parse().ok())
        .unwrap_or(f64::NAN)
}

/// The port of a `DNSREPLY {Robot other} {Port p}` reply.
fn relay_port(reply: &str, other: &str) -> u16 {
    reply
        .strip_prefix(&format!("DNSREPLY {{Robot {other}}} {{Port "))
        .and_then(|r| r.strip_suffix('}'))
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("{reply}"))
}

/// Issue #55: right after `INITREPLY`, `GETSS` answered `{Strength NaN}` and the relay port
/// refused connections until the next poll (about a second). The WSS now evaluates a robot's
/// links when it registers: here the periodic poll is an hour apart, and both work at once.
#[tokio::test]
async fn getss_and_dns_work_from_the_moment_init_is_answered() {
    // Its first poll comes at once, before any robot exists; the next one an hour later.
    let rig = wss_rig(Duration::from_secs(3600)).await;
    let wss_at = rig.wss_at;
    let base_listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let base_port = base_listener.local_addr().unwrap().port();
    let mut a = Control::connect(wss_at).await;
    let mut b = Control::connect(wss_at).await;
    assert_eq!(
        a.ask("INIT {Robot Robot1} {Port 8001}").await,
        "INITREPLY {Status OK}"
    );
    assert_eq!(
        b.ask(&format!("INIT {{Robot BaseStation}} {{Port {base_port}}}"))
            .await,
        "INITREPLY {Status OK}"
    );
    // At once: a finite strength (4 walls at 7.2 m, about -80.5 dBm), both ways...
    for (c, other) in [(&mut a, "BaseStation"), (&mut b, "Robot1")] {
        let reply = c.ask(&format!("GETSS {{Robot {other}}}")).await;
        let s = strength_of(&reply, other);
        assert!((-93.0..-70.0).contains(&s), "in range: {reply}");
    }
    // ... and a relay port that accepts.
    let port = relay_port(&a.ask("DNS {Robot BaseStation}").await, "BaseStation");
    let mut link = TcpStream::connect(("127.0.0.1", port))
        .await
        .expect("the relay port accepts at once");
    let (mut accepted, _) = base_listener.accept().await.unwrap();
    link.write_all(b"hello").await.unwrap();
    let mut got = [0u8; 5];
    accepted.read_exact(&mut got).await.unwrap();
    assert_eq!(&got, b"hello");
    rig.shutdown.cancel();
}

/// The reference's example session: two robots register, ask the signal and a relay port,
/// talk through it; the link breaks when one flies down behind eight walls and resumes when
/// it climbs back.
#[tokio::test]
async fn a_wss_session_relays_while_in_range_and_breaks_behind_walls() {
    let WssRig {
        robot1: _robot1,
        mut base,
        wss_at,
        shutdown,
    } = wss_rig(Duration::from_millis(100)).await;
    // Each robot's own listener (UsarCommander: 8000 + its number).
    let base_listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let base_port = base_listener.local_addr().unwrap().port();

    let mut a = Control::connect(wss_at).await;
    let mut b = Control::connect(wss_at).await;
    assert_eq!(
        a.ask("GETSS {Robot BaseStation}").await,
        "ERROR {Reason Must.Use.INIT.Method.First}"
    );
    assert_eq!(
        a.ask("INIT {Robot Robot1} {Port 8001}").await,
        "INITREPLY {Status OK}"
    );
    assert_eq!(
        a.ask("INIT {Robot Robot1} {Port 8001}").await,
        "ERROR {Reason Method.Unknown.Or.Can.INIT.only.once}"
    );
    assert_eq!(
        b.ask("INIT {Robot BaseStation} {Port x}").await,
        "ERROR {Reason Ports.List.Must.Be.Integer}"
    );
    assert_eq!(
        b.ask("INIT {Robot Robot1} {Port 1}").await,
        "ERROR {Reason Robot.Alread.Exists}"
    );
    assert_eq!(
        b.ask(&format!("INIT {{Robot BaseStation}} {{Port {base_port}}}"))
            .await,
        "INITREPLY {Status OK}"
    );
    assert_eq!(
        a.ask("GETSS {Robot Robot1}").await,
        "SS {Robot Robot1} {Strength INF} {Error SS.To.Self}"
    );
    assert_eq!(
        a.ask("GETSS {Robot Nobody}").await,
        "SS {Robot Nobody} {Strength NaN} {Error Robot.Does.Not.Exist}"
    );
    assert_eq!(
        a.ask("DNS {Robot Nobody}").await,
        "DNSREPLY {Robot Nobody} {Port -1} {Error NoSuchRobot}"
    );
    assert_eq!(
        a.ask("DNS {Robot BaseStation} {Port 9}").await,
        "DNSREPLY {Robot BaseStation} {Port -1} {Error RobotDoesNotListenOnThisPort}"
    );
    assert_eq!(
        a.ask("DNS {Robot BaseStation} {Port x}").await,
        "ERROR {Reason Port.Must.Be.Integer}"
    );
    assert_eq!(
        a.ask("HELLO").await,
        "ERROR {Reason Method.Unknown.Or.Can.INIT.only.once}"
    );

    // In range over the walls' tops: 4 walls at 7.2 m, about -80.5 dBm.
    let strength = async |a: &mut Control| -> f64 {
        strength_of(&a.ask("GETSS {Robot BaseStation}").await, "BaseStation")
    };
    let mut s = f64::NAN;
    for _ in 0..300 {
        s = strength(&mut a).await;
        if s.is_finite() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!((-93.0..-70.0).contains(&s), "in range: {s}");
    let reply = a.ask("DNS {Robot BaseStation}").await;
    let port = relay_port(&reply, "BaseStation");
    assert_eq!(
        a.ask("DNS {Robot BaseStation}").await,
        reply,
        "the same port again"
    );

    // Robot1 talks to the BaseStation through the relay; the BaseStation asks who it is.
    let mut link = TcpStream::connect(("127.0.0.1", port)).await.unwrap();
    let (mut accepted, from) = base_listener.accept().await.unwrap();
    link.write_all(b"hello base").await.unwrap();
    let mut got = [0u8; 10];
    accepted.read_exact(&mut got).await.unwrap();
    assert_eq!(&got, b"hello base");
    accepted.write_all(b"hi").await.unwrap();
    let mut back = [0u8; 2];
    link.read_exact(&mut back).await.unwrap();
    assert_eq!(&back, b"hi");
    assert_eq!(
        b.ask(&format!("REVERSEDNS {{Port {}}}", from.port())).await,
        format!("REVERSEDNSREPLY {{Port {}}} {{Robot Robot1}}", from.port())
    );
    assert_eq!(
        b.ask("REVERSEDNS {Port 1}").await,
        "REVERSEDNSREPLY {Port 1} {Error UnknownOrIllegalPort}"
    );

    // The BaseStation descends behind the walls: eight walls, out of range; the relayed
    // connection closes and new ones are refused.
    base.write_all(b"DRIVE {AltitudeVelocity -2}\r\n")
        .await
        .unwrap();
    let mut s = 0.0;
    for _ in 0..600 {
        s = strength(&mut a).await;
        if s < -93.0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(s < -93.0, "out of range behind the walls: {s}");
    base.write_all(b"DRIVE {AltitudeVelocity 0}\r\n")
        .await
        .unwrap();
    let mut rest = Vec::new();
    let closed = tokio::time::timeout(Duration::from_secs(30), link.read_to_end(&mut rest)).await;
    assert!(
        closed.is_ok(),
        "the relayed connection is closed when the link breaks"
    );
    let mut refused = false;
    for _ in 0..100 {
        if TcpStream::connect(("127.0.0.1", port)).await.is_err() {
            refused = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(refused, "the relay port does not listen while out of range");

    // Back up: the link resumes on the same port.
    base.write_all(b"DRIVE {AltitudeVelocity 2}\r\n")
        .await
        .unwrap();
    let mut again = None;
    for _ in 0..600 {
        if strength(&mut a).await >= -93.0
            && let Ok(c) = TcpStream::connect(("127.0.0.1", port)).await
        {
            again = Some(c);
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let mut again = again.expect("the link resumes when the BaseStation climbs back");
    base.write_all(b"DRIVE {AltitudeVelocity 0}\r\n")
        .await
        .unwrap();
    let (mut accepted, _) = base_listener.accept().await.unwrap();
    again.write_all(b"back").await.unwrap();
    let mut got = [0u8; 4];
    accepted.read_exact(&mut got).await.unwrap();
    assert_eq!(&got, b"back");
    // A robot that floods its link while the other side does not read: the relay holds no
    // more than the sockets' buffers, so the flooder's writes stop (64 MiB never all go).
    let flood = vec![0u8; 64 << 20];
    let sent = tokio::time::timeout(Duration::from_secs(3), again.write_all(&flood)).await;
    assert!(sent.is_err(), "the relay does not take an unbounded flood");
    drop(accepted);

    // A radio fault on the BaseStation: out of range while it lasts, then the link resumes.
    base.write_all(b"FAULT {Radio Off}\r\n").await.unwrap();
    let mut off = String::new();
    for _ in 0..600 {
        off = a.ask("GETSS {Robot BaseStation}").await;
        if off.contains("Radio.Off") {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(
        off,
        "SS {Robot BaseStation} {Strength -INF} {Error Radio.Off}"
    );
    let mut refused = false;
    for _ in 0..100 {
        if TcpStream::connect(("127.0.0.1", port)).await.is_err() {
            refused = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(refused, "no relay while the radio is off");
    base.write_all(b"FAULT {Radio On}\r\n").await.unwrap();
    let mut resumed = false;
    for _ in 0..600 {
        if strength(&mut a).await >= -93.0 && TcpStream::connect(("127.0.0.1", port)).await.is_ok()
        {
            resumed = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(resumed, "the link resumes when the radio is on again");

    // A name no robot in the simulation has: kicked at the next poll.
    let mut ghost = Control::connect(wss_at).await;
    assert_eq!(
        ghost.ask("INIT {Robot Ghost} {Port 1}").await,
        "INITREPLY {Status OK}"
    );
    let mut rest = Vec::new();
    let kicked =
        tokio::time::timeout(Duration::from_secs(30), ghost.read.read_to_end(&mut rest)).await;
    assert!(
        kicked.is_ok(),
        "a robot the simulation does not have is kicked"
    );
    shutdown.cancel();
}
