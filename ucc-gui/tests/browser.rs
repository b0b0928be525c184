//! The control center in a real browser: headless Chromium driven through chromedriver.
//!
//! Skips (with a message) when `chromium`/`chromedriver` are not installed, unless
//! `UCC_GUI_REQUIRE_BROWSER=1` (set by `.ci/run`), which turns the skip into a failure.
//! The map screenshot is written to `target/ucc-gui-artifacts/map.png`.

use std::path::PathBuf;
use std::process::Stdio;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use fantoccini::actions::{InputSource, MouseActions, PointerAction};
use fantoccini::{Client, ClientBuilder, Locator};
use serde_json::json;
use tokio_util::sync::CancellationToken;
use ucc_gui::{GuiConfig, ServerChoice};
use usar_server::{ServerConfig, TimeScale};

fn which(names: &[&str]) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    names.iter().find_map(|n| {
        std::env::split_paths(&path)
            .map(|d| d.join(n))
            .find(|p| p.is_file())
    })
}

/// chromium and chromedriver, or `None` (skip) — a failure when the browser is required.
fn browser() -> Option<(PathBuf, PathBuf)> {
    let found =
        which(&["chromium", "chromium-browser", "google-chrome"]).zip(which(&["chromedriver"]));
    if found.is_none() {
        let msg = "browser tests skipped: chromium and chromedriver are not installed \
                   (apt-get install chromium chromium-driver)";
        if std::env::var("UCC_GUI_REQUIRE_BROWSER").is_ok_and(|v| v == "1") {
            panic!("{msg}, and UCC_GUI_REQUIRE_BROWSER=1 requires them");
        }
        eprintln!("{msg}");
    }
    found
}

/// Where the screenshots and downloads go.
fn artifacts() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/ucc-gui-artifacts")
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

struct Session {
    client: Client,
    driver: tokio::process::Child,
    profile: PathBuf,
}

impl Drop for Session {
    fn drop(&mut self) {
        // A Chromium profile weighs tens of megabytes: leave none behind.
        let _ = std::fs::remove_dir_all(&self.profile);
    }
}

async fn start_browser(chromium: &PathBuf, chromedriver: &PathBuf) -> Result<Session> {
    start_browser_with(chromium, chromedriver, 1400, 1000, 1.0).await
}

/// How many times a browser is started before its test fails: on a loaded 2-core machine
/// Chromium sometimes does not answer chromedriver in time ("webdriver server did not
/// respond"), which says nothing about the control center.
const BROWSER_ATTEMPTS: usize = 3;

/// `start` until it succeeds, at most `attempts` times; the error names every attempt's.
async fn retried<T, F, Fut>(attempts: usize, what: &str, mut start: F) -> Result<T>
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Result<T>>,
{
    let mut errors = Vec::new();
    for attempt in 1..=attempts {
        match start().await {
            Ok(value) => return Ok(value),
            Err(e) => {
                eprintln!("{what}: attempt {attempt} of {attempts} failed: {e:#}");
                errors.push(format!("attempt {attempt}: {e:#}"));
            }
        }
    }
    bail!("{what} failed {attempts} times: {}", errors.join("; "))
}

#[tokio::test]
async fn a_failed_start_is_retried_and_every_failure_is_named() {
    let mut calls = 0;
    let value = retried(3, "start", || {
        calls += 1;
        let n = calls;
        async move {
            if n < 3 {
                bail!("no answer {n}")
            }
            Ok(n)
        }
    })
    .await
    .unwrap();
    assert_eq!(value, 3);
    let e = retried(2, "the browser", || async {
        Err::<(), _>(anyhow::anyhow!("no answer"))
    })
    .await
    .unwrap_err()
    .to_string();
    assert_eq!(
        e,
        "the browser failed 2 times: attempt 1: no answer; attempt 2: no answer"
    );
}

/// A browser with a window of `width`×`height` CSS pixels at `scale` device pixels each
/// (started again, [`BROWSER_ATTEMPTS`] times in all, when it does not come up).
async fn start_browser_with(
    chromium: &PathBuf,
    chromedriver: &PathBuf,
    width: u32,
    height: u32,
    scale: f64,
) -> Result<Session> {
    retried(BROWSER_ATTEMPTS, "starting chromium", || {
        start_browser_once(chromium, chromedriver, width, height, scale)
    })
    .await
}

/// One try of [`start_browser_with`]: chromedriver on a free port, then a Chromium session
/// (its profile removed again when the session does not open).
async fn start_browser_once(
    chromium: &PathBuf,
    chromedriver: &PathBuf,
    width: u32,
    height: u32,
    scale: f64,
) -> Result<Session> {
    let port = free_port();
    let driver = tokio::process::Command::new(chromedriver)
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .kill_on_drop(true)
        .spawn()
        .context("cannot start chromedriver")?;
    for _ in 0..100 {
        if tokio::net::TcpStream::connect(("127.0.0.1", port))
            .await
            .is_ok()
        {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let profile =
        std::env::temp_dir().join(format!("ucc-gui-chromium-{}-{port}", std::process::id()));
    let caps = json!({
        "goog:chromeOptions": {
            "binary": chromium,
            "args": ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                     "--disable-background-networking", "--disable-component-update", "--disable-sync",
                     "--disable-dev-shm-usage", format!("--window-size={width},{height}"),
                     format!("--force-device-scale-factor={scale}"),
                     "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
                     format!("--user-data-dir={}", profile.display())]

        }
    });
    let mut builder = ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new());
    builder.capabilities(caps.as_object().unwrap().clone());
    let client = match builder.connect(&format!("http://127.0.0.1:{port}")).await {
        Ok(client) => client,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&profile);
            return Err(e).context("cannot open a chromium session");
        }
    };
    Ok(Session {
        client,
        driver,
        profile,
    })
}

async fn start_gui(speed: TimeScale) -> Result<(String, CancellationToken, PathBuf)> {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
    let url = ucc_gui::url(listener.local_addr()?, None);
    let log_dir = std::env::temp_dir().join(format!("ucc-gui-test-{}", free_port()));
    let config = GuiConfig {
        server: ServerChoice::Local(Box::new(ServerConfig {
            time_scale: speed,
            lockstep: true,
            ..ServerConfig::default()
        })),
        log_dir: log_dir.clone(),
        token: None,
        ..GuiConfig::default()
    };
    let cancel = CancellationToken::new();
    let stop = cancel.clone();
    tokio::spawn(async move { ucc_gui::serve(listener, config, stop).await });
    Ok((url, cancel, log_dir))
}

async fn by_id(c: &Client, id: &str) -> Result<fantoccini::elements::Element> {
    Ok(c.find(Locator::Css(&format!("[data-testid=\"{id}\"]")))
        .await?)
}

async fn text(c: &Client, id: &str) -> Result<String> {
    Ok(by_id(c, id).await?.text().await?)
}

async fn type_into(c: &Client, id: &str, value: &str) -> Result<()> {
    let e = by_id(c, id).await?;
    e.clear().await?;
    e.send_keys(value).await?;
    Ok(())
}

