//! The `ucc` program as a user runs it.

use std::path::{Path, PathBuf};
use std::process::Command;

fn ucc() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ucc"))
}

/// A fresh, empty folder under the target directory's temp space.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ucc-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const MISSION: [&str; 8] = [
    "--goto",
    "3,0,-2",
    "--goto",
    "3,3,-2.5",
    "--goto",
    "-2,3,-1.5",
    "--goto",
    "-2,-2,-2",
];

fn run_local(dir: &Path, iterations: u32, extra: &[&str]) -> std::process::Output {
    ucc()
        .args(["run", "--local", "--lockstep", "--start", "0,0,-1"])
        .args(MISSION)
        .args(["--iterations", &iterations.to_string(), "--log-dir"])
        .arg(dir)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn twenty_iterations_complete_and_the_overlay_shows_them() {
    let dir = scratch("twenty");
    let out = run_local(&dir, 20, &["--quiet"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("iterations: 20 done, 0 failed"), "{stdout}");
    assert!(stdout.contains("real-time factor"), "{stdout}");
    let results = std::fs::read_to_string(dir.join("UCCLOG-results.csv")).unwrap();
    assert_eq!(results.lines().count(), 21, "{results}");
    assert!(
        results.lines().skip(1).all(|l| l.contains(",ok,4,")),
        "{results}"
    );
    for i in 1..=20 {
        let csv = dir.join(format!("UCCLOG-{i:02}-trajectory.csv"));
        assert!(std::fs::metadata(&csv).unwrap().len() > 100, "{csv:?}");
    }
    // The overlay draws one path per iteration: an SVG polyline of many points each (the
    // legend's and the scale's lines have two).
    let svg = std::fs::read_to_string(dir.join("UCCLOG-overlay.svg")).unwrap();
    let paths = svg
        .split("<polyline")
        .skip(1)
        .filter_map(|p| p.split(" points=\"").nth(1)?.split('"').next())
        .filter(|points| points.split_whitespace().count() > 10)
        .count();
    assert_eq!(paths, 20, "paths in the overlay");
    let png = std::fs::metadata(dir.join("UCCLOG-overlay.png")).unwrap();
    assert!(png.len() > 1000);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_same_lockstep_command_reproduces_its_recordings_byte_for_byte() {
    let (a, b) = (scratch("det-a"), scratch("det-b"));
    for dir in [&a, &b] {
        let record = dir.join("run.usarlog");
        let out = run_local(
            dir,
            3,
            &[
                "--quiet",
                "--pictures",
                "none",
                "--record",
                record.to_str().unwrap(),
            ],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    for name in [
        "run.usarlog",
        "run-2.usarlog",
        "run-3.usarlog",
        "UCCLOG-results.csv",
    ] {
        let (x, y) = (
            std::fs::read(a.join(name)).unwrap(),
            std::fs::read(b.join(name)).unwrap(),
        );
        assert!(
            x.len() > 10_000 || name.ends_with(".csv"),
            "{name}: {} bytes",
            x.len()
        );
        assert!(x == y, "{name} differs between the two runs");
    }
    std::fs::remove_dir_all(&a).unwrap();
    std::fs::remove_dir_all(&b).unwrap();
}

#[test]
fn no_server_is_a_clear_error() {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dir = scratch("noserver");
    let out = ucc()
        .args([
            "run",
            "--port",
            &port.to_string(),
            "--start",
            "0,0,-1",
            "--goto",
            "1,0,-1",
        ])
        .arg("--log-dir")
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("cannot connect to localhost:"), "{stderr}");
    assert!(stderr.contains("is the server running?"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn decode_and_encode_give_back_the_capture() {
    use std::io::Write;
    use std::process::Stdio;
    let capture = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../usar-proto/tests/data/USARcommandSample.txt"
    ))
    .unwrap();
    let pipe = |cmd: &str, input: &str| {
        let mut child = ucc()
            .arg(cmd)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        child
            .stdin
            .take()
            .unwrap()
            .write_all(input.as_bytes())
            .unwrap();
        let out = child.wait_with_output().unwrap();
        assert!(out.status.success(), "ucc {cmd} failed");
        String::from_utf8(out.stdout).unwrap()
    };
    let json = pipe("decode", &capture);
    let lines = pipe("encode", &json);
    let server = |text: &str| -> Vec<String> {
        text.lines()
            .filter(|l| {
                ["NFO ", "STA ", "SEN ", "CONF ", "GEO "]
                    .iter()
                    .any(|w| l.starts_with(w))
            })
            .map(str::to_owned)
            .collect()
    };
    assert_eq!(server(&lines), server(&capture));
    assert_eq!(server(&capture).len(), 21);
}

#[test]
fn ctrl_c_ends_a_run_cleanly() {
    let dir = scratch("interrupt");
    let mut child = ucc()
        .args(["run", "--local", "--time-scale", "1", "--start", "0,0,-1"])
        .args(["--goto", "8,8,-2", "--goto", "-8,-8,-2", "--log-dir"])
        .arg(&dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Interrupt mid-flight: once the UAV has spawned (the handler is installed by then).
    let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    while !line.contains("spawned") {
        line.clear();
        assert!(
            std::io::BufRead::read_line(&mut stdout, &mut line).unwrap() > 0,
            "ucc ended before spawning"
        );
    }
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    // Everything flown so far is written, marked as interrupted (the defect: nothing was).
    let results = std::fs::read_to_string(dir.join("UCCLOG-results.csv")).unwrap();
    assert!(
        results
            .lines()
            .nth(1)
            .unwrap()
            .starts_with("1,interrupted,"),
        "{results}"
    );
    let log = std::fs::read_to_string(dir.join("UCCLOG-01.log")).unwrap();
    assert!(
        log.trim_end().ends_with("interrupted: the run was stopped"),
        "{log}"
    );
    for file in [
        "UCCLOG-01-trajectory.csv",
        "UCCLOG-01-map.png",
        "UCCLOG-01-plots.png",
        "UCCLOG-overlay.png",
    ] {
        assert!(dir.join(file).exists(), "{file} missing");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
