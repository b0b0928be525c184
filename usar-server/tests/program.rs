//! The `usar-server` program as a user runs it.

use std::io::{BufRead, BufReader, Read};
use std::process::Stdio;

mod common;
use common::{program as server, start_program, terminate};

#[test]
fn prints_one_ready_line_per_service_and_exits_cleanly_on_sigterm() {
    let mut child = server()
        .args([
            "--port",
            "0",
            "--map",
            "arena",
            "--truth-port",
            "0",
            "--monitor-port",
            "0",
            "--wss-port",
            "0",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    stdout.read_line(&mut line).unwrap();
    let rest = line
        .strip_prefix("usar-server listening on 127.0.0.1:")
        .unwrap_or_else(|| panic!("ready line: {line:?}"));
    let (port, level) = rest.trim_end().split_once(" map ").unwrap();
    assert_eq!(level, "Arena");
    let port: u16 = port.parse().unwrap();
    // Then one line per side service.
    for service in ["image server", "USARTruth", "WSS", "robot monitor"] {
        line.clear();
        stdout.read_line(&mut line).unwrap();
        let prefix = format!("usar-server {service} listening on 127.0.0.1:");
        let side: u16 = line
            .strip_prefix(&prefix)
            .and_then(|p| p.trim_end().parse().ok())
            .unwrap_or_else(|| panic!("{service} line: {line:?}"));
        assert_ne!(side, 0);
    }

    // A client connected at shutdown sees EOF after its greeting.
    let mut client = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    let mut greeting = [0u8; 3];
    client.read_exact(&mut greeting).unwrap();
    assert_eq!(&greeting, b"NFO");

    terminate(&child);
    assert!(child.wait().unwrap().success(), "exit status 0 on SIGTERM");
    let mut rest = Vec::new();
    client.read_to_end(&mut rest).unwrap(); // EOF, not a reset
    let mut more = String::new();
    stdout.read_to_string(&mut more).unwrap();
    assert_eq!(more, "", "exactly one line per service on stdout");
}

#[test]
fn a_broken_map_file_names_the_file_and_line_and_exits_2() {
    let dir = std::env::temp_dir().join(format!("usar-map-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let map = dir.join("broken.toml");
    std::fs::write(
        &map,
        "level = \"X\"\n[[box]]\ncenter = [0.0, 0.0, 0.0]\nsize = [1.0, -1.0, 1.0]\n",
    )
    .unwrap();
    let out = server().arg("--map").arg(&map).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!("{}:2:", map.display()))
            && stderr.contains("size must be positive"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_flags_exit_2() {
    for args in [
        &["--time-scale", "fast"][..],
        &["--map", "no-such-map"],
        &["--bogus"],
        &["--wind", "3"],
        &["--gusts", "-1"],
        &["--wind", "1e300,0"],
    ] {
        let out = server().args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!out.stderr.is_empty());
    }
}

/// A scratch folder for one test.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("usar-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs the server with `args`; it must exit 2 at once, with `expected` on stderr.
fn refused(args: &[&std::ffi::OsStr], expected: &[&str]) -> String {
    let out = server().args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    for e in expected {
        assert!(stderr.contains(e), "{args:?}: {e:?} not in {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

#[test]
fn maps_with_numbers_beyond_the_world_are_refused() {
    // The panic: a box of 1e39 (finite as f64, infinite as f32) crashed parry.
    let dir = scratch("huge-map");
    for (name, solid) in [
        (
            "box",
            "[[box]]\ncenter = [0.0, 0.0, 0.0]\nsize = [1e39, 1.0, 1.0]\n",
        ),
        (
            "cylinder",
            "[[cylinder]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1e39\nheight = 1.0\n",
        ),
        (
            "start",
            "[[start]]\ntag = \"S\"\nlocation = [1e300, 0.0, 0.0]\n",
        ),
    ] {
        let map = dir.join(format!("{name}.toml"));
        std::fs::write(&map, format!("level = \"X\"\n{solid}")).unwrap();
        refused(
            &["--map".as_ref(), map.as_os_str()],
            &[&format!("{}:2:", map.display()), "out of range"],
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn mesh_errors_say_which_file_and_line_once() {
    let dir = scratch("mesh");
    let map = dir.join("m.toml");
    std::fs::write(&map, "level = \"X\"\n[[mesh]]\nfile = \"missing.obj\"\n").unwrap();
    let stderr = refused(
        &["--map".as_ref(), map.as_os_str()],
        &["cannot read mesh file", "missing.obj", "m.toml"],
    );
    assert!(!stderr.contains("map file"), "{stderr}");
    assert_eq!(stderr.matches("No such file").count(), 1, "{stderr}");
    // A binary file given as an OBJ: the line of the first bad byte.
    std::fs::write(&map, "level = \"X\"\n[[mesh]]\nfile = \"bad.obj\"\n").unwrap();
    std::fs::write(
        dir.join("bad.obj"),
        b"v 0 0 0\nv 1 0 0\n\xff\xfe\x00garbage\n",
    )
    .unwrap();
    refused(
        &["--map".as_ref(), map.as_os_str()],
        &[
            &format!("{}:3:", dir.join("bad.obj").display()),
            "not a text file",
        ],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn files_past_the_size_limits_are_refused_unread() {
    let dir = scratch("large");
    let big = dir.join("big.toml");
    // Sparse: nothing is written to disk, and nothing may be read.
    std::fs::File::create(&big)
        .unwrap()
        .set_len(1 << 30)
        .unwrap();
    refused(
        &["--map".as_ref(), big.as_os_str()],
        &["larger than the limit"],
    );
    refused(
        &["--robots".as_ref(), big.as_os_str()],
        &["larger than the limit"],
    );
    refused(
        &[
            "replay".as_ref(),
            big.as_os_str(),
            "--port".as_ref(),
            "0".as_ref(),
        ],
        &["line longer than the limit"],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn absurd_options_are_refused_not_panicked_on() {
    for args in [
        &["--time-scale", "1e-300"][..],
        &["--time-scale", "1e300"],
        &["replay", "x.usarlog", "--speed", "1e-300"],
        &["--lockstep-timeout", "inf"],
    ] {
        let out = server().args(args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

#[test]
fn replay_time_stamps_are_checked() {
    let dir = scratch("replay-times");
    for bad in ["NaN", "inf"] {
        let file = dir.join(format!("{bad}.usarlog"));
        std::fs::write(
            &file,
            format!("# usar-record 1\n0.0000 S NFO {{Level X}}\n{bad} S STA {{Time 1.0000}} {{Battery 1}}\n"),
        )
        .unwrap();
        refused(
            &[
                "replay".as_ref(),
                file.as_os_str(),
                "--port".as_ref(),
                "0".as_ref(),
            ],
            &[&format!("{}:3: bad time stamp", file.display())],
        );
    }
    // 1e300 is a number: served (the wait is capped), never a panic.
    let file = dir.join("far.usarlog");
    std::fs::write(
        &file,
        "# usar-record 1\n0.0000 S NFO {Level X}\n1e300 S STA {Time 1.0000} {Battery 1}\n",
    )
    .unwrap();
    let mut child = server()
        .args([
            "replay".as_ref(),
            file.as_os_str(),
            "--port".as_ref(),
            "0".as_ref(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    stdout.read_line(&mut line).unwrap();
    let addr = line.trim_end().rsplit(' ').next().unwrap().to_owned();
    let mut client = std::net::TcpStream::connect(addr).unwrap();
    let mut first = [0u8; 3];
    client.read_exact(&mut first).unwrap();
    assert_eq!(&first, b"NFO");
    std::thread::sleep(std::time::Duration::from_millis(200));
    terminate(&child);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_client_cannot_flood_the_log_or_write_control_bytes_into_it() {
    // The attack: 30 MB of garbage wrote 356 MB of log, with raw ESC and NUL bytes.
    let mut child = server()
        .args([
            "--port",
            "0",
            "--truth-port",
            "off",
            "--monitor-port",
            "off",
            "--wss-port",
            "off",
        ])
        .env("RUST_LOG", "info")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    stdout.read_line(&mut line).unwrap();
    let addr = line.split_whitespace().nth(3).unwrap().to_owned();
    let stderr = child.stderr.take().unwrap();
    let log = std::thread::spawn(move || {
        let mut text = Vec::new();
        BufReader::new(stderr).read_to_end(&mut text).unwrap();
        text
    });
    let mut client = std::net::TcpStream::connect(&addr).unwrap();
    let mut sink = client.try_clone().unwrap();
    std::thread::spawn(move || std::io::copy(&mut sink, &mut std::io::sink()));
    let garbage = "\u{1b}[2J\0{{{ }}} DRIVE {LinearVelocity x} {Bogus 1}\r\nFOO {Bar \u{1b}]0;pwned\u{7}}\r\n";
    let mut sent = 0;
    while sent < 4 << 20 {
        std::io::Write::write_all(&mut client, garbage.repeat(1000).as_bytes()).unwrap();
        sent += garbage.len() * 1000;
    }
    drop(client);
    std::thread::sleep(std::time::Duration::from_millis(500));
    terminate(&child);
    assert!(child.wait().unwrap().success());
    let log = log.join().unwrap();
    println!("{sent} bytes of garbage gave {} bytes of log", log.len());
    assert!(log.len() < 64 * 1024, "{} bytes of log", log.len());
    assert!(
        !log.contains(&0x1b) && !log.contains(&0),
        "raw control bytes in the log"
    );
}

/// The defect: `--record notadir` (a file) printed `listening on …`, then exited 1 with
/// `File exists (os error 17): File exists (os error 17)`, naming no path.
#[test]
fn a_record_folder_that_cannot_be_made_is_refused_before_listening() {
    let dir = scratch("record-notadir");
    let file = dir.join("notadir");
    std::fs::write(&file, "").unwrap();
    for path in [file.as_os_str(), std::ffi::OsStr::new("/proc/foo")] {
        let out = server()
            .args(["--port".as_ref(), "0".as_ref(), "--record".as_ref(), path])
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{path:?}: {stderr}");
        assert!(!stdout.contains("listening"), "{stdout}");
        let shown = path.to_string_lossy();
        assert!(stderr.contains(&*shown), "names {shown}: {stderr}");
        let cause = stderr.rsplit(": ").next().unwrap().trim();
        assert_eq!(stderr.matches(cause).count(), 1, "the cause once: {stderr}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// SIGTERM sent as soon as the ready line is out stops the server, cleanly, every time: the
/// handler is in place before the line is printed. (It was installed by a spawned task: a
/// signal before it killed the server, one while it was being installed was swallowed and
/// the server ran on, which hung a test.)
#[test]
fn sigterm_right_after_the_ready_line_stops_the_server_cleanly() {
    for run in 0..20 {
        let (mut child, line) = start_program(
            &[
                "--port",
                "0",
                "--image-port",
                "off",
                "--truth-port",
                "off",
                "--wss-port",
                "off",
                "--monitor-port",
                "off",
            ],
            Stdio::null(),
        );
        assert!(line.starts_with("usar-server listening on "), "{line:?}");
        terminate(&child);
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        let status = loop {
            if let Some(status) = child.try_wait().unwrap() {
                break status;
            }
            if std::time::Instant::now() > deadline {
                let _ = child.kill();
                panic!("run {run}: still running 10 s after SIGTERM");
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        };
        assert!(status.success(), "run {run}: {status}");
    }
}

#[test]
fn the_image_port_option_takes_a_port_or_off() {
    // Whether the image server's ready line comes (the other side services' lines come in
    // both cases).
    for (value, lines) in [("0", 1), ("off", 0)] {
        let mut child = server()
            .args(["--port", "0", "--image-port", value])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut text = String::new();
        stdout.read_line(&mut text).unwrap();
        assert!(text.starts_with("usar-server listening on "), "{text:?}");
        terminate(&child);
        stdout.read_to_string(&mut text).unwrap();
        assert!(child.wait().unwrap().success(), "--image-port {value}");
        assert_eq!(
            text.lines()
                .filter(|l| l.starts_with("usar-server image server listening on "))
                .count(),
            lines,
            "--image-port {value}: {text:?}"
        );
    }
    let out = server().args(["--image-port", "nope"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("'off'"));
}
