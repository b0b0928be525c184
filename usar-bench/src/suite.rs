//! `usar-bench --suite`: the headline benchmarks, each run three times, with the machine and
//! its load, into a table and a JSON file; `--compare` flags a slower tick against an earlier
//! file of the same machine.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context;
use clap::Parser;
use serde_json::{Value, json};

use super::{Args, Report, SimCost, quantile, run_once, sim_only};

/// Runs of each benchmark.
const RUNS: usize = 3;

/// A wall-clock figure more than this much worse than the same machine's previous run
/// (medians of three) is flagged: runs on a shared machine vary by ±10–15 %.
pub(crate) const WALL_MARGIN: f64 = 0.25;
/// A counted figure (allocations per tick: the same in every run of the same code) more
/// than this much higher is flagged.
pub(crate) const COUNT_MARGIN: f64 = 0.01;

/// The figures watched by `--compare`: name, whether lower is better, margin.
const WATCHED: &[(&str, bool, f64)] = &[
    ("tick_mean_us", true, WALL_MARGIN),
    ("tick_p99_us", true, WALL_MARGIN),
    ("thread_cpu_p50_us", true, WALL_MARGIN),
    ("allocations_per_tick", true, COUNT_MARGIN),
    ("real_time_factor", false, WALL_MARGIN),
];

/// The benchmarks: a title and the arguments a user would pass to reproduce one run.
fn cases(quick: bool) -> Vec<(&'static str, &'static str)> {
    if quick {
        return vec![
            (
                "world alone, 500 stsAirRobots",
                "--sim-only --map city --spacing 1.4 --uavs 500 --seconds 1",
            ),
            (
                "world alone, 200 stsQuadrotors",
                "--sim-only --map city --spacing 1.5 --uavs 200 --seconds 1 --robot stsQuadrotor",
            ),
            (
                "TCP, 50 stsAirRobots at real time",
                "--map city --spacing 1.5 --uavs 50 --seconds 3",
            ),
            (
                "TCP, one stsAirRobot as fast as it goes",
                "--uavs 1 --time-scale max --seconds 100",
            ),
        ];
    }
    vec![
        (
            "world alone, 10,000 stsAirRobots",
            "--sim-only --map city --spacing 1.4 --uavs 10000 --seconds 2",
        ),
        (
            "world alone, 10,000 stsAirRobots, one sensor thread",
            "--sim-only --map city --spacing 1.4 --uavs 10000 --seconds 2 --threads 1",
        ),
        (
            "world alone, 5000 stsQuadrotors",
            "--sim-only --map city --spacing 1.5 --uavs 5000 --seconds 2 --robot stsQuadrotor",
        ),
        (
            "TCP, 4000 stsAirRobots at real time",
            "--map city --spacing 1.5 --uavs 4000 --seconds 10",
        ),
        (
            "TCP, one stsAirRobot as fast as it goes",
            "--uavs 1 --time-scale max --seconds 1000",
        ),
    ]
}

/// The figures of one --sim-only run.
fn sim_figures(c: &SimCost) -> BTreeMap<&'static str, f64> {
    BTreeMap::from([
        ("tick_mean_us", c.tick),
        ("tick_p50_us", c.p50),
        ("tick_p99_us", c.p99),
        ("tick_p999_us", c.p999),
        ("tick_max_us", c.max),
        ("real_time_factor", c.rtf),
        ("cpu_us_per_tick", c.cpu),
        ("allocations_per_tick", c.allocations),
        ("kib_per_idle_robot", c.memory),
        ("thread_cpu_p50_us", c.cpu_p50),
        ("thread_cpu_p999_us", c.cpu_p999),
        ("thread_cpu_max_us", c.cpu_max),
        ("bytes_per_tick_p50", c.bytes_p50),
        ("bytes_per_tick_max", c.bytes_max),
    ])
}

/// The figures of one run over TCP.
fn tcp_figures(r: &Report) -> BTreeMap<&'static str, f64> {
    let mut figures = BTreeMap::from([
        ("real_time_factor", r.real_time_factor),
        ("messages_per_second", r.messages_per_second),
        (
            "delivered_min_percent",
            r.delivered.values().copied().fold(f64::MAX, f64::min) * 100.0,
        ),
    ]);
    for (name, value) in [
        ("drive_latency_p50_ms", r.latency_ms_p50),
        ("drive_latency_p99_ms", r.latency_ms_p99),
        ("server_cpu_s", r.server_cpu_seconds),
        ("server_peak_mib", r.server_peak_rss_mib),
    ] {
        if let Some(value) = value {
            figures.insert(name, value);
        }
    }
    figures
}

/// The machine: CPU model and cores (from /proc/cpuinfo and the scheduler).
fn machine() -> Value {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into());
    json!({ "cpu": cpu, "cores": usar_sim::default_threads() })
}

/// The load average over 1, 5 and 15 minutes (empty where /proc/loadavg is missing).
fn load() -> Vec<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| {
            s.split_whitespace()
                .take(3)
                .filter_map(|v| v.parse().ok())
                .collect()
        })
        .unwrap_or_default()
}

/// Now as `YYYY-MM-DDTHH:MM:SSZ` (UTC).
fn now_utc() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let (days, rest) = (secs / 86_400, secs % 86_400);
    // Howard Hinnant's civil_from_days.
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rest / 3600,
        rest / 60 % 60,
        rest % 60
    )
}

