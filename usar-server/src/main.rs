//! The `usar-server` program: a USARSim stand-in on TCP port 3000.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use clap::Parser;
use tokio_util::sync::CancellationToken;
use usar_server::sim::SimConfig;
use usar_server::sim::map::Map;
use usar_server::sim::robots::RobotCatalog;
use usar_server::{ServerConfig, TimeScale};

/// A USARSim (UDK) stand-in: speaks the Gamebots text protocol and flies simulated
/// quadrotors (USARBot.stsAirRobot, USARBot.AirRobot) headless, with rapier3d.
///
/// When ready it prints one line on stdout: `usar-server listening on ADDRESS:PORT map LEVEL`.
/// Ctrl-C or SIGTERM shut it down cleanly. Log level: RUST_LOG (default `info`), on stderr.
#[derive(Debug, Parser)]
#[command(version, about, args_conflicts_with_subcommands = true)]
struct Args {
    #[command(subcommand)]
    command: Option<Sub>,
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    bind: String,
    /// TCP port (0 picks a free one).
    #[arg(long, default_value_t = 3000)]
    port: u16,
    /// Map: an embedded map name (see --list-maps) or a map file (TOML, see docs/maps.md).
    #[arg(long, value_name = "NAME|FILE")]
    map: Option<String>,
    /// Robot configurations (TOML, see docs/robots.md); default: the embedded catalog.
    #[arg(long, value_name = "FILE")]
    robots: Option<PathBuf>,
    /// Seed of every noise source; the same seed and commands give the same run.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Threads that read the robots' sensors (default: the machine's cores). The output is
    /// the same at any count.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// Simulated seconds per wall second (e.g. 1, 10, 0.5), or `max` for as fast as possible.
    #[arg(long, default_value = "1", value_name = "K|max")]
    time_scale: TimeScale,
    /// Connections served at once; more are closed on accept.
    #[arg(long, default_value_t = 64)]
    max_connections: usize,
    /// Record every connection (both directions, stamped with simulated time) into DIR,
    /// one file per connection (docs/recording.md).
    #[arg(long, value_name = "DIR")]
    record: Option<PathBuf>,
    /// Offer lockstep to clients that ask (`SYNC`, docs/lockstep.md): reproducible runs at any
    /// speed. Off by default, so that no client can hold the world for the others.
    #[arg(long)]
    lockstep: bool,
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
        /// Speed-up of the time-stamp pacing (2 = twice as fast).
        #[arg(long, default_value_t = 1.0)]
        speed: f64,
    },
}

fn main() -> ExitCode {
    let args = Args::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
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
                eprintln!("usar-server replay: {error:#}");
                ExitCode::from(2)
            }
        };
    }
    if args.list_maps {
        for name in Map::embedded_names() {
            println!("{name}");
        }
        return ExitCode::SUCCESS;
    }
    let config = match build_config(&args) {
        Ok(config) => config,
        Err(error) => {
            eprintln!("usar-server: {error:#}");
            return ExitCode::from(2);
        }
    };
    match serve(args, config) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("usar-server: {error:#}");
            ExitCode::FAILURE
        }
    }
}

fn build_config(args: &Args) -> anyhow::Result<ServerConfig> {
    let map = match &args.map {
        None => Map::default_map(),
        Some(name) => Map::lookup(name).with_context(|| format!("--map {name}"))?,
    };
    let robots = match &args.robots {
        None => RobotCatalog::embedded(),
        Some(path) => RobotCatalog::from_file(path)?,
    };
    Ok(ServerConfig {
        map,
        robots,
        sim: SimConfig {
            seed: args.seed,
            threads: args
                .threads
                .map_or_else(usar_server::sim::default_threads, usize::from),
            ..SimConfig::default()
        },
        time_scale: args.time_scale,
        max_connections: args.max_connections,
        record: args.record.clone(),
        lockstep: args.lockstep,
        ..ServerConfig::default()
    })
}

fn serve(args: Args, config: ServerConfig) -> anyhow::Result<()> {
    let runtime = tokio::runtime::Runtime::new().context("cannot start the runtime")?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind((args.bind.as_str(), args.port))
            .await
            .with_context(|| format!("cannot listen on {}:{}", args.bind, args.port))?;
        let address = listener.local_addr()?;
        let level = config.map.level().to_owned();
        let shutdown = CancellationToken::new();
        tokio::spawn(cancel_on_signal(shutdown.clone()));
        let mut stdout = std::io::stdout().lock();
        writeln!(stdout, "usar-server listening on {address} map {level}")?;
        stdout.flush()?;
        drop(stdout);
        usar_server::run(listener, config, shutdown).await?;
        Ok(())
    })
}

fn replay(file: &Path, bind: &str, port: u16, fast: bool, speed: f64) -> anyhow::Result<()> {
    use usar_server::replay::{self, Pace};
    if !(speed.is_finite() && speed > 0.0) {
        anyhow::bail!("--speed must be a positive number, not {speed}");
    }
    let lines = replay::load(file)?;
    let pace = if fast {
        Pace::Fast
    } else {
        Pace::Timestamps(speed)
    };
    let runtime = tokio::runtime::Runtime::new().context("cannot start the runtime")?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind((bind, port))
            .await
            .with_context(|| format!("cannot listen on {bind}:{port}"))?;
        let shutdown = CancellationToken::new();
        tokio::spawn(cancel_on_signal(shutdown.clone()));
        let mut stdout = std::io::stdout().lock();
        writeln!(
            stdout,
            "usar-server replaying {} ({} lines) on {}",
            file.display(),
            lines.len(),
            listener.local_addr()?
        )?;
        stdout.flush()?;
        drop(stdout);
        replay::serve(listener, lines, pace, shutdown).await?;
        Ok(())
    })
}

/// Cancels `shutdown` on Ctrl-C or SIGTERM.
async fn cancel_on_signal(shutdown: CancellationToken) {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = ctrl_c => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = ctrl_c.await;
            }
        }
    }
    #[cfg(not(unix))]
    let _ = ctrl_c.await;
    tracing::info!("shutting down");
    shutdown.cancel();
}
