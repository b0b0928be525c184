//! `ucc`, the UAV Control Center: fly missions with an agent against a USARSim server, run a
//! self-contained demo, or decode/encode protocol lines.

mod conform;
mod scenario;
mod tap;
mod wire;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use tokio_util::sync::CancellationToken;
use ucc_client::agents::{self, AgentInfo};
use ucc_client::backend::{self, Backend};
use ucc_client::mission::{load_missions, parse_point};
use ucc_client::picture::MapGeometry;
use ucc_client::runner::start_poses;
use ucc_client::{
    CameraSettings, Coordinates, Lockstep, Mission, Progress, RadioSettings, RunSettings, Start,
    Summary,
};
use usar_server::sim::map::Map;
use usar_server::{ServerArgs, ServerConfig, TimeScale};

/// The first error writing a status line to standard output (`None`: none so far). Status
/// lines are not the job: a closed or full standard output does not stop a run, but the
/// exit status says so at the end (see [`stdout_exit`]).
static STDOUT_ERROR: std::sync::Mutex<Option<std::io::Error>> = std::sync::Mutex::new(None);

/// `println!` for status lines that never panics: a failed write is kept in
/// [`STDOUT_ERROR`] and later lines are skipped.
macro_rules! say {
    ($($arg:tt)*) => { status_line(format_args!($($arg)*)) };
}

fn status_line(line: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let mut failed = STDOUT_ERROR.lock().unwrap_or_else(|e| e.into_inner());
    if failed.is_none()
        && let Err(e) = writeln!(std::io::stdout().lock(), "{line}")
    {
        *failed = Some(e);
    }
}

