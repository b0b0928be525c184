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
    // The overlay draws every iteration's path, the legend counting them all. Lockstep
    // flies the same path each time: the first eight are drawn apart, the other twelve as
    // one line as dark as twelve translucent lines over each other (1 - 0.6^13).
    let svg = std::fs::read_to_string(dir.join("UCCLOG-overlay.svg")).unwrap();
    assert!(svg.contains("paths of 20 iterations"), "legend");
    let opacities: Vec<f64> = svg
        .split("<polyline")
        .skip(1)
        .filter(|p| p.contains("#1F77B4") && p.contains("stroke-width=\"1\""))
        .filter_map(|p| {
            p.split("opacity=\"")
                .nth(1)?
                .split('"')
                .next()?
                .parse()
                .ok()
        })
        .collect();
    assert_eq!(opacities.len(), 8, "paths in the overlay: {opacities:?}");
    assert!(
        (opacities[0] - (1.0 - 0.6f64.powi(13))).abs() < 1e-6,
        "{opacities:?}"
    );
    assert!(
        opacities[1..].iter().all(|o| (o - 0.4).abs() < 1e-9),
        "{opacities:?}"
    );
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
    // The defects: a warning about sensor time came first, the error was printed twice
    // (stdout and stderr), and an empty overlay and a results table with -0.0000 were written.
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!stdout.contains("sensor time"), "{stdout}");
    let both = format!("{stdout}{stderr}");
    assert_eq!(both.matches("cannot connect").count(), 1, "{both}");
    let written: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert!(written.is_empty(), "{written:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The defects: `--seed` without `--local` said "required arguments were not provided:
/// --local"; `--mission-timeout -1` said "unexpected argument '-1'"; `--start nan,0,-1` was
/// taken as a PlayerStart tag.
#[test]
fn argument_errors_say_what_is_wrong() {
    let mission = ["--start", "0,0,-1", "--goto", "1,0,-1"];
    let (code, _, err) = ucc_output(&[&["run", "--seed", "3"][..], &mission].concat());
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--seed") && err.contains("add --local") && !err.contains("not provided"),
        "{err}"
    );
    let (code, _, err) = ucc_output(&[&["run", "--time-scale", "5"][..], &mission].concat());
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--time-scale") && err.contains("add --local"),
        "{err}"
    );
    let (code, _, err) = ucc_output(&[&["run", "--mission-timeout", "-1"][..], &mission].concat());
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("expected a number from 0.001") && !err.contains("unexpected argument"),
        "{err}"
    );
    let (code, _, err) = ucc_output(&["run", "--iterations", "-1", "--start", "0,0,-1"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(!err.contains("unexpected argument"), "{err}");
    let (code, _, err) = ucc_output(&["run", "--local", "--start", "nan,0,-1", "--goto", "1,0,-1"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("\"nan\" is not a number"), "{err}");
}

/// The defect: `ucc run --help` named the log, the trajectory and the map pictures, but not
/// the plots and the results table.
#[test]
fn run_help_names_every_file_a_run_writes() {
    let (code, out, _) = ucc_output(&["run", "--help"]);
    assert_eq!(code, Some(0));
    for file in [
        "PREFIX-NN.log",
        "PREFIX-NN-trajectory.csv",
        "PREFIX-NN-map.svg/.png",
        "PREFIX-NN-plots.svg/.png",
        "PREFIX-overlay.svg/.png",
        "PREFIX-results.csv",
        "--force",
    ] {
        assert!(out.contains(file), "{file} not in {out}");
    }
}

/// The defect: running again with the same --log-dir overwrote the earlier results without
/// a word. Now it is refused before flying, unless --force.
#[test]
fn an_earlier_run_is_kept_unless_forced() {
    let dir = scratch("again");
    let once = |extra: &[&str]| {
        let mut command = ucc();
        command
            .args(["run", "--local", "--start", "0,0,-1", "--goto", "0.5,0,-1"])
            .arg("--log-dir")
            .arg(&dir)
            .args(extra);
        let out = command.output().unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, out, err) = once(&[]);
    assert_eq!(code, Some(0), "{out}{err}");
    let results = dir.join("UCCLOG-results.csv");
    let before = std::fs::metadata(&results).unwrap().modified().unwrap();
    let (code, out, err) = once(&[]);
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(!out.contains("connected"), "flew before refusing: {out}");
    assert!(
        err.contains(&*dir.to_string_lossy()) && err.contains("--force"),
        "{err}"
    );
    assert_eq!(
        std::fs::metadata(&results).unwrap().modified().unwrap(),
        before
    );
    // Another prefix in the same folder is another run.
    let (code, out, err) = once(&["--prefix", "second"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let (code, out, err) = once(&["--force"]);
    assert_eq!(code, Some(0), "{out}{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The defect: output paths were checked after the flight (`--prefix a/b` flew the whole
/// mission, then failed to write `DIR/a/b-01.log`; `ucc demo --output /proc/nope` too).
#[test]
fn output_paths_are_checked_before_flying() {
    let dir = scratch("prefix");
    let file = dir.join("a-file");
    std::fs::write(&file, "").unwrap();
    let mission = ["run", "--local", "--start", "0,0,-1", "--goto", "3,0,-1"];
    for (extra, named) in [
        (
            vec!["--prefix", "a/b", "--log-dir", dir.to_str().unwrap()],
            "--prefix",
        ),
        (
            vec!["--log-dir", file.to_str().unwrap()],
            file.to_str().unwrap(),
        ),
    ] {
        let (code, out, err) = ucc_output(&[&mission[..], &extra].concat());
        assert_eq!(code, Some(1), "{extra:?}: {out}{err}");
        assert!(!out.contains("connected"), "{extra:?} flew first: {out}");
        assert!(err.contains(named), "{extra:?}: {err}");
    }
    let (code, out, err) = ucc_output(&["demo", "--output", "/proc/nope"]);
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(!out.contains("spawning"), "flew first: {out}");
    assert!(err.contains("/proc/nope"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The defect: z points down, and nothing said so: `--start 0,0,1 --goto 2,0,1` flew a metre
/// under the floor and exited 0; `--goto 2,0,1` from a good start waited 120 simulated
/// seconds for "not done". The local server knows its map: such points are refused at once.
#[test]
fn points_under_the_floor_or_in_a_wall_are_refused_on_the_local_server() {
    for (args, what) in [
        (&["--start", "0,0,1", "--goto", "2,0,1"][..], "the start"),
        (&["--start", "0,0,-1", "--goto", "2,0,1"], "waypoint 1"),
        (
            &["--start", "0,0,-1", "--goto", "2,0,-1", "--goto", "2,0,3"],
            "waypoint 2",
        ),
    ] {
        let (code, out, err) = ucc_output(&[&["run", "--local"][..], args].concat());
        assert_eq!(code, Some(1), "{args:?}: {out}{err}");
        assert!(!out.contains("connected"), "{args:?}: flew first: {out}");
        assert!(
            err.contains(what) && err.contains("below the floor") && err.contains("z points down"),
            "{args:?}: {err}"
        );
    }
}

/// The defect: against a server of one's own, `--goto 2,0,1` from a valid start (a metre
/// under the floor: z points down) waited out the mission timeout and said only "not done".
#[test]
fn a_waypoint_under_the_floor_on_a_remote_server_says_z_points_down() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let server = rt
        .block_on(usar_server::LocalServer::start(usar_server::ServerConfig {
            lockstep: true,
            time_scale: usar_server::TimeScale::Max,
            ..usar_server::ServerConfig::default()
        }))
        .unwrap();
    let dir = scratch("under-the-floor-remote");
    let port = server.addr().port().to_string();
    let (code, out, err) = ucc_output(&[
        "run",
        "--host",
        "127.0.0.1",
        "--port",
        &port,
        "--lockstep",
        "--start",
        "0,0,-1",
        "--goto",
        "2,0,1",
        "--mission-timeout",
        "5",
        "--log-dir",
        dir.to_str().unwrap(),
    ]);
    rt.block_on(server.stop()).unwrap();
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(
        err.contains("not done after 5")
            && err.contains("below where the UAV stopped")
            && err.contains("z points down"),
        "{err}"
    );
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

/// Runs `ucc` with `args`; returns (exit code, stdout, stderr).
fn ucc_output(args: &[&str]) -> (Option<i32>, String, String) {
    let out = ucc().args(args).output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The defects: a bad robot class or start tag waited 10 s for a stream that never came,
/// although the local server knows at once; a bad map name did not list the maps; map names
/// were case-sensitive; an OS error was printed twice.
#[test]
fn a_local_run_says_at_once_what_is_wrong() {
    let go = ["--goto", "1,0,-1"];
    let (code, _, err) = ucc_output(
        &[
            &["run", "--local", "--robot", "Nope", "--start", "0,0,-1"][..],
            &go,
        ]
        .concat(),
    );
    assert_eq!(code, Some(1));
    assert!(
        err.contains("unknown robot class \"USARBot.Nope\"") && err.contains("USARBot.stsAirRobot"),
        "{err}"
    );
    let (_, _, err) = ucc_output(&[&["run", "--local", "--start", "Nowhere"][..], &go].concat());
    assert!(
        err.contains("no PlayerStart \"Nowhere\"") && err.contains("Start1"),
        "{err}"
    );
    let (_, _, err) = ucc_output(
        &[
            &["run", "--local", "--map", "nosuch", "--start", "0,0,-1"][..],
            &go,
        ]
        .concat(),
    );
    assert!(err.contains("empty_room, arena, city"), "{err}");
    let dir = scratch("map-is-a-directory");
    let (_, _, err) = ucc_output(
        &[
            &[
                "run",
                "--local",
                "--map",
                dir.to_str().unwrap(),
                "--start",
                "0,0,-1",
            ][..],
            &go,
        ]
        .concat(),
    );
    // The cause once: the OS's error, or the loader's "not a regular file" (a folder is
    // refused before it is opened).
    let causes = err.matches("(os error").count() + err.matches("not a regular file").count();
    assert_eq!(causes, 1, "{err}");
    let logs = scratch("arena-any-case");
    let (code, out, err) = ucc_output(
        &[
            &[
                "run",
                "--local",
                "--map",
                "ARENA",
                "--start",
                "Start1",
                "--goto",
                "0,0,-1.5",
                "-q",
                "--log-dir",
            ][..],
            &[logs.to_str().unwrap()],
        ]
        .concat(),
    );
    assert_eq!(code, Some(0), "{out}\n{err}");
}

/// The defects: `--speed 0` exited 1 (the docs promise 2 for bad arguments) and
/// `ucc demo --agent nope` announced a flight before failing.
#[test]
fn bad_arguments_are_usage_errors() {
    let (code, out, err) = ucc_output(&["demo", "--agent", "nope"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(out.is_empty(), "announced something: {out}");
    assert!(err.contains("known agents: base, avoid"), "{err}");
    for args in [
        &["demo", "--speed", "0"][..],
        &["demo", "--speed", "nan"],
        &[
            "run",
            "--start",
            "0,0,-1",
            "--goto",
            "1,0,-1",
            "--stream-timeout",
            "-1",
        ],
        &[
            "run",
            "--start",
            "0,0,-1",
            "--goto",
            "1,0,-1",
            "--mission-timeout",
            "inf",
        ],
        // Finite but absurd: Duration::from_secs_f64 panicked on these.
        &[
            "run",
            "--start",
            "0,0,-1",
            "--goto",
            "1,0,-1",
            "--stream-timeout",
            "1e300",
        ],
        &["demo", "--speed", "1e-300"],
    ] {
        let (code, _, err) = ucc_output(args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
    }
}

/// The defect: ANSI colour codes ended up in piped output and log files.
#[test]
fn no_colour_codes_off_a_terminal() {
    let dir = scratch("no-colour");
    let out = ucc()
        .env("RUST_LOG", "debug")
        .args([
            "run",
            "--local",
            "--start",
            "0,0,-1",
            "--goto",
            "1,0,-1.5",
            "--log-dir",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(!out.stderr.is_empty(), "debug logs were written");
    assert!(!out.stderr.contains(&0x1b), "escape codes on stderr");
    assert!(!out.stdout.contains(&0x1b), "escape codes on stdout");
    let log = std::fs::read(dir.join("UCCLOG-01.log")).unwrap();
    assert!(!log.contains(&0x1b), "escape codes in the log file");
}

/// The defect: `ucc decode | head` printed a broken-pipe error (#56: and exited 0).
#[test]
fn decode_into_a_closed_pipe_ends_quietly() {
    use std::io::{BufRead, Write};
    let mut child = ucc()
        .arg("decode")
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || {
        for _ in 0..20_000 {
            if stdin
                .write_all(b"STA {Time 1.0000} {Battery 1200}\n")
                .is_err()
            {
                break;
            }
        }
    });
    let mut first = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.contains("Sta"), "{first}");
    // The reader (like `head`) is gone now: a quiet end with the status of a program ended
    // by SIGPIPE (as `cat` would be), never a panic or a message.
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    assert_eq!(out.status.code(), Some(141));
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The defect (#56): `ucc run` into a closed pipe (`ucc run ... | head -1`) panicked at its
/// first status line and flew nothing more. Now the run is done and its files written, and
/// the exit status says that the output was cut short, as for `cat` (141).
#[test]
fn a_run_into_a_closed_pipe_flies_writes_its_files_and_says_so() {
    let dir = scratch("closed-stdout");
    let mut child = ucc()
        .args(["run", "--local", "--lockstep", "--start", "0,0,-1"])
        .args(["--goto", "1,0,-1", "--iterations", "2", "--log-dir"])
        .arg(&dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The reader is gone before the first line.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(141), "{err}");
    let results = std::fs::read_to_string(dir.join("UCCLOG-results.csv")).unwrap();
    assert_eq!(
        results.lines().filter(|l| l.contains(",ok")).count(),
        2,
        "{results}"
    );
}

/// The defect: `ucc run --local` without `--lockstep` ran a full-speed server against a
/// wall-clock client, and eight runs of one command flew 1.4 to 30.7 m. A local run is in
/// lockstep: the same command gives the same flight.
#[test]
fn a_local_run_is_the_same_every_time() {
    let results: Vec<String> = (0..3)
        .map(|i| {
            let dir = scratch(&format!("same-{i}"));
            let (code, out, err) = ucc_output(
                &[
                    &[
                        "run",
                        "--local",
                        "--start",
                        "0,0,-1",
                        "--goto",
                        "4,2,-2",
                        "-q",
                        "--log-dir",
                    ][..],
                    &[dir.to_str().unwrap()],
                ]
                .concat(),
            );
            assert_eq!(code, Some(0), "{out}{err}");
            assert!(
                out.contains("in lockstep") || !out.contains("sensor time"),
                "{out}"
            );
            // The defect: the overlay of one iteration was titled "1 iterations".
            let overlay = std::fs::read_to_string(dir.join("UCCLOG-overlay.svg")).unwrap();
            assert!(overlay.contains("UCCLOG — 1 iteration\n"), "title");
            std::fs::read_to_string(dir.join("UCCLOG-01-trajectory.csv")).unwrap()
        })
        .collect();
    assert!(results[0].lines().count() > 20);
    assert_eq!(results[0], results[1]);
    assert_eq!(results[0], results[2]);
}

/// `ucc gui` prints the URL to open, serves the page there, and asks for a token beyond the
/// loopback.
#[test]
fn gui_prints_the_url_and_serves_the_page() {
    use std::io::{BufRead, BufReader, Read, Write};
    let first_line = |args: &[&str]| {
        let mut child = ucc()
            .arg("gui")
            .args(args)
            .stdout(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut out = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        out.read_line(&mut line).unwrap();
        (child, line)
    };
    let (mut child, line) = first_line(&["--local", "--listen", "127.0.0.1:0"]);
    let url = line
        .trim()
        .strip_prefix("ucc gui: open ")
        .unwrap_or_else(|| panic!("{line}"));
    let hostport = url
        .strip_prefix("http://")
        .and_then(|u| u.strip_suffix('/'))
        .unwrap_or_else(|| panic!("{url}"));
    let mut s = std::net::TcpStream::connect(hostport).unwrap();
    write!(
        s,
        "GET / HTTP/1.1\r\nHost: {hostport}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut page = String::new();
    s.read_to_string(&mut page).unwrap();
    assert!(
        page.starts_with("HTTP/1.1 200") && page.contains("data-testid=\"map\""),
        "{page}"
    );
    child.kill().unwrap();
    child.wait().unwrap();

    let (mut child, line) = first_line(&["--listen", "0.0.0.0:0"]);
    assert!(line.contains("/?token=") && line.len() > 60, "{line}");
    child.kill().unwrap();
    child.wait().unwrap();

    let out = ucc().args(["gui", "--map", "arena"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--local"));
}

#[test]
fn scenario_lists_runs_writes_its_files_and_names_a_bad_line() {
    let list = ucc().args(["scenario", "--list"]).output().unwrap();
    assert!(list.status.success());
    let text = String::from_utf8_lossy(&list.stdout);
    for name in [
        "search",
        "relay",
        "tracking",
        "perimeter",
        "delivery",
        "partition-search",
    ] {
        assert!(text.contains(name), "{name} missing from\n{text}");
    }
    let dir = std::env::temp_dir().join(format!("ucc-cli-scenario-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let run = ucc()
        .args([
            "scenario",
            "tracking",
            "--iterations",
            "2",
            "--seed",
            "4",
            "--log-dir",
        ])
        .arg(&dir)
        .arg("--record")
        .arg(dir.join("rec"))
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{out}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(out.contains("iteration 2/2 (seed 5)"), "{out}");
    assert!(out.contains("target_seen_pct"), "{out}");
    for f in [
        "results.csv",
        "iteration-001.log",
        "iteration-002.png",
        "overlay.png",
        "rec/iteration-002/connection-0001.usarlog",
    ] {
        assert!(dir.join(f).is_file(), "{f}");
    }
    // A second run into the same folder is refused before flying.
    let again = ucc()
        .args(["scenario", "tracking", "--log-dir"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(again.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "kind = \"search\"\nmap = \"rescue\"\ntime_limit = 10\n[[uav]]\nagent = \"lane-serch\"\nstart = [0.0, 0.0, -1.0]\n",
    )
    .unwrap();
    let wrong = ucc().arg("scenario").arg(&bad).output().unwrap();
    let err = String::from_utf8_lossy(&wrong.stderr);
    assert_eq!(wrong.status.code(), Some(1), "{err}");
    assert!(
        err.contains("bad.toml:4: [[uav]]: unknown agent \"lane-serch\""),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn faults_of_the_server_are_logged_and_counted_in_the_results() {
    let dir = scratch("faults");
    let faults = dir.join("faults.toml");
    std::fs::write(
        &faults,
        "[[fault]]\ntime = 1.0\nrobot = 1\nline = \"FAULT {Sensor Position} {Mode Bias} {Value 0.05}\"\n\
         [[fault]]\ntime = 2.0\nrobot = 1\nline = \"FAULT {Sensor Position} {Mode Ok}\"\n",
    )
    .unwrap();
    let out = run_local(
        &dir,
        2,
        &[
            "--robot",
            "stsQuadrotor",
            "--quiet",
            "--faults",
            faults.to_str().unwrap(),
        ],
    );
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let log = std::fs::read_to_string(dir.join("UCCLOG-01.log")).unwrap();
    assert!(
        log.contains("fault at t=1.00s: Sensor Position Mode Bias Value 0.05"),
        "{log}"
    );
    let results = std::fs::read_to_string(dir.join("UCCLOG-results.csv")).unwrap();
    let mut rows = results.lines();
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let column = header
        .iter()
        .position(|h| *h == "faults")
        .expect("a faults column");
    let counts: Vec<&str> = rows.map(|r| r.split(',').nth(column).unwrap()).collect();
    // Robot 1 is the first iteration's: the second flies a new robot without faults.
    assert_eq!(counts, ["2", "0"], "{results}");
}

#[test]
fn randomize_draws_per_iteration_and_writes_the_draws() {
    let dir = scratch("randomize");
    let ranges = dir.join("ranges.toml");
    std::fs::write(&ranges, "mass = [0.8, 1.2]\nwind = [0, 1]\n").unwrap();
    let run = |dir: &Path| {
        let out = run_local(
            dir,
            2,
            &[
                "--robot",
                "stsQuadrotor",
                "--quiet",
                "--seed",
                "4",
                "--randomize",
                ranges.to_str().unwrap(),
            ],
        );
        assert!(
            out.status.success(),
            "{}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        let results = std::fs::read_to_string(dir.join("UCCLOG-results.csv")).unwrap();
        let mut rows = results.lines();
        let header: Vec<&str> = rows.next().unwrap().split(',').collect();
        let column = header.iter().position(|h| *h == "randomized").unwrap();
        rows.map(|r| r.split(',').nth(column).unwrap().to_owned())
            .collect::<Vec<_>>()
    };
    let draws = run(&dir);
    assert_eq!(draws.len(), 2);
    assert!(
        draws[0].starts_with("mass 0.") || draws[0].starts_with("mass 1."),
        "{draws:?}"
    );
    assert_ne!(draws[0], draws[1], "each iteration draws its own");
    let log = std::fs::read_to_string(dir.join("UCCLOG-01.log")).unwrap();
    assert!(log.contains(&format!("randomized: {}", draws[0])), "{log}");
    let again = scratch("randomize-again");
    assert_eq!(run(&again), draws, "the same seed, the same draws");
    // A bad file names the file, the line and the key.
    std::fs::write(&ranges, "mass = [0.8, 1.2]\nkf = [2, 1]\n").unwrap();
    let out = ucc()
        .args([
            "run",
            "--local",
            "--start",
            "0,0,-1",
            "--randomize",
            ranges.to_str().unwrap(),
        ])
        .args(["--goto", "1,0,-1"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("ranges.toml: line 2: key `kf`"), "{stderr}");
}

/// The defect (#56): on a full disk `ucc run` exited 1, but its results.csv said `ok` for the
/// iteration whose files were not written (they were written after its row). A file of the
/// run is made /dev/full here (writing it fails with ENOSPC).
#[test]
fn results_never_say_ok_for_an_iteration_whose_files_were_not_written() {
    for file in [
        "UCCLOG-01-trajectory.csv",
        "UCCLOG-01.log",
        "UCCLOG-01-map.png",
    ] {
        let dir = scratch("full-file");
        std::os::unix::fs::symlink("/dev/full", dir.join(file)).unwrap();
        let out = ucc()
            .args(["run", "--local", "--start", "0,0,-1", "--goto", "2,0,-1"])
            .args(["--quiet", "--force", "--log-dir"])
            .arg(&dir)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{file}: {stderr}");
        // `cannot write FILE: No space left ...` (`cannot draw` for a picture).
        let named = format!("{}: No space left", dir.join(file).display());
        assert!(stderr.contains(&named), "{file}: {stderr}");
        let results = std::fs::read_to_string(dir.join("UCCLOG-results.csv")).unwrap();
        let row = results.lines().nth(1).unwrap_or_default();
        assert!(
            row.starts_with("1,failed,") && row.contains(&named),
            "{file}: {results}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
    // The table itself on a full disk: the exit status and the message say so.
    let dir = scratch("full-results");
    let results = dir.join("UCCLOG-results.csv");
    std::os::unix::fs::symlink("/dev/full", &results).unwrap();
    let out = ucc()
        .args(["run", "--local", "--start", "0,0,-1", "--goto", "2,0,-1"])
        .args(["--quiet", "--force", "--pictures", "none", "--log-dir"])
        .arg(&dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "cannot write {}: No space left",
            results.display()
        )),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
