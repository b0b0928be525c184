//! `usar-bench`: the scale benchmark. Starts a usar-server (or targets one), connects N
//! clients that each fly an stsAirRobot and send a DRIVE every 0.1 s of simulated time, and
//! prints what was delivered, how fast, and at what cost.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use clap::Parser;
use serde::Serialize;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;

/// Scale benchmark for usar-server: N UAVs (stsAirRobot by default), each on its own TCP
/// connection.
#[derive(Debug, Clone, Parser)]
#[command(version, about)]
struct Args {
    /// Number of UAVs (one connection each).
    #[arg(long, default_value_t = 10, value_parser = at_least_one)]
    uavs: usize,
    /// Simulated seconds to fly (measured on each robot's STA time stamps).
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// Map for the started server (embedded name or file).
    #[arg(long)]
    map: Option<String>,
    /// Target a running server instead of starting one.
    #[arg(long)]
    host: Option<String>,
    /// Port of the running server (with --host).
    #[arg(long, default_value_t = 3000)]
    port: u16,
    /// --time-scale of the started server (a number or `max`).
    #[arg(long, default_value = "1")]
    time_scale: String,
    /// The usar-server program to start (default: next to this program).
    #[arg(long)]
    server_bin: Option<PathBuf>,
    /// Distance between neighbouring UAVs on the spawn grid, metres: at least 1.3, since
    /// each UAV is 0.9 m across and flies 0.2 m back and forth while the others spawn.
    #[arg(long, default_value_t = 1.5, value_parser = spacing)]
    spacing: f64,
    /// Horizontal layers of the spawn grid, each `--spacing` above the one below (the first
    /// at the map's first start): for more UAVs than fit on one floor. Default: the fewest
    /// layers in which every UAV fits on the map (checked before anything starts).
    #[arg(long, value_parser = at_least_one)]
    layers: Option<usize>,
    /// Print one JSON object per run instead of the table.
    #[arg(long)]
    json: bool,
    /// Step the simulation directly, without sockets (the cost of the world alone).
    #[arg(long)]
    sim_only: bool,
    /// Threads that read sensors, in the started server or with --sim-only (default: the
    /// machine's cores).
    #[arg(long, value_parser = at_least_one)]
    threads: Option<usize>,
    /// With --sim-only: cast every ray on its own and shape-cast every move (the slow
    /// reference the fast paths must equal; see --digest).
    #[arg(long)]
    reference: bool,
    /// With --sim-only: print a digest (FNV-1a, 64 bit) of every line the world printed, to
    /// compare runs at different --threads or with --reference.
    #[arg(long)]
    digest: bool,
    /// With --sim-only: write every tick's wall time, the stepping thread's CPU time (both
    /// µs) and bytes printed to this CSV file (`tick,wall_us,cpu_us,bytes`), to see where the
    /// tail comes from.
    #[arg(long, value_name = "FILE")]
    tick_log: Option<std::path::PathBuf>,
    /// With --sim-only: the scaling curve. Runs the world alone at each of these robot
    /// counts (comma-separated; `--uavs` is ignored), three times each, prints min/median/max
    /// of the cost per tick and draws it into --plot.
    #[arg(long, value_delimiter = ',', value_parser = at_least_one)]
    scaling: Vec<usize>,
    /// Runs per robot count of --scaling.
    #[arg(long, default_value_t = 3, value_parser = at_least_one)]
    runs: usize,
    /// The PNG file --scaling draws its curve into.
    #[arg(long, default_value = "scaling.png")]
    plot: PathBuf,
    /// Find the largest N that holds real time (real-time factor ≥ 0.98, every message
    /// delivered), doubling from --uavs and then bisecting.
    #[arg(long)]
    sweep: bool,
    /// With --sim-only: the per-robot cost of each stsQuadrotor model part. Runs --uavs
    /// stsQuadrotors with every part on, then with each of energy, sensor noise, ground
    /// effect and drag off, and with faults (a noisy IMU and a weak motor per robot) on,
    /// and prints µs per robot per tick for each.
    #[arg(long, requires = "sim_only")]
    parts: bool,
    /// Robot class to fly: `stsAirRobot` (kinematic) or `stsQuadrotor` (rigid-body
    /// quadrotor with the same parts plus a Crash touch sensor), or `Package.Class`.
    #[arg(long, default_value = "stsAirRobot")]
    robot: String,
    /// Run the headline benchmarks (each three times; the other options are ignored but
    /// --server-bin), print min/median/max of every figure with the machine and its load
    /// average, and write them as JSON to --out.
    #[arg(long)]
    suite: bool,
    /// With --suite: small sizes (under a minute in a debug build), for CI.
    #[arg(long, requires = "suite")]
    quick: bool,
    /// With --suite: the JSON file to write.
    #[arg(long, default_value = "usar-bench-suite.json", requires = "suite")]
    out: PathBuf,
    /// With --suite: an earlier suite's JSON file; every figure worse than there by more
    /// than its margin (25 % for wall-clock figures, 1 % for allocations) is flagged with a
    /// `SLOWER` line, when both are of the same machine, build and size. Never an error.
    #[arg(long, requires = "suite")]
    compare: Option<PathBuf>,
    /// Camera speed instead: the CPU renderer's frames per second on one core (64x64,
    /// 160x120, 320x240 on empty_room and city) and rays per second, then the image
    /// server's delivered frames per second to 1, 4 and 16 clients (a started server, one
    /// AirRobot, `--time-scale max`). Each figure is measured for --seconds / 10 wall
    /// seconds (at least 0.5).
    #[arg(long)]
    camera: bool,
    /// Scenario speed instead (docs/scenarios.md): each embedded scenario (or the ones
    /// named, comma separated) flown three times in-process with every UAV's agent, pictures
    /// off; prints simulated seconds per wall second and wall seconds per iteration,
    /// min / median / max.
    #[arg(long, value_name = "NAMES", num_args = 0..=1, default_missing_value = "all")]
    scenarios: Option<String>,
    /// With --camera: only the fleet figure: this many stsAirRobots (every sensor on), each
    /// with a 64x64 camera rendered at 10 Hz, in one world on --threads threads (default
    /// 2) for --seconds simulated seconds; prints the real-time factor (issue 20's goal:
    /// 100 UAVs at real time on 2 cores).
    #[arg(long, value_name = "N", requires = "camera", value_parser = at_least_one)]
    camera_fleet: Option<usize>,
    /// Flight figures instead (docs/quadrotor.md, issue #54): the `base` agent flies a 1 m
    /// step, a 60 s hover and a 2 m square with stsAirRobot and stsQuadrotor against an
    /// in-process lockstep server; prints overshoot, settling time, hold error and the
    /// square's error against their targets. Exit status 1 when one misses its target.
    #[arg(long)]
    flight: bool,
}

