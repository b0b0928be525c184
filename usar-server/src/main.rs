//! The `usar-server` program: a USARSim stand-in on TCP port 3000.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use clap::Parser;
use tokio_util::sync::CancellationToken;
use usar_server::logging::{Log, announce};
use usar_server::sim::map::Map;
use usar_server::{ServerArgs, ServerConfig, TimeScale};

/// A USARSim (UDK) stand-in: speaks the Gamebots text protocol and flies simulated
/// quadrotors (USARBot.stsAirRobot, USARBot.AirRobot, USARBot.stsQuadrotor) headless, with
/// rapier3d.
///
/// When ready it prints one line per service on stdout: `usar-server listening on
/// ADDRESS:PORT map LEVEL` (Gamebots), then `usar-server image server listening on
/// ADDRESS:PORT` and likewise `USARTruth`, `WSS` and `robot monitor` (each unless `off`).
/// Ctrl-C or SIGTERM shut it down cleanly. Log level: RUST_LOG (default `info`), on stderr;
/// output nobody reads never stops the server: log lines that stderr does not take are
/// dropped, counted and reported (docs/limits.md).
#[derive(Debug, Parser)]
#[command(version, about, args_conflicts_with_subcommands = true)]
struct Args {
    #[command(subcommand)]
    command: Option<Sub>,
    /// Address every port listens on (the Gamebots port, the side services and the WSS's
    /// relay ports). The default, loopback, serves this machine only; `0.0.0.0` (or `::`)
    /// exposes the server to the network, with no authentication: firewall it
    /// (docs/security.md).
    #[arg(long, default_value = "127.0.0.1")]
    bind: String,
    /// TCP port (0 picks a free one).
    #[arg(long, default_value_t = 3000)]
    port: u16,
    /// The image server's TCP port (camera frames, docs/camera.md): a number (0 picks a free
    /// one) or `off`. Default 5003, or a free port with `--port 0`.
    #[arg(long, value_name = "PORT|off", value_parser = side_port)]
    image_port: Option<SidePort>,
    /// Frames the image server sends: raw, or JPEG of quality super, good, normal, fair or
    /// bad (or USARSim's ImageType number, 0 to 5).
    #[arg(long, default_value = "raw", value_name = "TYPE", value_parser = image_type)]
    image_type: u8,
    /// Raw frames with pixels as R, G, B (default: B, G, R, as the original server).
    #[arg(long)]
    image_rgb: bool,
    /// No frame on connect: only one per request (USARSim's LegacyMode=false).
    #[arg(long)]
    image_no_legacy: bool,
    /// USARTruth's port (ground truth of robots and victims, docs/usartruth.md): a number
    /// (0 picks a free one) or `off`. Default 3989, or a free port with `--port 0`.
    #[arg(long, value_name = "PORT|off", value_parser = side_port)]
    truth_port: Option<SidePort>,
    /// The robot monitor's port (positions and wall counts for a WSS, docs/wss.md): a number
    /// (0 picks a free one) or `off`. Default 7435, or a free port with `--port 0`.
    #[arg(long, value_name = "PORT|off", value_parser = side_port)]
    monitor_port: Option<SidePort>,
    /// The Wireless Simulation Server's port (robot-to-robot radio, docs/wss.md; it asks the
    /// robot monitor every second, or with `--lockstep` follows simulated time): a number
    /// (0 picks a free one) or `off`. Default 50000, or a free port with `--port 0`.
    #[arg(long, value_name = "PORT|off", value_parser = side_port)]
    wss_port: Option<SidePort>,
    #[command(flatten)]
    world: ServerArgs,
    /// Connections served at once on the Gamebots port (USARSim: 64). At the limit the
    /// oldest connection that has not sent a complete line is closed to make room; if every
    /// one has, the new one is closed on accept.
    #[arg(long, default_value_t = 256, value_name = "N",
          value_parser = clap::value_parser!(u64).range(1..))]
    max_connections: u64,
    /// Connections from one IP address that have not yet sent a complete line (idle); at
    /// the limit the oldest of them is closed to make room. Connections that have sent a
    /// line count only against --max-connections: many local clients are served.
    #[arg(long, default_value_t = 16, value_name = "N",
          value_parser = clap::value_parser!(u64).range(1..))]
    max_connections_per_address: u64,
    /// Connections each side service (image server, USARTruth, robot monitor, WSS control
    /// port) serves at once. At the limit the oldest that has not completed a request (else
    /// the one whose unfinished request began first) is closed to make room; if there is
    /// none, the new one is closed on accept.
    #[arg(long, default_value_t = 256, value_name = "N",
          value_parser = clap::value_parser!(u64).range(1..))]
    max_side_connections: u64,
    /// Seconds a new connection may take to send its first complete line (request) before it
    /// is closed: Gamebots port, USARTruth, robot monitor, WSS control port.
    #[arg(long, default_value_t = 30.0, value_name = "SECONDS", value_parser = seconds)]
    idle_timeout: f64,
    /// Seconds a connection may take to finish a line (request) it has begun before it is
    /// closed, on every port (slow senders); waiting between lines is fine.
    #[arg(long, default_value_t = 30.0, value_name = "SECONDS", value_parser = seconds)]
    line_timeout: f64,
    /// Robots one connection may spawn (USARSim: 1); further INITs are ignored.
    #[arg(long, default_value_t = 1, value_name = "N")]
    robots_per_connection: usize,
    /// Offer lockstep to clients that ask (`SYNC`, docs/lockstep.md): reproducible runs at any
    /// speed. Off by default, so that no client can hold the world for the others.
    #[arg(long)]
    lockstep: bool,
    /// Wall-clock seconds a lockstep client may take to send its next SYNC before it leaves
    /// the barrier (with a warning) and the world goes on without it.
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS", value_parser = seconds)]
    lockstep_timeout: f64,
    /// Clients that may be in the lockstep barrier at once (the first to send SYNC; later
    /// ones' SYNCs are ignored): 1 for "the first connection" (default: no limit).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    lockstep_clients: Option<u64>,
    /// While clients outside the barrier are connected: the share of wall time (0.01 to 1,
    /// over 10 s) the barrier may hold the world; past it, the member that held it longest
    /// leaves the barrier for good, with a warning (1: off).
    #[arg(long, default_value_t = 0.5, value_name = "SHARE", value_parser = share)]
    lockstep_share: f64,
    /// While anyone else is connected: the share of wall time (0.01 to 1) the world may wait
    /// for clients that joined the barrier less than 10 s ago, all of them together (their
    /// first step, and any later step past 25 ms; a bucket of 0.1 s); once it is spent, for
    /// the next 0.1 s / SHARE their SYNCs are answered when the world reaches their time
    /// instead of holding it (a client reconnecting in a loop cannot hold the others; 1: off).
    #[arg(long, default_value_t = 0.05, value_name = "SHARE", value_parser = share)]
    lockstep_join_share: f64,
    /// With `--time-scale max`: wall-clock seconds the world waits for a client that reads
    /// nothing (it paces itself to its slowest reader) before it goes on without that client,
    /// dropping its output until it reads again. Each time a reader stops, everyone waits
    /// this long: lower it (e.g. 0.5) on a shared server (docs/limits.md).
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS", value_parser = seconds)]
    reader_timeout: f64,
    /// Record every connection (both directions, stamped with simulated time) into DIR,
    /// one file per connection (docs/recording.md).
    #[arg(long, value_name = "DIR")]
    record: Option<PathBuf>,
    /// List the embedded maps and exit.
    #[arg(long)]
    list_maps: bool,
}