/// Waits (up to `seconds`) until `check` holds, polling.
async fn until<F, Fut>(what: &str, seconds: u64, mut check: F) -> Result<()>
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Result<bool>>,
{
    let deadline = tokio::time::Instant::now() + Duration::from_secs(seconds);
    loop {
        if check().await? {
            return Ok(());
        }
        if tokio::time::Instant::now() > deadline {
            bail!("gave up waiting for {what}");
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

async fn status(c: &Client) -> Result<String> {
    Ok(c.find(Locator::Id("run-status"))
        .await?
        .attr("data-status")
        .await?
        .unwrap_or_default())
}

async fn count(c: &Client, css: &str) -> Result<usize> {
    Ok(c.find_all(Locator::Css(css)).await?.len())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fly_three_iterations_stop_and_refuse_bad_input() -> Result<()> {
    let Some((chromium, chromedriver)) = browser() else {
        return Ok(());
    };
    let _one = ONE_BROWSER.lock().await;
    let (url, gui, log_dir) = start_gui(TimeScale::Factor(5.0)).await?;
    let mut session = start_browser(&chromium, &chromedriver).await?;
    let result = futures::FutureExt::catch_unwind(std::panic::AssertUnwindSafe(scenario(
        &session.client,
        &url,
    )))
    .await;
    let _ = session.client.clone().close().await;
    let _ = session.driver.kill().await;
    gui.cancel();
    let _ = std::fs::remove_dir_all(&log_dir);
    result.unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

async fn scenario(c: &Client, url: &str) -> Result<()> {
    c.goto(url).await?;
    until("the page to connect", 20, || async {
        Ok(count(c, "[data-testid=agent-type] option").await? > 0)
    })
    .await?;
    let start = ServerConfig::default().map.starts()[0].clone();
    let [ox, oy, _] = start.location;

    // Create a UAV at the map's first start.
    type_into(c, "start-pose", &start.tag).await?;
    by_id(c, "create-uav").await?.click().await?;
    until("the UAV in the list", 10, || async {
        Ok(count(c, "#uav-list li").await? == 1)
    })
    .await?;
    assert!(c.title().await?.contains("UAV Control Center"));

    // A bad coordinate gets a clear message.
    type_into(c, "mission-x", "abc").await?;
    type_into(c, "mission-y", "0").await?;
    by_id(c, "mission-add").await?.click().await?;
    until("the error message", 10, || async {
        let e = by_id(c, "error").await?;
        Ok(e.is_displayed().await?
            && e.text()
                .await?
                .contains("mission x: \"abc\" is not a finite number"))
    })
    .await?;
    assert_eq!(count(c, "[data-testid=mission-list] li").await?, 0);

    // Two waypoints by the form, one by clicking on the map.
    for (x, y) in [(ox, oy), (ox + 2.5, oy)] {
        type_into(c, "mission-x", &format!("{x:.2}")).await?;
        type_into(c, "mission-y", &format!("{y:.2}")).await?;
        type_into(c, "mission-z", "-2").await?;
        by_id(c, "mission-add").await?.click().await?;
    }
    until("two missions", 10, || async {
        Ok(count(c, "[data-testid=mission-list] li").await? == 2)
    })
    .await?;
    let map = by_id(c, "map").await?;
    // Where the point (ox + 2.5, oy + 2.5) is, relative to the canvas centre, in CSS pixels.
    let offset = c
        .execute(
            "const [sx, sy] = ucc.toScreen(arguments[0], arguments[1]); const map = document.getElementById('map');\
             return [sx - map.clientWidth / 2, sy - map.clientHeight / 2];",
            vec![json!(ox + 2.5), json!(oy + 2.5)],
        )
        .await?;
    let (dx, dy) = (offset[0].as_f64().unwrap(), offset[1].as_f64().unwrap());
    let click = MouseActions::new("mouse".into())
        .then(PointerAction::MoveToElement {
            element: map.clone(),
            duration: None,
            x: dx,
            y: dy,
        })
        .then(PointerAction::Down { button: 0 })
        .then(PointerAction::Up { button: 0 });
    c.perform_actions(click).await?;
    until("the clicked waypoint", 10, || async {
        Ok(count(c, "[data-testid=mission-list] li").await? == 3)
    })
    .await?;
    let third = c
        .find_all(Locator::Css("[data-testid=mission-list] li"))
        .await?[2]
        .text()
        .await?;
    let nums: Vec<f64> = third
        .trim_start_matches("GotoXyz ")
        .trim_end_matches(" ×")
        .split(',')
        .map(|v| v.trim().parse().unwrap_or(f64::NAN))
        .collect();
    assert!(
        (nums[0] - (ox + 2.5)).abs() < 0.3 && (nums[1] - (oy + 2.5)).abs() < 0.3 && nums[2] == -2.0,
        "clicked waypoint {third:?}, expected near {},{}",
        ox + 2.5,
        oy + 2.5
    );

    // Drag pans (and adds no waypoint), the wheel zooms.
    let view = |c: &Client| {
        let c = c.clone();
        async move {
            Ok::<_, anyhow::Error>(
                c.execute("return [ucc.view.cx, ucc.view.cy, ucc.view.scale]", vec![])
                    .await?,
            )
        }
    };
    let before = view(c).await?;
    let drag = MouseActions::new("mouse".into())
        .then(PointerAction::MoveToElement {
            element: map.clone(),
            duration: None,
            x: 0.0,
            y: 0.0,
        })
        .then(PointerAction::Down { button: 0 })
        .then(PointerAction::MoveBy {
            duration: None,
            x: 60.0,
            y: 40.0,
        })
        .then(PointerAction::Up { button: 0 });
    c.perform_actions(drag).await?;
    let panned = view(c).await?;
    assert!(
        panned[0] != before[0] && panned[1] != before[1] && panned[2] == before[2],
        "{before} -> {panned}"
    );
    c.execute(
        "document.getElementById('map').dispatchEvent(new WheelEvent('wheel', {deltaY: -100, clientX: 100, clientY: 100, bubbles: true, cancelable: true}))",
        vec![],
    )
    .await?;
    let zoomed = view(c).await?;
    assert!(
        zoomed[2].as_f64() > panned[2].as_f64(),
        "{panned} -> {zoomed}"
    );
    c.execute("ucc.fit()", vec![]).await?;
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(
        count(c, "[data-testid=mission-list] li").await?,
        3,
        "a drag adds no waypoint"
    );

    // Loop three iterations; watch the position change, the counter reach 3, the log fill.
    type_into(c, "iterations", "3").await?;
    by_id(c, "start").await?.click().await?;
    until("a position", 30, || async {
        Ok(!text(c, "uav-position").await?.is_empty())
    })
    .await?;
    let first = text(c, "uav-position").await?;
    if let Err(e) = until("the position to change", 60, || async {
        Ok(text(c, "uav-position").await? != first)
    })
    .await
    {
        let log = text(c, "log").await.unwrap_or_default();
        let status = c.find(Locator::Id("run-status")).await?.text().await?;
        bail!("{e}: status {status:?}, log:\n{log}");
    }
    let parts: Vec<f64> = text(c, "uav-position")
        .await?
        .split(',')
        .map(|v| v.parse().unwrap_or(f64::NAN))
        .collect();
    assert!(
        parts.len() == 3 && parts.iter().all(|v| v.is_finite()),
        "position text {parts:?}"
    );
    assert!(text(c, "uav-battery").await?.contains('%'));
    until("the run to end", 240, || async {
        Ok(status(c).await? != "running")
    })
    .await?;
    assert_eq!(
        status(c).await?,
        "done",
        "{}",
        c.find(Locator::Id("run-status")).await?.text().await?
    );
    assert_eq!(text(c, "iteration-counter").await?, "3");
    let log = text(c, "log").await?;
    assert!(log.contains("[3] iteration done"), "{log}");
    assert!(log.lines().count() > 10, "{log}");
    assert!(
        count(c, "#files a").await? >= 6,
        "the run's files are offered for download"
    );

    // The map screenshot (with the overlay of three iterations) as a test artifact.
    let png = map.screenshot().await?;
    let dir = artifacts();
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join("map.png"), png)?;
    let page = c.screenshot().await?;
    std::fs::write(dir.join("page.png"), page)?;

    // Save log asks for the log as a download (headless Chromium does not finish downloads
    // here, so the test catches the link and fetches it itself).
    let href = c
        .execute(
            "let href = null; const orig = HTMLAnchorElement.prototype.click;\
             HTMLAnchorElement.prototype.click = function () { href = this.href; };\
             document.getElementById('save-log').click();\
             HTMLAnchorElement.prototype.click = orig; return href;",
            vec![],
        )
        .await?;
    let href = href.as_str().context("Save log made no link")?.to_owned();
    assert!(href.contains("/api/log?uav="), "{href}");
    let saved = c
        .execute_async(
            "const done = arguments[arguments.length - 1]; fetch(arguments[0]).then(r => r.text()).then(done);",
            vec![json!(href)],
        )
        .await?;
    let saved = saved.as_str().unwrap_or_default();
    assert!(saved.contains("UAV1 info [3] iteration done"), "{saved}");

    // Stop mid-flight.
    type_into(c, "iterations", "50").await?;
    by_id(c, "start").await?.click().await?;
    if let Err(e) = until("the second run to fly", 30, || async {
        Ok(status(c).await? == "running" && text(c, "iteration-counter").await? != "0")
    })
    .await
    {
        let log = text(c, "log").await.unwrap_or_default();
        let status = c.find(Locator::Id("run-status")).await?.text().await?;
        let counter = text(c, "iteration-counter").await?;
        let error = text(c, "error").await.unwrap_or_default();
        bail!("{e}: status {status:?}, counter {counter}, error {error:?}, log:\n{log}");
    }
    by_id(c, "stop").await?.click().await?;
    until("the run to stop", 30, || async {
        Ok(status(c).await? == "stopped")
    })
    .await?;
    let stopped_at: usize = text(c, "iteration-counter").await?.parse()?;
    assert!(
        (1..50).contains(&stopped_at),
        "stopped at iteration {stopped_at}"
    );
    // The log line may land a moment after the status (a loaded machine).
    until("the interruption in the log", 10, || async {
        Ok(text(c, "log").await?.contains("interrupted"))
    })
    .await?;
    Ok(())
}

/// The page with 50 UAVs flying: the browser's frame time. A benchmark, not a test: it runs
/// only with `UCC_GUI_BENCH=1` and prints its figures (BENCHMARKS.md).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bench_frame_time_with_50_uavs() -> Result<()> {
    if std::env::var("UCC_GUI_BENCH").as_deref() != Ok("1") {
        eprintln!("frame-time benchmark skipped: set UCC_GUI_BENCH=1 to run it");
        return Ok(());
    }
    let Some((chromium, chromedriver)) = browser() else {
        return Ok(());
    };
    let _one = ONE_BROWSER.lock().await;
    let (url, gui, log_dir) = start_gui(TimeScale::Factor(1.0)).await?;
    let mut session = start_browser(&chromium, &chromedriver).await?;
    let c = &session.client;
    c.goto(&url).await?;
    until("the page to connect", 20, || async {
        Ok(count(c, "[data-testid=agent-type] option").await? > 0)
    })
    .await?;
    // 50 UAVs on a grid, each flying a 1.5 m x 1 m box, many times.
    c.execute(
        "let id = 0;
         for (const x of [-8, -4.5, -1, 2.5, 6]) for (let k = 0; k < 10; k++) { const y = Math.round((-9 + 1.9 * k) * 10) / 10;
           id++;
           ucc.send({op: 'create', robot: 'stsAirRobot', agent: 'base', start: `${x},${y},-1`, name: ''});
           for (const [dx, dy] of [[0, 0], [1.5, 0], [1.5, 1], [0, 1]])
             ucc.send({op: 'add_mission', uav: id, kind: 'GotoXyz', x: String(x + dx), y: String(y + dy), z: '-2'});
           ucc.send({op: 'options', uav: id, prefix: 'B' + id, pictures: 'none', autosave: false});
           ucc.send({op: 'start', uav: id, iterations: '1000'});
         }",
        vec![],
    )
    .await?;
    until("50 UAVs flying", 120, || async {
        let n = c
            .execute("return [...ucc.uavs.values()].filter(u => u.live && u.info.status === 'running').length", vec![])
            .await?;
        Ok(n.as_u64() == Some(50))
    })
    .await?;
    tokio::time::sleep(Duration::from_secs(3)).await;
    let figures = c
        .execute_async(
            "const done = arguments[arguments.length - 1];
             window.uccFrameTimes = []; const u0 = window.uccUpdates; const gaps = []; let last = performance.now();
             const t0 = last;
             function f(t) { gaps.push(t - last); last = t; if (t - t0 < 10000) requestAnimationFrame(f); else {
               const q = (a, p) => { const s = [...a].sort((x, y) => x - y); return s[Math.min(s.length - 1, Math.floor(p * s.length))]; };
               const d = window.uccFrameTimes;
               done({draw_median: q(d, 0.5), draw_p95: q(d, 0.95), draw_max: q(d, 1), frames: d.length,
                     gap_median: q(gaps, 0.5), gap_p95: q(gaps, 0.95), updates_per_s: (window.uccUpdates - u0) / ((t - t0) / 1000),
                     trail_points: [...ucc.uavs.values()].reduce((n, u) => n + u.trail.length + u.past.flat().length, 0)});
             } }
             requestAnimationFrame(f);",
            vec![],
        )
        .await?;
    println!("ucc-gui frame time, 50 UAVs flying, 10 s: {figures}");
    let dir = artifacts();
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join("page-50-uavs.png"), c.screenshot().await?)?;
    let _ = session.client.clone().close().await;
    let _ = session.driver.kill().await;
    gui.cancel();
    let _ = std::fs::remove_dir_all(&log_dir);
    Ok(())
}

// ---- issue #23: defects a user hit, each checked the way the user met it ----

/// Browser tests run one at a time (two cores, a Chromium each).
static ONE_BROWSER: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// The page's objects for a test script.
const U: &str = "const U = window.ucc;";

/// The control center on a server of the given kind; its URL, its stop token and log dir.
async fn start_gui_on(server: ServerChoice) -> Result<(String, CancellationToken, PathBuf)> {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
    let url = ucc_gui::url(listener.local_addr()?, None);
    let log_dir = std::env::temp_dir().join(format!("ucc-gui-test-{}", free_port()));
    let config = GuiConfig {
        server,
        log_dir: log_dir.clone(),
        token: None,
        ..GuiConfig::default()
    };
    let cancel = CancellationToken::new();
    let stop = cancel.clone();
    tokio::spawn(async move { ucc_gui::serve(listener, config, stop).await });
    Ok((url, cancel, log_dir))
}

fn local(speed: TimeScale) -> ServerChoice {
    ServerChoice::Local(Box::new(ServerConfig {
        time_scale: speed,
        lockstep: true,
        ..ServerConfig::default()
    }))
}

/// Opens the page and waits until it is connected.
async fn open(c: &Client, url: &str) -> Result<()> {
    c.goto(url).await?;
    until("the page to connect", 30, || async {
        Ok(count(c, "[data-testid=agent-type] option").await? > 0)
    })
    .await?;
    // Errors thrown anywhere in the page are collected for the test.
    c.execute(
        "window.uccErrors = []; window.addEventListener('error', (e) => window.uccErrors.push(String(e.message)));",
        vec![],
    )
    .await?;
    Ok(())
}

async fn js(c: &Client, script: &str) -> Result<serde_json::Value> {
    Ok(c.execute(&format!("{U} {script}"), vec![]).await?)
}

/// Runs `body` with a browser of this window size and scale and a control center on
/// `server`; cleans up whatever the result.
async fn with_page<F, Fut>(
    server: ServerChoice,
    size: (u32, u32),
    scale: f64,
    body: F,
) -> Result<()>
where
    F: FnOnce(Client, String, PathBuf) -> Fut,
    Fut: std::future::Future<Output = Result<()>>,
{
    let Some((chromium, chromedriver)) = browser() else {
        return Ok(());
    };
    let _one = ONE_BROWSER.lock().await;
    let (url, gui, log_dir) = start_gui_on(server).await?;
    let mut session = start_browser_with(&chromium, &chromedriver, size.0, size.1, scale).await?;
    // A failed assertion panics: catch it so that Chromium is closed (not left running).
    let result = futures::FutureExt::catch_unwind(std::panic::AssertUnwindSafe(body(
        session.client.clone(),
        url,
        log_dir.clone(),
    )))
    .await;
    let _ = session.client.clone().close().await;
    let _ = session.driver.kill().await;
    gui.cancel();
    let _ = std::fs::remove_dir_all(&log_dir);
    result.unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

async fn create_uav(c: &Client, name: &str, start: &str) -> Result<()> {
    let before = count(c, "#uav-list li").await?;
    type_into(c, "start-pose", start).await?;
    let n = c.find(Locator::Id("uav-name")).await?;
    n.clear().await?;
    n.send_keys(name).await?;
    by_id(c, "create-uav").await?.click().await?;
    until("the UAV in the list", 10, || async {
        Ok(count(c, "#uav-list li").await? == before + 1)
    })
    .await
}

/// Defect 4: a name is text, never HTML; defect 9: the UAV list, the Loop field, the log
/// filters and the × buttons are usable from the keyboard and named; Enter submits a form.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn names_are_text_and_the_page_works_from_the_keyboard() -> Result<()> {
    with_page(local(TimeScale::Max), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        create_uav(&c, "<img/src=x>", "0,0,-1").await?;
        create_uav(&c, "<b>bold</b>", "1,0,-1").await?;
        assert_eq!(count(&c, "#uav-list img, #uav-list b").await?, 0, "a name became HTML");
        let items = c.find_all(Locator::Css("#uav-list li")).await?;
        assert!(items[0].text().await?.contains("<img/src=x>"));
        assert!(items[1].text().await?.contains("<b>bold</b>"));
        assert_eq!(count(&c, "#log-uav img, #log-uav b").await?, 0);

        // Keyboard: Tab reaches a UAV; Enter selects it.
        let focusable = js(&c, "return [...document.querySelectorAll('#uav-list li')].map(li => li.tabIndex >= 0 || !!li.querySelector('button'))").await?;
        assert_eq!(focusable, json!([true, true]), "UAV list items are focusable");
        let first = c.find(Locator::Css("#uav-list li")).await?;
        first.send_keys("\u{e007}").await?;
        until("the first UAV selected by Enter", 5, || async {
            Ok(c.find(Locator::Id("title")).await?.text().await?.contains("<img/src=x>"))
        })
        .await?;

        // Every field and button has a name.
        let unnamed = js(&c, "
            const name = (e) => (e.getAttribute('aria-label') || (e.labels && [...e.labels].map(l => l.textContent).join(' ')) || e.title || (e.tagName === 'BUTTON' ? e.textContent : '')).trim();
            return [...document.querySelectorAll('input, select, button')].filter(e => !e.hidden && e.type !== 'hidden' && !name(e)).map(e => e.id || e.outerHTML.slice(0, 60));").await?;
        assert_eq!(unnamed, json!([]), "fields and buttons without a name");
        let loop_name = js(&c, "return [...document.getElementById('iterations').labels].map(l => l.textContent.trim()).join('|')").await?;
        assert_eq!(loop_name, json!("Loop"));

        // Enter in a mission field adds the mission; the × button is named.
        type_into(&c, "mission-x", "1").await?;
        type_into(&c, "mission-y", "2").await?;
        by_id(&c, "mission-z").await?.send_keys("\u{e007}").await?;
        until("the mission added by Enter", 10, || async {
            Ok(count(&c, "[data-testid=mission-list] li").await? == 1)
        })
        .await?;
        let x = c.find(Locator::Css("[data-testid=mission-list] li button")).await?;
        assert_eq!(x.attr("aria-label").await?.as_deref(), Some("remove mission 1"));

        // Contrast of the warning text and of the walls on white: at least 4.5:1.
        let contrast = js(&c, "
            const lum = (hex) => { const c = hex.match(/\\w\\w/g).map(h => parseInt(h, 16) / 255).map(v => v <= 0.03928 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4); return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; };
            const ratio = (a, b) => { const [x, y] = [lum(a), lum(b)].sort((p, q) => q - p); return (x + 0.05) / (y + 0.05); };
            const rgb = (s) => '#' + s.match(/\\d+/g).slice(0, 3).map(v => Number(v).toString(16).padStart(2, '0')).join('');
            const d = document.createElement('div'); d.className = 'warn'; document.getElementById('log').appendChild(d);
            const warn = rgb(getComputedStyle(d).color); d.remove();
            return [ratio(warn, '#ffffff'), ratio(U.WALL_COLOR, '#ffffff')];").await?;
        let ratios: Vec<f64> = contrast.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        assert!(ratios.iter().all(|r| *r >= 4.5), "contrast {ratios:?}");
        assert_eq!(js(&c, "return window.uccErrors").await?, json!([]));
        Ok(())
    })
    .await
}

/// Defect 5: a waypoint beyond any map gets a message; a far one draws quickly; the wheel
/// zooms by the distance scrolled, within limits.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn huge_numbers_and_the_wheel_keep_the_map_usable() -> Result<()> {
    with_page(local(TimeScale::Max), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        create_uav(&c, "", "0,0,-1").await?;
        type_into(&c, "mission-x", "1e8").await?;
        type_into(&c, "mission-y", "0").await?;
        by_id(&c, "mission-add").await?.click().await?;
        until("the range message", 10, || async {
            let e = by_id(&c, "error").await?;
            Ok(e.is_displayed().await? && e.text().await?.contains("mission x: "))
        })
        .await?;
        assert_eq!(count(&c, "[data-testid=mission-list] li").await?, 0);
        type_into(&c, "mission-x", "99999").await?;
        by_id(&c, "mission-add").await?.click().await?;
        until("the far waypoint", 10, || async {
            Ok(count(&c, "[data-testid=mission-list] li").await? == 1)
        })
        .await?;
        let t = js(&c, "U.fit(); const t = performance.now(); U.drawMap(); return performance.now() - t;").await?;
        assert!(t.as_f64().unwrap() < 500.0, "one frame took {t} ms");

        // 70 notches of the wheel: bounded; a small scroll zooms less than a big one.
        let zoom = js(&c, "
            const map = document.getElementById('map');
            const wheel = (dy) => map.dispatchEvent(new WheelEvent('wheel', {deltaY: dy, clientX: 100, clientY: 100, bubbles: true, cancelable: true}));
            U.fit(); const s0 = U.view.scale; wheel(-1); const small = U.view.scale / s0;
            U.fit(); wheel(-100); const big = U.view.scale / s0;
            for (let i = 0; i < 70; i++) wheel(-100);
            const t = performance.now(); U.drawMap(); const frame = performance.now() - t;
            return [small, big, U.view.scale, frame];").await?;
        let z: Vec<f64> = zoom.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        assert!(z[0] > 1.0 && z[0] < z[1], "zoom by distance: {z:?}");
        assert!(z[2] <= 2000.0, "zoom limited: {z:?}");
        assert!(z[3] < 500.0, "a frame after 70 notches: {z:?}");
        assert_eq!(js(&c, "return window.uccErrors").await?, json!([]));
        Ok(())
    })
    .await
}

/// Defect 2: a state as large as a long loop's (200,000 trail points) neither kills the
/// animation nor the update.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_long_loops_state_keeps_the_map_alive() -> Result<()> {
    with_page(local(TimeScale::Max), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        let r = js(&c, "
            const trail = []; for (let i = 0; i < 200000; i++) trail.push([Math.sin(i / 1000) * 5, Math.cos(i / 1000) * 5, -1 - (i % 100) / 100]);
            const past = []; for (let k = 0; k < 50; k++) past.push(trail.slice(k * 3000, k * 3000 + 3000));
            const history = []; for (let i = 0; i < 5000; i++) history.push([i * 0.1, 1, 0.5, 0.9]);
            const u = {id: 77, info: {name: 'big', robot: 'stsAirRobot', agent: 'base', start: '0,0,-1', status: 'running', error: null,
              iteration: 2000, iterations: 10000, active: 0, prefix: 'big', pictures: 'none', autosave: false,
              missions: [{kind: 'GotoXyz', x: 5, y: 0, z: -1, text: 'GotoXyz 5,0,-1'}]},
              live: {time: 1, position: [0, 5, -1], attitude: [0, 0, 0], velocity: [0, 0, 0], battery: null,
                     laser: {ranges: new Array(181).fill(3), resolution: 0.0174, fov: 3.14}, sonars: [1, 2]},
              trail_reset: true, trail, history_reset: true, history, past_reset: true, past, hits: [], files: {total: 0, recent: []}};
            try { U.receive({type: 'state', server: {addr: 'x:1', local: true, time_scale: '1', paused: false, map: ''}, uavs: [u], log: []}); }
            catch (e) { return String(e); }
            return null;").await?;
        assert_eq!(r, json!(null), "the update threw");
        let frames = js(&c, "return window.uccFrameTimes.length").await?.as_u64().unwrap();
        c.execute("document.getElementById('fit').click()", vec![]).await?;
        tokio::time::sleep(Duration::from_millis(1500)).await;
        let after = js(&c, "return window.uccFrameTimes.length").await?.as_u64().unwrap();
        assert!(after > frames, "the animation stopped ({frames} -> {after} frames)");
        assert_eq!(js(&c, "return window.uccErrors").await?, json!([]));
        Ok(())
    })
    .await
}

/// #26, the page over a long loop: what the page holds per UAV and what three.js holds on the
/// GPU (geometries, textures), the 3D scene and the DOM (beside the log panel's lines, capped
/// at 2,000) stay the same from iteration 50 to iteration 250 of a loop
/// (fed the hub's update format: a new iteration every 80 ms, with trail, plots, overlay and
/// log lines, the selected UAV's laser and sonars drawn in 3D every frame).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_long_loop_leaves_the_pages_structures_bounded() -> Result<()> {
    with_page(local(TimeScale::Max), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        let counts = c
            .execute_async(
                "const done = arguments[arguments.length - 1]; const U = window.ucc;
                 const server = {addr: 'x:1', local: true, time_scale: '1', paused: false, map: ''};
                 const info = (k) => ({name: 'Soak', robot: 'stsAirRobot', agent: 'base', start: '0,0,-1', status: 'running', error: null,
                   iteration: k, iterations: 10000, active: 0, prefix: 'S', pictures: 'none', autosave: false,
                   missions: [{kind: 'GotoXyz', x: 0.5, y: 0, z: -1.2, text: 'GotoXyz 0.50,0.00,-1.20'}]});
                 let k = 0, at50 = null;
                 const count = () => { const u = U.uavs.get(1), m = U.view3d && U.view3d.ok ? U.view3d.renderer.info.memory : {geometries: -1, textures: -1};
                   return {trail: u.trail.length, past: u.past.length, history: u.history.length, log: U.store.log.length,
                           geometries: m.geometries, textures: m.textures, scene: U.view3d && U.view3d.ok ? U.view3d.scene.children.length : -1,
                           dom: document.getElementsByTagName('*').length - document.getElementById('log').children.length}; };
                 const timer = setInterval(() => {
                   k++;
                   const trail = []; for (let i = 0; i < 20; i++) trail.push([i * 0.025, 0, -1 - i * 0.01]);
                   const past = k > 1 ? [trail] : [];
                   const u = {id: 1, info: info(k), trail_reset: true, trail, history_reset: true,
                     history: trail.map((p, i) => [k + i * 0.1, -p[2], 0.4, 0.9]), past,
                     live: {time: k, position: [0.5, 0, -1.2], attitude: [0, 0, 0.1], velocity: [0.1, 0, 0], battery: {level: 0.9, remaining: 900},
                            laser: {ranges: new Array(181).fill(3), resolution: 0.0174, fov: 3.14}, sonars: [1, 2, 3, 4, 5, 6, 7, 8]}};
                   if (k % 100 === 0) u.past_reset = true;
                   U.receive({type: 'state', server, uavs: [u], removed: [],
                     log: [{seq: k, level: 'info', uav: 1, text: `[${k}] mission 1 done`}]});
                   if (k === 50) at50 = count();
                   if (k === 250) { clearInterval(timer); setTimeout(() => done({at50, at250: count()}), 300); }
                 }, 80);",
                vec![],
            )
            .await?;
        let (a, b) = (&counts["at50"], &counts["at250"]);
        for key in ["geometries", "textures", "scene", "dom", "trail", "history"] {
            assert_eq!(a[key], b[key], "{key} grew from iteration 50 to 250: {counts}");
        }
        assert!(b["past"].as_u64().unwrap() <= 100, "{counts}");
        assert!(b["log"].as_u64().unwrap() <= 2000, "{counts}");
        assert_eq!(js(&c, "return window.uccErrors").await?, json!([]));
        Ok(())
    })
    .await
}

