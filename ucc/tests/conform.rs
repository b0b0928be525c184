//! `ucc conform` as a user runs it: against our server every check passes (exit 0); against
//! a tiny fake server that answers one command wrongly that check fails, naming the line
//! (exit 1); bad input is a clear error (exit 2). Deadlines are generous: the kit's own
//! waits are its `--timeout` (30 s), never a tight wall-clock bound.

use std::process::{Command, Output};

use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

fn ucc() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ucc"))
}

/// Runs `ucc conform ARGS` off the async runtime's threads.
async fn conform(args: Vec<String>) -> Output {
    tokio::task::spawn_blocking(move || ucc().arg("conform").args(args).output().unwrap())
        .await
        .unwrap()
}

fn json(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "{e}: {}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// The check named `name`: (result, detail, line).
fn check<'a>(report: &'a serde_json::Value, name: &str) -> (&'a str, &'a str, Option<&'a str>) {
    let c = report["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["check"] == name)
        .unwrap_or_else(|| panic!("no check {name}: {report:#}"));
    (
        c["result"].as_str().unwrap(),
        c["detail"].as_str().unwrap(),
        c["line"].as_str(),
    )
}

/// A port nothing listens on.
async fn closed_port() -> u16 {
    let l = TcpListener::bind("127.0.0.1:0").await.unwrap();
    l.local_addr().unwrap().port()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn our_server_passes_every_check() {
    let bind = async || TcpListener::bind("127.0.0.1:0").await.unwrap();
    let (main, image, truth, monitor, wss) = (
        bind().await,
        bind().await,
        bind().await,
        bind().await,
        bind().await,
    );
    let port = |l: &TcpListener| l.local_addr().unwrap().port().to_string();
    let mut args = vec![format!("127.0.0.1:{}", port(&main))];
    for (flag, l) in [
        ("--image-port", &image),
        ("--truth-port", &truth),
        ("--wss-port", &wss),
    ] {
        args.extend([flag.to_string(), port(l)]);
    }
    for side in ["image", "truth", "wss"] {
        args.extend(["--require".to_string(), side.to_string()]);
    }
    for robot in ["AirRobot", "stsAirRobot", "stsQuadrotor"] {
        args.extend(["--robot".to_string(), robot.to_string()]);
    }
    args.push("--json".into());
    let shutdown = CancellationToken::new();
    let side = usar_server::SideListeners {
        image: Some(image),
        truth: Some(truth),
        monitor: Some(monitor),
        wss: Some(wss),
    };
    let config = usar_server::ServerConfig::default();
    tokio::spawn(usar_server::run_with(main, side, config, shutdown.clone()));

    let out = conform(args.clone()).await;
    let report = json(&out);
    let failed: Vec<&serde_json::Value> = report["checks"]
        .as_array()
        .unwrap()
        .iter()
        // Only the robots without a camera skip a check: SET {Type Camera}.
        .filter(|c| {
            c["result"] == "fail"
                || (c["result"] == "skip"
                    && !(c["check"].as_str().unwrap().starts_with("set-camera")
                        && c["detail"] == "no camera"))
        })
        .collect();
    assert!(failed.is_empty(), "not passed: {failed:#?}");
    assert_eq!(out.status.code(), Some(0), "{report:#}");
    assert_eq!(report["passed"], true);
    for name in [
        "nfo-on-connect",
        "getstartposes",
        "spawn AirRobot",
        "sta-rate AirRobot",
        "sen-rate AirRobot",
        "sta-format AirRobot",
        "sen-format AirRobot",
        "conf-format AirRobot",
        "geo-format AirRobot",
        "getconf-robot AirRobot",
        "getgeo-robot AirRobot",
        "conf-geo AirRobot",
        "drive AirRobot",
        "set-camera AirRobot",
        "malformed-lines AirRobot",
        "spawn stsQuadrotor",
        "conf-geo stsAirRobot",
        "image",
        "usartruth",
        "wss",
    ] {
        assert_eq!(check(&report, name).0, "pass", "{name}: {report:#}");
    }

    // The table says the same.
    args.pop();
    let out = conform(args).await;
    let table = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{table}");
    assert!(table.starts_with("check "), "{table}");
    assert!(table.contains("conforms"), "{table}");
    println!("{table}");
    shutdown.cancel();
}

/// What the fake server answers `GETGEO {Type IMU}` with.
const GOOD_GEO: &str = "GEO {Type IMU} {Name IMU} {Location 0.00,0.00,0.00} {Orientation 0.00,0.00,0.00}{Mount FakeBot}";
/// The same without its `{Orientation ..}`.
const BAD_GEO: &str = "GEO {Type IMU} {Name IMU} {Location 0.00,0.00,0.00}{Mount FakeBot}";

/// A tiny USARSim: NFO on connect, one start pose, a FakeBot streaming STA (with `battery`
/// as its Battery value) and an IMU at 10 per simulated second (faster than real time), CONF
/// and GEO answers with `geo` for the IMU.
async fn fake_server(geo: &'static str, battery: &'static str) -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    tokio::spawn(async move {
        while let Ok((stream, _)) = listener.accept().await {
            tokio::spawn(async move {
                let (read, mut write) = stream.into_split();
                let mut lines = BufReader::new(read).lines();
                let mut out =
                    String::from("NFO {Gametype BotDeathMatch} {Level Fake} {TimeLimit 20}\r\n");
                let mut spawned = false;
                let mut time = 0.0;
                let mut tick = tokio::time::interval(std::time::Duration::from_millis(20));
                loop {
                    if !out.is_empty() && write.write_all(out.as_bytes()).await.is_err() {
                        return;
                    }
                    out.clear();
                    tokio::select! {
                        line = lines.next_line() => {
                            let Ok(Some(line)) = line else { return };
                            let reply = match line.as_str() {
                                "GETSTARTPOSES" => "NFO {StartPoses 1} {Start1 0.0000,0.0000,0.0000 0.0000,0.0000,0.0000}",
                                l if l.starts_with("INIT ") => {
                                    spawned = true;
                                    ""
                                }
                                "GETCONF {Type Robot}" if spawned => "CONF {Name FakeBot}",
                                "GETGEO {Type Robot}" if spawned => "GEO {Name FakeBot}",
                                "GETCONF {Type IMU}" if spawned => "CONF {Type IMU} {Name IMU}",
                                "GETGEO {Type IMU}" if spawned => geo,
                                // A clear error line: no server word (advisory only).
                                "NOSUCHCOMMAND {Foo 1}" => "ERROR {Reason Unknown.Command}",
                                _ => "",
                            };
                            if !reply.is_empty() {
                                out = format!("{reply}\r\n");
                            }
                        }
                        _ = tick.tick(), if spawned => {
                            time += 0.1;
                            out = format!(
                                "STA {{Time {time:.4}}} {{Battery {battery}}}\r\nSEN {{Time {time:.4}}} {{Type IMU}} {{Name IMU}} {{XYZAcceleration 0.0000,0.0000,0.0000}} {{AngularVel 0.0000,0.0000,0.0000}} {{AngularAccel 0.0000,0.0000,0.0000}} {{Rotation 0.0000,0.0000,0.0000}}\r\n"
                            );
                        }
                    }
                }
            });
        }
    });
    port
}

async fn against_fake(
    geo: &'static str,
    battery: &'static str,
) -> (Option<i32>, serde_json::Value) {
    let port = fake_server(geo, battery).await;
    let mut args = vec![
        format!("127.0.0.1:{port}"),
        "--robot".into(),
        "FakeBot".into(),
    ];
    for flag in ["--image-port", "--truth-port", "--wss-port"] {
        args.extend([flag.to_string(), closed_port().await.to_string()]);
    }
    args.push("--json".into());
    let out = conform(args).await;
    (out.status.code(), json(&out))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wrong_answer_fails_its_check_with_the_line() {
    // The fake server as it should be passes (side ports refused: skipped).
    let (code, report) = against_fake(GOOD_GEO, "99999").await;
    assert_eq!(code, Some(0), "{report:#}");
    assert_eq!(check(&report, "geo-format FakeBot").0, "pass");
    assert_eq!(check(&report, "conf-geo FakeBot").0, "pass");
    assert_eq!(check(&report, "image").0, "skip");
    assert_eq!(check(&report, "wss").0, "skip");
    // Its error line for an unknown command is reported, but not counted.
    let (result, _, line) = check(&report, "unknown-word-format FakeBot");
    assert_eq!(
        (result, line),
        ("fail", Some("ERROR {Reason Unknown.Command}"))
    );
    let advisory = report["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["check"] == "unknown-word-format FakeBot")
        .unwrap();
    assert_eq!(advisory["mandatory"], false);

    // A GEO without its Orientation: that check fails, naming the line.
    let (code, report) = against_fake(BAD_GEO, "99999").await;
    assert_eq!(code, Some(1), "{report:#}");
    assert_eq!(report["passed"], false);
    let (result, detail, line) = check(&report, "geo-format FakeBot");
    assert_eq!((result, line), ("fail", Some(BAD_GEO)), "{report:#}");
    assert!(detail.contains("Orientation"), "{detail}");
    // The others still pass.
    assert_eq!(check(&report, "sta-format FakeBot").0, "pass");
    assert_eq!(check(&report, "malformed-lines FakeBot").0, "pass");

    // An STA whose Battery is not a number: sta-format fails, naming the first such line.
    let (code, report) = against_fake(GOOD_GEO, "full").await;
    assert_eq!(code, Some(1), "{report:#}");
    let (result, detail, line) = check(&report, "sta-format FakeBot");
    assert_eq!(result, "fail", "{report:#}");
    assert!(detail.contains("Battery"), "{detail}");
    assert!(
        line.is_some_and(|l| l.starts_with("STA {Time ") && l.ends_with("{Battery full}")),
        "{line:?}"
    );
    assert_eq!(check(&report, "geo-format FakeBot").0, "pass");
}

#[test]
fn bad_input_is_a_clear_error_with_exit_2() {
    for (args, says) in [
        (vec!["conform", "no-port-here"], "HOST:PORT"),
        (vec!["conform", "127.0.0.1:99999"], "HOST:PORT"),
        (vec!["conform"], "HOST:PORT"),
    ] {
        let out = ucc().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // Nothing listens: a clear error, exit 2.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let out = ucc()
        .args(["conform", &format!("127.0.0.1:{port}")])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("cannot connect"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    // The help says what the checks are and how the exit status reads.
    let out = ucc().args(["conform", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    for word in [
        "--robot",
        "--require",
        "--json",
        "image",
        "USARTruth",
        "Exit status",
        "docs/conformance.md",
    ] {
        assert!(help.contains(word), "{word}: {help}");
    }
}