#[derive(Debug, clap::Subcommand)]
enum Sub {
    /// Serve a recorded stream (a `--record` file or a plain capture of server lines, such as
    /// real USARSim output) to every client that connects; client lines are logged, never
    /// answered.
    Replay {
        /// The recording or capture.
        file: PathBuf,
        /// Address to listen on.
        #[arg(long, default_value = "127.0.0.1")]
        bind: String,
        /// TCP port (0 picks a free one).
        #[arg(long, default_value_t = 3000)]
        port: u16,
        /// Send as fast as the client reads instead of following the time stamps.
        #[arg(long)]
        fast: bool,
        /// Speed-up of the time-stamp pacing (2 = twice as fast), 0.001 to 1000000.
        #[arg(long, default_value_t = 1.0, value_parser = speed)]
        speed: f64,
    },
    /// Run only a Wireless Simulation Server (docs/wss.md) against any USARSim's robot
    /// monitor (a real USARSim or another usar-server). Prints
    /// `usar-server WSS listening on ADDRESS:PORT` when ready.
    Wss {
        /// The simulator's robot monitor, HOST:PORT (USARSim: port 7435).
        #[arg(long, default_value = "127.0.0.1:7435", value_name = "HOST:PORT")]
        monitor: String,
        /// Address to listen on, for the control port and the relay ports
        /// (docs/security.md).
        #[arg(long, default_value = "127.0.0.1")]
        bind: String,
        /// TCP port (0 picks a free one).
        #[arg(long, default_value_t = 50000)]
        port: u16,
        /// Seconds (wall clock) between polls of the positions (links break and resume then).
        #[arg(long, default_value_t = 1.0, value_parser = seconds)]
        poll: f64,
        /// Weakest usable signal, dBm.
        #[arg(long, default_value_t = -93.0, allow_hyphen_values = true)]
        cutoff: f64,
        /// Attenuation per wall, dB.
        #[arg(long, default_value_t = 6.325)]
        attenuation: f64,
        /// Control connections served at once; at the limit the oldest that has not
        /// completed a request (else the slowest sender) is closed to make room.
        #[arg(long, default_value_t = 256, value_name = "N",
              value_parser = clap::value_parser!(u64).range(1..))]
        max_connections: u64,
        /// Seconds a control connection may take to send its first complete request.
        #[arg(long, default_value_t = 30.0, value_name = "SECONDS", value_parser = seconds)]
        idle_timeout: f64,
        /// Seconds a control connection may take to finish a request it has begun.
        #[arg(long, default_value_t = 30.0, value_name = "SECONDS", value_parser = seconds)]
        line_timeout: f64,
    },
}

