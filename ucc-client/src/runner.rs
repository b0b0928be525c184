//! The runner: connect, spawn, fly every mission with a fresh agent, write the files, and do
//! it again as many times as asked — [`run`]. It drives the sans-I/O [`Flight`] over a
//! [`Connection`]; the agent comes from an [`AgentFactory`], progress goes to an
//! [`Observer`], and a cancellation token stops it with every file written.
//!
//! Each iteration uses a fresh connection (a second INIT on the same connection would leave
//! the old robot in the world). The flight decides everything said on it — the greeting,
//! the lockstep handshake, the spawn, the time limits (`stream_timeout`, wall clock, for the
//! stream to start and keep flowing; `mission_timeout`, simulated seconds, for each mission):
//! the runner is its I/O loop — it sends what the flight queued, hands it what comes, and
//! sleeps until [`Flight::poll_timeout`].

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use tokio::task::JoinHandle;
use tokio::time::Instant;
use tokio_util::sync::CancellationToken;
use usar_proto::{Command, Nfo, ServerMessage, StartPose};

use crate::agent::AgentFactory;
use crate::camera::ImageClient;
use crate::connection::{Connection, ConnectionError};
pub use crate::error::RunError;
use crate::flight::{Flight, FlightConfig, Phase};
use crate::output::{iteration_files, write_iteration};
use crate::picture::MapPicture;
use crate::progress::{Observer, Progress};
use crate::radio::{Radio, RadioError, Undelivered};
use crate::settings::{CameraSettings, Lockstep, Pictures, RunSettings};
use crate::stats::{IterationStatus, IterationSummary, ResultsTable, Summary};

/// Flies `settings.missions` `settings.iterations` times, each time with a new agent from
/// `agents`; reports progress to `observer`.
///
/// Returns when every iteration ended, at the first failure (unless `keep_going`), or when
/// `cancel` is cancelled: then the iteration in flight is marked interrupted and, like
/// every other, its log, trajectory and pictures are written, then the overlay and the
/// results table ([`Summary::interrupted`] tells).
///
/// An iteration's files are written on a blocking thread while the next iteration flies (one
/// iteration's files at a time); [`Progress::Written`] announces them once they are written,
/// so it may come after the next iteration's first events, and `run` returns only when every
/// file is written.
pub async fn run(
    settings: &RunSettings,
    agents: &dyn AgentFactory,
    observer: &mut dyn Observer,
    cancel: &CancellationToken,
) -> Result<Summary, RunError> {
    if settings.missions.is_empty() {
        return Err(RunError::NoMissions);
    }
    Flight::new(0, settings.flight(), agents.create())?; // refuse a mission before connecting
    settings.init().check().map_err(ConnectionError::from)?; // and a name that breaks a line
    if let Some(dir) = &settings.log_dir {
        std::fs::create_dir_all(dir).map_err(|error| RunError::Output {
            path: dir.clone(),
            error,
        })?;
    }
    let mut summary = Summary::default();
    let mut results = settings.file("results.csv").map(ResultsTable::new);
    let mut lockstep = settings.lockstep;
    let mut failure = None;
    // The files of the last iteration flown, being written.
    let mut writing = None;
    let shared = Arc::new(settings.clone());
    for iteration in 1..=settings.iterations.max(1) {
        if cancel.is_cancelled() {
            summary.interrupted = true;
            break;
        }
        let config = FlightConfig {
            lockstep,
            ..settings.flight()
        };
        let mut flight = Flight::new(iteration, config, agents.create())?;
        let result = tokio::select! {
            r = fly(&mut flight, settings, observer) => Some(r),
            () = cancel.cancelled() => None,
        };
        let (status, last_line) = match result {
            Some(Ok(())) => (IterationStatus::Done, "iteration done".to_owned()),
            None => {
                summary.interrupted = true;
                (
                    IterationStatus::Interrupted,
                    "interrupted: the run was stopped".into(),
                )
            }
            Some(Err(e)) => {
                let status = (
                    IterationStatus::Failed(e.to_string()),
                    format!("iteration failed: {e}"),
                );
                failure = Some(e);
                status
            }
        };
        // The files are written on another thread while the next iteration flies: one
        // iteration's at a time, so the previous one's must be done first (and its row of the
        // results table waits for them).
        written(writing.take(), &mut results, &mut summary, observer).await?;
        // Nothing flown and nothing to fly (no server, an unwritable recording): the error
        // alone, without a failed iteration's report or files that would show nothing.
        if summary.flown == 0
            && !flight.record().connected
            && let Some(e) = failure.take_if(|e| e.is_fatal())
        {
            return Err(e);
        }
        // Without lockstep once, do not wait for it again at every iteration.
        if lockstep == Lockstep::IfOffered && !flight.is_lockstep() {
            lockstep = Lockstep::Off;
        }
        drain(&mut flight, observer);
        let record = flight.into_record();
        let iteration_summary = IterationSummary {
            status,
            missions_done: record.missions_done,
            duration: record.duration(),
            distance: record.distance(),
            simulated_seconds: record.simulated_seconds(),
            trajectory: record.trajectory.clone(),
            files: iteration_files(settings, &record),
            faults: record.faults,
            randomized: record.randomized.clone().unwrap_or_default(),
        };
        let shared = Arc::clone(&shared);
        let files =
            tokio::task::spawn_blocking(move || write_iteration(&shared, &record, &last_line));
        observer.progress(&match &iteration_summary.status {
            IterationStatus::Done => Progress::IterationDone {
                iteration,
                summary: iteration_summary.clone(),
            },
            IterationStatus::Failed(error) => Progress::IterationFailed {
                iteration,
                error: error.clone(),
            },
            IterationStatus::Interrupted => Progress::Interrupted { iteration },
        });
        let deviation = summary.add(
            &iteration_summary,
            settings.kept_iterations,
            settings.pictures != Pictures::None && settings.log_dir.is_some(),
        );
        writing = Some(Writing {
            iteration,
            files,
            row: IterationSummary {
                trajectory: Vec::new(),
                ..iteration_summary
            },
            deviation,
        });
        match failure.take() {
            Some(e) if !settings.keep_going || e.is_fatal() => {
                written(writing.take(), &mut results, &mut summary, observer).await?;
                finish(settings, &mut summary, observer)?;
                return Err(e);
            }
            _ if summary.interrupted => break,
            _ => {}
        }
    }
    written(writing.take(), &mut results, &mut summary, observer).await?;
    finish(settings, &mut summary, observer)?;
    Ok(summary)
}

