//! The `usar-server` program under the conditions of issue #26: full disks, huge
//! recordings, odd files, crowded and unfair clients.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The program under test (`USAR_SERVER_BIN=path` tests another build).
fn server() -> Command {
    Command::new(
        std::env::var_os("USAR_SERVER_BIN")
            .unwrap_or_else(|| env!("CARGO_BIN_EXE_usar-server").into()),
    )
}

/// A scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("usar-hard-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Starts the server with `args` (stderr into `log`); returns it and its address.
fn start(args: &[&std::ffi::OsStr], log: &Path) -> (Child, String) {
    let mut child = server()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    stdout.read_line(&mut line).unwrap();
    let addr = line
        .trim_end()
        .rsplit(' ')
        .find(|w| w.starts_with("127.0.0.1:"))
        .unwrap_or_else(|| panic!("ready line: {line:?}"))
        .to_owned();
    (child, addr)
}

fn terminate(child: &Child) {
    Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
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
    assert!(text.ends_with('\n'), "ends mid-line: {:?}", &text[text.len() - 40..]);
    for (i, line) in text.lines().enumerate() {
        usar_proto::record::parse_entry(line)
            .unwrap_or_else(|e| panic!("line {}: {e}: {line:?}", i + 1));
    }
    std::fs::remove_dir_all(&logs).unwrap();
}
