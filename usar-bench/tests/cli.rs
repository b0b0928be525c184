//! `usar-bench` as a user runs it: the defects were a 30 s wait and "nothing from the
//! server" for 1000 UAVs on the default map, and NaN figures for `--uavs 0`.

use std::process::Command;

fn bench(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_usar-bench"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_thousand_uavs_get_a_layout_that_fits_the_default_map() {
    let (code, out, err) = bench(&["--uavs", "1000", "--sim-only", "--seconds", "0.05"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("1000 robots (1000 in the world)"), "{out}");
}

#[test]
fn a_layout_that_cannot_fit_is_refused_at_once_with_what_to_pass() {
    let (code, _, err) = bench(&["--uavs", "1000", "--layers", "1", "--sim-only"]);
    assert_eq!(code, Some(1));
    assert!(
        err.contains("do not fit on map EmptyRoom") && err.contains("--map city"),
        "{err}"
    );
}

#[test]
fn zero_uavs_is_a_usage_error_not_nan() {
    let (code, out, err) = bench(&["--uavs", "0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        !out.contains("NaN") && err.contains("at least 1"),
        "{out}{err}"
    );
}

#[test]
fn scaling_prints_the_curve_and_draws_it_and_threads_do_not_change_the_output() {
    let dir = std::env::temp_dir().join(format!("usar-bench-scaling-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let plot = dir.join("curve.png");
    let (code, out, err) = bench(&[
        "--sim-only",
        "--scaling",
        "150,300",
        "--runs",
        "2",
        "--seconds",
        "0.1",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("   150 ") && out.contains("   300 "), "{out}");
    let png = std::fs::read(&plot).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "not a PNG");
    // The same world stepped on 1 and 3 sensor threads and on the slow reference path
    // prints the same lines.
    let digest = |extra: &[&str]| {
        let mut args = vec![
            "--sim-only",
            "--uavs",
            "300",
            "--seconds",
            "0.5",
            "--digest",
        ];
        args.extend_from_slice(extra);
        let (code, out, err) = bench(&args);
        assert_eq!(code, Some(0), "{err}");
        out.lines()
            .find_map(|l| l.strip_prefix("digest of the output: "))
            .map(str::to_owned)
            .expect("a digest")
    };
    let one = digest(&["--threads", "1"]);
    assert_eq!(digest(&["--threads", "3"]), one);
    assert_eq!(digest(&["--threads", "1", "--reference"]), one);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_closed_stdout_is_not_a_panic() {
    use std::process::Stdio;
    // `usar-bench ... | head -1`: the reader is gone before the second line.
    let mut child = Command::new(env!("CARGO_BIN_EXE_usar-bench"))
        .args([
            "--sim-only",
            "--uavs",
            "20",
            "--seconds",
            "0.05",
            "--digest",
        ])
        .env("RUST_BACKTRACE", "0")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(0), "{err}");
}

#[test]
fn sim_only_prints_the_memory_per_idle_robot() {
    let (code, out, err) = bench(&["--sim-only", "--uavs", "200", "--seconds", "0.05"]);
    assert_eq!(code, Some(0), "{err}");
    let kib: f64 = out
        .split("memory: ")
        .nth(1)
        .and_then(|s| s.split(" KiB").next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no memory figure in {out}"));
    // Robots of one class share their sensors' tables (14.6 KiB each before they did).
    assert!(kib > 0.5 && kib < 10.0, "{kib} KiB per robot");
}

/// The defect: a map that does not exist and a server that does not answer printed a stack
/// backtrace (with RUST_BACKTRACE set), and the connection error named no address.
#[test]
fn user_errors_are_one_line_naming_what_and_where() {
    let port = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let port = port.to_string();
    for (args, expected) in [
        (&["--map", "nowhere", "--uavs", "1"][..], "nowhere"),
        (
            &["--host", "127.0.0.1", "--port", &port, "--uavs", "1"],
            &*format!("127.0.0.1:{port}"),
        ),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_usar-bench"))
            .args(args)
            .env("RUST_BACKTRACE", "1")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert!(!err.to_lowercase().contains("backtrace"), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
    }
}

/// `--suite --quick` as CI runs it: every benchmark three times, the machine and load in the
/// JSON file, and a figure worse than the previous run's flagged without failing.
#[test]
fn the_quick_suite_writes_its_figures_and_flags_a_slower_tick_without_failing() {
    let dir = std::env::temp_dir().join(format!("usar-bench-suite-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("quick.json");
    let (code, text, err) = bench(&["--suite", "--quick", "--out", out.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        text.contains("machine: ") && text.contains("load average after"),
        "{text}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).expect("the suite's JSON");
    assert!(json["machine"]["cores"].as_u64().unwrap() >= 1, "{json}");
    assert_eq!(json["load_average_before"].as_array().unwrap().len(), 3);
    let first = &json["benchmarks"][0];
    assert_eq!(first["runs"].as_array().unwrap().len(), 3, "{first}");
    for figure in ["tick_p50_us", "tick_p99_us", "tick_p999_us", "tick_max_us"] {
        assert!(
            first["min_median_max"][figure][1].as_f64().unwrap() > 0.0,
            "{figure}"
        );
    }
    // The same machine's previous run, with a tick a thousand times shorter: flagged, not
    // failed. (Only halving it flaked: this VM's fast and slow phases differ by up to 2×.)
    let mut previous = json.clone();
    let median = &mut previous["benchmarks"][0]["min_median_max"]["tick_mean_us"][1];
    *median = (median.as_f64().unwrap() / 1000.0).into();
    let before = dir.join("previous.json");
    std::fs::write(&before, previous.to_string()).unwrap();
    let (code, text, err) = bench(&[
        "--suite",
        "--quick",
        "--out",
        out.to_str().unwrap(),
        "--compare",
        before.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        text.contains("SLOWER: world alone, 500 stsAirRobots: tick_mean_us"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