impl Args {
    /// The INIT class name.
    fn class(&self) -> String {
        usar_proto::Init::qualified_class(&self.robot)
    }

    /// The parts whose rates are checked: the stsAirRobot's, plus the quadrotor's Crash.
    fn nominal(&self) -> Vec<(&'static str, f64)> {
        let mut parts = NOMINAL.to_vec();
        if self.class().eq_ignore_ascii_case("USARBot.stsQuadrotor") {
            parts.push(("Crash", 10.0));
        }
        parts
    }
}

/// A spawn grid spacing that leaves room for the benchmark's own motion.
fn spacing(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 1.3 => Ok(v),
        _ => Err(format!(
            "expected at least 1.3 (metres), not {text:?}: closer UAVs bump into each other"
        )),
    }
}

/// A count of at least 1.
fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!(
            "expected a whole number of at least 1, not {text:?}"
        )),
    }
}

/// Nominal rates of the stsAirRobot's parts (Hz), protocol.md §9.
const NOMINAL: &[(&str, f64)] = &[
    ("STA", 10.0),
    ("Position", 10.0),
    ("Velocity", 10.0),
    ("IMU", 10.0),
    ("Sonar0", 5.0),
    ("Sonar1", 5.0),
    ("Sonar2", 5.0),
    ("Sonar3", 5.0),
    ("Sonar4", 5.0),
    ("Sonar5", 5.0),
    ("Sonar6", 5.0),
    ("Sonar7", 5.0),
    ("SonarTop", 5.0),
    ("SonarBottom", 5.0),
    ("Scanner", 1.0 / 0.3),
];

/// What one run measured.
#[derive(Debug, Serialize)]
struct Report {
    uavs: usize,
    simulated_seconds: f64,
    wall_seconds: f64,
    real_time_factor: f64,
    messages_per_second: f64,
    bytes_per_second: f64,
    /// Delivered rate per part and robot, as a fraction of the nominal rate.
    delivered: BTreeMap<String, f64>,
    latency_ms_p50: Option<f64>,
    latency_ms_p90: Option<f64>,
    latency_ms_p99: Option<f64>,
    server_cpu_seconds: Option<f64>,
    server_peak_rss_mib: Option<f64>,
}

impl Report {
    fn holds_real_time(&self) -> bool {
        self.real_time_factor >= 0.98 && self.delivered.values().all(|&d| d >= 0.97)
    }
}

/// What one client saw.
#[derive(Debug, Default)]
struct ClientStats {
    counts: BTreeMap<String, u64>,
    messages: u64,
    bytes: u64,
    span: f64,
    latencies: Vec<Duration>,
    /// Wall instant and simulated time of the first and of the last STA counted.
    first: Option<(Instant, f64)>,
    last: Option<(Instant, f64)>,
}

/// `println!` that ignores a closed stdout (`usar-bench ... | head` must not panic; the run
/// still ends normally, stopping the server it started).
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

mod suite;

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    // A user's mistake (a map that does not exist, a host that does not answer) is one
    // line naming it, never a stack backtrace.
    match bench(&args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("usar-bench: error: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn bench(args: &Args) -> anyhow::Result<()> {
    let args = args.clone();
    if args.suite {
        return suite::suite(&args);
    }
    if args.camera {
        return camera(&args);
    }
    if args.flight {
        return flight();
    }
    if let Some(names) = &args.scenarios {
        return scenarios(names, args.threads.unwrap_or(1));
    }
    if args.sim_only && !args.scaling.is_empty() {
        return scaling(&args);
    }
    if args.sim_only && args.parts {
        return parts(&args);
    }
    if args.sim_only {
        return sim_only(&args).map(|_| ());
    }
    let runtime = tokio::runtime::Runtime::new()?;
    if !args.sweep {
        let report = runtime.block_on(run_once(&args, args.uavs))?;
        print(&args, &report);
        return Ok(());
    }
    let (mut good, mut bad) = (0, None);
    let mut n = args.uavs.max(1);
    while bad.is_none() || bad.is_some_and(|b: usize| b - good > (good / 10).max(1)) {
        let report = runtime.block_on(run_once(&args, n))?;
        print(&args, &report);
        if report.holds_real_time() {
            good = n;
        } else {
            bad = Some(n);
        }
        n = match bad {
            None => n * 2,
            Some(b) => (good + b) / 2,
        };
        if n == good || Some(n) == bad {
            break;
        }
    }
    say!("largest N holding real time: {good}");
    Ok(())
}

/// `--flight`: the figures of both robots and their targets.
fn flight() -> anyhow::Result<()> {
    let runtime = tokio::runtime::Runtime::new()?;
    let robots = ["stsAirRobot", "stsQuadrotor"];
    let figures = runtime
        .block_on(ucc_client::figures::measure_local(&robots))
        .map_err(anyhow::Error::msg)?;
    let t = ucc_client::figures::TARGETS;
    say!(
        "targets: overshoot <= {} m of the 1 m step, settled within 0.1 m in <= {} s, hover within {} m and {} rad, square within {} m",
        t.overshoot,
        t.settling,
        t.hold,
        t.hold_yaw,
        t.square
    );
    let mut missed = Vec::new();
    for f in &figures {
        say!("{f}");
        missed.extend(f.misses().into_iter().map(|m| format!("{}: {m}", f.robot)));
    }
    anyhow::ensure!(missed.is_empty(), "missed: {}", missed.join("; "));
    Ok(())
}

fn print(args: &Args, r: &Report) {
    if args.json {
        say!("{}", serde_json::to_string(r).unwrap_or_default());
        return;
    }
    let ms = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.1}"));
    say!(
        "{:>6} {:>8} {:>8} {:>6} {:>10} {:>10} {:>24} {:>8} {:>8}",
        "N",
        "sim s",
        "wall s",
        "RTF",
        "msg/s",
        "MB/s",
        "DRIVE latency p50/90/99",
        "CPU s",
        "peak MiB"
    );
    say!(
        "{:>6} {:>8.1} {:>8.2} {:>6.2} {:>10.0} {:>10.2} {:>24} {:>8} {:>8}",
        r.uavs,
        r.simulated_seconds,
        r.wall_seconds,
        r.real_time_factor,
        r.messages_per_second,
        r.bytes_per_second / 1e6,
        format!(
            "{}/{}/{} ms",
            ms(r.latency_ms_p50),
            ms(r.latency_ms_p90),
            ms(r.latency_ms_p99)
        ),
        r.server_cpu_seconds
            .map_or("-".into(), |v| format!("{v:.1}")),
        r.server_peak_rss_mib
            .map_or("-".into(), |v| format!("{v:.0}")),
    );
    let rates: Vec<String> = r
        .delivered
        .iter()
        .map(|(k, v)| format!("{k} {:.0}%", v * 100.0))
        .collect();
    say!("  delivered vs nominal: {}", rates.join(", "));
}

