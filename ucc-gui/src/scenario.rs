//! Runs a scenario for the page: in this process, on a thread of its own, as `ucc scenario`
//! does (the [`Episode`] owns its world; no server, so a remote USARSim plays no part). The
//! world steps in lockstep with the team agents, paced to the page's speed (× real time or
//! as fast as it can), held while the page is paused; the state goes to the hub at most
//! every [`PUBLISH`] of wall time, and the UAVs' samples every [`TRAIL_EVERY`] simulated
//! seconds besides (whole trails at any speed).

use std::sync::Arc;
use std::time::{Duration, Instant};

use ucc_client::scenario::engine::Episode;
use usar_server::TimeScale;

use crate::hub::scenario::ScenarioPlan;
use crate::hub::{RequestError, Shared, Status};

/// Wall time between two publications of the scenario's state to the hub (≤ 20 Hz).
pub const PUBLISH: Duration = Duration::from_millis(50);
/// Simulated seconds between two samples of the UAVs (their trails).
pub const TRAIL_EVERY: f64 = 0.5;
/// The longest sleep between two checks of the stop and the speed.
const NAP: Duration = Duration::from_millis(50);

/// Starts the scenario's run on a thread of its own.
pub fn spawn(shared: Arc<Shared>, plan: ScenarioPlan) -> Result<(), RequestError> {
    let thread_shared = shared.clone();
    let spawned = std::thread::Builder::new()
        .name(format!("ucc-gui-scenario-{}", plan.prepared.scenario.name))
        .spawn(move || {
            let shared = thread_shared;
            // A defect in an agent or the world ends this run, not the control center.
            let flown =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| fly(&shared, &plan)));
            let (status, error) = match flown {
                Ok(Ok(true)) => (Status::Stopped, None),
                Ok(Ok(false)) => (Status::Done, None),
                Ok(Err(e)) => (Status::Failed, Some(e)),
                Err(_) => (
                    Status::Failed,
                    Some("the scenario's thread panicked (a defect: see the terminal)".into()),
                ),
            };
            let mut hub = shared.lock();
            let line = match (&status, &error) {
                (Status::Stopped, _) => "scenario stopped".to_owned(),
                (_, Some(e)) => format!("scenario failed: {e}"),
                _ => format!("scenario ended: {} iteration(s) done", plan.iterations),
            };
            hub.log(0, if error.is_some() { "error" } else { "info" }, line);
            hub.scenario_finished(status, error);
        });
    if let Err(e) = spawned {
        shared
            .lock()
            .scenario_finished(Status::Failed, Some(format!("cannot start a thread: {e}")));
        return Err(RequestError::State(format!(
            "cannot start a thread for the scenario: {e}"
        )));
    }
    Ok(())
}

/// The speed the page asks for now.
fn current_speed(shared: &Shared) -> Option<TimeScale> {
    shared.lock().scenario.as_ref().map(|s| s.speed)
}

/// Flies the iterations; `Ok(true)` when stopped.
fn fly(shared: &Shared, plan: &ScenarioPlan) -> Result<bool, String> {
    let name = &plan.prepared.scenario.name;
    for i in 0..plan.iterations {
        let iteration = i + 1;
        let seed = plan.seed.wrapping_add(i as u64);
        let mut episode = Episode::new(Arc::clone(&plan.prepared), seed, 1)
            .map_err(|e| format!("iteration {iteration}: {e}"))?;
        shared.lock().scenario_iteration(iteration, seed, &episode);
        let mut logged = 0;
        // The pace: simulated time `sim0` was reached at wall time `wall0`.
        let (mut wall0, mut sim0) = (Instant::now(), episode.time());
        let mut speed = TimeScale::Factor(1.0);
        let mut published = Instant::now();
        let mut next_trail = 0.0;
        loop {
            if plan.cancel.is_cancelled() {
                return Ok(true);
            }
            let ended = episode.step(&[]).is_some();
            let time = episode.time();
            let due = published.elapsed() >= PUBLISH;
            if due || ended || time >= next_trail {
                if time >= next_trail {
                    next_trail = time + TRAIL_EVERY;
                }
                let mut hub = shared.lock();
                hub.scenario_sample(&episode, due || ended);
                for line in &episode.log()[logged..] {
                    hub.log(0, "info", format!("{name} {line}"));
                }
                logged = episode.log().len();
                if due || ended {
                    published = Instant::now();
                }
                // The page's speed, and its pause (the world waits with the run).
                let now = hub.scenario.as_ref().map_or(speed, |s| s.speed);
                if now != speed {
                    speed = now;
                    (wall0, sim0) = (Instant::now(), time);
                }
                if hub.paused {
                    while hub.paused && !plan.cancel.is_cancelled() {
                        hub = shared
                            .resumed
                            .wait_timeout(hub, Duration::from_millis(100))
                            .unwrap_or_else(|e| e.into_inner())
                            .0;
                    }
                    (wall0, sim0) = (Instant::now(), time);
                }
            }
            if ended {
                break;
            }
            if let TimeScale::Factor(k) = speed {
                let target = Duration::from_secs_f64(((time - sim0) / k).clamp(0.0, 1e6));
                // Naps, so that a stop or a new speed is taken within one.
                while !plan.cancel.is_cancelled() {
                    let ahead = target.saturating_sub(wall0.elapsed());
                    if ahead.is_zero() || current_speed(shared) != Some(speed) {
                        break;
                    }
                    std::thread::sleep(ahead.min(NAP));
                }
            }
        }
        let outcome = episode.finish();
        let mut hub = shared.lock();
        let figures: Vec<String> = outcome
            .metrics
            .values
            .iter()
            .filter_map(|(n, v)| v.map(|v| format!("{n}={v:.2}")))
            .collect();
        hub.log(
            0,
            "info",
            format!(
                "{name} iteration {iteration}/{} (seed {seed}): {}",
                plan.iterations,
                figures.join(" ")
            ),
        );
        hub.scenario_row(iteration, &outcome);
    }
    Ok(false)
}