/// An iteration whose files are being written, with its row of the results table: the row
/// waits for the files, so that it never says `ok` for an iteration whose files were not
/// written.
struct Writing {
    iteration: usize,
    files: JoinHandle<Result<Vec<PathBuf>, RunError>>,
    /// The iteration (without its trajectory).
    row: IterationSummary,
    /// How far its path lies from the first completed iteration's.
    deviation: Option<f64>,
}

/// Waits for the files of an iteration to be written (see `run`), writes its row of the
/// results table (`failed`, with the file that could not be written, if one could not),
/// then announces them. Returns the first failure: the files', else the table's.
async fn written(
    writing: Option<Writing>,
    results: &mut Option<ResultsTable>,
    summary: &mut Summary,
    observer: &mut dyn Observer,
) -> Result<(), RunError> {
    let Some(Writing {
        iteration,
        files,
        mut row,
        deviation,
    }) = writing
    else {
        return Ok(());
    };
    let files = files
        .await
        .unwrap_or_else(|e| std::panic::resume_unwind(e.into_panic()));
    if let Err(e) = &files {
        row.status = IterationStatus::Failed(e.to_string());
    }
    if let Some(table) = results {
        let path = table.path().to_owned();
        match table.row(&row, deviation) {
            Ok(()) => summary.results = Some(path),
            Err(error) => {
                let error = RunError::Output { path, error };
                if files.is_err() {
                    // Both are said: the table is incomplete too.
                    observer.progress(&Progress::Warning {
                        iteration,
                        message: error.to_string(),
                    });
                } else {
                    return Err(error);
                }
            }
        }
    }
    let files = files?;
    if !files.is_empty() {
        observer.progress(&Progress::Written { files });
    }
    Ok(())
}

