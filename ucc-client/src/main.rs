//! `ucc`, the UAV Control Center: fly missions with an agent against a USARSim server, run a
//! self-contained demo, or decode/encode protocol lines.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::{Args, Parser, Subcommand};
use tokio_util::sync::CancellationToken;
use ucc_client::controller::start_poses;
use ucc_client::mission::{load_missions, parse_point};
use ucc_client::{Coordinates, Mission, Progress, RunConfig, Start, Summary, agents, run_missions};

#[derive(Parser)]
#[command(
    name = "ucc",
    version,
    about = "UAV Control Center: fly USARSim UAVs through missions with control agents",
    long_about = "UAV Control Center: fly USARSim UAVs through missions with control agents.\n\n\
                  Coordinates are the USARSim world frame: metres, x north, y east, z DOWN \
                  (z = -2 is 2 m above z = 0). Start with `ucc demo`."
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Fly missions against a running server (usar-server or USARSim).
    #[command(
        after_help = "Example:\n  ucc run --start 0,0,-1 --goto 3,0,-2 --goto 3,3,-2 --iterations 2\n\n\
                            Each iteration writes, in --log-dir: PREFIX-NN.log, \
                            PREFIX-NN-trajectory.csv, PREFIX-NN-map.svg/.png; at the end \
                            PREFIX-overlay.svg/.png with every iteration's path."
    )]
    Run(Box<RunArgs>),
    /// Start a server inside this process and fly a built-in mission; writes the pictures.
    Demo(DemoArgs),
    /// Read protocol lines on stdin and print them as JSON (or re-printed); exit 1 if any failed.
    Decode {
        /// Print JSON, one object per line (the default).
        #[arg(long, conflicts_with = "print")]
        json: bool,
        /// Print each parsed line back in its canonical wire form.
        #[arg(long)]
        print: bool,
    },
    /// Read JSON messages on stdin and print their wire lines; exit 1 if any failed.
    Encode,
    /// A transparent proxy between a client and a USARSim host: forwards every byte, records
    /// both directions and warns about lines that do not parse.
    #[command(
        after_help = "Example:\n  ucc tap --listen 3001 --upstream usarsim-host:3000 --record session.usarlog\n  \
                      (then point the client at localhost:3001)"
    )]
    Tap {
        /// Local port to accept the client on.
        #[arg(long, value_name = "PORT")]
        listen: u16,
        /// Address to listen on.
        #[arg(long, default_value = "127.0.0.1")]
        bind: String,
        /// The USARSim server, `host:port`.
        #[arg(long, value_name = "HOST:PORT")]
        upstream: String,
        /// Recording of the first connection; later ones get `-2`, `-3`, … before the extension.
        #[arg(long, value_name = "FILE")]
        record: PathBuf,
    },
}