/// The exit status once the job is done: `code`, unless the job succeeded and a status line
/// could not be written
/// (a reader that went away: [`CLOSED_PIPE`], quietly; another error, such as a full disk:
/// a message and failure).
fn stdout_exit(code: ExitCode) -> ExitCode {
    let failed = STDOUT_ERROR
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .take();
    match failed {
        // The job's own failure says more.
        _ if code != ExitCode::SUCCESS => code,
        None => code,
        Some(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::from(CLOSED_PIPE),
        Some(e) => {
            eprintln!("ucc: error: cannot write standard output: {e}");
            ExitCode::FAILURE
        }
    }
}

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
                      Coordinates: metres, x north, y east, z DOWN (z = -2 is 2 m above z = 0).\n\n\
                      Each iteration NN writes, in --log-dir:\n  \
                      PREFIX-NN.log              the events, with simulated times\n  \
                      PREFIX-NN-trajectory.csv   time, position, attitude, velocity, battery\n  \
                      PREFIX-NN-map.svg/.png     the path over the map, seen from above\n  \
                      PREFIX-NN-plots.svg/.png   side view; altitude, speed, battery, attitude, \
                      position over time\n\
                      and at the end:\n  \
                      PREFIX-overlay.svg/.png    every iteration's path on one map\n  \
                      PREFIX-results.csv         one row per iteration: status, missions, time, \
                      distance\n\n\
                      A folder that already holds files of PREFIX is refused before flying \
                      (--force overwrites them)."
    )]
    Run(Box<RunArgs>),
    /// Start a server inside this process and fly a built-in mission; writes the pictures.
    Demo(DemoArgs),
    /// Serve the control center in the browser: create UAVs, add waypoints, fly, watch live.
    #[command(
        after_help = "Example:\n  ucc gui --local          # then open the printed URL\n  \
                            ucc gui --host usarsim-host --port 3000"
    )]
    Gui(GuiArgs),
    /// Run a scenario of the thesis (search, relay, tracking, delivery) in-process, in
    /// lockstep: its UAVs, agents, moving targets and metrics (docs/scenarios.md).
    #[command(
        after_help = "Examples:\n  ucc scenario --list\n  ucc scenario search --iterations 5\n  \
                      ucc scenario my-scenario.toml --seed 7 --log-dir runs/mine\n  \
                      ucc scenario relay --record rec    (then: usar-server replay rec/iteration-001/connection-0001.usarlog)\n\n\
                      Writes, in --log-dir:\n  \
                      results.csv              one row per iteration: seed, ending, the metrics\n  \
                      iteration-NNN.log        the events, with simulated times\n  \
                      iteration-NNN.svg/.png   coverage, victims, paths, links, perimeter\n  \
                      overlay.svg/.png         every iteration on one map, the metrics' means"
    )]
    Scenario(scenario::ScenarioArgs),
    /// Check that a USARSim-protocol server (ours or anyone's) speaks the protocol: spawn each
    /// robot class, send every command family, check every answer; exit 0 only when every
    /// mandatory check passes.
    #[command(
        long_about = "Check that a USARSim-protocol server (ours or anyone's) speaks the protocol.\n\n\
                      Connects to HOST:PORT, checks the NFO sent on connect and the GETSTARTPOSES \
                      answer, then for each robot class (--robot, or a default list: classes the \
                      server does not offer are skipped) spawns one robot at the first start pose, \
                      watches its STA/SEN stream (rates per simulated second, time order), asks \
                      GETCONF and GETGEO for the robot and each sensor type it reports (the same \
                      parts must be named), drives, sets the camera where there is one, sends \
                      malformed lines (the connection must stay usable), and checks every line \
                      against UDK's layout (field names, order, number formats) and plausible \
                      units. While the first robot is in the world the side ports on HOST are \
                      tried: the image server, USARTruth and the WSS; one that refuses the \
                      connection is skipped unless --require names it.\n\n\
                      Prints a table (check, result, detail, the offending line) or, with \
                      --json, one JSON object. Exit status: 0 when every mandatory check passed, \
                      1 when one failed, 2 for bad input (an address that does not parse, a \
                      server that cannot be reached). What each check means: docs/conformance.md.",
        after_help = "Examples:\n  ucc conform 127.0.0.1:3000\n  \
                      ucc conform usarsim-host:3000 --robot P3AT --robot AirRobot --require image\n  \
                      ucc conform 127.0.0.1:3000 --json > conformance.json"
    )]
    Conform(conform::ConformArgs),
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
        /// Connections served at once; more are closed on accept.
        #[arg(long, value_name = "N", default_value_t = tap::MAX_CONNECTIONS,
              value_parser = clap::value_parser!(u16).range(1..))]
        max_connections: u16,
    },
}