/// A fault the server applies (`--faults`) shows on the UAV's panel and in the log.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fault_shows_on_the_uav_panel_and_in_the_log() -> Result<()> {
    let mut config = ServerConfig {
        time_scale: TimeScale::Factor(2.0),
        lockstep: true,
        ..ServerConfig::default()
    };
    config.sim.faults = usar_server::sim::faults::FaultPlan::from_toml(
        "[[fault]]\ntime = 0.5\nrobot = 1\nline = \"FAULT {Sensor Position} {Mode Bias} {Value 0.1}\"\n",
    )
    .unwrap();
    with_page(
        ServerChoice::Local(Box::new(config)),
        (1400, 900),
        1.0,
        |c, url, _| async move {
            open(&c, &url).await?;
            create_uav(&c, "", "0,0,-1").await?;
            type_into(&c, "mission-x", "3").await?;
            type_into(&c, "mission-y", "0").await?;
            by_id(&c, "mission-add").await?.click().await?;
            by_id(&c, "start").await?.click().await?;
            until("the fault on the panel", 60, || async {
                Ok(text(&c, "uav-faults")
                    .await?
                    .contains("Sensor Position Mode Bias Value 0.1"))
            })
            .await?;
            let shown = text(&c, "uav-faults").await?;
            assert!(
                shown.starts_with("1: ") && shown.contains("t=0.50"),
                "{shown}"
            );
            until("the fault in the log", 30, || async {
                Ok(text(&c, "log").await?.contains("fault at t=0.50s"))
            })
            .await?;
            let dir = artifacts();
            std::fs::create_dir_all(&dir)?;
            std::fs::write(dir.join("fault.png"), c.screenshot().await?)?;
            by_id(&c, "stop").await?.click().await?;
            Ok(())
        },
    )
    .await
}