/// What one --sim-only run cost, µs of wall clock per tick.
#[derive(Debug, Clone, Copy)]
struct SimCost {
    /// Wall time of a tick: moving the robots, reading their sensors and printing the
    /// lines (as the server does it), µs; the mean over the run.
    tick: f64,
    /// CPU time of the whole process (all threads), µs per tick (10 ms resolution).
    cpu: f64,
    /// The ticks' wall times, µs: median, 99th and 99.9th percentiles, longest.
    p50: f64,
    p99: f64,
    p999: f64,
    max: f64,
    /// Simulated seconds per second of ticks.
    rtf: f64,
    /// Allocations (and reallocations) per tick, counted by the allocator: the same in
    /// every run of the same world, whatever the machine's load.
    allocations: f64,
    /// The stepping thread's CPU time per tick, µs: median, 99.9th percentile, longest.
    /// Unlike the wall time it does not grow while the thread waits for a core (a loaded
    /// machine); with one sensor thread it is the whole tick's work.
    cpu_p50: f64,
    cpu_p999: f64,
    cpu_max: f64,
    /// Bytes printed per tick: median and most (the same in every run).
    bytes_p50: f64,
    bytes_max: f64,
    /// Bytes allocated per idle robot (spawned, before the first tick), KiB.
    memory: f64,
}

/// CPU time of the calling thread.
fn thread_cpu() -> Duration {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::ThreadCPUTime);
    Duration::new(
        t.tv_sec.max(0) as u64,
        t.tv_nsec.clamp(0, 999_999_999) as u32,
    )
}

/// The value at fraction `p` (0 to 1) of `sorted` (ascending, not empty): the nearest rank.
fn quantile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// The scaling curve (--sim-only --scaling): each count --runs times, a table of
/// min/median/max, and the PNG plot.
fn scaling(args: &Args) -> anyhow::Result<()> {
    let mut rows = Vec::new();
    for &n in &args.scaling {
        let mut costs = Vec::new();
        for _ in 0..args.runs {
            let run = Args {
                uavs: n,
                layers: None,
                ..args.clone()
            };
            costs.push(sim_only(&run)?);
        }
        rows.push((n, costs));
    }
    say!(
        "{:>6} {:>26} {:>26} {:>14}",
        "N",
        "tick µs (wall) min/med/max",
        "CPU µs/tick min/med/max",
        "RTF (median)"
    );
    let mut curve = Vec::new();
    for (n, costs) in &rows {
        let stat = |f: fn(&SimCost) -> f64| {
            let mut v: Vec<f64> = costs.iter().map(f).collect();
            v.sort_by(f64::total_cmp);
            (v[0], v[v.len() / 2], v[v.len() - 1])
        };
        let tick = stat(|c| c.tick);
        let cpu = stat(|c| c.cpu);
        say!(
            "{n:>6} {:>26} {:>26} {:>14.2}",
            format!("{:.0}/{:.0}/{:.0}", tick.0, tick.1, tick.2),
            format!("{:.0}/{:.0}/{:.0}", cpu.0, cpu.1, cpu.2),
            5000.0 / tick.1
        );
        curve.push((*n, tick, cpu));
    }
    plot_scaling(&args.plot, &curve)?;
    say!("plot: {}", args.plot.display());
    Ok(())
}

/// The font of the plot's text (the one ucc-client draws with).
const FONT: &[u8] = include_bytes!("../../ucc-client/assets/DejaVuSans.ttf");

type Stat = (f64, f64, f64);

/// Draws µs per tick against robots (log-log): wall and CPU time of a tick (medians with
/// min–max bars), and the real-time budget of a 5 ms tick.
fn plot_scaling(path: &std::path::Path, curve: &[(usize, Stat, Stat)]) -> anyhow::Result<()> {
    use plotters::prelude::*;
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| anyhow::anyhow!("the embedded font is invalid"))?;
    let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
        let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let n_max = curve.iter().map(|c| c.0).max().unwrap_or(10) as f64 * 1.3;
        let n_min = curve.iter().map(|c| c.0).min().unwrap_or(1) as f64 / 1.3;
        let y_max = curve
            .iter()
            .map(|c| c.1.2.max(c.2.2))
            .fold(6000.0, f64::max)
            * 1.5;
        let y_min = curve
            .iter()
            .map(|c| c.1.0)
            .fold(f64::MAX, f64::min)
            .max(1.0)
            / 1.5;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "usar-bench --sim-only: the world alone, stsAirRobots (city)",
                ("sans-serif", 22),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d((n_min..n_max).log_scale(), (y_min..y_max).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("robots")
            .y_desc("µs per 5 ms tick")
            .label_style(("sans-serif", 15))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .light_line_style(WHITE)
            .draw()?;
        chart
            .draw_series(LineSeries::new(
                [(n_min, 5000.0), (n_max, 5000.0)],
                RED.stroke_width(2),
            ))?
            .label("real time (5000 µs per tick)")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED.stroke_width(2)));
        for (index, name, colour) in [
            (1usize, "wall: a tick (fly, sensors, printing)", BLACK),
            (2, "CPU, all threads", GREEN),
        ] {
            let pick = move |c: &(usize, Stat, Stat)| if index == 1 { c.1 } else { c.2 };
            chart
                .draw_series(LineSeries::new(
                    curve.iter().map(|c| (c.0 as f64, pick(c).1)),
                    colour.stroke_width(2),
                ))?
                .label(format!("{name}, median of 3"))
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2))
                });
            chart.draw_series(curve.iter().map(|c| {
                let (lo, mid, hi) = pick(c);
                ErrorBar::new_vertical(c.0 as f64, lo, mid, hi, colour.filled(), 8)
            }))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font(("sans-serif", 15))
            .position(SeriesLabelPosition::UpperLeft)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("cannot draw {}: {e}", path.display()))
}