fn main() -> ExitCode {
    let args = Args::parse();
    // The log never blocks serving (a full or closed stderr drops lines, counted), and
    // neither do the ready lines on stdout (src/logging.rs).
    let log = usar_server::logging::init();
    let code = run(args, &log);
    log.finish();
    code
}

fn run(args: Args, log: &Log) -> ExitCode {
    if let Some(Sub::Replay {
        file,
        bind,
        port,
        fast,
        speed,
    }) = &args.command
    {
        return match replay(file, bind, *port, *fast, *speed) {
            Ok(()) => ExitCode::SUCCESS,
            Err(error) => {
                log.say(format!("usar-server replay: {error:#}\n"));
                ExitCode::from(2)
            }
        };
    }
    if let Some(Sub::Wss {
        monitor,
        bind,
        port,
        poll,
        cutoff,
        attenuation,
        max_connections,
        idle_timeout,
        line_timeout,
    }) = &args.command
    {
        let limits = (*max_connections, *idle_timeout, *line_timeout);
        return match wss(monitor, bind, *port, *poll, (*cutoff, *attenuation), limits) {
            Ok(()) => ExitCode::SUCCESS,
            Err(error) => {
                log.say(format!("usar-server wss: {error:#}\n"));
                ExitCode::from(2)
            }
        };
    }
    if args.list_maps {
        let mut names = String::new();
        for name in Map::embedded_names() {
            names.push_str(&format!("{name}\n"));
        }
        // A reader that closed the pipe (`| head -1`) got what it wanted.
        let _ = std::io::stdout().write_all(names.as_bytes());
        return ExitCode::SUCCESS;
    }
    let config = match build_config(&args) {
        Ok(config) => config,
        Err(error) => {
            log.say(format!("usar-server: {error:#}\n"));
            return ExitCode::from(2);
        }
    };
    match serve(args, config) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            log.say(format!("usar-server: {error:#}\n"));
            ExitCode::FAILURE
        }
    }
}