/// Defect 3: the download links stay put while nothing changes (a held click reaches
/// them), and a long run does not grow the list without bound.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn download_links_stay_put_and_the_list_stays_short() -> Result<()> {
    with_page(local(TimeScale::Max), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        create_uav(&c, "", "0,0,-1").await?;
        type_into(&c, "mission-x", "0.5").await?;
        type_into(&c, "mission-y", "0").await?;
        by_id(&c, "mission-add").await?.click().await?;
        type_into(&c, "iterations", "8").await?;
        by_id(&c, "start").await?.click().await?;
        until("the run to end", 120, || async {
            Ok(status(&c).await? == "done")
        })
        .await?;
        let links = count(&c, "#files a").await?;
        assert!((1..=12).contains(&links), "{links} links after 8 iterations");
        let same = js(&c, "
            const a = document.querySelector('#files a');
            return new Promise((done) => setTimeout(() => done(a.isConnected && document.querySelector('#files a') === a), 400));").await?;
        assert_eq!(same, json!(true), "the links were rebuilt while nothing changed");
        // A real press held 150 ms reaches the link.
        c.execute("window.uccClicked = null; document.getElementById('files').addEventListener('click', (e) => { window.uccClicked = e.target.textContent; e.preventDefault(); });", vec![]).await?;
        let link = c.find(Locator::Css("#files a")).await?;
        let press = MouseActions::new("mouse".into())
            .then(PointerAction::MoveToElement { element: link, duration: None, x: 0.0, y: 0.0 })
            .then(PointerAction::Down { button: 0 })
            .then(PointerAction::Pause { duration: Duration::from_millis(150) })
            .then(PointerAction::Up { button: 0 });
        c.perform_actions(press).await?;
        let clicked = js(&c, "return window.uccClicked").await?;
        assert!(clicked.is_string(), "the click did not reach the link");
        Ok(())
    })
    .await
}

