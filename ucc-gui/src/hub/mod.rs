//! The state the page shows, owned by the Rust side: the server, every UAV with its
//! settings, missions, live state, trails, plots, log and files.
//!
//! The page only renders it and sends [`Request`]s. Three parts, one job each:
//! * this module: the state and what the runs report into it ([`Hub::sample`],
//!   [`Hub::new_iteration`], [`Hub::written`], [`Hub::finished`], [`Hub::log`]);
//! * [`request`]: one function per request kind, which checks the request and changes the
//!   state or plans what to do outside the lock ([`Action`]), or answers a [`RequestError`];
//! * [`update`]: what a page is sent, only what changed since its [`Cursor`].
//!
//! Nothing here starts a run or touches a socket: `runs` and `socket` use the hub, never
//! the other way round.

mod live;
pub mod request;
pub mod scenario;
pub mod update;

use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use serde::Serialize;
use tokio_util::sync::CancellationToken;
use usar_server::TimeScale;

pub use live::Live;
pub use request::{Action, Request, RequestError};
pub use scenario::{ScenarioCursor, ScenarioView};
pub use update::Cursor;

/// Points kept of one iteration's trail (older points are thinned out beyond this).
const MAX_TRAIL: usize = 20_000;
/// A new trail point is kept when the UAV has moved at least this far (metres).
const TRAIL_STEP: f32 = 0.05;
/// Points kept of a past iteration's trail (the overlay).
const MAX_PAST_POINTS: usize = 1_000;
/// Past iterations kept for the overlay; beyond it the older half goes.
const MAX_PAST: usize = 100;
/// Samples kept for the plots of one iteration.
const MAX_HISTORY: usize = 5_000;
/// Log lines kept, all UAVs: the newest, for new pages and "Save log" (about 0.7 MiB). The
/// complete log of a run is its log files (`PREFIX-NN.log`, with "write files" on).
const MAX_LOG: usize = 5_000;
/// Laser hits kept per UAV (the map of a real USARSim).
const MAX_HITS: usize = 20_000;

/// Where a UAV's run stands.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Created, not flying.
    Idle,
    /// Flying.
    Running,
    /// Stop asked, finishing the files.
    Stopping,
    /// Every iteration ended.
    Done,
    /// Stopped by the user.
    Stopped,
    /// Failed.
    Failed,
}

/// One line of a UAV's log.
#[derive(Debug, Clone, Serialize)]
pub struct LogLine {
    /// Increasing over the whole hub.
    pub seq: u64,
    /// `info`, `warn` or `error`.
    pub level: &'static str,
    /// The UAV.
    pub uav: u32,
    /// The text.
    pub text: String,
}