#[derive(Args)]
// The local server's options are usar-server's, defaulting to `max`; given without --local
// they are a usage error that says what to do (`local_only`).
#[command(mut_arg("time_scale", |a| a.default_value("max")))]
struct RunArgs {
    /// Server host.
    #[arg(long, default_value = "localhost")]
    host: String,
    /// Server port.
    #[arg(long, default_value_t = 3000)]
    port: u16,
    /// Start a usar-server inside this process on a free port instead of connecting to
    /// --host/--port (with --map, --robots, --seed and --time-scale). Always in lockstep:
    /// the same command gives the same flight on any machine.
    #[arg(long)]
    local: bool,
    /// The local server's world (with --local).
    #[command(flatten, next_help_heading = "The local server (with --local)")]
    server: ServerArgs,
    /// Robot class (`stsAirRobot`, `stsQuadrotor`, `AirRobot`, or `Package.Class`).
    #[arg(long, default_value = "stsAirRobot")]
    robot: String,
    /// Robot name in the world.
    #[arg(long, default_value = "UAV1")]
    name: String,
    /// Control agent (see `ucc run --help` for the list).
    #[arg(long, default_value = "base", help = agent_help(), value_parser = agent_name)]
    agent: &'static AgentInfo,
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
    #[arg(long, default_value_t = 1, allow_hyphen_values = true,
          value_parser = clap::value_parser!(u32).range(1..))]
    iterations: u32,
    /// Directory for logs, trajectories and pictures.
    #[arg(long, default_value = "ucc-logs")]
    log_dir: PathBuf,
    /// Overwrite the files of an earlier run with the same --log-dir and --prefix (without
    /// it such a run is refused before flying).
    #[arg(long)]
    force: bool,
    /// File name prefix of everything written.
    #[arg(long, default_value = "UCCLOG")]
    prefix: String,
    /// Simulated seconds a single mission may take before the run fails.
    #[arg(long, default_value_t = 120.0, value_name = "SECONDS", allow_hyphen_values = true,
          value_parser = positive_seconds)]
    mission_timeout: f64,
    /// Wall-clock seconds to wait for the sensor stream after spawning (and for any silence).
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS", allow_hyphen_values = true,
          value_parser = positive_seconds)]
    stream_timeout: f64,
    /// Run in lockstep with the server (docs/lockstep.md; `usar-server --lockstep`):
    /// reproducible runs at any speed; a server that does not offer it is an error. Without
    /// it the agent runs on sensor time, as against a stock USARSim, and results depend on
    /// timing. Implied by --local.
    #[arg(long)]
    lockstep: bool,
    /// Record every line of each iteration's connection (docs/recording.md): FILE for the
    /// first iteration, FILE-2, FILE-3, … (before the extension) for the next.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// Map pictures to draw: all (each iteration and the overlay), overlay, or none.
    #[arg(long, default_value = "all", value_name = "all|overlay|none")]
    pictures: ucc_client::Pictures,
    /// Give the agent the UAV's camera frames (UavState::image) from the image server at
    /// --host:--image-port (with --local, its own); the robot needs a camera (the stock
    /// AirRobot has one). Off by default: state-only runs stay fast. See docs/camera.md.
    #[arg(long)]
    camera: bool,
    /// The image server's port (USARSim: 5003), with --camera.
    #[arg(long, default_value_t = 5003, value_name = "PORT")]
    image_port: u16,
    /// Write every N-th camera frame as PNG into --log-dir (PREFIX-NN-frame-IIIII.png,
    /// NN the iteration, IIIII the frame's number); implies --camera.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    frames: Option<u32>,
    /// Raw frames of the image server carry R, G, B (usar-server --image-rgb), not USARSim's
    /// B, G, R.
    #[arg(long)]
    image_rgb: bool,
    /// Give the agent a radio through the WSS at --host:--wss-port (with --local, its own):
    /// Step::send, UavState::inbox, ::undelivered and ::signal (docs/wss.md).
    #[arg(long)]
    radio: bool,
    /// The WSS's port (50000), with --radio.
    #[arg(long, default_value_t = 50000, value_name = "PORT")]
    wss_port: u16,
    /// With --radio: another UAV whose signal the agent sees at every step (repeatable).
    #[arg(long, value_name = "NAME")]
    peer: Vec<String>,
    /// Print only the progress bar, failures and the summary.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args)]
struct GuiArgs {
    /// Address and port to serve the page on. Beyond the loopback a token is required; it is
    /// printed in the URL.
    #[arg(long, default_value = "127.0.0.1:8080", value_name = "ADDR:PORT")]
    listen: std::net::SocketAddr,
    /// USARSim server host.
    #[arg(long, default_value = "localhost", conflicts_with = "local")]
    host: String,
    /// USARSim server port.
    #[arg(long, default_value_t = 3000, conflicts_with = "local")]
    port: u16,
    /// Start a usar-server inside this process (lockstep; the page sets its speed).
    #[arg(long)]
    local: bool,
    /// With --local: the map (an embedded name, any case, or a map file).
    #[arg(long, requires = "local", value_name = "NAME|FILE")]
    map: Option<String>,
    /// With --local: the starting speed, simulated seconds per wall second, or `max`.
    #[arg(long, requires = "local", default_value = "1", value_name = "K|max")]
    speed: TimeScale,
    /// Directory for the logs, trajectories, pictures and results of the runs.
    #[arg(long, default_value = "ucc-logs")]
    log_dir: PathBuf,
    /// A host name the page may also be opened by (repeatable). A request naming any other
    /// host than this server's address, localhost, 127.0.0.1 or [::1] is refused (DNS
    /// rebinding).
    #[arg(long, value_name = "NAME")]
    allow_host: Vec<String>,
    /// Seconds a peer may take to send a request, leave a response or its page's updates
    /// unread, or (a page) not answer the server's pings; then it is dropped, and its page's
    /// slot (of 32) freed.
    #[arg(long, default_value_t = 30, value_name = "SECONDS",
          value_parser = clap::value_parser!(u64).range(1..=3600))]
    page_timeout: u64,
}