/// Runs the suite, prints its table, writes `out` and compares with `previous`.
pub(crate) fn suite(args: &Args) -> anyhow::Result<()> {
    let quick = args.quick;
    let size = if quick { "quick" } else { "full" };
    let build = if cfg!(debug_assertions) {
        "debug"
    } else {
        "release"
    };
    let machine = machine();
    let load_before = load();
    let date = now_utc();
    let began = std::time::Instant::now();
    say!(
        "usar-bench --suite{}: {} runs of each benchmark, {build} build, {date}",
        if quick { " --quick" } else { "" },
        RUNS
    );
    say!(
        "machine: {}, {} cores; load average before: {:?}",
        machine["cpu"].as_str().unwrap_or("unknown"),
        machine["cores"],
        load_before
    );
    let runtime = tokio::runtime::Runtime::new()?;
    let mut results = Vec::new();
    for (title, line) in cases(quick) {
        let command = format!("usar-bench {line}");
        say!("\n== {title}: {command}");
        let mut case = Args::try_parse_from(command.split_whitespace())
            .with_context(|| format!("the suite's own command {command:?}"))?;
        case.server_bin = args.server_bin.clone();
        let mut runs = Vec::new();
        for _ in 0..RUNS {
            let figures = if case.sim_only {
                sim_figures(&sim_only(&case)?)
            } else {
                let report = runtime.block_on(run_once(&case, case.uavs))?;
                super::print(&case, &report);
                tcp_figures(&report)
            };
            runs.push(figures);
        }
        let summary = summarize(&runs);
        say!(
            "{:<24} {:>12} {:>12} {:>12}",
            "figure",
            "min",
            "median",
            "max"
        );
        for (name, [min, median, max]) in &summary {
            say!("{name:<24} {min:>12.2} {median:>12.2} {max:>12.2}");
        }
        results.push(json!({
            "title": title,
            "command": command,
            "runs": runs,
            "min_median_max": summary,
        }));
    }
    let load_after = load();
    say!(
        "\nload average after: {load_after:?}; the suite took {:.0} s",
        began.elapsed().as_secs_f64()
    );
    let report = json!({
        "suite": size,
        "date": date,
        "build": build,
        "machine": machine,
        "load_average_before": load_before,
        "load_average_after": load_after,
        "seconds": began.elapsed().as_secs_f64(),
        "benchmarks": results,
    });
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    std::fs::write(&args.out, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    say!("written: {}", args.out.display());
    if let Some(previous) = &args.compare {
        compare(&report, previous);
    }
    Ok(())
}

/// Min, median and max of each figure over the runs.
fn summarize(runs: &[BTreeMap<&'static str, f64>]) -> BTreeMap<&'static str, [f64; 3]> {
    let mut summary = BTreeMap::new();
    for name in runs.iter().flat_map(|r| r.keys()) {
        let mut values: Vec<f64> = runs.iter().filter_map(|r| r.get(name).copied()).collect();
        values.sort_by(f64::total_cmp);
        let stat = [values[0], quantile(&values, 0.5), values[values.len() - 1]];
        summary.insert(*name, stat);
    }
    summary
}

/// Prints a `SLOWER` line for each watched figure whose median is worse than in the file
/// `previous` by more than its margin, when that file is of the same machine, build and
/// size. Never an error: a missing or different file is one line saying so.
fn compare(now: &Value, previous: &Path) {
    let before = match std::fs::read_to_string(previous)
        .map_err(anyhow::Error::from)
        .and_then(|text| Ok(serde_json::from_str::<Value>(&text)?))
    {
        Ok(before) => before,
        Err(error) => {
            say!(
                "compare: no previous run to compare with ({}: {error})",
                previous.display()
            );
            return;
        }
    };
    let key = |v: &Value| (v["machine"].clone(), v["build"].clone(), v["suite"].clone());
    if key(&before) != key(now) {
        say!(
            "compare: {} is of another machine, build or size ({} {} {}); not compared",
            previous.display(),
            before["machine"],
            before["build"],
            before["suite"]
        );
        return;
    }
    let mut flagged = 0;
    let empty = Vec::new();
    let benchmarks = |v: &Value| v["benchmarks"].as_array().cloned().unwrap_or_default();
    let old = benchmarks(&before);
    for bench in benchmarks(now) {
        let Some(was) = old.iter().find(|b| b["command"] == bench["command"]) else {
            continue;
        };
        for &(name, lower_is_better, margin) in WATCHED {
            let median = |v: &Value| {
                v["min_median_max"][name]
                    .as_array()
                    .unwrap_or(&empty)
                    .get(1)?
                    .as_f64()
            };
            let (Some(now), Some(then)) = (median(&bench), median(was)) else {
                continue;
            };
            let worse = if lower_is_better {
                now > then * (1.0 + margin)
            } else {
                now < then * (1.0 - margin)
            };
            let change = (now / then - 1.0) * 100.0;
            if worse {
                flagged += 1;
                say!(
                    "SLOWER: {}: {name} {now:.2} against {then:.2} on {} ({change:+.0} %, margin {:.0} %)",
                    bench["title"].as_str().unwrap_or("?"),
                    before["date"].as_str().unwrap_or("the previous run"),
                    margin * 100.0
                );
            }
        }
    }
    say!(
        "compare: {flagged} figure(s) worse than on {} by more than their margin \
         (wall clock {:.0} %, allocations {:.0} %){}",
        before["date"].as_str().unwrap_or("the previous run"),
        WALL_MARGIN * 100.0,
        COUNT_MARGIN * 100.0,
        if flagged > 0 {
            " — flagged, not failed: check the load average"
        } else {
            ""
        }
    );
}