/// One UAV.
#[derive(Debug)]
pub struct Uav {
    /// Its id in this hub.
    pub id: u32,
    /// Name in the world.
    pub name: String,
    /// Robot class.
    pub robot: String,
    /// Agent name.
    pub agent: String,
    /// Start pose or tag, as given.
    pub start: ucc_client::Start,
    /// Missions, flown in order.
    pub missions: Vec<ucc_client::Mission>,
    /// Iterations asked for the current or last run.
    pub iterations: usize,
    /// File prefix.
    pub prefix: String,
    /// Pictures to draw.
    pub pictures: ucc_client::Pictures,
    /// Write files.
    pub autosave: bool,
    /// The run's state.
    pub status: Status,
    /// The last error.
    pub error: Option<String>,
    /// The iteration flying (or last flown), 1-based; 0 before the first.
    pub iteration: usize,
    /// The mission being flown (0-based).
    pub active: Option<usize>,
    /// The latest state.
    pub live: Option<Live>,
    /// Samples received (a page is sent `live` when it changed).
    pub samples: u64,
    /// This iteration's trail, `[x, y, z]`.
    pub trail: Vec<[f32; 3]>,
    /// Bumped when `trail` starts over (a new iteration).
    pub trail_epoch: u64,
    /// Earlier iterations' trails (bounded: [`MAX_PAST`] of [`MAX_PAST_POINTS`] points).
    pub past: Vec<Vec<[f32; 3]>>,
    /// Bumped when `past` is cleared or thinned.
    pub past_epoch: u64,
    /// `[t, altitude, speed, battery]` for the plots.
    pub history: Vec<[f32; 4]>,
    /// What the laser hit, `[x, y]` (the map of a real USARSim).
    pub hits: Vec<[f32; 2]>,
    /// Files written by the runs, each once, in the order first written.
    pub files: Vec<PathBuf>,
    /// The same, to keep them unique.
    files_seen: HashSet<PathBuf>,
    /// Bumped when `files` changes.
    pub files_version: u64,
    /// Cancels the run.
    pub cancel: Option<CancellationToken>,
    /// Bumped whenever what `info` shows changes (name, status, missions, options…): a
    /// page is sent `info` again only then.
    pub info_version: u64,
    /// Whether its run reads camera frames now: while a page shows its camera panel
    /// (`/api/camera/ID`, asked at least every [`CAMERA_IDLE`]).
    pub camera_on: Arc<AtomicBool>,
    /// When a page last asked for its camera frame.
    pub camera_asked: Option<Instant>,
    /// The latest camera frame.
    pub frame: Option<Arc<ucc_client::camera::CameraImage>>,
}

/// A camera panel not asked for this long is taken as closed: the run stops reading frames.
pub const CAMERA_IDLE: Duration = Duration::from_secs(2);

impl Uav {
    fn new(
        id: u32,
        name: String,
        prefix: String,
        robot: String,
        agent: String,
        start: ucc_client::Start,
    ) -> Self {
        Self {
            id,
            prefix,
            name,
            robot,
            agent,
            start,
            missions: Vec::new(),
            iterations: 1,
            pictures: ucc_client::Pictures::All,
            autosave: true,
            status: Status::Idle,
            error: None,
            iteration: 0,
            active: None,
            live: None,
            samples: 0,
            trail: Vec::new(),
            trail_epoch: 0,
            past: Vec::new(),
            past_epoch: 0,
            history: Vec::new(),
            hits: Vec::new(),
            files: Vec::new(),
            files_seen: HashSet::new(),
            files_version: 0,
            cancel: None,
            info_version: 1,
            camera_on: Arc::default(),
            camera_asked: None,
            frame: None,
        }
    }

    /// A page asks for the camera frame: the run reads frames (again); the latest one.
    pub fn camera_frame(&mut self) -> Option<Arc<ucc_client::camera::CameraImage>> {
        self.camera_asked = Some(Instant::now());
        self.camera_on.store(true, Ordering::Relaxed);
        self.frame.clone()
    }

    /// A new camera frame; stops the frames when no page asked for them lately.
    pub fn camera_sample(&mut self, frame: Option<&Arc<ucc_client::camera::CameraImage>>) {
        if let Some(frame) = frame {
            self.frame = Some(Arc::clone(frame));
        }
        if self.camera_asked.is_none_or(|t| t.elapsed() > CAMERA_IDLE) {
            self.camera_on.store(false, Ordering::Relaxed);
        }
    }

    /// Marks `info` changed.
    pub fn touch(&mut self) {
        self.info_version += 1;
    }

    /// Whether its run is under way.
    pub fn flying(&self) -> bool {
        matches!(self.status, Status::Running | Status::Stopping)
    }
}

