//! No port opens wider than asked, and no web page drives a robot (issue #56,
//! docs/security.md): the real program with `--bind 127.0.0.1` listens on loopback only,
//! the WSS's relay ports included; a connection whose first line is HTTP is closed, on
//! every text port, before anything of it is served.

mod common;

use std::collections::HashSet;
use std::io::BufRead;
use std::net::SocketAddr;
use std::process::{Child, Stdio};
use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;

/// Every service of the server on a free port.
const FREE_PORTS: [&str; 8] = [
    "--port",
    "0",
    "--truth-port",
    "0",
    "--monitor-port",
    "0",
    "--wss-port",
    "0",
];

/// The program with `args`, its ready lines read (`lines` of them), its stderr into `log`.
fn start(args: &[&str], lines: usize, log: &std::path::Path) -> (Child, String) {
    let mut child = common::program()
        .args(args)
        .env("RUST_LOG", "info")
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .unwrap();
    let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut ready = String::new();
    for _ in 0..lines {
        stdout.read_line(&mut ready).unwrap();
    }
    (child, ready)
}

/// The address a ready line names for `service`.
fn at(ready: &str, service: &str) -> SocketAddr {
    ready
        .lines()
        .find(|l| l.starts_with(&format!("usar-server {service}")))
        .unwrap_or_else(|| panic!("no {service} in {ready:?}"))
        .split_whitespace()
        .find_map(|w| w.parse().ok())
        .unwrap()
}

/// The local addresses of every TCP socket process `pid` listens on (from /proc).
fn listening(pid: u32) -> Vec<String> {
    let inodes: HashSet<String> = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .filter_map(|e| std::fs::read_link(e.ok()?.path()).ok())
        .filter_map(|l| {
            let l = l.to_string_lossy().into_owned();
            Some(l.strip_prefix("socket:[")?.strip_suffix(']')?.to_owned())
        })
        .collect();
    let mut out = Vec::new();
    for table in ["/proc/net/tcp", "/proc/net/tcp6"] {
        let text = std::fs::read_to_string(table).unwrap_or_default();
        for line in text.lines().skip(1) {
            let f: Vec<&str> = line.split_whitespace().collect();
            // local_address, state 0A = LISTEN, inode.
            if f.len() > 9 && f[3] == "0A" && inodes.contains(f[9]) {
                out.push(f[1].to_owned());
            }
        }
    }
    out
}

/// 127.0.0.1 as /proc/net/tcp shows it (little-endian hex), with any port.
fn loopback(local: &str) -> bool {
    local.starts_with("0100007F:")
}

fn port_of(local: &str) -> u16 {
    u16::from_str_radix(local.rsplit(':').next().unwrap(), 16).unwrap()
}

/// One WSS control request and its reply line.
async fn ask(c: &mut BufReader<TcpStream>, request: &str) -> String {
    c.get_mut()
        .write_all(format!("{request}\r\n").as_bytes())
        .await
        .unwrap();
    let mut line = String::new();
    tokio::time::timeout(common::PATIENCE, c.read_line(&mut line))
        .await
        .expect("a WSS reply")
        .unwrap();
    line.trim_end().to_owned()
}

/// Spawns robots A and B on `gamebots` (held open), registers both with the WSS at `wss`
/// and asks it for a relay port from A to B; returns the port and what must stay open.
async fn open_relay(gamebots: SocketAddr, wss: SocketAddr) -> (u16, Vec<TcpStream>) {
    let mut held = Vec::new();
    for (name, at) in [("A", "0,0,-1"), ("B", "2,0,-1")] {
        let mut s = TcpStream::connect(gamebots).await.unwrap();
        let init =
            format!("INIT {{ClassName USARBot.AirRobot}} {{Name {name}}} {{Location {at}}}\r\n");
        s.write_all(init.as_bytes()).await.unwrap();
        held.push(s);
    }
    let mut a = BufReader::new(TcpStream::connect(wss).await.unwrap());
    let mut b = BufReader::new(TcpStream::connect(wss).await.unwrap());
    // The WSS kicks names the simulation does not have yet: register once it has both.
    let mut registered = false;
    for _ in 0..300 {
        tokio::time::sleep(Duration::from_millis(100)).await;
        if !registered {
            if ask(&mut a, "INIT {Robot A} {Port 9}").await != "INITREPLY {Status OK}" {
                continue;
            }
            assert_eq!(
                ask(&mut b, "INIT {Robot B} {Port 9}").await,
                "INITREPLY {Status OK}"
            );
            registered = true;
        }
        let ss = ask(&mut a, "GETSS {Robot B}").await;
        if ss.contains("NaN") || ss.contains("ERROR") {
            continue;
        }
        let reply = ask(&mut a, "DNS {Robot B}").await;
        let port = reply
            .strip_prefix("DNSREPLY {Robot B} {Port ")
            .and_then(|r| r.strip_suffix('}'))
            .unwrap_or_else(|| panic!("{reply}"))
            .parse()
            .unwrap();
        held.push(a.into_inner());
        held.push(b.into_inner());
        return (port, held);
    }
    panic!("the WSS never saw both robots in range");
}