fn build_config(args: &Args) -> anyhow::Result<ServerConfig> {
    let mut config = args.world.config()?;
    config.sim.robots_per_connection = args.robots_per_connection;
    // The recording folder before the ready line: a path that cannot be a folder is a
    // configuration error, not a failure after "listening on".
    if let Some(dir) = &args.record {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("--record {}: cannot create the folder", dir.display()))?;
    }
    let count = |n: u64| usize::try_from(n).unwrap_or(usize::MAX);
    Ok(ServerConfig {
        max_connections: count(args.max_connections),
        max_connections_per_address: count(args.max_connections_per_address),
        side_connections: count(args.max_side_connections),
        idle_timeout: std::time::Duration::from_secs_f64(args.idle_timeout),
        line_timeout: std::time::Duration::from_secs_f64(args.line_timeout),
        lockstep: args.lockstep,
        lockstep_timeout: std::time::Duration::from_secs_f64(args.lockstep_timeout),
        lockstep_clients: args
            .lockstep_clients
            .map_or(usize::MAX, |n| usize::try_from(n).unwrap_or(usize::MAX)),
        lockstep_share: args.lockstep_share,
        lockstep_join_share: args.lockstep_join_share,
        reader_timeout: std::time::Duration::from_secs_f64(args.reader_timeout),
        record: args.record.clone(),
        image: usar_server::ImageConfig {
            kind: args.image_type,
            legacy: !args.image_no_legacy,
            bgr: !args.image_rgb,
            ..usar_server::ImageConfig::default()
        },
        ..config
    })
}

fn serve(args: Args, config: ServerConfig) -> anyhow::Result<()> {
    on_runtime(async {
        let listener = tokio::net::TcpListener::bind((args.bind.as_str(), args.port))
            .await
            .with_context(|| format!("cannot listen on {}:{}", args.bind, args.port))?;
        let address = listener.local_addr()?;
        let level = config.map.level().to_owned();
        let shutdown = CancellationToken::new();
        usar_server::cancel_on_signal(shutdown.clone());
        // With `--port 0` (tests, several servers on one machine) every side service picks
        // a free port unless told otherwise.
        let bind = async |service: &str, flag: &str, port: Option<SidePort>, default: u16| {
            let default = SidePort(Some(if args.port == 0 { 0 } else { default }));
            let SidePort(Some(port)) = port.unwrap_or(default) else {
                return anyhow::Ok(None);
            };
            let listener = tokio::net::TcpListener::bind((args.bind.as_str(), port))
                .await
                .with_context(|| {
                    format!("{flag}: cannot listen on {}:{port} ({service})", args.bind)
                })?;
            Ok(Some(listener))
        };
        let side = usar_server::SideListeners {
            image: bind("image server", "--image-port", args.image_port, 5003).await?,
            truth: bind("USARTruth", "--truth-port", args.truth_port, 3989).await?,
            monitor: bind("robot monitor", "--monitor-port", args.monitor_port, 7435).await?,
            wss: bind("WSS", "--wss-port", args.wss_port, 50000).await?,
        };
        if side.wss.is_some() && side.monitor.is_none() {
            anyhow::bail!(
                "--wss-port needs the robot monitor (--monitor-port is off); use --wss-port off"
            );
        }
        // All ready lines in one write: a reader that takes the first line and closes the
        // pipe must not make the next line fail (stdout is line-buffered).
        let mut ready = format!("usar-server listening on {address} map {level}\n");
        for (service, listener) in [
            ("image server", &side.image),
            ("USARTruth", &side.truth),
            ("WSS", &side.wss),
            ("robot monitor", &side.monitor),
        ] {
            if let Some(listener) = listener {
                ready.push_str(&format!(
                    "usar-server {service} listening on {}\n",
                    listener.local_addr()?
                ));
            }
        }
        announce(ready);
        usar_server::run_with(listener, side, config, shutdown).await?;
        Ok(())
    })
}

/// Runs `work` on a new tokio runtime; then gives the runtime's tasks at most 1 s to end,
/// so that nothing left blocking (an output nobody reads) keeps the program from exiting.
fn on_runtime<T>(work: impl Future<Output = anyhow::Result<T>>) -> anyhow::Result<T> {
    let runtime = tokio::runtime::Runtime::new().context("cannot start the runtime")?;
    let result = runtime.block_on(work);
    runtime.shutdown_timeout(std::time::Duration::from_secs(1));
    result
}

