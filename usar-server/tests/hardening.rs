//! The `usar-server` program under the conditions of issue #26: full disks, huge
//! recordings, odd files, crowded and unfair clients.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{program as server, start_program, terminate};

/// A scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("usar-hard-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Starts the server with `args` (stderr into `log`); returns it and its address.
fn start(args: &[&std::ffi::OsStr], log: &Path) -> (Child, String) {
    let (child, line) = start_program(args, std::fs::File::create(log).unwrap().into());
    let addr = line
        .trim_end()
        .rsplit(' ')
        .find(|w| w.starts_with("127.0.0.1:"))
        .unwrap_or_else(|| panic!("ready line: {line:?}"))
        .to_owned();
    (child, addr)
}

/// Waits until `log` contains `text` (at most 60 s).
fn wait_for_log(log: &Path, text: &str) -> String {
    let start = Instant::now();
    loop {
        let seen = std::fs::read_to_string(log).unwrap_or_default();
        if seen.contains(text) {
            return seen;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{text:?} not logged: {seen}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
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

#[test]
fn a_full_disk_while_recording_is_reported_once_and_the_exit_status_says_so() {
    let Some(disk) = Tmpfs::mount("full-disk", "64k") else {
        return;
    };
    let logs = scratch("full-disk-log");
    let log = logs.join("stderr.txt");
    let (mut child, addr) = start(
        &[
            "--port".as_ref(),
            "0".as_ref(),
            "--truth-port".as_ref(),
            "0".as_ref(),
            "--monitor-port".as_ref(),
            "0".as_ref(),
            "--wss-port".as_ref(),
            "0".as_ref(),
            "--time-scale".as_ref(),
            "20".as_ref(),
            "--record".as_ref(),
            disk.0.as_os_str(),
        ],
        &log,
    );
    let mut client = std::net::TcpStream::connect(&addr).unwrap();
    client
        .write_all(b"INIT {ClassName USARBot.stsAirRobot} {Name UAV1} {Location 0,0,-1}\r\n")
        .unwrap();
    // Keep reading, so that the server is never held by this client.
    let mut reader = client.try_clone().unwrap();
    let drain = std::thread::spawn(move || {
        let mut sink = [0u8; 65536];
        while reader.read(&mut sink).is_ok_and(|n| n > 0) {}
    });
    let file = disk.0.join("connection-0001.usarlog");
    let seen = wait_for_log(&log, "cannot write the recording");
    // Keep going a while: later lines must not be reported again.
    std::thread::sleep(Duration::from_millis(500));
    terminate(&child);
    let status = child.wait().unwrap();
    drop(client);
    drain.join().unwrap();
    let stderr = std::fs::read_to_string(&log).unwrap();
    assert!(seen.contains(&file.display().to_string()), "{seen}");
    assert_eq!(
        stderr.matches("cannot write the recording").count(),
        1,
        "reported once: {stderr}"
    );
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("the recording is incomplete")
            && stderr.contains(&file.display().to_string()),
        "{stderr}"
    );
    // What was written stays readable: whole lines, each a recording entry.
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.len() > 1000, "{} bytes kept", text.len());
    assert!(
        text.ends_with('\n'),
        "ends mid-line: {:?}",
        &text[text.len() - 40..]
    );
    for (i, line) in text.lines().enumerate() {
        usar_proto::record::parse_entry(line)
            .unwrap_or_else(|e| panic!("line {}: {e}: {line:?}", i + 1));
    }
    std::fs::remove_dir_all(&logs).unwrap();
}

/// The peak resident memory (VmHWM) of a running process, in KiB.
fn peak_kib(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or_else(|| panic!("no VmHWM in {status}"))
}

#[test]
fn replaying_a_large_recording_keeps_memory_bounded() {
    let dir = scratch("big-replay");
    let file = dir.join("big.usarlog");
    // 128 MiB of server lines.
    let mut out = std::io::BufWriter::new(std::fs::File::create(&file).unwrap());
    writeln!(out, "# usar-record 1").unwrap();
    writeln!(out, "0.0000 S NFO {{Gametype BotDeathMatch}} {{Level X}}").unwrap();
    let mut written = 0u64;
    let mut lines = 1u64;
    let mut tick = 0u64;
    while written < 128 << 20 {
        tick += 1;
        let t = tick as f64 / 100.0;
        let line = format!(
            "{t:.4} S SEN {{Time {t:.4}}} {{Type Position}} {{Name Position}} {{Location {t:.4},0.0000,-1.0000}}\n"
        );
        out.write_all(line.as_bytes()).unwrap();
        written += line.len() as u64;
        lines += 1;
    }
    out.flush().unwrap();
    drop(out);
    let log = dir.join("stderr.txt");
    let (mut child, addr) = start(
        &[
            "replay".as_ref(),
            file.as_os_str(),
            "--fast".as_ref(),
            "--port".as_ref(),
            "0".as_ref(),
        ],
        &log,
    );
    let mut client = std::net::TcpStream::connect(&addr).unwrap();
    let mut received = BufReader::new(&mut client);
    let mut count = 0u64;
    let mut last = String::new();
    let mut line = String::new();
    while received.read_line(&mut line).unwrap() > 0 {
        count += 1;
        std::mem::swap(&mut last, &mut line);
        line.clear();
    }
    let peak = peak_kib(child.id());
    terminate(&child);
    let status = child.wait().unwrap();
    let stderr = std::fs::read_to_string(&log).unwrap();
    assert!(status.success(), "{stderr}");
    assert_eq!(count, lines, "every server line replayed");
    assert!(last.starts_with(&format!("SEN {{Time {:.4}}}", tick as f64 / 100.0)));
    eprintln!("replayed {written} bytes, peak resident memory {peak} KiB");
    assert!(
        peak < 48 * 1024,
        "peak resident memory {peak} KiB for a {written}-byte recording"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Runs the server with `args`; it must exit 2 within 30 s, with `expected` on stderr.
fn refused(args: &[&std::ffi::OsStr], expected: &[&str]) -> String {
    let mut child = server()
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(30) {
            child.kill().unwrap();
            panic!("{args:?}: still running after 30 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    for e in expected {
        assert!(stderr.contains(e), "{args:?}: {e:?} not in {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

fn mkfifo(path: &Path) {
    assert!(Command::new("mkfifo").arg(path).status().unwrap().success());
}

#[test]
fn a_fifo_named_as_a_mesh_or_a_recording_is_refused_at_once() {
    let dir = scratch("fifo");
    let fifo = dir.join("pipe.obj");
    mkfifo(&fifo);
    let map = dir.join("m.toml");
    std::fs::write(&map, "level = \"X\"\n[[mesh]]\nfile = \"pipe.obj\"\n").unwrap();
    refused(
        &[
            "--map".as_ref(),
            map.as_os_str(),
            "--port".as_ref(),
            "0".as_ref(),
        ],
        &[&fifo.display().to_string(), "not a regular file"],
    );
    refused(
        &[
            "--map".as_ref(),
            fifo.as_os_str(),
            "--port".as_ref(),
            "0".as_ref(),
        ],
        &["not a regular file"],
    );
    refused(
        &[
            "replay".as_ref(),
            fifo.as_os_str(),
            "--port".as_ref(),
            "0".as_ref(),
        ],
        &[&format!("{}: not a regular file", fifo.display())],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_recording_of_an_unknown_version_says_so() {
    let dir = scratch("version");
    let file = dir.join("future.usarlog");
    std::fs::write(
        &file,
        "# usar-record 999\n0.0000 S NFO {Level X}\n0.1000 S STA {Time 0.1000} {Battery 1}\n",
    )
    .unwrap();
    refused(
        &[
            "replay".as_ref(),
            file.as_os_str(),
            "--port".as_ref(),
            "0".as_ref(),
        ],
        &[&format!(
            "{}:1: unknown recording version 999 (this usar-server reads version 1)",
            file.display()
        )],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn huge_numbers_in_error_messages_are_short() {
    let dir = scratch("huge-number");
    let map = dir.join("far.toml");
    std::fs::write(
        &map,
        "level = \"X\"\n[[start]]\ntag = \"S\"\nlocation = [1e308, 0.0, 0.0]\n",
    )
    .unwrap();
    let robots = dir.join("robots.toml");
    std::fs::write(
        &robots,
        "[[robot]]\nclass = \"USARBot.X\"\n[robot.flight]\nmax_linear_speed = 1e308\n\
         max_lateral_speed = 2.0\nmax_altitude_speed = 2.0\nmax_rotation_speed = 100.0\n\
         max_tilt = 25.0\n",
    )
    .unwrap();
    for (args, number) in [
        (["--map".as_ref(), map.as_os_str()], "1e308 is out of range"),
        (["--robots".as_ref(), robots.as_os_str()], "got 1e308"),
    ] {
        let stderr = refused(&args, &[number]);
        assert!(!stderr.contains("0000000000"), "{stderr}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A map or robot file whose names would forge a protocol line or field (issue #56) is
/// refused at start, naming the file, the line and the value, escaped: the server never
/// sends `NFO {Gametype BotDeathMatch} {Level X} {Foo 1} ...`.
#[test]
fn a_file_that_would_forge_a_line_is_refused_at_start() {
    let dir = scratch("forged-names");
    let map = dir.join("forged.toml");
    std::fs::write(&map, "# a level that adds a field\nlevel = \"X} {Foo 1\"\n").unwrap();
    let starts = dir.join("starts.toml");
    std::fs::write(
        &starts,
        "level = \"X\"\n[[start]]\ntag = \"A\\r\\nDRIVE {LinearVelocity 9}\"\nlocation = [0, 0, -1]\n",
    )
    .unwrap();
    let robots = dir.join("robots.toml");
    std::fs::write(
        &robots,
        "[[robot]]\nclass = \"USARBot.X\"\n[[robot.part]]\ntype = \"Sonar\"\nname = \"S\\u001b[2J\"\n",
    )
    .unwrap();
    let shown = |p: &Path, line: u32| format!("{}:{line}:", p.display());
    for (args, expected) in [
        (
            ["--map".as_ref(), map.as_os_str()],
            [
                shown(&map, 2),
                "level \"X} {Foo 1\" holds a brace (})".to_owned(),
            ],
        ),
        (
            ["--map".as_ref(), starts.as_os_str()],
            [
                shown(&starts, 2),
                "start tag \"A\\r\\nDRIVE {LinearVelocity 9}\" holds a carriage return".to_owned(),
            ],
        ),
        (
            ["--robots".as_ref(), robots.as_os_str()],
            [
                shown(&robots, 3),
                "part name \"S\\u{1b}[2J\" holds a control character (U+001B)".to_owned(),
            ],
        ),
    ] {
        let expected: Vec<&str> = expected.iter().map(String::as_str).collect();
        let stderr = refused(&args, &expected);
        assert!(!stderr.contains('\u{1b}'), "{stderr:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `usar-server replay` under a connection flood (the attack suite's rule for every listening
/// program): with the open files limited to 48, 100 clients that never read must not end
/// the replay server (it exited on the first "Too many open files"); once they leave, a new
/// client gets the whole recording.
#[test]
fn the_replay_server_outlives_a_connection_flood() {
    let dir = scratch("replay-flood");
    let file = dir.join("small.usarlog");
    std::fs::write(
        &file,
        "# usar-record 1\n0.0000 S NFO {Gametype BotDeathMatch} {Level X}\n\
         0.0100 S SEN {Time 0.0100} {Type Position} {Name Position} {Location 0,0,-1}\n",
    )
    .unwrap();
    let log = dir.join("stderr.txt");
    let bin = std::env::var_os("USAR_SERVER_BIN")
        .unwrap_or_else(|| env!("CARGO_BIN_EXE_usar-server").into());
    let mut child = Command::new("sh")
        .arg("-c")
        .arg("ulimit -n 48 && exec \"$0\" \"$@\"")
        .arg(bin)
        .arg("replay")
        .arg(&file)
        .args(["--port", "0"])
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let addr = line
        .trim_end()
        .rsplit(' ')
        .find(|w| w.starts_with("127.0.0.1:"))
        .unwrap_or_else(|| panic!("ready line: {line:?}"))
        .to_owned();
    // (A connect the server's full queue leaves unanswered gives up after 200 ms.)
    let to: std::net::SocketAddr = addr.parse().unwrap();
    let flood: Vec<std::net::TcpStream> = (0..100)
        .filter_map(|_| std::net::TcpStream::connect_timeout(&to, Duration::from_millis(200)).ok())
        .collect();
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the replay server exited under {} connections: {}",
        flood.len(),
        std::fs::read_to_string(&log).unwrap()
    );
    drop(flood);
    // The flood has left: a new client is served the whole recording.
    let deadline = Instant::now() + Duration::from_secs(30);
    let got = loop {
        let mut text = String::new();
        if let Ok(mut client) = std::net::TcpStream::connect(&addr) {
            client
                .set_read_timeout(Some(Duration::from_secs(10)))
                .unwrap();
            let _ = client.read_to_string(&mut text);
        }
        if text.contains("SEN {Time 0.0100}") || Instant::now() > deadline {
            break text;
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let alive = child.try_wait().unwrap().is_none();
    terminate(&child);
    let _ = child.wait();
    let stderr = std::fs::read_to_string(&log).unwrap();
    assert!(alive, "the replay server exited: {stderr}");
    assert!(
        got.starts_with("NFO {Gametype BotDeathMatch}"),
        "{got:?}\n{stderr}"
    );
    assert!(got.contains("SEN {Time 0.0100}"), "{got:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
