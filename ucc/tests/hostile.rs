//! `ucc decode`, `ucc encode` and `ucc tap` under hostile input (docs/limits.md): memory
//! bounds read from the process's peak resident memory (VmHWM), the tap's start-up checks,
//! and the attack suite of the tap: floods, connection exhaustion, control bytes, over-long
//! lines, each while a healthy client flies through the tap and must keep 90 % of its rate
//! (measured against a client flying straight to the server at the same time, so that what
//! the machine's load does to the server is not counted against the tap).
//!
//! `UCC_BIN=path` runs these against another build of `ucc` (an older one, to compare).

use std::io::{BufRead, Read, Write};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;
use tokio_util::sync::CancellationToken;

/// Peak resident memory any of these programs may reach, MiB (as the server's bound).
const MEMORY_BOUND_MIB: f64 = 64.0;

fn ucc() -> Command {
    let bin = std::env::var_os("UCC_BIN").unwrap_or_else(|| env!("CARGO_BIN_EXE_ucc").into());
    Command::new(bin)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ucc-hostile-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Peak resident memory of a running process, MiB.
fn peak_mib(pid: u32) -> f64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .unwrap_or_default()
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

/// Writes `total` bytes of `chunk` repeated to `ucc args` and returns its peak memory (MiB,
/// read once everything was written), exit status and stderr.
fn feed(args: &[&str], chunk: &[u8], total: usize) -> (f64, Option<i32>, String) {
    let mut child = ucc()
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let errors = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr.read_to_string(&mut text);
        text
    });
    let mut stdin = child.stdin.take().unwrap();
    let mut written = 0;
    while written < total && stdin.write_all(chunk).is_ok() {
        written += chunk.len();
    }
    // The pipe holds 64 KiB: all but that has been read by now.
    let peak = peak_mib(child.id());
    drop(stdin);
    let status = child.wait().unwrap();
    (peak, status.code(), errors.join().unwrap())
}

/// The defect (#26): 1 GB without a line ending took 6.1 GB of memory in `decode`, 1 GB of
/// CR-only line endings 2.4 GB, and `encode` 1.0 GB.
#[test]
fn decode_and_encode_stream_in_bounded_memory() {
    let mib = 1024 * 1024;
    let no_ending = vec![b'A'; mib];
    let (peak, code, stderr) = feed(&["decode"], &no_ending, 256 * mib);
    println!("decode, 256 MiB without a line ending: peak {peak:.1} MiB");
    assert!(peak < MEMORY_BOUND_MIB, "decode took {peak:.1} MiB");
    assert_eq!(code, Some(1));
    assert!(
        stderr.starts_with("line 1: 268435456 bytes, longer than the limit of 65536: skipped"),
        "{stderr}"
    );

    // Lines just under the limit, ended by a lone CR: each is read and written on.
    let mut cr_lines = vec![b'B'; 60_000];
    cr_lines.push(b'\r');
    let (peak, code, stderr) = feed(&["decode"], &cr_lines, 128 * mib);
    println!("decode, 128 MiB of 60 KB lines ended by CR: peak {peak:.1} MiB");
    assert!(peak < MEMORY_BOUND_MIB, "decode took {peak:.1} MiB");
    assert_eq!((code, stderr.as_str()), (Some(0), ""));

    let (peak, code, stderr) = feed(&["encode"], &no_ending, 256 * mib);
    println!("encode, 256 MiB without a line ending: peak {peak:.1} MiB");
    assert!(peak < MEMORY_BOUND_MIB, "encode took {peak:.1} MiB");
    assert_eq!(code, Some(1));
    assert!(
        stderr.starts_with("line 1: 268435456 bytes, longer than the limit of 1048576: skipped"),
        "{stderr}"
    );
}

/// `ucc tap` as a child process: its address, and its stderr in a file.
struct Tap {
    child: Child,
    addr: SocketAddr,
    log: PathBuf,
}