/// The standalone WSS against the robot monitor at `monitor`, with its model's cutoff and
/// attenuation and its limits (connections, idle and line timeouts in seconds).
fn wss(
    monitor: &str,
    bind: &str,
    port: u16,
    poll: f64,
    (cutoff, attenuation): (f64, f64),
    (max_connections, idle_timeout, line_timeout): (u64, f64, f64),
) -> anyhow::Result<()> {
    use std::net::ToSocketAddrs;
    let at = monitor
        .to_socket_addrs()
        .with_context(|| format!("--monitor {monitor}: not HOST:PORT"))?
        .next()
        .with_context(|| format!("--monitor {monitor}: no address"))?;
    anyhow::ensure!(
        cutoff.is_finite() && attenuation.is_finite() && attenuation >= 0.0,
        "--cutoff and --attenuation must be finite numbers (attenuation >= 0)"
    );
    use usar_server::net::wss::{PathLoss, WssConfig};
    let config = WssConfig {
        poll: std::time::Duration::from_secs_f64(poll),
        model: PathLoss {
            cutoff,
            attenuation,
            ..PathLoss::default()
        },
        max_connections: usize::try_from(max_connections).unwrap_or(usize::MAX),
        idle_timeout: std::time::Duration::from_secs_f64(idle_timeout),
        line_timeout: std::time::Duration::from_secs_f64(line_timeout),
        ..WssConfig::new(at)
    };
    on_runtime(async {
        let (listener, shutdown) = listen(bind, port, |at| {
            format!("usar-server WSS listening on {at}")
        })
        .await?;
        usar_server::net::wss::serve(listener, config, shutdown).await;
        Ok(())
    })
}

/// Listens on `bind`:`port`, stops at Ctrl-C or SIGTERM (the token) and says where on
/// stdout (`line` of the address), at once: scripts wait for that line.
async fn listen(
    bind: &str,
    port: u16,
    line: impl FnOnce(std::net::SocketAddr) -> String,
) -> anyhow::Result<(tokio::net::TcpListener, CancellationToken)> {
    let listener = tokio::net::TcpListener::bind((bind, port))
        .await
        .with_context(|| format!("cannot listen on {bind}:{port}"))?;
    let shutdown = CancellationToken::new();
    usar_server::cancel_on_signal(shutdown.clone());
    announce(format!("{}\n", line(listener.local_addr()?)));
    Ok((listener, shutdown))
}

/// A side service's port; `None`: off.
#[derive(Debug, Clone, Copy)]
struct SidePort(Option<u16>);

/// A side service's port: a number (0 for any free port) or `off`.
fn side_port(s: &str) -> Result<SidePort, String> {
    if s.eq_ignore_ascii_case("off") {
        return Ok(SidePort(None));
    }
    s.parse::<u16>()
        .map(|p| SidePort(Some(p)))
        .map_err(|_| format!("expected a port from 0 to 65535 or 'off', not '{s}'"))
}

/// An image type: a name or USARSim's ImageType number.
fn image_type(s: &str) -> Result<u8, String> {
    const NAMES: [&str; 6] = ["raw", "super", "good", "normal", "fair", "bad"];
    if let Some(i) = NAMES.iter().position(|n| n.eq_ignore_ascii_case(s)) {
        return Ok(i as u8);
    }
    match s.parse::<u8>() {
        Ok(n) if n <= 5 => Ok(n),
        _ => Err(format!(
            "expected raw, super, good, normal, fair, bad or 0 to 5, not '{s}'"
        )),
    }
}

/// A number of seconds from 0.001 to one day.
fn seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (1e-3..=86_400.0).contains(&v) => Ok(v),
        _ => Err(format!("expected seconds from 0.001 to 86400, not '{s}'")),
    }
}

/// A share of the wall time, 0.01 to 1.
fn share(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (0.01..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("expected a share from 0.01 to 1, not '{s}'")),
    }
}

/// A replay speed factor, in the range of `--time-scale`.
fn speed(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (TimeScale::MIN_FACTOR..=TimeScale::MAX_FACTOR).contains(&v) => Ok(v),
        _ => Err(format!(
            "expected a number from {} to {}, not '{s}'",
            TimeScale::MIN_FACTOR,
            TimeScale::MAX_FACTOR
        )),
    }
}

fn replay(file: &Path, bind: &str, port: u16, fast: bool, speed: f64) -> anyhow::Result<()> {
    use usar_server::replay::{self, Pace};
    let recording = replay::open(file)?;
    let pace = if fast {
        Pace::Fast
    } else {
        Pace::Timestamps(speed)
    };
    on_runtime(async {
        let lines = recording.lines();
        let (listener, shutdown) = listen(bind, port, |at| {
            format!(
                "usar-server replaying {} ({lines} lines) on {at}",
                file.display()
            )
        })
        .await?;
        replay::serve(listener, recording, pace, shutdown).await?;
        Ok(())
    })
}