/// The per-robot cost of each stsQuadrotor model part (`--sim-only --parts`).
fn parts(args: &Args) -> anyhow::Result<()> {
    use usar_sim::faults::FaultPlan;
    use usar_sim::robots::RobotCatalog;
    let mut args = args.clone();
    args.robot = "stsQuadrotor".into();
    let class = args.class();
    let variant = |change: &dyn Fn(&mut usar_sim::RobotClass)| {
        let mut catalog = RobotCatalog::embedded();
        if let Some(c) = catalog.get_mut(&class) {
            change(c);
        }
        catalog
    };
    let faults = {
        let mut text = String::new();
        for robot in 1..=args.uavs {
            for line in [
                "FAULT {Sensor IMU} {Mode Noise} {Std 0.01}",
                "FAULT {Motor 2} {Thrust 0.95}",
            ] {
                text.push_str(&format!(
                    "[[fault]]\ntime = 0.0\nrobot = {robot}\nline = \"{line}\"\n"
                ));
            }
        }
        FaultPlan::from_toml(&text).map_err(anyhow::Error::msg)?
    };
    let runs: Vec<(&str, RobotCatalog, FaultPlan)> = vec![
        ("all parts on", variant(&|_| {}), FaultPlan::default()),
        (
            "energy off",
            variant(&|c| c.battery = None),
            FaultPlan::default(),
        ),
        (
            "sensor noise off",
            variant(&|c| {
                for p in &mut c.parts {
                    p.noise = 0.0;
                    if p.kind == "IMU" {
                        p.settings = Default::default();
                    }
                }
            }),
            FaultPlan::default(),
        ),
        (
            "ground effect off",
            variant(&|c| c.quadrotor.ground_effect = false),
            FaultPlan::default(),
        ),
        (
            "drag off",
            variant(&|c| {
                c.quadrotor.drag_linear = 0.0;
                c.quadrotor.drag_quadratic = 0.0;
            }),
            FaultPlan::default(),
        ),
        ("faults on", variant(&|_| {}), faults),
    ];
    let mut table = Vec::new();
    for (name, catalog, faults) in runs {
        say!("--- {name}");
        let cost = sim_only_in(&args, catalog, faults)?;
        table.push((name, cost.tick / args.uavs as f64, cost.rtf));
    }
    let base = table[0].1;
    say!(
        "per-robot cost of each stsQuadrotor part, {} robots, {} s simulated, {} thread(s):",
        args.uavs,
        args.seconds,
        args.threads.unwrap_or_else(usar_sim::default_threads)
    );
    say!(
        "{:>20} {:>14} {:>12} {:>8}",
        "run",
        "µs/robot/tick",
        "vs all on",
        "RTF"
    );
    for (name, per, rtf) in &table {
        say!(
            "{name:>20} {per:>14.2} {:>+11.1}% {rtf:>8.2}",
            (per / base - 1.0) * 100.0
        );
    }
    Ok(())
}

/// Steps a world with `--uavs` robots for `--seconds` and prints the cost per tick.
fn sim_only(args: &Args) -> anyhow::Result<SimCost> {
    sim_only_in(
        args,
        usar_sim::robots::RobotCatalog::embedded(),
        usar_sim::faults::FaultPlan::default(),
    )
}