/// Everything the page shows.
#[derive(Debug)]
pub struct Hub {
    /// `host:port` of the server.
    pub addr: String,
    /// The image server of the local server (camera frames for the camera panel).
    pub image_server: Option<String>,
    /// The local server's robot classes that have a camera (`Package.Class`).
    pub camera_classes: Vec<String>,
    /// Whether the server runs in this process (time scale, lockstep, map geometry).
    pub local: bool,
    /// The local server's time scale.
    pub time_scale: TimeScale,
    /// Every flight holds while set.
    pub paused: bool,
    /// The map's solids (local server).
    pub geometry: Option<ucc_client::picture::MapGeometry>,
    /// The map's name.
    pub map: String,
    /// The UAVs.
    pub uavs: Vec<Uav>,
    /// File prefixes that UAVs wrote files under and no longer use (the UAV was removed or
    /// took another prefix): (UAV id, its name, the prefix). No UAV may take them, so no
    /// file of this session is written over.
    retired: Vec<(u32, String, String)>,
    /// Where runs write their files.
    pub log_dir: PathBuf,
    /// The robot classes of a local server (`None`: not known, any class may be asked for).
    pub robot_classes: Option<Vec<String>>,
    /// The log, all UAVs, in order.
    pub log: std::collections::VecDeque<LogLine>,
    /// The scenario shown (the last one started), with its UAVs among `uavs`.
    pub scenario: Option<ScenarioView>,
    /// The robot classes scenarios fly (the local server's, else the embedded ones).
    pub catalog: usar_server::sim::RobotCatalog,
    scenario_epoch: u64,
    next_id: u32,
    next_seq: u64,
}

/// The hub and the condition a paused flight waits on: what the runs, the sockets and the
/// HTTP handlers share.
#[derive(Debug)]
pub struct Shared {
    /// The state.
    pub hub: Mutex<Hub>,
    /// Signalled when the pause ends.
    pub resumed: Condvar,
}

impl Shared {
    /// Shares `hub`.
    pub fn new(hub: Hub) -> Self {
        Self {
            hub: Mutex::new(hub),
            resumed: Condvar::new(),
        }
    }