#[derive(Args)]
struct DemoArgs {
    /// Folder for the log, trajectory and pictures.
    #[arg(long, default_value = "ucc-demo-output")]
    output: PathBuf,
    /// Control agent.
    #[arg(long, default_value = "base", help = agent_help(), value_parser = agent_name)]
    agent: &'static AgentInfo,
    /// How many times to fly the mission.
    #[arg(long, default_value_t = 1, allow_hyphen_values = true,
          value_parser = clap::value_parser!(u32).range(1..))]
    iterations: u32,
    /// Simulation speed: simulated seconds per wall-clock second (the flight is the same at
    /// any speed: the demo runs in lockstep).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true, value_parser = positive_seconds)]
    speed: f64,
}

fn agent_help() -> String {
    let list: Vec<_> = agents::AGENTS
        .iter()
        .map(|a| format!("{} ({})", a.name, a.description))
        .collect();
    format!("Control agent: {}", list.join("; "))
}

/// `--agent NAME`: a registered agent (a bad name is a usage error, exit 2).
fn agent_name(name: &str) -> Result<&'static AgentInfo, String> {
    agents::info(name).ok_or_else(|| format!("unknown agent (known agents: {})", agents::names()))
}

/// The options of `ucc run` that configure the server `--local` starts: given without
/// `--local`, a usage error (exit 2) that says what to do.
fn local_only(run: &ArgMatches) {
    if run.get_flag("local") {
        return;
    }
    let given = [
        "map",
        "robots",
        "seed",
        "threads",
        "time_scale",
        "wind",
        "gusts",
        "gust_length",
        "physics_rate",
        "sensor_rate",
    ]
    .into_iter()
    .find(|id| run.value_source(id) == Some(ValueSource::CommandLine));
    if let Some(id) = given {
        let option = format!("--{}", id.replace('_', "-"));
        let mut command = Cli::command();
        command.build();
        let run = command
            .find_subcommand_mut("run")
            .expect("the run subcommand");
        run.error(
            clap::error::ErrorKind::ArgumentConflict,
            format!(
                "{option} configures the server that --local starts: add --local, or, against a \
                 server of your own, start it with the option (usar-server {option} ...)"
            ),
        )
        .exit();
    }
}

/// A positive, finite number of seconds (or a positive speed).
/// From 0.001 to 1 000 000: beyond, a Duration or the server's pacing would overflow.
fn positive_seconds(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if (1e-3..=1e6).contains(&v) => Ok(v),
        _ => Err(format!(
            "expected a number from 0.001 to 1000000, not {text:?}"
        )),
    }
}