/// [`sim_only`] with a catalog and faults.
fn sim_only_in(
    args: &Args,
    catalog: usar_sim::robots::RobotCatalog,
    faults: usar_sim::faults::FaultPlan,
) -> anyhow::Result<SimCost> {
    use usar_proto::{Command, Drive, Init, Vec3};
    let mut args = args.clone();
    plan_layout(&mut args)?;
    let args = &args;
    use usar_sim::{SimConfig, World, map::Map};
    let map = match &args.map {
        None => Map::default_map(),
        Some(name) => Map::lookup(name)?,
    };
    let start = map.starts().first().context("no start pose")?.location;
    let config = SimConfig {
        threads: args.threads.unwrap_or_else(usar_sim::default_threads),
        faults,
        ..SimConfig::default()
    };
    let mut world = World::new(map, catalog, config);
    world.set_shortcuts(!args.reference);
    let live_before = live_bytes();
    let mut clients = Vec::new();
    for i in 0..args.uavs {
        let c = world.connect();
        let [x, y, z] = spawn_point(args, start, i);
        world.command(
            c,
            Command::Init(Init {
                class_name: args.class(),
                location: Some(Vec3::new(x, y, z)),
                ..Init::default()
            }),
        );
        clients.push(c);
    }
    // Memory the robots hold in the world, idle (spawned, not yet stepped).
    let per_robot = live_bytes().saturating_sub(live_before) as f64 / 1024.0 / args.uavs as f64;
    let ticks = ((args.seconds / world.dt()).round() as u64).max(1);
    let mut out = usar_sim::Printed::default();
    let (mut messages, mut bytes) = (0u64, 0u64);
    let mut digest: u64 = 0xcbf2_9ce4_8422_2325;
    let cpu_before = process_usage(std::process::id()).0.unwrap_or(0.0);
    let began = Instant::now();
    let mut step_time = Duration::ZERO;
    let mut tick_times = Vec::with_capacity(ticks as usize);
    let mut tick_cpu = Vec::with_capacity(ticks as usize);
    let mut tick_bytes = Vec::with_capacity(ticks as usize);
    let mut allocations = 0;
    for tick in 0..ticks {
        if tick % 20 == 0 {
            let v = if (tick / 200) % 2 == 0 { 0.2 } else { -0.2 };
            for &c in &clients {
                world.command(
                    c,
                    Command::Drive(Drive {
                        linear_velocity: Some(v),
                        ..Drive::default()
                    }),
                );
            }
        }
        let counted = ALLOCATOR.stats();
        let (t, cpu_at) = (Instant::now(), thread_cpu());
        world.step_printed(&mut out);
        let took = t.elapsed();
        tick_cpu.push((thread_cpu().saturating_sub(cpu_at)).as_secs_f64() * 1e6);
        let counted = ALLOCATOR.stats() - counted;
        allocations += counted.allocations + counted.reallocations;
        step_time += took;
        tick_times.push(took.as_secs_f64() * 1e6);
        let bytes_before = bytes;
        for (_, text) in out.robots() {
            if args.digest {
                digest = text.iter().fold(digest, |h, &b| {
                    (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
                });
            }
            messages += text.iter().filter(|&&b| b == b'\n').count() as u64;
            bytes += text.len() as u64;
        }
        tick_bytes.push((bytes - bytes_before) as f64);
    }
    let wall = began.elapsed().as_secs_f64();
    let cpu = process_usage(std::process::id()).0.unwrap_or(0.0) - cpu_before;
    let tick = step_time.as_secs_f64() * 1e6 / ticks as f64;
    say!(
        "sim only: {} robots ({} in the world), {:.1} simulated s in {:.2} s of ticks: real-time factor {:.2}; \
         {tick:.1} µs per tick (moving, sensors, printing); {messages} messages, {:.1} MB; \
         {wall:.2} s wall in all",
        args.uavs,
        world.robot_count(),
        args.seconds,
        step_time.as_secs_f64(),
        args.seconds / step_time.as_secs_f64(),
        bytes as f64 / 1e6
    );
    say!("memory: {per_robot:.2} KiB allocated per idle robot (spawned, before the first tick)");
    if let Some(path) = &args.tick_log {
        let mut csv = String::from("tick,wall_us,cpu_us,bytes\n");
        for (i, ((w, c), b)) in tick_times
            .iter()
            .zip(&tick_cpu)
            .zip(&tick_bytes)
            .enumerate()
        {
            csv.push_str(&format!("{},{w:.0},{c:.0},{b:.0}\n", i + 1));
        }
        std::fs::write(path, csv)
            .with_context(|| format!("cannot write the tick log {}", path.display()))?;
    }
    let slowest = (0..tick_times.len()).max_by(|&a, &b| tick_times[a].total_cmp(&tick_times[b]));
    tick_times.sort_by(f64::total_cmp);
    tick_cpu.sort_by(f64::total_cmp);
    tick_bytes.sort_by(f64::total_cmp);
    let cost = SimCost {
        tick,
        cpu: cpu * 1e6 / ticks as f64,
        p50: quantile(&tick_times, 0.5),
        p99: quantile(&tick_times, 0.99),
        p999: quantile(&tick_times, 0.999),
        max: quantile(&tick_times, 1.0),
        rtf: args.seconds / step_time.as_secs_f64(),
        allocations: allocations as f64 / ticks as f64,
        memory: per_robot,
        cpu_p50: quantile(&tick_cpu, 0.5),
        cpu_p999: quantile(&tick_cpu, 0.999),
        cpu_max: quantile(&tick_cpu, 1.0),
        bytes_p50: quantile(&tick_bytes, 0.5),
        bytes_max: quantile(&tick_bytes, 1.0),
    };
    say!(
        "tick µs: p50 {:.0}, p99 {:.0}, p99.9 {:.0}, max {:.0} (tick {}); {:.1} allocations per tick",
        cost.p50,
        cost.p99,
        cost.p999,
        cost.max,
        slowest.map_or(0, |i| i + 1),
        cost.allocations
    );
    say!(
        "tick CPU µs (stepping thread): p50 {:.0}, p99.9 {:.0}, max {:.0}; bytes per tick: p50 {:.0}, max {:.0}",
        cost.cpu_p50,
        cost.cpu_p999,
        cost.cpu_max,
        cost.bytes_p50,
        cost.bytes_max
    );
    if args.digest {
        say!("digest of the output: {digest:016x}");
    }
    Ok(cost)
}

/// How many of `args.uavs` UAVs the grid of `args` puts where a robot can be on `map` (a dry
/// run of the spawns in a world of its own).
fn fitting(args: &Args, map: &usar_sim::map::Map) -> anyhow::Result<usize> {
    use usar_proto::{Command, Init, Vec3};
    use usar_sim::{SimConfig, World, robots::RobotCatalog};
    let start = map
        .starts()
        .first()
        .context("the map has no PlayerStart")?
        .location;
    let mut world = World::new(map.clone(), RobotCatalog::embedded(), SimConfig::default());
    for i in 0..args.uavs {
        let c = world.connect();
        let [x, y, z] = spawn_point(args, start, i);
        world.command(
            c,
            Command::Init(Init {
                class_name: "USARBot.stsAirRobot".into(),
                location: Some(Vec3::new(x, y, z)),
                ..Init::default()
            }),
        );
    }
    Ok(world.robot_count())
}

/// Checks that every UAV fits on the map (a started server's or --sim-only's): with the
/// given --layers, or else with the fewest layers that work. The defect it answers:
/// 1000 UAVs on the default map failed after 30 s with "nothing from the server".
fn plan_layout(args: &mut Args) -> anyhow::Result<()> {
    if args.host.is_some() {
        return Ok(()); // a running server's map is unknown here
    }
    let map = match &args.map {
        None => usar_sim::map::Map::default_map(),
        Some(name) => usar_sim::map::Map::lookup(name)?,
    };
    let candidates: Vec<usize> = match args.layers {
        Some(l) => vec![l],
        None => (1..=16).collect(),
    };
    let mut best = (0, 1);
    for layers in candidates {
        args.layers = Some(layers);
        let n = fitting(args, &map)?;
        if n == args.uavs {
            return Ok(());
        }
        best = best.max((n, layers));
    }
    bail!(
        "{} UAVs do not fit on map {} at --spacing {}: at most {} fit (with --layers {}). \
         Pass fewer --uavs, a smaller --spacing, a bigger map or more --layers \
         (on its own the layout tries at most 16; `--map city --spacing 1.3 --layers 32` \
         holds 20,000)",
        args.uavs,
        map.level(),
        args.spacing,
        best.0,
        best.1
    )
}

/// Where UAV `i` of `args.uavs` spawns: a square grid per layer centred on `start`, layers
/// stacked upwards (z down).
fn spawn_point(args: &Args, start: [f64; 3], i: usize) -> [f64; 3] {
    let layers = args.layers.unwrap_or(1).max(1);
    let per_layer = args.uavs.div_ceil(layers);
    let side = (per_layer as f64).sqrt().ceil() as usize;
    let (layer, k) = (i / per_layer, i % per_layer);
    let offset = (side as f64 - 1.0) / 2.0;
    [
        start[0] + ((k / side) as f64 - offset) * args.spacing,
        start[1] + ((k % side) as f64 - offset) * args.spacing,
        start[2] - layer as f64 * args.spacing,
    ]
}

/// A started server process, killed on drop.
struct Server {
    child: Child,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start_server(args: &Args) -> anyhow::Result<(Server, SocketAddr)> {
    let bin = match &args.server_bin {
        Some(bin) => bin.clone(),
        None => std::env::current_exe()?.with_file_name("usar-server"),
    };
    let mut command = Command::new(&bin);
    command
        .args(["--port", "0", "--time-scale", &args.time_scale])
        .args([
            "--truth-port",
            "off",
            "--monitor-port",
            "off",
            "--wss-port",
            "off",
        ])
        .args(["--max-connections", &(args.uavs * 2 + 16).to_string()])
        // Every simulated UAV connects from this machine's loopback address.
        .args([
            "--max-connections-per-address",
            &(args.uavs * 2 + 16).to_string(),
        ])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit());
    if let Some(map) = &args.map {
        command.args(["--map", map]);
    }
    if let Some(threads) = args.threads {
        command.args(["--threads", &threads.to_string()]);
    }
    let mut child = command.spawn().with_context(|| {
        format!(
            "cannot start {} (build it with `cargo build --release -p usar-server`, or pass --server-bin or --host)",
            bin.display()
        )
    })?;
    let stdout = child.stdout.take().context("no stdout")?;
    let mut line = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line)?;
    let addr = line
        .split_whitespace()
        .nth(3)
        .and_then(|a| a.parse().ok())
        .with_context(|| format!("unexpected first line from the server: {line:?}"))?;
    Ok((Server { child }, addr))
}