/// Defect 7: the map is the largest view at 1024×700, the log is in view at 1400×900, Host
/// and Port show the local server's address; a remote server hides the speed.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_layout_fits_small_and_large_windows() -> Result<()> {
    for (w, h) in [(1024u32, 700u32), (1400, 900)] {
        with_page(local(TimeScale::Max), (w, h), 1.0, |c, url, _| async move {
            open(&c, &url).await?;
            let r = js(&c, "
                const rect = (id) => document.getElementById(id).getBoundingClientRect();
                const m = rect('map'), log = rect('log-box');
                const others = [...document.querySelectorAll('#side canvas, #plots canvas')].map(e => { const r = e.getBoundingClientRect(); return r.width * r.height; });
                return {map_w: m.width, map_h: m.height, map_area: m.width * m.height, biggest_other: Math.max(0, ...others),
                        log_top: log.top, vw: innerWidth, vh: innerHeight,
                        host: document.getElementById('server-host').value, port: document.getElementById('server-port').value,
                        speed_shown: getComputedStyle(document.getElementById('time-scale-row')).display !== 'none',
                        addr: document.getElementById('server-info').textContent};").await?;
            assert!(r["map_w"].as_f64().unwrap() >= 0.45 * r["vw"].as_f64().unwrap(), "{w}x{h}: {r}");
            assert!(r["map_h"].as_f64().unwrap() >= 0.5 * r["vh"].as_f64().unwrap(), "{w}x{h}: {r}");
            assert!(r["map_area"].as_f64().unwrap() > r["biggest_other"].as_f64().unwrap(), "{w}x{h}: {r}");
            if w == 1400 {
                assert!(r["log_top"].as_f64().unwrap() < r["vh"].as_f64().unwrap() - 60.0, "the log below the fold: {r}");
            }
            let addr = format!("{}:{}", r["host"].as_str().unwrap(), r["port"].as_str().unwrap());
            assert!(r["addr"].as_str().unwrap().contains(&addr), "Host/Port {addr} vs {r}");
            assert_eq!(r["speed_shown"], json!(true));
            let dir = artifacts();
            std::fs::create_dir_all(&dir)?;
            std::fs::write(dir.join(format!("page-{w}x{h}.png")), c.screenshot().await?)?;
            Ok(())
        })
        .await?;
    }
    let server = usar_server::LocalServer::start(ServerConfig::default()).await?;
    let remote = ServerChoice::Remote(server.addr().to_string());
    with_page(remote, (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        let shown = js(
            &c,
            "return getComputedStyle(document.getElementById('time-scale-row')).display !== 'none'",
        )
        .await?;
        assert_eq!(
            shown,
            json!(false),
            "the speed of a remote server is not ours to set"
        );
        Ok(())
    })
    .await?;
    server.stop().await?;
    Ok(())
}

/// Defect 8: sharp canvases on a HiDPI screen, plots with axes, a side view for each
/// horizontal axis, and a 3D view.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn views_are_sharp_with_axes_and_in_3d() -> Result<()> {
    with_page(
        local(TimeScale::Max),
        (1400, 900),
        2.0,
        |c, url, _| async move {
            open(&c, &url).await?;
            create_uav(&c, "", "0,0,-1").await?;
            for (x, y) in [(0.0, 3.0), (0.0, -3.0)] {
                type_into(&c, "mission-x", &format!("{x}")).await?;
                type_into(&c, "mission-y", &format!("{y}")).await?;
                by_id(&c, "mission-add").await?.click().await?;
            }
            type_into(&c, "iterations", "1").await?;
            by_id(&c, "start").await?.click().await?;
            until("the run to end", 120, || async {
                Ok(status(&c).await? == "done")
            })
            .await?;
            tokio::time::sleep(Duration::from_millis(500)).await;
            let r = js(
                &c,
                "
            const m = document.getElementById('map');
            return {ratio: m.width / m.clientWidth, dpr: devicePixelRatio,
                    axes: document.querySelectorAll('#plots .u-axis').length,
                    east: U.side && U.side.east ? U.side.east.range : null,
                    three: !!document.querySelector('#view3d canvas')};",
            )
            .await?;
            assert!((r["ratio"].as_f64().unwrap() - 2.0).abs() < 0.05, "{r}");
            assert!(
                r["axes"].as_u64().unwrap() >= 6,
                "three plots with two axes each: {r}"
            );
            let east = r["east"].as_array().context("no east–altitude view")?;
            assert!(
                east[1].as_f64().unwrap() - east[0].as_f64().unwrap() >= 5.0,
                "an east–west leg shows its length: {r}"
            );
            assert_eq!(r["three"], json!(true), "{r}");
            // No label is cut or drawn over another: the plots' y-axis labels fit in their
            // plots, the side views' captions clear their tick values.
            let clipped = js(
                &c,
                // uPlot draws a y-axis label on its canvas, upwards, centred on the plotting
                // area: cut when it is longer than the canvas is high around that centre.
                "const ctx = document.createElement('canvas').getContext('2d');
                 return U.plots.plots.filter((p) => {
                   const a = p.axes[1]; ctx.font = a.labelFont[0];
                   const half = ctx.measureText(a.label).width / 2, mid = p.bbox.top + p.bbox.height / 2;
                   return mid - half < 0 || mid + half > p.ctx.canvas.height;
                 }).map((p) => p.axes[1].label);",
            )
            .await?;
            assert_eq!(clipped, json!([]), "plot axis labels cut");
            let overlaps = js(
                &c,
                "const out = [];
                 for (const v of [U.side.north, U.side.east]) {
                   const ls = v.labels;
                   for (let i = 0; i < ls.length; i++) for (let j = i + 1; j < ls.length; j++) {
                     const a = ls[i], b = ls[j];
                     if (a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h) out.push(a.text + ' / ' + b.text);
                   }
                 }
                 return out;",
            )
            .await?;
            assert_eq!(overlaps, json!([]), "side-view labels drawn over each other");
            let dir = artifacts();
            std::fs::create_dir_all(&dir)?;
            std::fs::write(dir.join("views-hidpi.png"), c.screenshot().await?)?;
            Ok(())
        },
    )
    .await
}