fn main() -> ExitCode {
    // Colour only on a terminal: never escape codes in a log file or a pipe.
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .init();
    let matches = Cli::command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    if let Some(("run", run)) = matches.subcommand() {
        local_only(run);
    }
    let result = match cli.command {
        Cmd::Decode { print, .. } => wire_exit(wire::decode(
            wire::Named::new(std::io::stdin().lock(), "standard input"),
            wire::Named::new(std::io::stdout().lock(), "standard output"),
            wire::Named::new(std::io::stderr().lock(), "standard error"),
            print,
        )),
        Cmd::Encode => wire_exit(wire::encode(
            wire::Named::new(std::io::stdin().lock(), "standard input"),
            wire::Named::new(std::io::stdout().lock(), "standard output"),
            wire::Named::new(std::io::stderr().lock(), "standard error"),
        )),
        Cmd::Run(args) => runtime().and_then(|rt| rt.block_on(run_command(*args))),
        Cmd::Tap {
            listen,
            bind,
            upstream,
            record,
            max_connections,
        } => runtime().and_then(|rt| {
            rt.block_on(tap(&bind, listen, upstream, record, max_connections.into()))
        }),
        Cmd::Demo(args) => runtime().and_then(|rt| rt.block_on(demo(args))),
        Cmd::Scenario(args) => scenario::scenario(args),
        Cmd::Conform(args) => runtime().and_then(|rt| rt.block_on(conform::conform(args))),
        Cmd::Gui(args) => runtime().and_then(|rt| rt.block_on(gui(args))),
    };
    match result {
        Ok(code) => stdout_exit(code),
        Err(e) => {
            eprintln!("ucc: error: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes, `: `-separated, leaving out a cause that its effect already
/// quotes (an I/O error is often both the message's tail and its source).
fn error_chain(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain() {
        let cause = cause.to_string();
        if text.contains(&cause) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&cause);
    }
    text
}

fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")
}

/// The exit status of a program whose output was closed by its reader (`ucc decode | head`):
/// what a shell reports for one ended by SIGPIPE, as `cat` or `yes` are (128 + 13).
const CLOSED_PIPE: u8 = 141;

fn wire_exit(failed: std::io::Result<usize>) -> anyhow::Result<ExitCode> {
    let failed = match failed {
        Ok(n) => n,
        // The reader went away (`ucc decode | head`): the conventional quiet end, with the
        // status of a program ended by SIGPIPE (a pipeline under `set -o pipefail` fails as
        // it would with `cat`).
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            return Ok(ExitCode::from(CLOSED_PIPE));
        }
        // The error names the stream (`cannot write standard output: No space left ...`).
        Err(e) => return Err(e.into()),
    };
    Ok(if failed > 0 {
        eprintln!("ucc: {failed} line(s) reported above");
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

/// A token cancelled by Ctrl-C or SIGTERM (the handlers in place at once).
fn interrupt_token() -> CancellationToken {
    let token = CancellationToken::new();
    usar_server::cancel_on_signal(token.clone());
    token
}

/// The exit code of an interrupted run (as a shell reports SIGINT).
const INTERRUPTED: u8 = 130;

/// `ucc run`: against --host/--port, or against a server started here with --local.
async fn run_command(args: RunArgs) -> anyhow::Result<ExitCode> {
    // Everything that can be checked before flying is: a mistake found after the flight
    // costs the whole flight.
    let mut missions = match &args.missions {
        Some(path) => load_missions(path)?,
        None => Vec::new(),
    };
    missions.extend(args.goto.iter().copied().map(Mission::goto));
    if missions.is_empty() {
        bail!("no missions: give --goto x,y,z (repeatable) or --missions FILE");
    }
    let backend = if args.local {
        let config = args.server.config()?;
        check_points(
            &MapGeometry::from(&config.map),
            &args.start,
            &missions,
            config.map.level(),
        )?;
        Backend::Local(Box::new(config))
    } else {
        Backend::Remote(format!("{}:{}", args.host, args.port))
    };
    prepare_output(&args.log_dir, &args.prefix, args.force)?;
    let class = RunSettings {
        robot: args.robot.clone(),
        ..RunSettings::default()
    }
    .class_name();
    let sides = backend::Sides {
        camera: args.camera || args.frames.is_some(),
        radio: args.radio,
    };
    let server = backend.start_with(sides).await?;
    if let Some(problem) = server.spawn_problem(&class, &args.start) {
        _ = server.stop().await;
        bail!("{problem}");
    }
    let result = run(args, missions, &server).await;
    if let Err(e) = server.stop().await {
        eprintln!("ucc: {e}");
    }
    result
}

/// Refuses a start or a waypoint inside a solid of the local server's map or below its
/// floor, naming it (z points down: a sign slip puts a point under the floor).
fn check_points(
    map: &MapGeometry,
    start: &Start,
    missions: &[Mission],
    level: &str,
) -> anyhow::Result<()> {
    let refuse = |what: String, p: &Coordinates, problem: String| {
        anyhow::anyhow!(
            "map {level}: {what} {:.2},{:.2},{:.2} {problem}; z points down: z = -1 is 1 m \
             above z = 0",
            p.x,
            p.y,
            p.z
        )
    };
    if let Start::Pose { location, .. } = start
        && let Some(problem) = map.problem_at(location)
    {
        return Err(refuse("the start".into(), location, problem));
    }
    for (n, target) in missions.iter().filter_map(Mission::target).enumerate() {
        if let Some(problem) = map.problem_at(&target) {
            return Err(refuse(format!("waypoint {}", n + 1), &target, problem));
        }
    }
    Ok(())
}

/// Makes the output folder and checks, before anything flies, that the run's files can be
/// written there and that no earlier run's files would be overwritten (unless `force`).
fn prepare_output(dir: &Path, prefix: &str, force: bool) -> anyhow::Result<()> {
    if prefix.is_empty() || prefix.contains(['/', '\\']) || prefix.starts_with('.') {
        bail!(
            "--prefix {prefix:?}: a file name prefix is a name, not a path (the folder is \
             --log-dir)"
        );
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the output folder {}", dir.display()))?;
    if !force {
        let start = format!("{prefix}-");
        let mut earlier: Vec<String> = std::fs::read_dir(dir)
            .with_context(|| format!("cannot read the output folder {}", dir.display()))?
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|name| name.starts_with(&start))
            .collect();
        earlier.sort();
        if let Some(first) = earlier.first() {
            bail!(
                "{} already holds {} file(s) of an earlier run ({first}, ...): pass --force to \
                 overwrite them, or choose another --log-dir or --prefix",
                dir.display(),
                earlier.len()
            );
        }
    }
    let probe = dir.join(format!(".{prefix}-{}.probe", std::process::id()));
    std::fs::write(&probe, b"")
        .with_context(|| format!("cannot write into the output folder {}", dir.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

async fn run(
    args: RunArgs,
    missions: Vec<Mission>,
    server: &backend::Server,
) -> anyhow::Result<ExitCode> {
    let lockstep = server.lockstep(if args.lockstep {
        Lockstep::Required
    } else {
        Lockstep::Off
    });
    let settings = server.settings(RunSettings {
        robot: args.robot,
        name: args.name,
        start: args.start,
        missions,
        iterations: args.iterations as usize,
        log_dir: Some(args.log_dir),
        prefix: args.prefix,
        stream_timeout: Duration::from_secs_f64(args.stream_timeout),
        mission_timeout: args.mission_timeout,
        lockstep,
        record: args.record,
        keep_going: true,
        pictures: args.pictures,
        camera: (args.camera || args.frames.is_some()).then(|| CameraSettings {
            server: format!("{}:{}", args.host, args.image_port),
            bgr: !args.image_rgb,
            save_every: args.frames.unwrap_or(0),
            ..CameraSettings::default()
        }),
        radio: args.radio.then(|| RadioSettings {
            wss: format!("{}:{}", args.host, args.wss_port),
            peers: args.peer,
        }),
        ..RunSettings::default()
    });
    let bar = progress_bar(settings.iterations);
    let quiet = args.quiet;
    let began = std::time::Instant::now();
    let mut observer = |p: &Progress| {
        match p {
            Progress::IterationDone { .. } | Progress::IterationFailed { .. } => bar.inc(1),
            // Said once, when it is true: connected, and not in lockstep.
            Progress::Connected {
                iteration: 1,
                lockstep: false,
                ..
            } => bar.suspend(|| {
                say!(
                    "ucc: running on sensor time: results depend on timing (with usar-server, \
                     start it with --lockstep and pass --lockstep for repeatable runs)"
                );
            }),
            _ => {}
        }
        let show = !quiet
            || matches!(
                p,
                Progress::IterationFailed { .. }
                    | Progress::Interrupted { .. }
                    | Progress::Warning { .. }
            );
        if show && p.is_loggable() && !matches!(p, Progress::Written { .. }) {
            bar.suspend(|| say!("{p}"));
        }
    };
    let cancel = interrupt_token();
    let summary = ucc_client::run(&settings, &args.agent.create, &mut observer, &cancel).await;
    bar.finish_and_clear();
    let summary = summary?;
    let wall = began.elapsed().as_secs_f64();
    print_summary(&summary, &settings);
    print_statistics(&summary, wall);
    if summary.interrupted {
        eprintln!("ucc: interrupted; everything flown so far is written");
        return Ok(ExitCode::from(INTERRUPTED));
    }
    let failed = summary.statistics().failed;
    if failed > 0 {
        let first = &summary.first_error;
        eprintln!(
            "ucc: error: {failed} of {} iteration(s) failed{}",
            summary.flown,
            first
                .as_ref()
                .map_or(String::new(), |e| format!(" (first: {e})"))
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
    say!("iterations: {} done, {} failed", s.completed, s.failed);
    if s.completed > 0 {
        say!(
            "completion time: {:.2} s mean, {:.3} s spread (simulated)",
            s.duration.0,
            s.duration.1
        );
        say!(
            "path length: {:.2} m mean, {:.3} m spread; largest distance from the first path: {:.3} m",
            s.distance.0,
            s.distance.1,
            s.max_deviation
        );
    }
    say!(
        "wall time {wall:.2} s for {:.1} simulated s: real-time factor {:.1}",
        s.simulated_seconds,
        s.simulated_seconds / wall.max(1e-9)
    );
    if let Some(results) = &summary.results {
        say!("results: {}", results.display());
    }
}

async fn tap(
    bind: &str,
    port: u16,
    upstream: String,
    record: PathBuf,
    max_connections: usize,
) -> anyhow::Result<ExitCode> {
    let announce = format!(
        "forwarding to {upstream}, recording to {}, at most {max_connections} connections",
        record.display()
    );
    // Both checked before listening: a bad address or path is an error now, not when a
    // client comes.
    let tap = tap::Tap::check(upstream, record, max_connections).await?;
    let listener = tokio::net::TcpListener::bind((bind, port))
        .await
        .with_context(|| format!("cannot listen on {bind}:{port}"))?;
    say!(
        "ucc tap: listening on {}, {announce}",
        listener.local_addr()?
    );
    let incomplete = tap.run(listener, interrupt_token()).await;
    if incomplete.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    for file in &incomplete {
        eprintln!("ucc tap: error: the recording is incomplete: {file}");
    }
    Ok(ExitCode::FAILURE)
}

fn print_summary(summary: &Summary, settings: &RunSettings) {
    say!(
        "{}: {} iteration(s), {} mission(s) completed",
        if summary.interrupted {
            "interrupted"
        } else {
            "done"
        },
        summary.flown,
        summary.missions_done
    );
    if let Some(dir) = &settings.log_dir {
        say!("files are in {}", dir.display());
        // Name every file of a short run; for a long one only the overlay and the table.
        let listed: Vec<&PathBuf> = if summary.flown <= 3 {
            summary.iterations.iter().flat_map(|i| &i.files).collect()
        } else {
            say!("  ({} files of the iterations)", summary.files_written);
            Vec::new()
        };
        for file in listed
            .into_iter()
            .chain(&summary.overlay)
            .chain(&summary.results)
        {
            say!("  {}", file.display());
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
    // The demo's folder is its own: each demo replaces the last one's files.
    prepare_output(&args.output, "demo", true)?;
    let config = ServerConfig {
        time_scale: TimeScale::Factor(args.speed),
        ..ServerConfig::default()
    };
    let server = Backend::Local(Box::new(config)).start().await?;
    say!(
        "ucc demo: usar-server started on {} with its embedded map",
        server.addr()
    );
    let result = fly_demo(&server, &args).await;
    if let Err(e) = server.stop().await {
        eprintln!("ucc demo: the server stopped with an error: {e}");
    }
    let (summary, settings) = result?;
    print_summary(&summary, &settings);
    if summary.interrupted {
        return Ok(ExitCode::from(INTERRUPTED));
    }
    let png = summary
        .overlay
        .iter()
        .find(|p| p.extension().is_some_and(|e| e == "png"));
    if let Some(png) = png {
        say!("open {} to see the flight", png.display());
    }
    Ok(ExitCode::SUCCESS)
}

async fn fly_demo(
    server: &backend::Server,
    args: &DemoArgs,
) -> anyhow::Result<(Summary, RunSettings)> {
    let poses = start_poses(server.addr(), Duration::from_secs(5))
        .await
        .context("cannot read the map's start poses")?;
    let Some(pose) = poses.first() else {
        bail!("the demo map has no PlayerStart");
    };
    let origin = Coordinates::new(pose.location.x, pose.location.y, pose.location.z);
    say!(
        "ucc demo: spawning a stsAirRobot at start {} ({:.2},{:.2},{:.2}), flying {} waypoints with the {} agent",
        pose.name,
        origin.x,
        origin.y,
        origin.z,
        DEMO_OFFSETS.len(),
        args.agent.name
    );
    // Our own server: lockstep makes the demo the same flight every time.
    let settings = server.settings(RunSettings {
        start: Start::Tag(pose.name.clone()),
        missions: DEMO_OFFSETS
            .iter()
            .map(|o| Mission::goto(origin + Coordinates::from(*o)))
            .collect(),
        iterations: args.iterations as usize,
        log_dir: Some(args.output.clone()),
        prefix: "demo".into(),
        ..RunSettings::default()
    });
    let cancel = interrupt_token();
    let mut print = |p: &Progress| {
        if p.is_loggable() {
            say!("{p}");
        }
    };
    let summary = ucc_client::run(&settings, &args.agent.create, &mut print, &cancel).await?;
    Ok((summary, settings))
}

/// `ucc gui`: serve the control center until Ctrl-C.
async fn gui(args: GuiArgs) -> anyhow::Result<ExitCode> {
    let server = if args.local {
        let map = match &args.map {
            None => Map::default_map(),
            Some(name) => Map::lookup(name).with_context(|| format!("--map {name}"))?,
        };
        ucc_gui::ServerChoice::Local(Box::new(ServerConfig {
            map,
            time_scale: args.speed,
            ..ServerConfig::default()
        }))
    } else {
        ucc_gui::ServerChoice::Remote(format!("{}:{}", args.host, args.port))
    };
    let listener = tokio::net::TcpListener::bind(args.listen)
        .await
        .with_context(|| format!("cannot listen on {}", args.listen))?;
    let addr = listener.local_addr()?;
    let token = (!addr.ip().is_loopback()).then(ucc_gui::new_token);
    say!("ucc gui: open {}", ucc_gui::url(addr, token.as_deref()));
    if token.is_some() {
        say!(
            "ucc gui: listening beyond the loopback; the page and its API need the token in that URL"
        );
    }
    let config = ucc_gui::GuiConfig {
        server,
        log_dir: args.log_dir,
        token,
        allowed_hosts: args.allow_host,
        page_timeout: Duration::from_secs(args.page_timeout),
    };
    ucc_gui::serve(listener, config, interrupt_token()).await?;
    Ok(ExitCode::SUCCESS)
}