/// A robot with one camera of `{w}` x `{h}` pixels (the AirRobot's, looking 0.3 rad down).
fn camera_catalog(w: u32, h: u32) -> anyhow::Result<usar_sim::RobotCatalog> {
    let text = format!(
        "[[robot]]\nclass = \"USARBot.Cam\"\n[[robot.part]]\ntype = \"Camera\"\nname = \"cams\"\n\
         direction = [0.0, -0.3, 0.0]\nwidth = {w}\nheight = {h}\n"
    );
    Ok(usar_sim::RobotCatalog::from_toml(
        &text,
        std::path::Path::new("camera.toml"),
    )?)
}

/// `--camera --camera-fleet N`: N stsAirRobots with every sensor and a 64x64 camera each,
/// rendered every 0.1 simulated seconds, in one world; the real-time factor.
fn camera_fleet(args: &Args, uavs: usize) -> anyhow::Result<()> {
    use usar_proto::{Command, Drive, Init, Vec3};
    use usar_sim::{SimConfig, World, map::Map, robots::RobotCatalog};
    let mut catalog = RobotCatalog::embedded();
    let camera = camera_catalog(64, 64)?;
    let part = camera.classes()[0].parts[0].clone();
    let class = catalog
        .get_mut("USARBot.stsAirRobot")
        .context("the stsAirRobot class")?;
    class.parts.push(part);
    let threads = args.threads.unwrap_or(2);
    let config = SimConfig {
        threads,
        ..SimConfig::default()
    };
    let map = Map::lookup(args.map.as_deref().unwrap_or("empty_room"))?;
    let mut world = World::new(map, catalog, config);
    let side = (uavs as f64).sqrt().ceil() as usize;
    let mut clients = Vec::new();
    for i in 0..uavs {
        let c = world.connect();
        let (x, y) = (
            (i % side) as f64 * 1.6 - side as f64 * 0.8,
            (i / side) as f64 * 1.6 - side as f64 * 0.8,
        );
        world.command(
            c,
            Command::Init(Init {
                class_name: "USARBot.stsAirRobot".into(),
                location: Some(Vec3::new(x, y, -1.5)),
                ..Init::default()
            }),
        );
        // Turning: a new view in every frame.
        world.command(
            c,
            Command::Drive(Drive {
                rotational_velocity: Some(0.5),
                ..Drive::default()
            }),
        );
        clients.push(c);
    }
    anyhow::ensure!(
        world.robot_count() == uavs,
        "only {} of {uavs} UAVs spawned (a smaller N, or a bigger --map)",
        world.robot_count()
    );
    let ticks = ((args.seconds / world.dt()).round() as u64).max(1);
    let every = (0.1 / world.dt()).round() as u64;
    let (mut out, mut frames) = (Vec::new(), Vec::new());
    let (mut step_time, mut render_time, mut rendered) = (Duration::ZERO, Duration::ZERO, 0u64);
    let began = Instant::now();
    for tick in 0..ticks {
        let t = Instant::now();
        out.clear();
        world.step(&mut out);
        step_time += t.elapsed();
        if tick % every == 0 {
            let t = Instant::now();
            world.render_cameras(&mut frames);
            render_time += t.elapsed();
            rendered += frames.len() as u64;
        }
    }
    let wall = began.elapsed().as_secs_f64();
    let simulated = ticks as f64 * world.dt();
    say!(
        "camera fleet: {uavs} stsAirRobots (all their sensors) + a 64x64 camera each at 10 Hz, \
         {threads} threads, {simulated:.0} simulated s: real-time factor {:.2} ({:.1} s wall: \
         {:.1} s stepping, {:.1} s rendering {rendered} frames, {:.0} frames/s)",
        simulated / wall,
        wall,
        step_time.as_secs_f64(),
        render_time.as_secs_f64(),
        rendered as f64 / render_time.as_secs_f64().max(1e-9)
    );
    Ok(())
}

/// `--camera`: the renderer on one core, then the image server.
fn camera(args: &Args) -> anyhow::Result<()> {
    use usar_sim::{SimConfig, World, map::Map};
    if let Some(uavs) = args.camera_fleet {
        return camera_fleet(args, uavs);
    }
    let budget = Duration::from_secs_f64((args.seconds / 10.0).max(0.5));
    say!("camera renderer, one core (frames per CPU-second, million rays per CPU-second):");
    for map_name in ["empty_room", "city"] {
        for (w, h) in [(64u32, 64u32), (160, 120), (320, 240)] {
            let map = Map::embedded(map_name).context("embedded map")?;
            let config = SimConfig {
                threads: 1,
                ..SimConfig::default()
            };
            let mut world = World::new(map, camera_catalog(w, h)?, config);
            let client = world.connect();
            world.command(
                client,
                usar_proto::Command::Init(usar_proto::Init {
                    class_name: "USARBot.Cam".into(),
                    start: Some("Start1".into()),
                    ..usar_proto::Init::default()
                }),
            );
            // Turning 30 degrees a second, a tick between frames: a new view each frame.
            world.command(
                client,
                usar_proto::Command::Drive(usar_proto::Drive {
                    rotational_velocity: Some(30.0),
                    ..usar_proto::Drive::default()
                }),
            );
            let (mut frames, mut out) = (Vec::new(), Vec::new());
            world.render_cameras(&mut frames);
            anyhow::ensure!(frames.len() == 1, "the camera robot did not spawn");
            let (start, mut n, mut spent) = (Instant::now(), 0u64, Duration::ZERO);
            while start.elapsed() < budget {
                out.clear();
                world.step(&mut out);
                let cpu = thread_cpu();
                world.render_cameras(&mut frames);
                // CPU time of this thread (a shared machine's wall time would count other
                // programs' turns).
                spent += thread_cpu().saturating_sub(cpu);
                n += 1;
            }
            let fps = n as f64 / spent.as_secs_f64();
            say!(
                "  {map_name:<10} {w:>3}x{h:<3} {fps:>8.0} fps  {:>6.1} Mrays/s",
                fps * f64::from(w * h) / 1e6
            );
        }
    }
    say!("image server, delivered frames per second (640x480 raw frames, 1 AirRobot):");
    for clients in [1usize, 4, 16] {
        let fps = image_server_fps(args, clients, budget)?;
        say!(
            "  {clients:>2} clients {fps:>8.1} fps in all, {:>7.1} each",
            fps / clients as f64
        );
    }
    Ok(())
}