/// Defect 10: 50 UAVs fly at once from the page on its local server.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fifty_uavs_fly_from_the_page() -> Result<()> {
    with_page(local(TimeScale::Factor(2.0)), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        js(&c, "
            let id = 0;
            for (const x of [-8, -4.5, -1, 2.5, 6]) for (let k = 0; k < 10; k++) { const y = Math.round((-9 + 1.9 * k) * 10) / 10;
              id++;
              U.send({op: 'create', robot: 'stsAirRobot', agent: 'base', start: `${x},${y},-1`, name: ''});
              U.send({op: 'add_mission', uav: id, kind: 'GotoXyz', x: String(x + 1), y: String(y), z: '-2'});
              U.send({op: 'options', uav: id, prefix: 'F' + id, pictures: 'none', autosave: false});
              U.send({op: 'start', uav: id, iterations: '2'});
            }").await?;
        until("50 UAVs done", 240, || async {
            let s = js(&c, "return [...U.uavs.values()].map(u => u.info.status)").await?;
            let s = s.as_array().unwrap();
            Ok(s.len() == 50 && s.iter().all(|v| v != "running" && v != "idle"))
        })
        .await?;
        let s = js(&c, "return [...U.uavs.values()].filter(u => u.info.status !== 'done').map(u => u.info.name + ': ' + u.info.error)").await?;
        assert_eq!(s, json!([]), "UAVs that did not fly");
        Ok(())
    })
    .await
}

/// #23, "send only what is in view": a UAV outside the map's view gets only a light summary
/// (its trail stops growing in the page while it flies), and its detail comes when the map is
/// panned onto it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_uav_out_of_view_gets_its_detail_when_panned_into_view() -> Result<()> {
    with_page(local(TimeScale::Factor(1.0)), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        js(&c, "
            U.send({op: 'create', robot: 'stsAirRobot', agent: 'base', start: '-8,-8,-1', name: 'Here'});
            U.send({op: 'create', robot: 'stsAirRobot', agent: 'base', start: '8,8,-1', name: 'There'});
            for (const [id, x, y] of [[1, -8, 0], [2, 8, 0]]) {
              U.send({op: 'add_mission', uav: id, kind: 'GotoXyz', x: String(x), y: String(y), z: '-1'});
              U.send({op: 'options', uav: id, prefix: 'V' + id, pictures: 'none', autosave: false});
              U.send({op: 'start', uav: id, iterations: '1'});
            }").await?;
        until("both UAVs flying", 30, || async {
            Ok(js(&c, "return [1, 2].every((id) => { const u = U.uavs.get(id); return u && u.trail.length > 3; })").await? == json!(true))
        })
        .await?;
        // Zoom onto the first UAV: the second one is far outside the view.
        js(&c, "U.select(1); Object.assign(U.view, {cx: -8, cy: -6, scale: 200}); window.dispatchEvent(new Event('resize'));").await?;
        tokio::time::sleep(Duration::from_millis(1500)).await;
        let probe = "const u = U.uavs.get(2); return {trail: u.trail.length, summary: u.live.summary === true, velocity: Array.isArray(u.live.velocity), y: u.live.position[1]}";
        let before = js(&c, probe).await?;
        tokio::time::sleep(Duration::from_millis(1500)).await;
        let later = js(&c, probe).await?;
        assert_eq!(later["summary"], true, "a UAV out of view is sent a summary: {later}");
        assert_eq!(later["velocity"], false, "{later}");
        assert_eq!(later["trail"], before["trail"], "its trail was sent while out of view: {before} {later}");
        assert!(later["y"].as_f64() < before["y"].as_f64(), "it flies on (its summary moves): {before} {later}");
        // Pan onto it: its trail (flown while out of view) and its full live state come.
        js(&c, "const p = U.uavs.get(2).live.position; Object.assign(U.view, {cx: p[0], cy: p[1], scale: 60}); window.dispatchEvent(new Event('resize'));").await?;
        until("its detail", 10, || async {
            let now = js(&c, probe).await?;
            Ok(now["velocity"] == json!(true) && now["trail"].as_u64() > later["trail"].as_u64())
        })
        .await?;
        let errors = js(&c, "return window.uccErrors").await?;
        assert_eq!(errors, json!([]));
        Ok(())
    })
    .await
}

/// The page with 1000 UAVs: frame time and memory of the page itself, fed the hub's update
/// format at 20 Hz (every UAV moving, trails growing) for 10 s. A benchmark: runs only with
/// `UCC_GUI_BENCH=1` and prints its figures (BENCHMARKS.md). Writes the screenshots of the
/// docs (docs/img/) when `UCC_GUI_SCREENSHOTS=1`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bench_page_with_1000_uavs() -> Result<()> {
    if std::env::var("UCC_GUI_BENCH").as_deref() != Ok("1") {
        eprintln!("1000-UAV page benchmark skipped: set UCC_GUI_BENCH=1 to run it");
        return Ok(());
    }
    with_page(local(TimeScale::Max), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        let figures = c
            .execute_async(
                "const done = arguments[arguments.length - 1]; const U = window.ucc; const N = 1000;
                 const server = {addr: '127.0.0.1:3000', local: true, time_scale: '1', paused: false, map: 'EmptyRoom'};
                 const first = []; for (let i = 0; i < N; i++) first.push({id: i + 1, info: {name: 'U' + (i + 1), robot: 'stsAirRobot', agent: 'base', start: '0,0,-1', status: 'running', error: null, iteration: 1, iterations: 10000, active: 0, prefix: 'U', pictures: 'none', autosave: false, missions: [{kind: 'GotoXyz', x: 5, y: 0, z: -2, text: 'GotoXyz 5,0,-2'}]}, trail_reset: true, history_reset: true, past_reset: true});
                 U.receive({type: 'state', server, uavs: first, removed: [], log: []});
                 U.select(1);
                 let k = 0; const t0 = performance.now(); const mem0 = performance.memory ? performance.memory.usedJSHeapSize : 0;
                 const timer = setInterval(() => {
                   k++; const uavs = [];
                   for (let i = 0; i < N; i++) {
                     const a = k * 0.02 + i, r = 2 + (i % 7), x = -9 + (i % 40) * 0.45 + Math.cos(a) * 0.3, y = -9 + Math.floor(i / 40) * 0.7 + Math.sin(a) * 0.3;
                     const p = [x, y, -1 - (i % 3) * 0.5];
                     uavs.push({id: i + 1, live: {time: k * 0.05, position: p, attitude: [0.05, -0.05, a], velocity: [0.3, 0.3, 0], battery: {level: 0.9, remaining: 900}},
                                trail: [p], history: [[k * 0.05, -p[2], 0.42, 0.9]]});
                   }
                   U.receive({type: 'state', server, uavs, removed: [], log: []});
                 }, 50);
                 window.uccFrameTimes = []; for (const k in window.uccParts) window.uccParts[k] = 0; const gaps = []; let last = performance.now();
                 function f(t) { gaps.push(t - last); last = t; if (t - t0 < 10000) requestAnimationFrame(f); else {
                   clearInterval(timer);
                   const q = (a, p) => { const s = [...a].sort((x, y) => x - y); return s[Math.min(s.length - 1, Math.floor(p * s.length))]; };
                   const d = window.uccFrameTimes;
                   done({uavs: N, draw_median_ms: q(d, 0.5), draw_p95_ms: q(d, 0.95), frames: d.length,
                         gap_median_ms: q(gaps, 0.5), gap_p95_ms: q(gaps, 0.95), updates: k,
                         heap_mb_start: mem0 / 1e6, heap_mb_end: performance.memory ? performance.memory.usedJSHeapSize / 1e6 : null,
                         trail_points: [...U.uavs.values()].reduce((n, u) => n + u.trail.length, 0), parts_ms: window.uccParts});
                 } }
                 requestAnimationFrame(f);",
                vec![],
            )
            .await?;
        println!("ucc-gui page with 1000 UAVs, 10 s: {figures}");
        if std::env::var("UCC_GUI_SCREENSHOTS").as_deref() == Ok("1") {
            let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs/img");
            std::fs::write(dir.join("ucc-gui-1000-uavs.png"), c.screenshot().await?)?;
        }
        Ok(())
    })
    .await
}