impl Tap {
    /// Starts `ucc tap` in front of `upstream` (through `sh` for `ulimit -n`), recording
    /// to `record`, its log in `dir`.
    fn start(
        upstream: SocketAddr,
        dir: &std::path::Path,
        record: &std::path::Path,
        fd_limit: u32,
        extra: &[&str],
    ) -> Self {
        let log = dir.join("tap.log");
        let bin = std::env::var_os("UCC_BIN").unwrap_or_else(|| env!("CARGO_BIN_EXE_ucc").into());
        let mut child = Command::new("sh")
            .arg("-c")
            .arg(format!("ulimit -n {fd_limit} && exec \"$0\" \"$@\""))
            .arg(bin)
            .args(["tap", "--listen", "0", "--upstream", &upstream.to_string()])
            .arg("--record")
            .arg(record)
            .args(extra)
            .env("RUST_LOG", "warn")
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap();
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        // "ucc tap: listening on 127.0.0.1:PORT, forwarding to ..."
        let addr = line
            .split_whitespace()
            .nth(4)
            .and_then(|a| a.trim_end_matches(',').parse().ok())
            .unwrap_or_else(|| panic!("no address in {line:?}"));
        Self { child, addr, log }
    }

    fn alive(&mut self) -> bool {
        self.child.try_wait().unwrap().is_none()
    }
}