/// Frames per second that `clients` image clients (each `OK` after each frame) receive
/// together from a started server.
fn image_server_fps(
    args: &Args,
    clients: usize,
    budget: std::time::Duration,
) -> anyhow::Result<f64> {
    use std::io::{BufRead, Read, Write};
    let bin = match &args.server_bin {
        Some(bin) => bin.clone(),
        None => std::env::current_exe()?.with_file_name("usar-server"),
    };
    let mut child = Command::new(&bin)
        .args(["--port", "0", "--image-port", "0", "--time-scale", "max"])
        .args(["--map", args.map.as_deref().unwrap_or("city")])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .spawn()
        .with_context(|| format!("cannot start {}", bin.display()))?;
    let stdout = child.stdout.take().context("no stdout")?;
    let _server = Server { child };
    let mut lines = std::io::BufReader::new(stdout).lines();
    let mut addr = |prefix: &str| -> anyhow::Result<SocketAddr> {
        let line = lines.next().context("the server said nothing")??;
        line.strip_prefix(prefix)
            .and_then(|a| a.split_whitespace().next())
            .and_then(|a| a.parse().ok())
            .with_context(|| format!("unexpected line from the server: {line:?}"))
    };
    let game = addr("usar-server listening on ")?;
    let image = addr("usar-server image server listening on ")?;
    let measure = || {
        let mut robot = std::net::TcpStream::connect(game)?;
        robot.write_all(b"INIT {ClassName USARBot.AirRobot} {Start Start1}\r\n")?;
        let mut seen = Vec::new();
        let mut buf = [0u8; 4096];
        while !String::from_utf8_lossy(&seen).contains("STA {") {
            let n = robot.read(&mut buf)?;
            anyhow::ensure!(n > 0, "the server closed the robot's connection");
            seen.extend_from_slice(&buf[..n]);
        }
        // The robot's output is not read from here on: at `max` the server leaves it
        // behind after its reader timeout; the image clients are what is measured.
        let start = std::time::Instant::now();
        let counts: Vec<u64> = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..clients)
                .map(|_| {
                    scope.spawn(move || -> anyhow::Result<u64> {
                        let mut s = std::net::TcpStream::connect(image)?;
                        let mut parser = usar_proto::image::FrameParser::new(64 << 20);
                        let (mut n, mut buf) = (0u64, vec![0u8; 1 << 16]);
                        while start.elapsed() < budget {
                            match parser.next_frame()? {
                                Some(_) => {
                                    n += 1;
                                    s.write_all(b"OK")?;
                                }
                                None => {
                                    let k = s.read(&mut buf)?;
                                    anyhow::ensure!(k > 0, "the image server closed");
                                    parser.push(&buf[..k]);
                                }
                            }
                        }
                        Ok(n)
                    })
                })
                .collect();
            workers
                .into_iter()
                .map(|w| w.join().expect("client thread").unwrap_or(0))
                .collect()
        });
        drop(robot);
        Ok(counts.iter().sum::<u64>() as f64 / start.elapsed().as_secs_f64())
    };
    measure()
}

/// The allocator, counting the bytes in use (the memory per robot of `--sim-only`: the
/// process's resident size does not show it, since freed memory is reused, not returned).
#[global_allocator]
static ALLOCATOR: &stats_alloc::StatsAlloc<std::alloc::System> = &stats_alloc::INSTRUMENTED_SYSTEM;

/// Bytes allocated and not yet freed.
fn live_bytes() -> usize {
    let s = ALLOCATOR.stats();
    (s.bytes_allocated as isize - s.bytes_deallocated as isize + s.bytes_reallocated).max(0)
        as usize
}

/// CPU seconds and peak resident memory (MiB) of a process, from /proc.
fn process_usage(pid: u32) -> (Option<f64>, Option<f64>) {
    let cpu = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| {
            let fields: Vec<&str> = s.rsplit_once(')')?.1.split_whitespace().collect();
            let ticks: f64 =
                fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
            Some(ticks / 100.0) // USER_HZ is 100 on Linux
        });
    let rss = std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
            let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
            Some(kib / 1024.0)
        });
    (cpu, rss)
}

async fn run_once(args: &Args, uavs: usize) -> anyhow::Result<Report> {
    let mut args = args.clone();
    args.uavs = uavs;
    plan_layout(&mut args)?;
    let args = &args;
    let (server, addr) = match &args.host {
        Some(host) => {
            let addr = tokio::net::lookup_host((host.as_str(), args.port))
                .await
                .with_context(|| format!("cannot find host {host}"))?
                .next()
                .with_context(|| format!("host {host} has no address"))?;
            (None, addr)
        }
        None => {
            let (server, addr) = start_server(args)?;
            (Some(server), addr)
        }
    };
    let start = first_start(addr).await?;
    let began = Instant::now();
    let mut tasks = Vec::new();
    for i in 0..uavs {
        let location = spawn_point(args, start, i);
        let seconds = args.seconds;
        tasks.push(tokio::spawn(fly(addr, i, location, seconds, args.class())));
    }
    let mut all = Vec::new();
    for task in tasks {
        all.push(task.await??);
    }
    let wall = began.elapsed().as_secs_f64();
    let (cpu, rss) = server
        .as_ref()
        .map_or((None, None), |s| process_usage(s.child.id()));
    drop(server);

    let span = all.iter().map(|c| c.span).sum::<f64>() / all.len().max(1) as f64;
    // Real-time factor over the time every robot was flying (not connecting): simulated
    // time against wall time between the first and the last STA anyone counted.
    let firsts = all.iter().filter_map(|c| c.first);
    let lasts = all.iter().filter_map(|c| c.last);
    let start = firsts.clone().min_by_key(|f| f.0);
    let end = lasts.clone().max_by_key(|l| l.0);
    let (flying_wall, flying_sim) = match (start, end) {
        (Some(a), Some(b)) => (
            (b.0 - a.0).as_secs_f64(),
            lasts.map(|l| l.1).fold(f64::MIN, f64::max)
                - firsts.map(|f| f.1).fold(f64::MAX, f64::min),
        ),
        _ => (wall, span),
    };
    let mut delivered = BTreeMap::new();
    for (name, hz) in args.nominal() {
        let total: u64 = all
            .iter()
            .map(|c| c.counts.get(name).copied().unwrap_or(0))
            .sum();
        let per_robot = total as f64 / all.len().max(1) as f64;
        delivered.insert(name.to_owned(), per_robot / (span * hz));
    }
    let mut latencies: Vec<f64> = all
        .iter()
        .flat_map(|c| c.latencies.iter().map(|d| d.as_secs_f64() * 1e3))
        .collect();
    latencies.sort_by(f64::total_cmp);
    let pct = |p: f64| {
        (!latencies.is_empty())
            .then(|| latencies[((latencies.len() - 1) as f64 * p).round() as usize])
    };
    Ok(Report {
        uavs,
        simulated_seconds: span,
        wall_seconds: wall,
        real_time_factor: flying_sim / flying_wall.max(1e-9),
        messages_per_second: all.iter().map(|c| c.messages).sum::<u64>() as f64
            / flying_wall.max(1e-9),
        bytes_per_second: all.iter().map(|c| c.bytes).sum::<u64>() as f64 / flying_wall.max(1e-9),
        delivered,
        latency_ms_p50: pct(0.5),
        latency_ms_p90: pct(0.9),
        latency_ms_p99: pct(0.99),
        server_cpu_seconds: cpu,
        server_peak_rss_mib: rss,
    })
}