/// #23 end to end: 1000 UAVs really flying on the control center's local server (the map
/// `city`, the spawn grid of `usar-bench --map city --spacing 1.5 --layers 6`), each created,
/// given a mission and started from the page, which then draws them for 10 s with all in
/// the map's view and 10 s zoomed onto one. A benchmark:
/// runs only with `UCC_GUI_BENCH=1` and prints the page's draw time and what the hub sent
/// (BENCHMARKS.md).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bench_page_with_1000_uavs_flying() -> Result<()> {
    if std::env::var("UCC_GUI_BENCH").as_deref() != Ok("1") {
        eprintln!("1000 flying UAVs benchmark skipped: set UCC_GUI_BENCH=1 to run it");
        return Ok(());
    }
    let n: usize = std::env::var("UCC_GUI_BENCH_UAVS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1000);
    let map = usar_server::sim::map::Map::lookup("city")?;
    let start = map.starts().first().context("city has no start")?.location;
    let (spacing, layers) = (1.5, 6);
    let per_layer = n.div_ceil(layers);
    let side = (per_layer as f64).sqrt().ceil() as usize;
    let offset = (side as f64 - 1.0) / 2.0;
    let starts: Vec<String> = (0..n)
        .map(|i| {
            let (layer, k) = (i / per_layer, i % per_layer);
            let x = start[0] + ((k / side) as f64 - offset) * spacing;
            let y = start[1] + ((k % side) as f64 - offset) * spacing;
            let z = start[2] - layer as f64 * spacing;
            format!("{x:.2},{y:.2},{z:.2}")
        })
        .collect();
    let server = ServerChoice::Local(Box::new(ServerConfig {
        map,
        time_scale: TimeScale::Factor(1.0),
        lockstep: true,
        ..ServerConfig::default()
    }));
    with_page(server, (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        // Requests are limited per update period: sent in batches.
        for (b, batch) in starts.chunks(40).enumerate() {
            let mut script = String::from("const U = window.ucc;");
            for (j, s) in batch.iter().enumerate() {
                let id = b * 40 + j + 1;
                let [x, y, z]: [f64; 3] = {
                    let v: Vec<f64> = s.split(',').map(|p| p.parse().unwrap()).collect();
                    [v[0], v[1], v[2]]
                };
                script.push_str(&format!(
                    "U.send({{op: 'create', robot: 'stsAirRobot', agent: 'base', start: '{s}', name: ''}});
                     U.send({{op: 'add_mission', uav: {id}, kind: 'GotoXyz', x: '{:.2}', y: '{y:.2}', z: '{z:.2}'}});
                     U.send({{op: 'add_mission', uav: {id}, kind: 'GotoXyz', x: '{x:.2}', y: '{y:.2}', z: '{z:.2}'}});
                     U.send({{op: 'options', uav: {id}, prefix: 'B{id}', pictures: 'none', autosave: false}});
                     U.send({{op: 'start', uav: {id}, iterations: '100'}});",
                    x + 0.7
                ));
            }
            c.execute(&script, vec![]).await?;
            tokio::time::sleep(Duration::from_millis(120)).await;
        }
        until("every UAV flying", 300, || async {
            let s = js(&c, "return [...U.uavs.values()].filter((u) => u.info.status === 'running' && u.live && u.live.position).length").await?;
            Ok(s.as_u64().unwrap_or(0) as usize >= n)
        })
        .await?;
        js(&c, "U.fit()").await?;
        // 10 s with every UAV in the map's view, then 10 s zoomed onto the selected UAV (the
        // hub then sends the others' summaries only).
        let figures = c
            .execute_async(
                "const done = arguments[arguments.length - 1]; const U = window.ucc;
                 const q = (a, p) => { const s = [...a].sort((x, y) => x - y); return s[Math.min(s.length - 1, Math.floor(p * s.length))]; };
                 const detailed = () => [...U.uavs.values()].filter((u) => u.live && !u.live.summary).length;
                 const measure = (ms) => new Promise((resolve) => {
                   window.uccFrameTimes = []; for (const k in window.uccParts) window.uccParts[k] = 0;
                   const u0 = window.uccUpdates, b0 = window.uccBytes, t0 = performance.now(), gaps = []; let last = t0;
                   function f(t) { gaps.push(t - last); last = t; if (t - t0 < ms) requestAnimationFrame(f); else {
                     const d = window.uccFrameTimes;
                     resolve({draw_median_ms: q(d, 0.5), draw_p95_ms: q(d, 0.95), frames: d.length,
                              gap_median_ms: q(gaps, 0.5), gap_p95_ms: q(gaps, 0.95), updates: window.uccUpdates - u0,
                              kib_received_per_s: (window.uccBytes - b0) / 1024 / (ms / 1000), uavs_in_detail: detailed(),
                              parts_ms: Object.assign({}, window.uccParts)});
                   } }
                   requestAnimationFrame(f);
                 });
                 (async () => {
                   const all = await measure(10000);
                   const p = [...U.uavs.values()].find((u) => u.info.id === 1).live.position;
                   U.select(1); Object.assign(U.view, {cx: p[0], cy: p[1], scale: 200}); window.dispatchEvent(new Event('resize'));
                   await new Promise((r) => setTimeout(r, 2000));
                   const zoomed = await measure(10000);
                   done({uavs: U.uavs.size, flying: [...U.uavs.values()].filter((u) => u.info.status === 'running').length,
                         all_in_view: all, zoomed_on_one: zoomed,
                         heap_mb: performance.memory ? performance.memory.usedJSHeapSize / 1e6 : null});
                 })();",
                vec![],
            )
            .await?;
        println!("ucc-gui page with {n} UAVs flying on the local server: {figures}");
        let dir = artifacts();
        std::fs::create_dir_all(&dir)?;
        std::fs::write(dir.join("ucc-gui-1000-flying.png"), c.screenshot().await?)?;
        Ok(())
    })
    .await
}

/// The screenshots of docs/gui.md (docs/img/): three UAVs flying in the arena, the page at
/// 1400×900 and 1024×700, the 3D view and the plots. Runs only with `UCC_GUI_SCREENSHOTS=1`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn screenshots_for_the_docs() -> Result<()> {
    if std::env::var("UCC_GUI_SCREENSHOTS").as_deref() != Ok("1") {
        eprintln!("screenshots skipped: set UCC_GUI_SCREENSHOTS=1 to write docs/img/");
        return Ok(());
    }
    let arena = ServerChoice::Local(Box::new(ServerConfig {
        map: usar_server::sim::Map::embedded("arena").context("the arena map")?,
        time_scale: TimeScale::Factor(5.0),
        lockstep: true,
        ..ServerConfig::default()
    }));
    with_page(arena, (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        js(&c, "
            const fly = [['Start1', [[-12, 0], [-6, 3], [-2, -4]]], ['Start2', [[12, -6], [6, -7], [3, -2]]], ['Start3', [[10, 7], [4, 7], [0, 5]]]];
            fly.forEach(([tag, pts], i) => {
              U.send({op: 'create', robot: 'stsAirRobot', agent: 'avoid', start: tag, name: ''});
              for (const [x, y] of pts) U.send({op: 'add_mission', uav: i + 1, kind: 'GotoXyz', x: String(x), y: String(y), z: '-1.5'});
              U.send({op: 'options', uav: i + 1, prefix: 'S' + (i + 1), pictures: 'none', autosave: false});
              U.send({op: 'start', uav: i + 1, iterations: '3'});
            });").await?;
        until("a second iteration", 120, || async {
            Ok(js(&c, "return [...U.uavs.values()].every(u => u.info.iteration >= 2)").await?.as_bool() == Some(true))
        })
        .await?;
        tokio::time::sleep(Duration::from_secs(3)).await;
        js(&c, "U.select(1); U.fit(); const v = U.view3d; if (v) { v.orbit.theta = 0.6; v.orbit.phi = 0.75; v.dirty = true; }").await?;
        tokio::time::sleep(Duration::from_millis(700)).await;
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs/img");
        std::fs::create_dir_all(&dir)?;
        std::fs::write(dir.join("ucc-gui-1400x900.png"), c.screenshot().await?)?;
        let view3d = c.find(Locator::Id("view3d-box")).await?;
        std::fs::write(dir.join("ucc-gui-3d.png"), view3d.screenshot().await?)?;
        let side = c.find(Locator::Id("side")).await?;
        std::fs::write(dir.join("ucc-gui-plots.png"), side.screenshot().await?)?;
        c.set_window_size(1024, 700).await?;
        tokio::time::sleep(Duration::from_millis(1000)).await;
        js(&c, "U.fit()").await?;
        tokio::time::sleep(Duration::from_millis(300)).await;
        std::fs::write(dir.join("ucc-gui-1024x700.png"), c.screenshot().await?)?;
        Ok(())
    })
    .await
}

/// Issue 20: the camera panel shows the selected AirRobot's view live, fetched only while
/// the panel is open. Writes `camera-panel.png`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_camera_panel_shows_the_selected_uavs_view_while_open() -> Result<()> {
    with_page(local(TimeScale::Factor(1.0)), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        js(&c, "
            U.send({op: 'create', robot: 'AirRobot', agent: 'base', start: '-3,0,-1.5', name: 'Cam'});
            U.send({op: 'add_mission', uav: 1, kind: 'Hover', seconds: '60'});
            U.send({op: 'start', uav: 1, iterations: '1'});").await?;
        until("the UAV flying", 20, || async {
            Ok(js(&c, "return [...U.uavs.values()].some(u => u.info.status === 'running')").await? == json!(true))
        })
        .await?;
        assert_eq!(js(&c, "return U.camera.n").await?, json!(0), "fetched while closed");
        c.find(Locator::Css("#camera-panel summary")).await?.click().await?;
        until("a camera frame", 30, || async {
            Ok(js(&c, "return document.getElementById('camera').naturalWidth").await? == json!(320))
        })
        .await?;
        // A picture, not a blank: a wall or the sky above, the floor below.
        let colours = c.execute_async("
            const done = arguments[arguments.length - 1];
            fetch('/api/camera/1').then((r) => r.blob()).then(createImageBitmap).then((img) => {
              const cv = document.createElement('canvas'); cv.width = 320; cv.height = 240;
              const g = cv.getContext('2d'); g.drawImage(img, 0, 0);
              done([[...g.getImageData(160, 2, 1, 1).data].slice(0, 3), [...g.getImageData(160, 237, 1, 1).data].slice(0, 3)]);
            });", vec![]).await?;
        assert_ne!(colours[1], colours[0], "one colour: {colours}");
        assert!(colours.as_array().unwrap().iter().all(|c| c != &json!([0, 0, 0])), "{colours}");
        let n = js(&c, "return U.camera.n").await?.as_u64().unwrap();
        until("more frames", 10, || async {
            Ok(js(&c, "return U.camera.n").await?.as_u64().unwrap() > n + 2)
        })
        .await?;
        let dir = artifacts();
        std::fs::create_dir_all(&dir)?;
        std::fs::write(dir.join("camera-panel.png"), c.screenshot().await?)?;
        // The defect: the 3D view failed to draw while no UAV existed yet ("drawing failed:
        // Cannot set properties of null"), and the page showed it.
        let shown = js(&c, "const e = document.getElementById('error'); return e.hidden ? '' : e.textContent").await?;
        assert_eq!(shown, json!(""), "the page shows an error");
        // Closed: no more requests.
        c.find(Locator::Css("#camera-panel summary")).await?.click().await?;
        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
        let closed = js(&c, "return U.camera.n").await?;
        tokio::time::sleep(std::time::Duration::from_millis(700)).await;
        assert_eq!(js(&c, "return U.camera.n").await?, closed, "fetched while closed");
        assert_eq!(js(&c, "return window.uccErrors").await?, json!([]));
        js(&c, "U.send({op: 'stop', uav: 1})").await?;
        Ok(())
    })
    .await
}