/// Writes the overlay.
fn finish(
    settings: &RunSettings,
    summary: &mut Summary,
    observer: &mut dyn Observer,
) -> Result<(), RunError> {
    if settings.pictures != Pictures::None
        && summary.flown > 0
        && let Some(base) = settings.file("overlay")
    {
        let n = summary.flown;
        let (paths, left_out) = summary.overlay_paths();
        let picture = MapPicture {
            title: format!(
                "{} — {n} iteration{}{}{}",
                settings.prefix,
                if n == 1 { "" } else { "s" },
                if left_out > 0 {
                    format!(" ({} different paths drawn)", paths.len())
                } else {
                    String::new()
                },
                if summary.interrupted {
                    " (interrupted)"
                } else {
                    ""
                }
            ),
            paths: paths.iter().map(|(p, _)| p.clone()).collect(),
            repeats: paths.iter().map(|(_, n)| *n).collect(),
            waypoints: settings.waypoints(),
            start: summary.start(),
            geometry: settings.map.clone(),
            laser_hits: Vec::new(),
        };
        summary.overlay = picture.write(&base)?.to_vec();
        observer.progress(&Progress::Written {
            files: summary.overlay.clone(),
        });
    }
    Ok(())
}

fn drain(flight: &mut Flight, observer: &mut dyn Observer) {
    while let Some(p) = flight.poll_progress() {
        observer.progress(&p);
    }
}

/// Sends what the flight queued, in one write.
async fn send_all(flight: &mut Flight, conn: &mut Connection) -> Result<(), ConnectionError> {
    let commands: Vec<Command> = std::iter::from_fn(|| flight.poll_command()).collect();
    if commands.is_empty() {
        return Ok(());
    }
    conn.send_all(&commands).await
}

/// One iteration.
async fn fly(
    flight: &mut Flight,
    settings: &RunSettings,
    observer: &mut dyn Observer,
) -> Result<(), RunError> {
    // A failure ends up in the log once, as its last line (`run` writes it).
    let result = fly_inner(flight, settings, observer).await;
    drain(flight, observer);
    result
}

async fn fly_inner(
    flight: &mut Flight,
    settings: &RunSettings,
    observer: &mut dyn Observer,
) -> Result<(), RunError> {
    let iteration = flight.record().iteration;
    let mut conn = match &settings.record {
        Some(path) => {
            let path = record_path(path, iteration);
            Connection::connect_recording(&settings.addr, settings.connect_timeout, &path).await?
        }
        None => Connection::connect(&settings.addr, settings.connect_timeout).await?,
    };
    flight.start(Instant::now().into_std());
    let mut side = Side::default();
    let result = fly_loop(flight, settings, &mut conn, &mut side, observer).await;
    let frames = side.finish(flight, settings).await;
    result?;
    frames?;
    conn.disconnect().await?;
    Ok(())
}

/// The camera and the radio of one flight (when the settings ask for them).
#[derive(Default)]
struct Side {
    image: Option<ImageClient>,
    /// The index of the last frame handed to the flight.
    last_frame: Option<u64>,
    /// Frames handed to the flight.
    frames: u64,
    /// PNG files being written.
    saving: Vec<JoinHandle<Result<PathBuf, RunError>>>,
    radio: Option<Radio>,
    /// The flight's step count when the signals were last asked.
    signals_at: u64,
}