/// The map's first start location, asked over the protocol.
async fn first_start(addr: SocketAddr) -> anyhow::Result<[f64; 3]> {
    let stream = TcpStream::connect(addr)
        .await
        .with_context(|| format!("cannot connect to the server at {addr}"))?;
    let (read, mut write) = stream.into_split();
    let mut lines = BufReader::new(read).lines();
    write.write_all(b"GETSTARTPOSES\r\n").await?;
    while let Some(line) = lines.next_line().await? {
        if let Ok(parsed) = usar_proto::ServerMessage::parse(&line)
            && let usar_proto::ServerMessage::Nfo(usar_proto::Nfo::StartPoses { poses, .. }) =
                parsed.message
        {
            let p = poses.first().context("the map has no start pose")?;
            return Ok([p.location.x, p.location.y, p.location.z]);
        }
    }
    bail!("the server closed the connection before answering GETSTARTPOSES")
}

/// The part a line is about: `STA`, or the `{Name ..}` of a SEN line.
fn part(line: &str) -> Option<&str> {
    if line.starts_with("STA ") {
        return Some("STA");
    }
    let rest = line.strip_prefix("SEN ")?;
    let name = rest.split("{Name ").nth(1)?;
    name.split('}').next()
}

/// The `{Time t}` of a line.
fn time_of(line: &str) -> Option<f64> {
    line.split("{Time ").nth(1)?.split('}').next()?.parse().ok()
}

/// One UAV: spawn, fly back and forth, count what arrives.
async fn fly(
    addr: SocketAddr,
    index: usize,
    [x, y, z]: [f64; 3],
    seconds: f64,
    class: String,
) -> anyhow::Result<ClientStats> {
    let stream = TcpStream::connect(addr)
        .await
        .with_context(|| format!("client {index} cannot connect"))?;
    stream.set_nodelay(true)?;
    let (read, mut write) = stream.into_split();
    let mut lines = BufReader::new(read).lines();
    write
        .write_all(
            format!("INIT {{ClassName {class}}} {{Name UAV{index}}} {{Location {x},{y},{z}}}\r\n")
                .as_bytes(),
        )
        .await?;
    let mut stats = ClientStats::default();
    let (mut first, mut next_drive, mut sign) = (None::<f64>, 0.0, 1.0);
    let mut flipped: Option<(Instant, f64)> = None;
    loop {
        let line = tokio::time::timeout(Duration::from_secs(30), lines.next_line())
            .await
            .with_context(|| {
                format!("client {index}: nothing from the server for 30 s (did the spawn at {x},{y},{z} fail?)")
            })??;
        let Some(line) = line else {
            bail!("client {index}: the server closed the connection");
        };
        stats.bytes += line.len() as u64 + 2;
        let Some(part) = part(&line) else { continue };
        if part == "STA" {
            let Some(t) = time_of(&line) else { continue };
            let t0 = *first.get_or_insert(t);
            stats.first.get_or_insert((Instant::now(), t));
            if t >= t0 + seconds {
                stats.span = t - t0;
                stats.last = Some((Instant::now(), t));
                break;
            }
            if t >= next_drive {
                // Reverse every second; otherwise repeat the set-point (10 Hz of DRIVE).
                let want = if ((t - t0) as u64).is_multiple_of(2) {
                    1.0
                } else {
                    -1.0
                };
                if want != sign {
                    sign = want;
                    flipped = Some((Instant::now(), sign));
                }
                let drive = format!("DRIVE {{LinearVelocity {}}}\r\n", 0.2 * sign);
                write.write_all(drive.as_bytes()).await?;
                next_drive = t + 0.1;
            }
        } else if part == "Velocity"
            && let Some((at, want)) = flipped
            && let Some(v) = line
                .split("{RelativeVelocity ")
                .nth(1)
                .and_then(|s| s.split(',').next())
                .and_then(|s| s.parse::<f64>().ok())
            && v * want > 0.0
        {
            stats.latencies.push(at.elapsed());
            flipped = None;
        }
        if first.is_some() {
            stats.messages += 1;
            match stats.counts.get_mut(part) {
                Some(n) => *n += 1,
                None => {
                    stats.counts.insert(part.to_owned(), 1);
                }
            }
        }
    }
    Ok(stats)
}

/// `--scenarios`: each scenario's iteration three times (seeds 1, 2, 3).
fn scenarios(names: &str, threads: usize) -> anyhow::Result<()> {
    use ucc_client::scenario::spec::EMBEDDED;
    use ucc_client::scenario::{Prepared, Scenario, fly};
    let names: Vec<&str> = if names == "all" {
        EMBEDDED.iter().map(|(n, _)| *n).collect()
    } else {
        names.split(',').map(str::trim).collect()
    };
    say!(
        "scenarios, in-process lockstep, every UAV's agent, pictures off ({threads} sensor thread(s)), 3 iterations each:"
    );
    say!(
        "{:<14} {:>5} {:>9}  {:>26}  {:>26}",
        "scenario",
        "UAVs",
        "sim s",
        "sim s per wall s (min/med/max)",
        "wall s per iteration"
    );
    for name in names {
        let prepared = Prepared::new(Scenario::lookup(name)?, usar_sim::RobotCatalog::embedded())?;
        let mut rates = Vec::new();
        let mut walls = Vec::new();
        let mut simulated = 0.0;
        for seed in 1..=3 {
            let start = std::time::Instant::now();
            let outcome =
                fly(&prepared, seed, threads).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
            let wall = start.elapsed().as_secs_f64();
            simulated = outcome.metrics.get("time_s").unwrap_or(0.0);
            rates.push(simulated / wall.max(1e-9));
            walls.push(wall);
        }
        let sorted = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v
        };
        let (r, w) = (sorted(rates), sorted(walls));
        say!(
            "{:<14} {:>5} {:>9.0}  {:>8.0} {:>8.0} {:>8.0}  {:>8.3} {:>8.3} {:>8.3}",
            name,
            prepared.scenario.uav_count(),
            simulated,
            r[0],
            r[1],
            r[2],
            w[0],
            w[1],
            w[2]
        );
    }
    Ok(())
}