impl Drop for Tap {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The healthy client, through the tap: an stsAirRobot, reading everything; its rate in
/// lines per wall second over three whole simulated seconds (from one STA to the STA three
/// seconds later, so that the sensors' intervals do not change the count), after a head
/// start of 0.7 s, with a deadline of 7 s (a stalled stream is measured as stalled). It
/// spawns at `x`,0,-1.
async fn healthy_rate(addr: SocketAddr, name: &str, x: f64) -> f64 {
    let Ok(stream) = TcpStream::connect(addr).await else {
        return 0.0;
    };
    let (read, mut write) = stream.into_split();
    let mut lines = BufReader::new(read);
    let mut line = String::new();
    let next = async |lines: &mut BufReader<_>, line: &mut String, until: Instant| {
        line.clear();
        let wait = until.saturating_duration_since(Instant::now());
        matches!(
            tokio::time::timeout(wait, lines.read_line(line)).await,
            Ok(Ok(n)) if n > 0
        )
    };
    if !next(
        &mut lines,
        &mut line,
        Instant::now() + Duration::from_secs(10),
    )
    .await
        || !line.starts_with("NFO")
    {
        return 0.0;
    }
    let init =
        format!("INIT {{ClassName USARBot.stsAirRobot}} {{Name {name}}} {{Location {x},0,-1}}\r\n");
    if write.write_all(init.as_bytes()).await.is_err() {
        return 0.0;
    }
    let sta_time = |line: &str| {
        line.strip_prefix("STA {Time ")
            .and_then(|rest| rest.split('}').next())
            .and_then(|t| t.parse::<f64>().ok())
    };
    let begin = Instant::now() + Duration::from_millis(700);
    let deadline = begin + Duration::from_secs(7);
    let (first, t0) = loop {
        if !next(&mut lines, &mut line, deadline).await {
            return 0.0;
        }
        if let Some(t) = sta_time(&line).filter(|_| Instant::now() >= begin) {
            break (Instant::now(), t);
        }
    };
    let mut count = 1u64;
    while next(&mut lines, &mut line, deadline).await {
        if sta_time(&line).is_some_and(|t| t >= t0 + 3.0 - 1e-3) {
            break;
        }
        count += 1;
    }
    count as f64 / first.elapsed().as_secs_f64()
}

/// The healthy client's rate through the tap at `tap` over the rate of another one flying
/// straight to the server at `server` at the same time: 1 when the tap costs nothing. On a
/// busy machine both slow down alike; only what the tap adds lowers this. Also the rate
/// through the tap, lines/s. A direct client that gets nothing measures nothing: share 0.
async fn tap_share(tap: SocketAddr, server: SocketAddr, name: &str) -> (f64, f64) {
    let other = format!("{name}Direct");
    let (through, direct) = tokio::join!(
        healthy_rate(tap, name, 0.0),
        healthy_rate(server, &other, 3.0)
    );
    println!("{name}: {through:.1} lines/s through the tap, {direct:.1} direct");
    let share = if direct > 0.0 { through / direct } else { 0.0 };
    (share, through)
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

/// The defects (#25, #26): `--upstream nohostport` failed only when a client came, a bad
/// `--record` path dropped every client without naming the path.
#[test]
fn the_tap_checks_its_upstream_and_recording_at_start() {
    let dir = scratch("tap-start");
    let record = dir.join("s.usarlog");
    // A tap that does not check listens until stopped: 10 s is its limit here.
    let run = |upstream: &str, record: &std::path::Path| {
        let mut child = ucc()
            .args(["tap", "--listen", "0", "--upstream", upstream, "--record"])
            .arg(record)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let began = Instant::now();
        while child.try_wait().unwrap().is_none() && began.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = child.kill();
        let out = child.wait_with_output().unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, stdout, stderr) = run("nohostport", &record);
    assert_eq!(code, Some(1), "{stdout}{stderr}");
    assert!(!stdout.contains("listening"), "{stdout}");
    assert!(
        stderr.contains("--upstream nohostport:") && stderr.contains("expected HOST:PORT"),
        "{stderr}"
    );
    let (code, stdout, stderr) = run("127.0.0.1:3000", &dir.join("missing/s.usarlog"));
    assert_eq!(code, Some(1), "{stdout}{stderr}");
    assert!(!stdout.contains("listening"), "{stdout}");
    assert!(stderr.contains("missing/s.usarlog"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A real-time server that takes a thousand connections, and `ucc tap` in front of it with
/// `fd_limit` open files and `--max-connections max`, recording into a fresh folder `name`.
async fn attacked_tap(
    name: &str,
    fd_limit: u32,
    max: &str,
) -> (usar_server::LocalServer, PathBuf, Tap) {
    let server = usar_server::LocalServer::start(usar_server::ServerConfig {
        time_scale: usar_server::TimeScale::Factor(1.0),
        max_connections: 1000,
        max_connections_per_address: 1000,
        ..usar_server::ServerConfig::default()
    })
    .await
    .unwrap();
    let dir = scratch(name);
    let record = dir.join("session.usarlog");
    let tap = Tap::start(
        server.addr(),
        &dir,
        &record,
        fd_limit,
        &["--max-connections", max],
    );
    (server, dir, tap)
}

/// The attack suite of the tap (docs/limits.md): with the open files limited to 48, the tap
/// must outlive 200 connections, refuse those past `--max-connections`, keep its log small
/// and free of control bytes under a flood of them (66 MB of traffic gave 662 MB of log), and stay under the memory bound, while a
/// healthy client flying through it keeps 90 % of its rate (in one of three attempts per
/// attack: a starving attack starves every time, a busy machine only now and then).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_tap_survives_the_attack_suite() {
    // A session holds three files (its client, its upstream, its recording): eight of them
    // and the tap's own fit in 48, so the limit of connections is what refuses the others.
    // (With 32, the files could run out first, and whether the log said "connection
    // refused" depended on how the sessions' tasks and the accepts interleaved; running out
    // of files is the next test's.)
    let (server, dir, mut tap) = attacked_tap("tap-attack", 48, "8").await;
    let (baseline, rate) = tap_share(tap.addr, server.addr(), "Base").await;
    assert!(rate > 20.0, "the healthy client gets {rate:.1} lines/s");
    assert!(
        baseline > 0.5,
        "without an attack the client through the tap gets {:.0} % of the direct one's rate",
        baseline * 100.0
    );

    type Attack = fn(SocketAddr, CancellationToken) -> tokio::task::JoinHandle<()>;
    let attacks: [(&str, Attack); 3] = [
        ("200 connections, idle", |addr, stop| {
            tokio::spawn(async move {
                // The healthy client connects first: at the tap's cap (32) the excess is
                // refused, so an attacker that won the race for every slot would measure the
                // cap, not the tap's health. Its measurement starts 0.7 s in, with all 200
                // connections made.
                tokio::time::sleep(Duration::from_millis(300)).await;
                let mut held = Vec::new();
                for _ in 0..200 {
                    if let Ok(Ok(s)) =
                        tokio::time::timeout(Duration::from_millis(200), TcpStream::connect(addr))
                            .await
                    {
                        held.push(s);
                    }
                }
                stop.cancelled().await;
            })
        }),
        (
            "control bytes (ESC, BEL, NUL) as fast as possible",
            |addr, stop| {
                tokio::spawn(async move {
                    let chunk = "DRIVE \u{1b}[2J\u{7}{Left \0 1}\u{1b}]0;pwned\u{7}\r\n"
                        .repeat(2000)
                        .into_bytes();
                    let s = TcpStream::connect(addr).await.unwrap();
                    flood(s, chunk, stop).await;
                })
            },
        ),
        (
            "8 connections of over-long lines, never reading",
            |addr, stop| {
                tokio::spawn(async move {
                    let mut floods = Vec::new();
                    for _ in 0..8 {
                        let s = TcpStream::connect(addr).await.unwrap();
                        floods.push(tokio::spawn(flood(s, vec![b'X'; 256 * 1024], stop.clone())));
                    }
                    for f in floods {
                        let _ = f.await;
                    }
                })
            },
        ),
    ];
    let mut failures = Vec::new();
    'attacks: for (i, (name, attack)) in attacks.iter().enumerate() {
        // An attack that starves the healthy client does so every time; a share below 90 %
        // once (a 2-core machine busy with other tests) is measured again, up to three times.
        let mut shares = Vec::new();
        for attempt in 0..3 {
            let stop = CancellationToken::new();
            let running = attack(tap.addr, stop.clone());
            let client = format!("Healthy{i}x{attempt}");
            let share = tap_share(tap.addr, server.addr(), &client).await.0 / baseline;
            stop.cancel();
            let _ = running.await;
            let peak = peak_mib(tap.child.id());
            println!(
                "{name}: healthy client {:.0} % of its rate, tap peak {peak:.1} MiB",
                share * 100.0
            );
            if !tap.alive() {
                failures.push(format!("{name}: the tap died"));
                break 'attacks;
            }
            // Let the attack's connections close before the next one.
            tokio::time::sleep(Duration::from_millis(500)).await;
            shares.push(share);
            if share >= 0.9 {
                break;
            }
        }
        // The high-water mark: of every attempt so far.
        let peak = peak_mib(tap.child.id());
        if peak > MEMORY_BOUND_MIB {
            failures.push(format!("{name}: {peak:.1} MiB"));
        }
        if shares.iter().all(|&s| s < 0.9) {
            let shown: Vec<String> = shares
                .iter()
                .map(|s| format!("{:.0} %", s * 100.0))
                .collect();
            failures.push(format!("{name}: healthy client at {}", shown.join(", ")));
        }
    }
    // After everything, a new client is served.
    assert!(
        healthy_rate(tap.addr, "After", 0.0).await > 0.0,
        "no service after the attacks"
    );
    let log = std::fs::read(&tap.log).unwrap();
    println!("tap log: {} bytes", log.len());
    assert!(
        !log.iter().any(|b| matches!(b, 0x1b | 0x07 | 0)),
        "raw control bytes in the tap's log"
    );
    assert!(
        log.len() < 256 * 1024,
        "the log grew to {} bytes",
        log.len()
    );
    let text = String::from_utf8_lossy(&log);
    assert!(text.contains("connection refused"), "{text}");
    assert!(failures.is_empty(), "{failures:?}");
    drop(tap);
    server.stop().await.unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}

/// With the open files limited to 32 and no limit of connections in the way, 100 idle
/// connections take every file the tap may open: it says so in its log, outlives it (it
/// died at 101 connections with "Too many open files" before it waited such accepts out),
/// and serves a new client once they have gone.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_tap_outlives_running_out_of_files() {
    let (server, dir, mut tap) = attacked_tap("tap-files", 32, "200").await;
    let mut held = Vec::new();
    for _ in 0..100 {
        if let Ok(Ok(s)) =
            tokio::time::timeout(Duration::from_millis(200), TcpStream::connect(tap.addr)).await
        {
            held.push(s);
        }
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert!(tap.alive(), "the tap died out of files");
    let log = String::from_utf8_lossy(&std::fs::read(&tap.log).unwrap()).into_owned();
    assert!(log.contains("Too many open files"), "{log}");
    drop(held);
    // The tap drains the closed connections from its backlog first (each a session that
    // opens and closes its upstream connection and recording): on a loaded machine that
    // takes a while, so a new client is tried again, for up to about a minute.
    let mut served = false;
    for attempt in 0..6 {
        tokio::time::sleep(Duration::from_millis(500)).await;
        if healthy_rate(tap.addr, &format!("AfterFiles{attempt}"), 0.0).await > 0.0 {
            served = true;
            break;
        }
    }
    assert!(served, "no service once the files were free again");
    assert!(tap.alive());
    drop(tap);
    server.stop().await.unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A tmpfs of `size` mounted on a fresh folder (`None` where this process may not mount).
struct Tmpfs(PathBuf);

impl Tmpfs {
    fn mount(name: &str, size: &str) -> Option<Self> {
        let dir = scratch(name);
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(&dir)
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            Some(Self(dir))
        } else {
            eprintln!("cannot mount a tmpfs here (not root?): test skipped");
            None
        }
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A recording cut by a full disk: it ends with a whole line, and every line reads.
fn assert_whole_lines(path: &std::path::Path) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.len() > 1000, "{} bytes recorded", text.len());
    assert!(
        text.ends_with('\n'),
        "the recording ends mid-line: {:?}",
        &text[text.len().saturating_sub(80)..]
    );
    for line in text.lines() {
        usar_proto::record::parse_entry(line).unwrap_or_else(|e| panic!("{line:?}: {e}"));
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn a_full_disk_ends_the_taps_recording_at_a_whole_line_and_the_tap_goes_on() {
    let Some(disk) = Tmpfs::mount("tap-full", "16k") else {
        return;
    };
    let server = usar_server::LocalServer::start(usar_server::ServerConfig {
        time_scale: usar_server::TimeScale::Factor(1.0),
        ..usar_server::ServerConfig::default()
    })
    .await
    .unwrap();
    let dir = scratch("tap-full-log");
    let record = disk.0.join("session.usarlog");
    let mut tap = Tap::start(server.addr(), &dir, &record, 256, &[]);
    // Three seconds of an stsAirRobot's lines are several times the disk.
    let rate = healthy_rate(tap.addr, "Full", 0.0).await;
    assert!(rate > 20.0, "the client gets {rate:.1} lines/s");
    assert!(tap.alive(), "the tap ended");
    let log = std::fs::read_to_string(&tap.log).unwrap();
    assert_eq!(
        log.matches("cannot write the recording").count(),
        1,
        "said once: {log}"
    );
    assert!(log.contains(&record.display().to_string()), "{log}");
    assert_whole_lines(&record);
}

#[test]
fn a_full_disk_ends_a_runs_recording_at_a_whole_line_and_the_error_says_it_once() {
    let Some(disk) = Tmpfs::mount("run-full", "16k") else {
        return;
    };
    let logs = scratch("run-full-logs");
    let record = disk.0.join("flight.usarlog");
    let out = ucc()
        .args(["run", "--local", "--start", "0,0,-1", "--goto", "3,0,-1"])
        .args([
            "--goto",
            "0,0,-1",
            "--pictures",
            "none",
            "--quiet",
            "--log-dir",
        ])
        .arg(&logs)
        .arg("--record")
        .arg(&record)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&record.display().to_string()) && stderr.contains("No space left"),
        "{stderr}"
    );
    assert_eq!(
        stderr.matches("No space left").count(),
        1,
        "the cause said once: {stderr}"
    );
    assert_whole_lines(&record);
}

/// Runs `ucc args` with `input` on stdin: exit status, stdout, stderr.
fn pipe(args: &[&str], input: &[u8]) -> (Option<i32>, String, String) {
    let mut child = ucc()
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let input = input.to_vec();
    // A program that stops reading early closes the pipe: not an error here.
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(&input);
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The defect (#56): `ucc decode` exited 0 on random bytes, reading them lossily as unknown
/// commands. It stops where the input stops being the protocol, naming the line and the
/// byte offset; real captures, unknown message words included, still decode.
#[test]
fn decode_stops_where_the_input_stops_being_the_protocol() {
    // Random bytes (a fixed generator: the same bytes every run).
    let mut x = 0x2545_f491_4f6c_dd1du64;
    let random: Vec<u8> = (0..100_000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 24) as u8
        })
        .collect();
    let (code, _, stderr) = pipe(&["decode"], &random);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("not the protocol") && stderr.contains(", byte "),
        "{stderr}"
    );
    for (input, at) in [
        // Text that parses as nothing: where the message word should end.
        (
            &b"STA {Time 1.0000} {Battery 99}\nhello world\n"[..],
            "line 2, byte 37:",
        ),
        (
            b"STA {Time 1.0000} {Battery 99}\r\nDRIVE {Left \xff}\n",
            "line 2, byte 44:",
        ),
        (b"GETSTARTPOSES\n\x1b[2J\n", "line 2, byte 14:"),
        (b"\n  #!x\n", "line 2, byte 3:"),
    ] {
        let (code, stdout, stderr) = pipe(&["decode", "--print"], input);
        assert_eq!(code, Some(1), "{stderr}");
        assert!(
            stderr.starts_with(&format!("{at} not the protocol")),
            "{at}: {stderr}"
        );
        // What came before was decoded (the last case has only a blank line before).
        let before = usize::from(!input.starts_with(b"\n"));
        assert_eq!(stdout.lines().count(), before, "{stdout}");
    }
    // Real captures, with their unknown words (MULTIDRIVE, TEST, Com1), decode with exit 0.
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../usar-proto/tests/data/");
    let capture = std::fs::read(format!("{data}USARcommandSample.txt")).unwrap();
    let (code, _, stderr) = pipe(&["decode"], &capture);
    assert_eq!((code, stderr.as_str()), (Some(0), ""));
    let examples = std::fs::read_to_string(format!("{data}protocol_examples.txt")).unwrap();
    let lines: String = examples
        .lines()
        .filter_map(|l| l.get(2..).filter(|_| !l.starts_with('#')))
        .map(|l| format!("{l}\r\n"))
        .collect();
    let (code, _, stderr) = pipe(&["decode"], lines.as_bytes());
    assert_eq!((code, stderr.as_str()), (Some(0), ""));
}

/// The defect (#56): `ucc encode` printed braces of a value as they were, so that a name
/// could add a field (`UAV} {Location 9,9,9`) to the line.
#[test]
fn encode_refuses_a_value_that_would_add_a_field() {
    let input = concat!(
        "{\"client\":{\"Init\":{\"class_name\":\"USARBot.stsAirRobot\",\"name\":\"UAV} {Location 9,9,9\",\"location\":null,\"rotation\":null,\"start\":null}}}\n",
        "{\"server\":{\"Nfo\":{\"GameInfo\":{\"gametype\":\"BotDeathMatch\",\"level\":\"Map} {TimeLimit 1\",\"time_limit\":20}}}}\n",
        "{\"client\":{\"Other\":{\"kind\":\"X\",\"groups\":[{\"pairs\":[{\"key\":\"A\",\"value\":\"1}{B 2\"}]}]}}}\n",
        "{\"client\":\"GetStartPoses\"}\n",
    );
    let (code, stdout, stderr) = pipe(&["encode"], input.as_bytes());
    assert_eq!(code, Some(1), "{stderr}");
    assert_eq!(stdout, "GETSTARTPOSES\n", "{stderr}");
    for line in 1..=3 {
        assert!(stderr.contains(&format!("line {line}: ")), "{stderr}");
    }
    assert!(
        stderr.contains("INIT {Name ..}") && stderr.contains("a brace"),
        "{stderr}"
    );
    assert!(stderr.contains("{level ..}"), "{stderr}");
}

/// The defect (#56): `1e308` came out of `ucc decode --print` and `ucc encode` as 309 digits.
/// UDK's floats are 32-bit: nothing longer than f32::MAX (39 digits) is printed.
#[test]
fn no_number_comes_out_as_hundreds_of_digits() {
    let longest_number = |text: &str| {
        text.split(|c: char| !c.is_ascii_digit())
            .map(str::len)
            .max()
            .unwrap_or(0)
    };
    let (code, stdout, stderr) = pipe(
        &["decode", "--print"],
        b"DRIVE {Left 1e308} {Right 1}\nINIT {ClassName X} {Location 1e308,0,-1e308}\n",
    );
    assert_eq!((code, stderr.as_str()), (Some(0), ""));
    assert!(longest_number(&stdout) <= 39, "{stdout}");
    let (code, stdout, stderr) = pipe(
        &["encode"],
        concat!(
            "{\"server\":{\"Sta\":{\"time\":{\"seconds\":1e308,\"decimals\":4},\"battery\":1,\"vehicle\":null,\"layout\":\"Udk\"}}}\n",
            "{\"client\":{\"Drive\":{\"left\":-1e308,\"right\":5e-324}}}\n",
        )
        .as_bytes(),
    );
    assert_eq!((code, stderr.as_str()), (Some(0), ""));
    assert!(longest_number(&stdout) <= 39, "{stdout}");
    assert!(
        stdout.starts_with("STA {Time 340282346638528859811704183484516925440.0000}"),
        "{stdout}"
    );
}

/// The defect (#56): a full disk under `ucc decode`'s output said "cannot read or write the
/// lines", naming nothing.
#[test]
fn decode_into_a_full_disk_names_its_output() {
    for command in ["decode", "encode"] {
        let input: &[u8] = if command == "decode" {
            b"STA {Time 1.0000} {Battery 99}\n"
        } else {
            b"{\"client\":\"GetStartPoses\"}\n"
        };
        let out = ucc()
            .arg(command)
            .stdin(Stdio::piped())
            .stdout(std::fs::File::create("/dev/full").unwrap())
            .stderr(Stdio::piped())
            .spawn()
            .and_then(|mut child| {
                child.stdin.take().unwrap().write_all(input)?;
                child.wait_with_output()
            })
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("cannot write standard output: No space left"),
            "{command}: {stderr}"
        );
    }
}

/// The defect (#56): `ucc tap` exited 0 after its recording could not be written. It goes on
/// forwarding, and at exit names the incomplete recording with status 1. The recording is
/// /dev/full (writing it fails with ENOSPC), so no mount is needed.
#[tokio::test(flavor = "multi_thread")]
async fn the_tap_exits_non_zero_naming_a_recording_it_could_not_write() {
    let server = usar_server::LocalServer::start(usar_server::ServerConfig {
        time_scale: usar_server::TimeScale::Factor(1.0),
        ..usar_server::ServerConfig::default()
    })
    .await
    .unwrap();
    let dir = scratch("tap-dev-full");
    let record = dir.join("session.usarlog");
    std::os::unix::fs::symlink("/dev/full", &record).unwrap();
    let mut tap = Tap::start(server.addr(), &dir, &record, 256, &[]);
    let rate = healthy_rate(tap.addr, "Full", 0.0).await;
    assert!(rate > 20.0, "the client gets {rate:.1} lines/s");
    assert!(tap.alive(), "the tap ended");
    let term = Command::new("kill")
        .args(["-TERM", &tap.child.id().to_string()])
        .status()
        .unwrap();
    assert!(term.success());
    let began = Instant::now();
    let status = loop {
        if let Some(status) = tap.child.try_wait().unwrap() {
            break status;
        }
        assert!(
            began.elapsed() < Duration::from_secs(30),
            "the tap did not end"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let log = std::fs::read_to_string(&tap.log).unwrap();
    assert_eq!(status.code(), Some(1), "{log}");
    assert!(
        log.contains(&format!(
            "ucc tap: error: the recording is incomplete: {}: No space left",
            record.display()
        )),
        "{log}"
    );
    server.stop().await.unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}