#[derive(Args)]
struct RunArgs {
    /// Server host.
    #[arg(long, default_value = "localhost")]
    host: String,
    /// Server port.
    #[arg(long, default_value_t = 3000)]
    port: u16,
    /// Start a usar-server inside this process on a free port instead of connecting to
    /// --host/--port (with --map, --seed and --time-scale).
    #[arg(long)]
    local: bool,
    /// With --local: the map (an embedded name or a file).
    #[arg(long, requires = "local", value_name = "NAME|FILE")]
    map: Option<String>,
    /// With --local: the seed of every noise source.
    #[arg(long, requires = "local", default_value_t = 0)]
    seed: u64,
    /// With --local: simulated seconds per wall second, or `max`.
    #[arg(long, requires = "local", default_value = "max", value_name = "K|max")]
    time_scale: usar_server::TimeScale,
    /// Robot class (`stsAirRobot`, `AirRobot`, or `Package.Class`).
    #[arg(long, default_value = "stsAirRobot")]
    robot: String,
    /// Robot name in the world.
    #[arg(long, default_value = "UAV1")]
    name: String,
    /// Control agent (see `ucc run --help` for the list).
    #[arg(long, default_value = "base", help = agent_help())]
    agent: String,
    /// Start pose `x,y,z[,roll,pitch,yaw]` (metres, z down; radians) or a map PlayerStart tag.
    #[arg(long, allow_hyphen_values = true)]
    start: Start,
    /// Fly to x,y,z (metres, z down); repeat for several waypoints, flown after --missions.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = parse_point)]
    goto: Vec<Coordinates>,
    /// Mission file (TOML, see docs/missions.md).
    #[arg(long, value_name = "FILE")]
    missions: Option<PathBuf>,
    /// How many times to fly the missions (respawning at the start each time).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    iterations: u32,
    /// Directory for logs, trajectories and pictures.
    #[arg(long, default_value = "ucc-logs")]
    log_dir: PathBuf,
    /// File name prefix of everything written.
    #[arg(long, default_value = "UCCLOG")]
    prefix: String,
    /// Simulated seconds a single mission may take before the run fails.
    #[arg(long, default_value_t = 120.0, value_name = "SECONDS")]
    mission_timeout: f64,
    /// Wall-clock seconds to wait for the sensor stream after spawning (and for any silence).
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    stream_timeout: f64,
    /// Run in lockstep with the server when it offers it (docs/lockstep.md): reproducible
    /// runs at any --time-scale. Without it (or against a stock USARSim) the agent runs on
    /// sensor time.
    #[arg(long)]
    lockstep: bool,
    /// Record every line of each iteration's connection (docs/recording.md): FILE for the
    /// first iteration, FILE-2, FILE-3, … (before the extension) for the next.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// Map pictures to draw: all (each iteration and the overlay), overlay, or none.
    #[arg(long, default_value = "all", value_name = "all|overlay|none")]
    pictures: ucc_client::Pictures,
    /// Print only the progress bar, failures and the summary.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args)]
struct DemoArgs {
    /// Folder for the log, trajectory and pictures.
    #[arg(long, default_value = "ucc-demo-output")]
    output: PathBuf,
    /// Control agent.
    #[arg(long, default_value = "base", help = agent_help())]
    agent: String,
    /// How many times to fly the mission.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    iterations: u32,
    /// Simulation speed: simulated seconds per wall-clock second.
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
}

fn agent_help() -> String {
    let list: Vec<_> = agents::AGENTS
        .iter()
        .map(|a| format!("{} ({})", a.name, a.description))
        .collect();
    format!("Control agent: {}", list.join("; "))
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Cmd::Decode { print, .. } => wire_exit(ucc_client::wire::decode(
            std::io::stdin().lock(),
            std::io::stdout().lock(),
            std::io::stderr().lock(),
            print,
        )),
        Cmd::Encode => wire_exit(ucc_client::wire::encode(
            std::io::stdin().lock(),
            std::io::stdout().lock(),
            std::io::stderr().lock(),
        )),
        Cmd::Run(args) => runtime().and_then(|rt| rt.block_on(run_command(*args))),
        Cmd::Tap {
            listen,
            bind,
            upstream,
            record,
        } => runtime().and_then(|rt| rt.block_on(tap(&bind, listen, upstream, record))),
        Cmd::Demo(args) => runtime().and_then(|rt| rt.block_on(demo(args))),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("ucc: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")
}

fn wire_exit(failed: std::io::Result<usize>) -> anyhow::Result<ExitCode> {
    let failed = failed.context("cannot read or write the lines")?;
    Ok(if failed > 0 {
        eprintln!("ucc: {failed} line(s) could not be converted");
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

fn print_progress(progress: &Progress) {
    println!("{progress}");
}

/// Runs `future` until it ends or Ctrl-C.
async fn until_interrupted<T>(
    future: impl Future<Output = anyhow::Result<T>>,
) -> anyhow::Result<T> {
    tokio::select! {
        result = future => result,
        _ = tokio::signal::ctrl_c() => bail!("interrupted"),
    }
}

/// `ucc run`: against --host/--port, or against a server started here with --local.
async fn run_command(args: RunArgs) -> anyhow::Result<ExitCode> {
    if !args.local {
        let addr = format!("{}:{}", args.host, args.port);
        return run(args, addr).await;
    }
    let map = match &args.map {
        None => usar_server::sim::map::Map::default_map(),
        Some(name) => match usar_server::sim::map::Map::embedded(name) {
            Some(map) => map,
            None => usar_server::sim::map::Map::from_file(std::path::Path::new(name))?,
        },
    };
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .context("cannot open a local port for the server")?;
    let addr = listener.local_addr()?.to_string();
    let mut config = usar_server::ServerConfig {
        map,
        time_scale: args.time_scale,
        // Its own server: lockstep (opt-in on shared servers) is always on offer.
        lockstep: true,
        ..usar_server::ServerConfig::default()
    };
    config.sim.seed = args.seed;
    let shutdown = CancellationToken::new();
    let server = tokio::spawn(usar_server::run(listener, config, shutdown.child_token()));
    let result = run(args, addr).await;
    shutdown.cancel();
    let _ = tokio::time::timeout(Duration::from_secs(5), server).await;
    result
}

async fn run(args: RunArgs, addr: String) -> anyhow::Result<ExitCode> {
    let mut missions = match &args.missions {
        Some(path) => load_missions(path)?,
        None => Vec::new(),
    };
    missions.extend(args.goto.iter().copied().map(Mission::goto));
    if missions.is_empty() {
        bail!("no missions: give --goto x,y,z (repeatable) or --missions FILE");
    }
    if !(args.stream_timeout > 0.0 && args.stream_timeout.is_finite()) {
        bail!("--stream-timeout must be a positive number of seconds");
    }
    let config = RunConfig {
        addr,
        robot: args.robot,
        name: args.name,
        agent: args.agent,
        start: args.start,
        missions,
        iterations: args.iterations as usize,
        log_dir: Some(args.log_dir),
        prefix: args.prefix,
        stream_timeout: Duration::from_secs_f64(args.stream_timeout),
        mission_timeout: args.mission_timeout,
        lockstep: args.lockstep,
        record: args.record,
        keep_going: true,
        pictures: args.pictures,
        ..RunConfig::default()
    };
    let bar = progress_bar(config.iterations);
    let quiet = args.quiet;
    let began = std::time::Instant::now();
    let observer = |p: &Progress| {
        match p {
            Progress::IterationDone { .. } | Progress::IterationFailed { .. } => bar.inc(1),
            _ => {}
        }
        let show = !quiet || matches!(p, Progress::IterationFailed { .. });
        if show && !matches!(p, Progress::Written { .. }) {
            bar.suspend(|| println!("{p}"));
        }
    };
    let summary = until_interrupted(async { Ok(run_missions(&config, observer).await?) }).await;
    bar.finish_and_clear();
    let summary = summary?;
    let wall = began.elapsed().as_secs_f64();
    print_summary(&summary, &config);
    print_statistics(&summary, wall);
    let failed = summary.statistics().failed;
    if failed > 0 {
        let first = summary.iterations.iter().find_map(|i| i.error.as_deref());
        eprintln!(
            "ucc: error: {failed} of {} iteration(s) failed{}",
            summary.iterations.len(),
            first.map_or(String::new(), |e| format!(" (first: {e})"))
        );
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}

/// A progress bar over the iterations (hidden when stderr is not a terminal or for one
/// iteration).
fn progress_bar(iterations: usize) -> indicatif::ProgressBar {
    if iterations < 2 {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(iterations as u64);
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{bar:40} {pos}/{len} iterations, {elapsed} elapsed, {eta} left",
    ) {
        bar.set_style(style);
    }
    bar
}

fn print_statistics(summary: &Summary, wall: f64) {
    let s = summary.statistics();
    println!("iterations: {} done, {} failed", s.completed, s.failed);
    if s.completed > 0 {
        println!(
            "completion time: {:.2} s mean, {:.3} s spread (simulated)",
            s.duration.0, s.duration.1
        );
        println!(
            "path length: {:.2} m mean, {:.3} m spread; largest distance from the first path: {:.3} m",
            s.distance.0, s.distance.1, s.max_deviation
        );
    }
    println!(
        "wall time {wall:.2} s for {:.1} simulated s: real-time factor {:.1}",
        s.simulated_seconds,
        s.simulated_seconds / wall.max(1e-9)
    );
    if let Some(results) = &summary.results {
        println!("results: {}", results.display());
    }
}

async fn tap(bind: &str, port: u16, upstream: String, record: PathBuf) -> anyhow::Result<ExitCode> {
    let listener = tokio::net::TcpListener::bind((bind, port))
        .await
        .with_context(|| format!("cannot listen on {bind}:{port}"))?;
    println!(
        "ucc tap: listening on {}, forwarding to {upstream}, recording to {}",
        listener.local_addr()?,
        record.display()
    );
    let shutdown = CancellationToken::new();
    let token = shutdown.clone();
    tokio::spawn(async move {
        let _ = tokio::signal::ctrl_c().await;
        token.cancel();
    });
    ucc_client::tap::run(listener, upstream, record, shutdown).await?;
    Ok(ExitCode::SUCCESS)
}

fn print_summary(summary: &Summary, config: &RunConfig) {
    let missions: usize = summary.iterations.iter().map(|i| i.missions_done).sum();
    println!(
        "done: {} iteration(s), {missions} mission(s) completed",
        summary.iterations.len()
    );
    if let Some(dir) = &config.log_dir {
        let per_iteration: Vec<&PathBuf> =
            summary.iterations.iter().flat_map(|i| &i.files).collect();
        println!("files are in {}", dir.display());
        // Name every file of a short run; for a long one only the overlay.
        let listed = if summary.iterations.len() <= 3 {
            per_iteration.clone()
        } else {
            println!("  ({} files of the iterations)", per_iteration.len());
            Vec::new()
        };
        for file in listed.into_iter().chain(&summary.overlay) {
            println!("  {}", file.display());
        }
    }
}

/// Waypoints of the demo, relative to the start (metres, z down): a climb, then a box of
/// 2.5 m, all within 4 m of the start and 2 m above it.
const DEMO_OFFSETS: [[f64; 3]; 5] = [
    [0.0, 0.0, -1.5],
    [2.5, 0.0, -1.5],
    [2.5, 2.5, -2.0],
    [0.0, 2.5, -1.5],
    [0.0, 0.0, -1.5],
];

async fn demo(args: DemoArgs) -> anyhow::Result<ExitCode> {
    if !(args.speed > 0.0 && args.speed.is_finite()) {
        bail!("--speed must be a positive number");
    }
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .context("cannot open a local port for the demo server")?;
    let addr = listener.local_addr()?.to_string();
    let shutdown = CancellationToken::new();
    let server_config = usar_server::ServerConfig {
        time_scale: usar_server::TimeScale::Factor(args.speed),
        lockstep: true,
        ..usar_server::ServerConfig::default()
    };
    let server = tokio::spawn(usar_server::run(
        listener,
        server_config,
        shutdown.child_token(),
    ));
    println!("ucc demo: usar-server started on {addr} with its embedded map");

    let result = until_interrupted(fly_demo(&addr, &args)).await;

    shutdown.cancel();
    match tokio::time::timeout(Duration::from_secs(5), server).await {
        Ok(Ok(Err(e))) => eprintln!("ucc demo: the server stopped with an error: {e}"),
        Ok(Err(e)) => eprintln!("ucc demo: the server task failed: {e}"),
        Err(_) => eprintln!("ucc demo: the server did not stop within 5 s"),
        Ok(Ok(Ok(()))) => {}
    }
    let (summary, config) = result?;
    print_summary(&summary, &config);
    let png = summary
        .overlay
        .iter()
        .find(|p| p.extension().is_some_and(|e| e == "png"));
    if let Some(png) = png {
        println!("open {} to see the flight", png.display());
    }
    Ok(ExitCode::SUCCESS)
}

async fn fly_demo(addr: &str, args: &DemoArgs) -> anyhow::Result<(Summary, RunConfig)> {
    let poses = start_poses(addr, Duration::from_secs(5))
        .await
        .context("cannot read the map's start poses")?;
    let Some(pose) = poses.first() else {
        bail!("the demo map has no PlayerStart");
    };
    let origin = Coordinates::new(pose.location.x, pose.location.y, pose.location.z);
    println!(
        "ucc demo: spawning a stsAirRobot at start {} ({:.2},{:.2},{:.2}), flying {} waypoints with the {} agent",
        pose.name,
        origin.x,
        origin.y,
        origin.z,
        DEMO_OFFSETS.len(),
        args.agent
    );
    let config = RunConfig {
        addr: addr.to_owned(),
        agent: args.agent.clone(),
        start: Start::Tag(pose.name.clone()),
        missions: DEMO_OFFSETS
            .iter()
            .map(|o| Mission::goto(origin + Coordinates::from(*o)))
            .collect(),
        iterations: args.iterations as usize,
        log_dir: Some(args.output.clone()),
        prefix: "demo".into(),
        // Our own server: lockstep makes the demo the same flight every time.
        lockstep: true,
        ..RunConfig::default()
    };
    let summary = run_missions(&config, print_progress).await?;
    Ok((summary, config))
}