/// The coverage shown in the scenario panel, percent (`None`: not shown yet).
async fn shown_coverage(c: &Client) -> Result<Option<f64>> {
    let v = js(
        c,
        "const td = document.querySelector('#scenario-metrics tr[data-metric=coverage_pct] td');\
         return td ? td.textContent : null;",
    )
    .await?;
    Ok(v.as_str()
        .and_then(|t| t.trim_end_matches(" %").parse::<f64>().ok()))
}

/// Issue 22: a scenario is picked from the list and started in one action; its UAVs fly on
/// the map with their names, the heat map grows, the metrics panel updates, a second start
/// is refused on the page, Stop ends it. Writes `scenario.png` (and, with
/// `UCC_GUI_SCREENSHOTS=1`, docs/img/ucc-gui-scenario.png).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scenario_runs_from_the_list_with_live_metrics() -> Result<()> {
    with_page(local(TimeScale::Factor(1.0)), (1400, 900), 1.0, |c, url, _| async move {
        open(&c, &url).await?;
        until("the scenario list", 10, || async {
            Ok(count(&c, "[data-testid=scenario-name] option").await? >= 7)
        })
        .await?;
        by_id(&c, "scenario-name").await?.select_by_value("search-team").await?;
        assert!(
            c.find(Locator::Id("scenario-about")).await?.text().await?.contains("three UAVs"),
            "the description of the chosen scenario"
        );
        by_id(&c, "scenario-speed").await?.select_by_value("10").await?;
        // Absurd numbers get the reason, and nothing is created.
        for (field, value, says) in [
            ("scenario-iterations", "0", "scenario iterations: \"0\" is not a whole number from 1 to 1000"),
            ("scenario-iterations", "1e9", "scenario iterations: \"1e9\""),
            ("scenario-seed", "-4", "scenario seed: \"-4\" is not a whole number"),
        ] {
            type_into(&c, field, value).await?;
            by_id(&c, "scenario-start").await?.click().await?;
            until("the message", 10, || async { Ok(text(&c, "error").await?.contains(says)) }).await?;
            by_id(&c, field).await?.clear().await?;
        }
        assert_eq!(count(&c, "#uav-list li").await?, 0);
        type_into(&c, "scenario-seed", "3").await?;
        by_id(&c, "scenario-start").await?.click().await?;
        // Its three UAVs, named, in the list and on the map.
        until("the scenario's UAVs", 20, || async {
            Ok(count(&c, "#uav-list li").await? == 3)
        })
        .await?;
        let names = js(&c, "return [...U.uavs.values()].map((u) => u.info.name + ' ' + u.info.agent)").await?;
        assert_eq!(names, json!(["UAV1 partition-search", "UAV2 partition-search", "UAV3 partition-search"]));
        until("the UAVs flying over the block", 60, || async {
            Ok(js(&c, "return [...U.uavs.values()].every((u) => u.live && u.live.position && -u.live.position[2] > 10 && u.trail.length > 3)").await? == json!(true))
        })
        .await?;
        // The metrics panel updates live: coverage rises above 0, then further.
        until("coverage above 0", 60, || async { Ok(shown_coverage(&c).await?.is_some_and(|v| v > 0.0)) }).await?;
        let first = shown_coverage(&c).await?.unwrap_or(0.0);
        until("coverage rising", 60, || async { Ok(shown_coverage(&c).await?.is_some_and(|v| v > first + 2.0)) }).await?;
        let status = text(&c, "scenario-status").await?;
        assert!(status.starts_with("running · iteration 1/1 · seed 3"), "{status}");
        assert!(count(&c, "#scenario-metrics tr[data-metric=victims_total]").await? == 1);
        // The heat map is drawn under the UAVs: seen cells greenish, unseen pale red.
        let colours = js(&c, "
            const s = U.scenario.state, g = s.fixed.grid, [nx, ny] = g.shape, ctx = document.getElementById('map').getContext('2d');
            U.drawMap();
            const out = {seen: 0, seenGreen: 0, unseen: 0, unseenRed: 0};
            for (let k = 0; k < s.levels.length; k += 23) {
              const i = Math.floor(k / ny), j = k % ny;
              const [sx, sy] = U.toScreen(g.origin[0] + (i + 0.5) * g.cell, g.origin[1] + (j + 0.5) * g.cell);
              const [r, gr] = ctx.getImageData(Math.round(sx), Math.round(sy), 1, 1).data;
              if (s.levels[k] > 0) { out.seen++; if (gr > r) out.seenGreen++; } else { out.unseen++; if (r > gr) out.unseenRed++; }
            }
            return out;").await?;
        let n = |k: &str| colours[k].as_f64().unwrap_or(0.0);
        assert!(n("seen") > 5.0 && n("seenGreen") >= 0.7 * n("seen"), "{colours}");
        assert!(n("unseen") > 5.0 && n("unseenRed") >= 0.7 * n("unseen"), "{colours}");
        tokio::time::sleep(Duration::from_secs(3)).await;
        let dir = artifacts();
        std::fs::create_dir_all(&dir)?;
        let shot = c.screenshot().await?;
        std::fs::write(dir.join("scenario.png"), &shot)?;
        if std::env::var("UCC_GUI_SCREENSHOTS").as_deref() == Ok("1") {
            let docs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs/img");
            std::fs::write(docs.join("ucc-gui-scenario.png"), &shot)?;
        }
        // A second start is refused with the reason (the page's button is disabled while
        // it runs; the request is sent as another page would).
        assert!(!by_id(&c, "scenario-start").await?.is_enabled().await?);
        js(&c, "U.send({op: 'scenario_start', name: 'relay'})").await?;
        until("the refusal", 10, || async {
            Ok(text(&c, "error").await?.contains("scenario search-team is running"))
        })
        .await?;
        by_id(&c, "scenario-stop").await?.click().await?;
        until("the scenario stopped", 20, || async {
            Ok(text(&c, "scenario-status").await?.starts_with("stopped"))
        })
        .await?;
        assert_eq!(js(&c, "return window.uccErrors").await?, json!([]));
        Ok(())
    })
    .await
}

/// Issue 22: every embedded scenario on the page, mid-run at ×10 (the relay's link strip,
/// the fire, the target, the pads): `scenario-NAME.png` in the artifacts. Runs only with
/// `UCC_GUI_SCREENSHOTS=1`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn screenshots_of_every_scenario_kind() -> Result<()> {
    if std::env::var("UCC_GUI_SCREENSHOTS").as_deref() != Ok("1") {
        eprintln!("screenshots skipped: set UCC_GUI_SCREENSHOTS=1");
        return Ok(());
    }
    with_page(
        local(TimeScale::Max),
        (1400, 900),
        1.0,
        |c, url, _| async move {
            open(&c, &url).await?;
            for (name, seconds) in [
                ("relay", 8),
                ("perimeter", 6),
                ("tracking", 4),
                ("delivery", 6),
                ("search", 3),
            ] {
                js(
                    &c,
                    &format!("U.send({{op: 'scenario_start', name: '{name}', speed: '10'}})"),
                )
                .await?;
                tokio::time::sleep(Duration::from_secs(seconds)).await;
                js(&c, "U.fit()").await?;
                tokio::time::sleep(Duration::from_millis(300)).await;
                let dir = artifacts();
                std::fs::create_dir_all(&dir)?;
                std::fs::write(
                    dir.join(format!("scenario-{name}.png")),
                    c.screenshot().await?,
                )?;
                js(&c, "U.send({op: 'scenario_stop'})").await?;
                until("the scenario stopped", 20, || async {
                    Ok(text(&c, "scenario-status").await?.starts_with("stopped"))
                })
                .await?;
            }
            assert_eq!(js(&c, "return window.uccErrors").await?, json!([]));
            Ok(())
        },
    )
    .await
}