impl Side {
    /// Connects the image client once the flight knows its tile, joins the radio once the
    /// UAV flies; hands frames and messages to the flight; sends what the agent sent.
    async fn serve(&mut self, flight: &mut Flight, settings: &RunSettings) -> Result<(), RunError> {
        if let Some(camera) = &settings.camera {
            if !camera.is_active()
                && let Some(image) = self.image.take()
            {
                let _ = image.close().await;
                self.last_frame = None; // a new connection numbers its frames from 0
            }
            if self.image.is_none()
                && camera.is_active()
                && let Some(request) = flight.camera_request()
            {
                let error = |error: String| RunError::Camera {
                    addr: camera.server.clone(),
                    error,
                };
                let addr = resolve(&camera.server).await.map_err(error)?;
                let client = ImageClient::connect_with(addr, camera.bgr, request)
                    .await
                    .map_err(|e| error(e.to_string()))?;
                self.image = Some(client);
            }
            self.take_frame(flight, settings, camera);
        }
        let Some(radio_settings) = &settings.radio else {
            return Ok(());
        };
        if self.radio.is_none() {
            if flight.phase() != Phase::Flying {
                return Ok(());
            }
            let error = |error: String| RunError::Radio {
                addr: radio_settings.wss.clone(),
                error,
            };
            let addr = resolve(&radio_settings.wss).await.map_err(error)?;
            let radio = Radio::join(addr, &settings.name)
                .await
                .map_err(|e| error(e.to_string()))?;
            flight.log(format!(
                "radio: joined the WSS at {} as {}",
                radio_settings.wss, settings.name
            ));
            self.radio = Some(radio);
        }
        let Some(radio) = &mut self.radio else {
            return Ok(());
        };
        while let Some(message) = radio.try_recv() {
            flight.on_radio(message);
        }
        while let Some(message) = flight.poll_radio() {
            if let Err(e) = radio.send(&message.to, &message.data).await {
                let strength = match &e {
                    RadioError::OutOfRange { strength, .. } => *strength,
                    _ => f64::NAN,
                };
                flight.on_undelivered(Undelivered {
                    message,
                    strength,
                    reason: e.to_string(),
                });
            }
        }
        if flight.steps() > self.signals_at {
            self.signals_at = flight.steps();
            let mut names: Vec<String> = flight.uav().signal.keys().cloned().collect();
            names.extend(radio_settings.peers.iter().cloned());
            names.sort();
            names.dedup();
            for name in names.iter().filter(|n| **n != settings.name) {
                let strength = radio.strength(name).await.unwrap_or(f64::NAN);
                flight.set_signal(name, strength);
            }
        }
        Ok(())
    }

    /// Hands the latest frame to the flight if it is new; writes every N-th as PNG.
    fn take_frame(&mut self, flight: &mut Flight, settings: &RunSettings, camera: &CameraSettings) {
        let Some(frame) = self.image.as_ref().and_then(ImageClient::latest) else {
            return;
        };
        if self.last_frame.is_some_and(|last| frame.index <= last) {
            return;
        }
        self.last_frame = Some(frame.index);
        if !flight.on_image(Arc::clone(&frame)) {
            return;
        }
        self.frames += 1;
        let n = self.frames;
        if camera.save_every == 0 || !(n - 1).is_multiple_of(u64::from(camera.save_every)) {
            return;
        }
        let iteration = flight.record().iteration;
        if let Some(path) = settings.file(&format!("{iteration:02}-frame-{n:05}.png")) {
            self.saving.push(tokio::task::spawn_blocking(move || {
                image::save_buffer(
                    &path,
                    &frame.rgb,
                    frame.width,
                    frame.height,
                    image::ColorType::Rgb8,
                )
                .map_err(|e| RunError::Output {
                    path: path.clone(),
                    error: std::io::Error::other(e),
                })?;
                Ok(path)
            }));
        }
    }

    /// Closes the image client and waits for the frames being written; logs them.
    async fn finish(
        &mut self,
        flight: &mut Flight,
        settings: &RunSettings,
    ) -> Result<(), RunError> {
        if let Some(image) = self.image.take() {
            let _ = image.close().await;
        }
        let mut written = 0;
        let mut first_error = None;
        for saving in self.saving.drain(..) {
            match saving
                .await
                .unwrap_or_else(|e| std::panic::resume_unwind(e.into_panic()))
            {
                Ok(_) => written += 1,
                Err(e) => {
                    first_error.get_or_insert(e);
                }
            }
        }
        if written > 0 {
            let iteration = flight.record().iteration;
            flight.log(format!(
                "camera: {} frame(s) received, {written} written as \
                 {}-{iteration:02}-frame-NNNNN.png",
                self.frames, settings.prefix
            ));
        }
        first_error.map_or(Ok(()), Err)
    }
}

async fn resolve(addr: &str) -> Result<std::net::SocketAddr, String> {
    tokio::net::lookup_host(addr)
        .await
        .map_err(|e| e.to_string())?
        .next()
        .ok_or_else(|| "no address".to_owned())
}