    /// Locks the hub (a poisoned lock is taken over: the state stays usable).
    pub fn lock(&self) -> MutexGuard<'_, Hub> {
        self.hub.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl Hub {
    /// A hub for the server at `addr`.
    pub fn new(addr: String, local: bool, log_dir: PathBuf) -> Self {
        Self {
            addr,
            image_server: None,
            camera_classes: Vec::new(),
            local,
            time_scale: TimeScale::Factor(1.0),
            paused: false,
            geometry: None,
            map: String::new(),
            uavs: Vec::new(),
            retired: Vec::new(),
            log_dir,
            robot_classes: None,
            log: Default::default(),
            scenario: None,
            catalog: usar_server::sim::RobotCatalog::embedded(),
            scenario_epoch: 0,
            next_id: 1,
            next_seq: 1,
        }
    }

    /// The UAV with this id.
    pub fn uav(&mut self, id: u32) -> Result<&mut Uav, RequestError> {
        self.uavs
            .iter_mut()
            .find(|u| u.id == id)
            .ok_or(RequestError::NoUav(id))
    }

    /// Appends a line to a UAV's log (0: the control center's own).
    pub fn log(&mut self, uav: u32, level: &'static str, text: String) {
        let seq = self.next_seq;
        self.next_seq += 1;
        self.log.push_back(LogLine {
            seq,
            level,
            uav,
            text,
        });
        while self.log.len() > MAX_LOG {
            self.log.pop_front();
        }
    }

    /// Whether any UAV is flying.
    pub fn busy(&self) -> bool {
        self.uavs.iter().any(Uav::flying)
    }

    /// A new state sample of a UAV: the live panel, the trail, the plots, the laser's hits.
    pub fn sample(&mut self, uav: u32, iteration: usize, live: Live) {
        let Ok(u) = self.uav(uav) else { return };
        if u.iteration != iteration {
            u.iteration = iteration;
            u.touch();
        }
        u.samples += 1;
        if let Some(p) = live.position {
            let point = [p[0] as f32, p[1] as f32, p[2] as f32];
            let moved = u.trail.last().is_none_or(|q| {
                let d = [point[0] - q[0], point[1] - q[1], point[2] - q[2]];
                d[0] * d[0] + d[1] * d[1] + d[2] * d[2] >= TRAIL_STEP * TRAIL_STEP
            });
            if moved {
                if u.trail.len() >= MAX_TRAIL {
                    // Keep every other point: the trail stays whole, only coarser.
                    u.trail = u.trail.iter().copied().step_by(2).collect();
                    u.trail_epoch += 1;
                }
                u.trail.push(point);
            }
            if u.history.len() >= MAX_HISTORY {
                u.history = u.history.iter().copied().step_by(2).collect();
                u.trail_epoch += 1;
            }
            let speed = live
                .velocity
                .map_or(0.0, |v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt());
            u.history.push([
                live.time as f32,
                -p[2] as f32,
                speed as f32,
                live.battery.map_or(f32::NAN, |b| b.0 as f32),
            ]);
            if u.hits.len() < MAX_HITS {
                u.hits
                    .extend(live.hits.iter().map(|h| [h[0] as f32, h[1] as f32]));
            }
        }
        u.live = Some(live);
    }

    /// A new iteration began: the last one's trail goes to the overlay (thinned), and the
    /// overlay keeps at most [`MAX_PAST`] iterations.
    pub fn new_iteration(&mut self, uav: u32, iteration: usize) {
        let Ok(u) = self.uav(uav) else { return };
        if !u.trail.is_empty() {
            let trail = std::mem::take(&mut u.trail);
            let step = trail.len().div_ceil(MAX_PAST_POINTS).max(1);
            let mut thinned: Vec<_> = trail.iter().copied().step_by(step).collect();
            if let Some(last) = trail.last()
                && thinned.last() != Some(last)
            {
                thinned.push(*last);
            }
            u.past.push(thinned);
            if u.past.len() > MAX_PAST {
                u.past.drain(..MAX_PAST / 2);
                u.past_epoch += 1;
            }
        }
        u.history.clear();
        u.trail_epoch += 1;
        u.iteration = iteration;
        u.active = None;
        u.touch();
    }

    /// A UAV's agent started its mission `index` (0-based).
    pub fn mission_started(&mut self, uav: u32, index: usize) {
        let Ok(u) = self.uav(uav) else { return };
        u.active = Some(index);
        u.touch();
    }

    /// A run wrote these files (a file written again is listed once).
    pub fn written(&mut self, uav: u32, files: &[PathBuf]) {
        let Ok(u) = self.uav(uav) else { return };
        for f in files {
            if u.files_seen.insert(f.clone()) {
                u.files.push(f.clone());
                u.files_version += 1;
            }
        }
    }

    /// The run of a UAV ended.
    pub fn finished(&mut self, uav: u32, status: Status, error: Option<String>) {
        let Ok(u) = self.uav(uav) else { return };
        u.status = status;
        u.error = error;
        u.cancel = None;
        u.active = None;
        u.touch();
    }

    /// A UAV's log as text, filtered by level (`""` for all).
    pub fn log_text(&self, uav: Option<u32>, level: &str) -> String {
        let mut out = String::new();
        for line in self
            .log
            .iter()
            .filter(|l| uav.is_none_or(|u| l.uav == u) && level_passes(l.level, level))
        {
            let name = self
                .uavs
                .iter()
                .find(|u| u.id == line.uav)
                .map_or("ucc", |u| u.name.as_str());
            out.push_str(&format!("{name} {} {}\n", line.level, line.text));
        }
        out
    }
}

/// Whether a line of `level` passes the filter `min` (`""`, `info`, `warn`, `error`).
pub fn level_passes(level: &str, min: &str) -> bool {
    let rank = |l: &str| match l {
        "error" => 2,
        "warn" => 1,
        _ => 0,
    };
    min.is_empty() || rank(level) >= rank(min)
}
