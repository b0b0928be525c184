//! `ucc scenario`: runs an embedded scenario or a scenario file (docs/scenarios.md).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;
use ucc_client::agents::team::TEAM_AGENTS;
use ucc_client::scenario::run::{ScenarioProgress, ScenarioRun};
use ucc_client::scenario::spec::EMBEDDED;
use ucc_client::scenario::{Prepared, Scenario, run_scenario};
use usar_server::sim::RobotCatalog;

#[derive(Args)]
pub(crate) struct ScenarioArgs {
    /// An embedded scenario's name (see --list) or a scenario file (TOML).
    #[arg(value_name = "NAME|FILE", required_unless_present = "list")]
    scenario: Option<String>,
    /// List the embedded scenarios and the team agents, then exit.
    #[arg(long)]
    list: bool,
    /// Iterations to fly; iteration i flies seed + i - 1.
    #[arg(long, short = 'n', default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    iterations: u64,
    /// The first iteration's seed (default: the scenario's `seed`).
    #[arg(long)]
    seed: Option<u64>,
    /// Folder for results.csv, each iteration's log and picture (default
    /// ucc-logs/scenario-NAME).
    #[arg(long, value_name = "DIR")]
    log_dir: Option<PathBuf>,
    /// Write no pictures (the figures and logs only; faster).
    #[arg(long)]
    no_pictures: bool,
    /// Robot catalog (TOML, docs/robots.md) instead of the embedded one.
    #[arg(long, value_name = "FILE")]
    robots: Option<PathBuf>,
    /// Sensor threads of the simulated world.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=64))]
    threads: u64,
    /// Overwrite an earlier run's files in the log folder.
    #[arg(long)]
    force: bool,
    /// Record each UAV's traffic, as `usar-server --record` would, into
    /// DIR/iteration-NNN/connection-KKKK.usarlog (UAV k in connection k; docs/recording.md).
    #[arg(long, value_name = "DIR")]
    record: Option<PathBuf>,
    /// Print only the summary.
    #[arg(long, short = 'q')]
    quiet: bool,
}

pub(crate) fn scenario(args: ScenarioArgs) -> anyhow::Result<ExitCode> {
    let mut out = std::io::stdout().lock();
    match run(args, &mut out) {
        // The reader went away (`ucc scenario ... | head`): the run goes on quietly.
        Err(e)
            if e.downcast_ref::<std::io::Error>()
                .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            Ok(ExitCode::SUCCESS)
        }
        other => other,
    }
}

fn run(args: ScenarioArgs, out: &mut dyn Write) -> anyhow::Result<ExitCode> {
    if args.list {
        writeln!(out, "Embedded scenarios (ucc scenario NAME):")?;
        for (name, _) in EMBEDDED {
            let s = Scenario::lookup(name)?;
            writeln!(
                out,
                "  {name:<14} {:<9} {:>3} UAV{} {:>5} s  {}",
                s.kind.name(),
                s.uav_count(),
                if s.uav_count() == 1 { " " } else { "s" },
                s.time_limit,
                s.description
            )?;
        }
        writeln!(out, "\nTeam agents (a scenario's [[uav]] agent = NAME):")?;
        for a in TEAM_AGENTS {
            writeln!(out, "  {:<17} {}", a.name, a.description)?;
        }
        return Ok(ExitCode::SUCCESS);
    }
    let name = args.scenario.as_deref().unwrap_or_default();
    let scenario = Scenario::lookup(name)?;
    let catalog = match &args.robots {
        Some(path) => RobotCatalog::from_file(path)?,
        None => RobotCatalog::embedded(),
    };
    let prepared = Prepared::new(scenario, catalog)?;
    let dir = args.log_dir.clone().unwrap_or_else(|| {
        PathBuf::from("ucc-logs").join(format!("scenario-{}", prepared.scenario.name))
    });
    let settings = ScenarioRun {
        iterations: args.iterations as usize,
        seed: args.seed,
        log_dir: Some(dir.clone()),
        pictures: !args.no_pictures,
        threads: args.threads as usize,
        force: args.force,
        record: args.record.clone(),
    };
    let s = &prepared.scenario;
    if !args.quiet {
        writeln!(
            out,
            "scenario {} ({}, {} UAVs, map {}, up to {} s): {} iteration{}",
            s.name,
            s.kind.name(),
            s.uav_count(),
            s.map,
            s.time_limit,
            settings.iterations,
            if settings.iterations == 1 { "" } else { "s" }
        )?;
    }
    let quiet = args.quiet;
    let total = settings.iterations;
    let mut failed: Option<std::io::Error> = None;
    let summary = run_scenario(&prepared, &settings, &mut |p| match p {
        ScenarioProgress::Finished { iteration, outcome } => {
            if !quiet && failed.is_none() {
                let figures: Vec<String> = outcome
                    .metrics
                    .values
                    .iter()
                    .filter_map(|(n, v)| v.map(|v| format!("{n}={}", round(v))))
                    .collect();
                if let Err(e) = writeln!(
                    out,
                    "iteration {iteration}/{total} (seed {}): {}",
                    outcome.seed,
                    figures.join(" ")
                ) {
                    failed = Some(e);
                }
            }
        }
    })
    .context("the scenario")?;
    if let Some(e) = failed {
        return Err(e.into());
    }
    writeln!(
        out,
        "{} iteration{}: {:.0} simulated s in {:.2} wall s ({:.0}x real time)",
        summary.iterations,
        if summary.iterations == 1 { "" } else { "s" },
        summary.simulated,
        summary.wall,
        summary.simulated / summary.wall.max(1e-9)
    )?;
    for (name, mean, n) in &summary.means {
        writeln!(
            out,
            "  {name:<22} {:>10}{}",
            round(*mean),
            if *n < summary.iterations {
                format!("  ({n} of {})", summary.iterations)
            } else {
                String::new()
            }
        )?;
    }
    writeln!(out, "files in {}", dir.display())?;
    Ok(ExitCode::SUCCESS)
}

fn round(v: f64) -> String {
    if v == v.trunc() && v.abs() < 1e12 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}
