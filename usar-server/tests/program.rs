//! The `usar-server` program as a user runs it.

use std::io::{BufRead, BufReader, Read};
use std::process::{Command, Stdio};

fn server() -> Command {
    Command::new(env!("CARGO_BIN_EXE_usar-server"))
}

#[test]
fn prints_one_ready_line_and_exits_cleanly_on_sigterm() {
    let mut child = server()
        .args(["--port", "0", "--map", "arena"])
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

    // A client connected at shutdown sees EOF after its greeting.
    let mut client = std::net::TcpStream::connect(("127.0.0.1", port.parse().unwrap())).unwrap();
    let mut greeting = [0u8; 3];
    client.read_exact(&mut greeting).unwrap();
    assert_eq!(&greeting, b"NFO");

    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    assert!(child.wait().unwrap().success(), "exit status 0 on SIGTERM");
    let mut rest = Vec::new();
    client.read_to_end(&mut rest).unwrap(); // EOF, not a reset
    let mut more = String::new();
    stdout.read_to_string(&mut more).unwrap();
    assert_eq!(more, "", "exactly one line on stdout");
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
