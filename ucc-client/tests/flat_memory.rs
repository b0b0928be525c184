//! A long loop of iterations keeps the run's memory flat (issue 26, item 10): the summary of
//! a run keeps running figures, not every iteration's trajectory. Checked by the process's
//! peak resident memory (this file holds one test, so the process is its alone).

use ucc_client::record::TrajectoryPoint;
use ucc_client::{Coordinates, IterationStatus, IterationSummary, RunSettings, Summary};

/// Peak resident memory of this process, KiB (Linux).
fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// An iteration that flew a zigzag of `points` samples, a little different every time (so
/// that neither simplification nor sharing equal paths hides it).
fn iteration(n: usize, points: usize) -> IterationSummary {
    let trajectory: Vec<TrajectoryPoint> = (0..points)
        .map(|i| TrajectoryPoint {
            time: i as f64 * 0.1,
            position: Coordinates::new(
                i as f64 * 0.1,
                if i % 2 == 0 { 0.5 } else { -0.5 } + n as f64 * 1e-3,
                -1.0,
            ),
            orientation: Some(Coordinates::zeros()),
            velocity: Some(Coordinates::zeros()),
            battery: Some(1.0),
        })
        .collect();
    IterationSummary {
        status: if n.is_multiple_of(7) {
            IterationStatus::Failed("mission 1 timed out".into())
        } else {
            IterationStatus::Done
        },
        missions_done: 1,
        duration: 30.0,
        distance: 40.0 + n as f64 * 1e-3,
        simulated_seconds: points as f64 * 0.1,
        trajectory,
        files: vec!["UCCLOG-01.log".into(), "UCCLOG-01-trajectory.csv".into()],
        faults: 0,
        randomized: String::new(),
    }
}

#[test]
fn twenty_thousand_iterations_keep_the_summary_flat() {
    let Some(_) = peak_rss_kib() else {
        eprintln!("no /proc/self/status: skipped");
        return;
    };
    let keep = RunSettings::default().kept_iterations;
    let mut summary = Summary::default();
    // Each trajectory is 20 samples (about 2 KiB): before, the summary kept all of them,
    // 20,000 iterations about 40 MiB.
    let (warm_up, total, points) = (2_000, 20_000, 20);
    for n in 0..warm_up {
        summary.add(&iteration(n, points), keep, true);
    }
    let before = peak_rss_kib().unwrap();
    for n in warm_up..total {
        summary.add(&iteration(n, points), keep, true);
    }
    let after = peak_rss_kib().unwrap();
    let grown = after.saturating_sub(before);
    assert!(
        grown < 8 * 1024,
        "peak memory grew {grown} KiB over {} iterations (from {before} KiB)",
        total - warm_up
    );
    // Nothing counted is lost.
    let s = summary.statistics();
    assert_eq!(summary.flown, total);
    assert_eq!(s.failed, total.div_ceil(7));
    assert_eq!(s.completed, total - s.failed);
    assert_eq!(summary.missions_done, total);
    assert_eq!(summary.files_written, 2 * total);
    assert!((s.simulated_seconds - total as f64 * 2.0).abs() < 1e-3);
    assert!((s.duration.0 - 30.0).abs() < 1e-9 && s.duration.1 < 1e-6);
    assert_eq!(summary.iterations.len(), keep);
    assert_eq!(summary.first_error.as_deref(), Some("mission 1 timed out"));
    // The first completed path is iteration 1's; the last completed one (19,998; 19,999
    // failed) lies 19.997 m beside it.
    assert!(
        (s.max_deviation - 19.997).abs() < 1e-6,
        "{}",
        s.max_deviation
    );
}