/// The I/O loop: send what the flight queued, serve the camera and the radio, wait for a
/// message until the flight's next deadline, hand it the message or the time-out.
async fn fly_loop(
    flight: &mut Flight,
    settings: &RunSettings,
    conn: &mut Connection,
    side: &mut Side,
    observer: &mut dyn Observer,
) -> Result<(), RunError> {
    loop {
        // The radio first: a step's messages are written, and the signals asked, before
        // the step's `SYNC` goes out, so that in lockstep the WSS takes them at the barrier
        // the world is held at (docs/wss.md), whatever the timing.
        side.serve(flight, settings).await?;
        send_all(flight, conn).await?;
        drain(flight, observer);
        match flight.phase() {
            Phase::Done => break,
            Phase::Failed => {
                return Err(flight.take_error().map_or(
                    RunError::StreamStopped {
                        timeout: settings.stream_timeout,
                    },
                    RunError::from,
                ));
            }
            _ => {}
        }
        let message = match flight.poll_timeout() {
            Some(due) => tokio::time::timeout_at(Instant::from_std(due), conn.next_message())
                .await
                .ok(),
            None => Some(conn.next_message().await),
        };
        // The frames and messages that came meanwhile, before the agent may step.
        side.serve(flight, settings).await?;
        let now = Instant::now().into_std();
        match message {
            Some(message) => flight.handle_message(&message?, now),
            None => flight.handle_timeout(now),
        }
    }
    Ok(())
}

/// The recording file of iteration `n`: `path` for the first, `NAME-n.EXT` for the next.
pub fn record_path(path: &std::path::Path, n: usize) -> PathBuf {
    if n <= 1 {
        return path.to_owned();
    }
    let stem = path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let name = match path.extension() {
        Some(ext) => format!("{stem}-{n}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{n}"),
    };
    path.with_file_name(name)
}

/// Asks the server for the map's start poses (`GETSTARTPOSES`) on a connection of its own.
pub async fn start_poses(addr: &str, timeout: Duration) -> Result<Vec<StartPose>, RunError> {
    let mut conn = Connection::connect(addr, timeout).await?;
    conn.send(&Command::GetStartPoses).await?;
    let reply = tokio::time::timeout(timeout, async {
        loop {
            if let ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) = conn.next_message().await? {
                return Ok::<_, ConnectionError>(poses);
            }
        }
    })
    .await
    .map_err(|_| RunError::NoStartPoses { timeout })??;
    conn.disconnect().await?;
    Ok(reply)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Coordinates;
    use crate::agents;
    use crate::mission::Mission;

    #[test]
    fn each_iteration_records_to_its_own_file() {
        let base = std::path::Path::new("/tmp/run.usarlog");
        assert_eq!(record_path(base, 1), PathBuf::from("/tmp/run.usarlog"));
        assert_eq!(record_path(base, 3), PathBuf::from("/tmp/run-3.usarlog"));
        assert_eq!(
            record_path(std::path::Path::new("log"), 2),
            PathBuf::from("log-2")
        );
    }

    #[tokio::test]
    async fn refuses_before_connecting() {
        let mut settings = RunSettings {
            addr: "127.0.0.1:1".into(),
            ..RunSettings::default()
        };
        let base = || agents::create("base").unwrap();
        let cancel = CancellationToken::new();
        assert!(matches!(
            run(&settings, &base, &mut |_: &Progress| {}, &cancel).await,
            Err(RunError::NoMissions)
        ));
        settings.missions = vec![Mission::Hover { seconds: 1.0 }];
        let avoid = || agents::create("avoid").unwrap();
        let err = run(&settings, &avoid, &mut |_: &Progress| {}, &cancel)
            .await
            .unwrap_err();
        assert!(matches!(err, RunError::Refused(_)), "{err}");
    }

    #[tokio::test]
    async fn no_server() {
        let port = {
            let l = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
            l.local_addr().unwrap().port()
        };
        let settings = RunSettings {
            addr: format!("127.0.0.1:{port}"),
            missions: vec![Mission::goto(Coordinates::zeros())],
            ..RunSettings::default()
        };
        let base = || agents::create("base").unwrap();
        let err = run(
            &settings,
            &base,
            &mut |_: &Progress| {},
            &CancellationToken::new(),
        )
        .await
        .unwrap_err();
        assert!(
            matches!(err, RunError::Connection(ConnectionError::Connect { .. })),
            "{err}"
        );
    }
}