/// Every listening socket of the server, the WSS's relay ports included, is on 127.0.0.1
/// with `--bind 127.0.0.1`: at real time (the WSS on the wall clock) and with `--lockstep`
/// (the WSS on the simulated clock); and those of `usar-server wss`.
#[tokio::test]
async fn with_bind_loopback_every_listener_is_on_loopback() {
    let dir = std::env::temp_dir().join(format!("usar-exposure-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for extra in [None, Some("--lockstep")] {
        let mut args = vec!["--bind", "127.0.0.1"];
        args.extend(FREE_PORTS);
        args.extend(extra);
        let (mut server, ready) = start(&args, 5, &dir.join("server.log"));
        let gamebots: SocketAddr = ready.split_whitespace().nth(3).unwrap().parse().unwrap();
        let (relay, held) = open_relay(gamebots, at(&ready, "WSS listening")).await;
        let sockets = listening(server.id());
        assert!(
            sockets.iter().any(|s| port_of(s) == relay),
            "{extra:?}: the relay port {relay} listens: {sockets:?}"
        );
        assert!(sockets.len() >= 6, "{extra:?}: {sockets:?}");
        let wide: Vec<_> = sockets.iter().filter(|s| !loopback(s)).collect();
        assert!(
            wide.is_empty(),
            "{extra:?}: listening beyond loopback: {wide:?}"
        );
        drop(held);
        // The standalone WSS against this server's monitor.
        let monitor = at(&ready, "robot monitor listening").to_string();
        let (mut wss, wss_ready) = start(
            &[
                "wss",
                "--bind",
                "127.0.0.1",
                "--port",
                "0",
                "--monitor",
                &monitor,
                "--poll",
                "0.2",
            ],
            1,
            &dir.join("wss.log"),
        );
        let (relay, held) = open_relay(gamebots, at(&wss_ready, "WSS listening")).await;
        let sockets = listening(wss.id());
        assert!(sockets.iter().any(|s| port_of(s) == relay), "{sockets:?}");
        let wide: Vec<_> = sockets.iter().filter(|s| !loopback(s)).collect();
        assert!(
            wide.is_empty(),
            "usar-server wss: listening beyond loopback: {wide:?}"
        );
        drop(held);
        let _ = (wss.kill(), wss.wait(), server.kill(), server.wait());
    }
}

/// Reads what the server sends until it closes (or resets) the connection; `None` if it
/// is still open after the patience.
async fn until_closed(s: &mut TcpStream) -> Option<Vec<u8>> {
    let mut got = Vec::new();
    let read = tokio::time::timeout(common::PATIENCE, async {
        let mut buf = [0u8; 4096];
        loop {
            match s.read(&mut buf).await {
                Ok(0) | Err(_) => return,
                Ok(n) => got.extend_from_slice(&buf[..n]),
            }
        }
    });
    read.await.ok().map(|()| got)
}

/// A web page's `text/plain` form POST whose body holds protocol lines.
fn form_post(port: u16, body: &str) -> String {
    format!(
        "POST / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nOrigin: http://evil.example\r\n\
         Content-Type: text/plain\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
}

#[tokio::test]
async fn a_connection_whose_first_line_is_http_is_closed_and_nothing_of_it_is_served() {
    let dir = std::env::temp_dir().join(format!("usar-http-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("server.log");
    let (mut server, ready) = start(&FREE_PORTS, 5, &log);
    let gamebots: SocketAddr = ready.split_whitespace().nth(3).unwrap().parse().unwrap();
    let monitor = at(&ready, "robot monitor listening");
    // The Gamebots port: a POST whose body spawns and drives a robot; and a first line that
    // is a header.
    let body = "INIT {ClassName USARBot.AirRobot} {Name Evil} {Location 0,0,-1}\r\n\
                DRIVE {AltitudeVelocity 1}\r\n";
    for request in [
        form_post(gamebots.port(), body),
        format!("Host: 127.0.0.1\r\n{body}"),
    ] {
        let mut s = TcpStream::connect(gamebots).await.unwrap();
        s.write_all(request.as_bytes()).await.unwrap();
        let got = until_closed(&mut s)
            .await
            .expect("the server closes the connection");
        let text = String::from_utf8_lossy(&got);
        assert!(text.starts_with("NFO"), "only the greeting: {text:?}");
        assert!(!text.contains("STA") && !text.contains("SEN"), "{text:?}");
    }
    // No robot was spawned: the monitor sees none (asked after the INIT would have run).
    tokio::time::sleep(Duration::from_secs(1)).await;
    let mut m = BufReader::new(TcpStream::connect(monitor).await.unwrap());
    assert_eq!(ask(&mut m, "GETPOS").await, "POSITIONS {Robots 0}");
    // The text side ports: closed without an answer.
    for (service, request) in [
        (
            "USARTruth listening",
            "GET / HTTP/1.1\r\nHost: x\r\n\r\n{Name x}\r\n".to_owned(),
        ),
        (
            "robot monitor listening",
            form_post(monitor.port(), "GETPOS\r\n"),
        ),
        (
            "WSS listening",
            form_post(1, "INIT {Robot Evil} {Port 9}\r\nGETSS {Robot A}\r\n"),
        ),
        ("USARTruth listening", "User-Agent: x\r\n\r\n".to_owned()),
    ] {
        let mut s = TcpStream::connect(at(&ready, service)).await.unwrap();
        s.write_all(request.as_bytes()).await.unwrap();
        let got = until_closed(&mut s)
            .await
            .expect("the server closes the connection");
        assert!(
            got.is_empty(),
            "{service}: answered {:?}",
            String::from_utf8_lossy(&got)
        );
    }
    // A real client's first line is still served everywhere.
    assert!(ask(&mut m, "GETPOS").await.starts_with("POSITIONS"));
    // The log is written by a thread of its own (it never blocks serving): its lines may
    // come a moment later on a loaded machine, so read it until all six are there (a
    // generous deadline, only for a failure) before the server is stopped.
    let said = |text: &str| {
        text.lines()
            .filter(|l| l.contains("the first line is HTTP"))
            .count()
    };
    let mut text = String::new();
    for _ in 0..600 {
        text = std::fs::read_to_string(&log).unwrap_or_default();
        if said(&text) >= 6 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let _ = (server.kill(), server.wait());
    assert_eq!(
        said(&text),
        6,
        "each closed connection is logged with the reason:\n{text}"
    );
}
