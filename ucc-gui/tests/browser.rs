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
                     "--disable-dev-shm-usage", "--window-size=1400,1000",
                     format!("--user-data-dir={}", profile.display())]

        }
    });
    let mut builder = ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new());
    builder.capabilities(caps.as_object().unwrap().clone());
    let client = builder
        .connect(&format!("http://127.0.0.1:{port}"))
        .await
        .context("cannot open a chromium session")?;
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
    let (url, gui, log_dir) = start_gui(TimeScale::Factor(5.0)).await?;
    let mut session = start_browser(&chromium, &chromedriver).await?;
    let result = scenario(&session.client, &url).await;
    let _ = session.client.clone().close().await;
    let _ = session.driver.kill().await;
    gui.cancel();
    let _ = std::fs::remove_dir_all(&log_dir);
    result
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
            "const [sx, sy] = toScreen(arguments[0], arguments[1]); const k = map.clientWidth / map.width;\
             return [(sx - map.width / 2) * k, (sy - map.height / 2) * k];",
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
                c.execute("return [view.cx, view.cy, view.scale]", vec![])
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
        "map.dispatchEvent(new WheelEvent('wheel', {deltaY: -100, clientX: 100, clientY: 100, bubbles: true, cancelable: true}))",
        vec![],
    )
    .await?;
    let zoomed = view(c).await?;
    assert!(
        zoomed[2].as_f64() > panned[2].as_f64(),
        "{panned} -> {zoomed}"
    );
    c.execute("fit()", vec![]).await?;
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
    until("the position to change", 60, || async {
        Ok(text(c, "uav-position").await? != first)
    })
    .await?;
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
    type_into(c, "iterations", "5").await?;
    by_id(c, "start").await?.click().await?;
    until("the second run to fly", 30, || async {
        Ok(status(c).await? == "running" && text(c, "iteration-counter").await? == "1")
    })
    .await?;
    by_id(c, "stop").await?.click().await?;
    until("the run to stop", 30, || async {
        Ok(status(c).await? == "stopped")
    })
    .await?;
    assert_eq!(text(c, "iteration-counter").await?, "1");
    assert!(text(c, "log").await?.contains("interrupted"));
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
           send({op: 'create', robot: 'stsAirRobot', agent: 'base', start: `${x},${y},-1`, name: ''});
           for (const [dx, dy] of [[0, 0], [1.5, 0], [1.5, 1], [0, 1]])
             send({op: 'add_mission', uav: id, kind: 'GotoXyz', x: String(x + dx), y: String(y + dy), z: '-2'});
           send({op: 'options', uav: id, prefix: 'B' + id, pictures: 'none', autosave: false});
           send({op: 'start', uav: id, iterations: '1000'});
         }",
        vec![],
    )
    .await?;
    until("50 UAVs flying", 120, || async {
        let n = c
            .execute("return [...uavs.values()].filter(u => u.info.live && u.info.status === 'running').length", vec![])
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
                     trail_points: [...uavs.values()].reduce((n, u) => n + u.trail.length + u.past.flat().length, 0)});
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
