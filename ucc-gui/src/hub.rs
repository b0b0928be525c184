//! The state the page shows, owned by the Rust side: the server, every UAV with its
//! settings, missions, live state, trails, plots, log and files. The page only renders it and
//! sends [`Request`]s; [`Hub::apply`] checks each one and answers bad input with a message.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use tokio_util::sync::CancellationToken;

use crate::flight::{self, Live};

/// Points kept of one iteration's trail (older points are thinned out beyond this).
const MAX_TRAIL: usize = 20_000;
/// Samples kept for the plots of one iteration.
const MAX_HISTORY: usize = 5_000;
/// Log lines kept per UAV.
const MAX_LOG: usize = 20_000;
/// Laser hits kept per UAV (the map of a real USARSim).
const MAX_HITS: usize = 20_000;

/// A request from the page, as JSON: `{"op": "create", ...}`. Numbers come as the text the
/// user typed, so that the Rust side says what is wrong with them.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum Request {
    /// Use the server at `host:port` (checked by connecting).
    Connect {
        /// Host name or address.
        host: String,
        /// Port, as typed.
        port: String,
    },
    /// Restart the local server at this speed: `1`, `2`, … (× real time) or `max`.
    Speed {
        /// As typed.
        value: String,
    },
    /// Pause or resume every flight.
    Pause {
        /// Pause (`true`) or resume.
        paused: bool,
    },
    /// Create a UAV.
    Create {
        /// Robot class.
        robot: String,
        /// Agent name.
        agent: String,
        /// Start pose `x,y,z[,roll,pitch,yaw]` or a PlayerStart tag.
        start: String,
        /// Name in the world (empty: `UAVn`).
        #[serde(default)]
        name: String,
    },
    /// Remove an idle UAV.
    Remove {
        /// The UAV.
        uav: u32,
    },
    /// Add a mission to a UAV.
    AddMission {
        /// The UAV.
        uav: u32,
        /// `GotoXyz` or `Hover`.
        kind: String,
        /// x, as typed (GotoXyz).
        #[serde(default)]
        x: String,
        /// y, as typed (GotoXyz).
        #[serde(default)]
        y: String,
        /// z, as typed (GotoXyz).
        #[serde(default)]
        z: String,
        /// Seconds, as typed (Hover).
        #[serde(default)]
        seconds: String,
    },
    /// Remove mission `index` (0-based) of a UAV.
    RemoveMission {
        /// The UAV.
        uav: u32,
        /// 0-based.
        index: usize,
    },
    /// The logging options of a UAV.
    Options {
        /// The UAV.
        uav: u32,
        /// File name prefix.
        prefix: String,
        /// `all`, `overlay` or `none`.
        pictures: String,
        /// Write the logs and pictures (autosave).
        autosave: bool,
    },
    /// Fly a UAV's missions `iterations` times.
    Start {
        /// The UAV.
        uav: u32,
        /// As typed.
        iterations: String,
    },
    /// Stop a UAV's run (its files are written).
    Stop {
        /// The UAV.
        uav: u32,
    },
    /// End the control center: stop every run (their files are written) and the server.
    Quit,
    /// Which UAV this page shows in detail (laser beams, sonar cones, sensors).
    Select {
        /// The UAV.
        uav: u32,
    },
}

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
    /// This iteration's trail, `[x, y, z]`.
    pub trail: Vec<[f32; 3]>,
    /// Bumped when `trail` starts over (a new iteration).
    pub trail_epoch: u64,
    /// Earlier iterations' trails.
    pub past: Vec<Vec<[f32; 3]>>,
    /// Bumped when `past` is cleared (a new run).
    pub past_epoch: u64,
    /// `[t, altitude, speed, battery]` for the plots.
    pub history: Vec<[f32; 4]>,
    /// What the laser hit, `[x, y]` (the map of a real USARSim).
    pub hits: Vec<[f32; 2]>,
    /// Files written by the runs.
    pub files: Vec<PathBuf>,
    /// Cancels the run.
    pub cancel: Option<CancellationToken>,
}

/// What a page has already received, so that each update carries only what is new.
#[derive(Debug, Default, Clone)]
pub struct Cursor {
    uavs: std::collections::HashMap<u32, UavCursor>,
    log_seq: u64,
    /// The UAV shown in detail.
    pub selected: Option<u32>,
}

#[derive(Debug, Default, Clone, Copy)]
struct UavCursor {
    epoch: u64,
    past_epoch: u64,
    trail: usize,
    past: usize,
    history: usize,
    hits: usize,
}

/// Everything the page shows.
#[derive(Debug)]
pub struct Hub {
    /// `host:port` of the server.
    pub addr: String,
    /// Whether the server runs in this process (speed control, lockstep, map geometry).
    pub local: bool,
    /// The local server's speed, as shown.
    pub speed: String,
    /// Every flight waits while set.
    pub paused: bool,
    /// The map's solids (local server).
    pub geometry: Option<ucc_client::picture::MapGeometry>,
    /// The map's name.
    pub map: String,
    /// The UAVs.
    pub uavs: Vec<Uav>,
    /// Where runs write their files.
    pub log_dir: PathBuf,
    /// The robot classes of a local server (`None`: not known, any class may be asked for).
    pub robot_classes: Option<Vec<String>>,
    /// The log, all UAVs, in order.
    pub log: std::collections::VecDeque<LogLine>,
    next_id: u32,
    next_seq: u64,
}

/// What [`Hub::apply`] asks the caller to do outside the lock.
#[derive(Debug)]
pub enum Action {
    /// Nothing more.
    None,
    /// A UAV was created (tell the page which).
    Created(u32),
    /// Check the server and switch to it.
    Connect(String),
    /// Restart the local server at this speed.
    Speed(String),
    /// End the control center.
    Quit,
    /// Start this UAV's run with these settings.
    Start(u32, Box<ucc_client::RunSettings>, String),
}

impl Hub {
    /// A hub for the server at `addr`.
    pub fn new(addr: String, local: bool, log_dir: PathBuf) -> Self {
        Self {
            addr,
            local,
            speed: "1".into(),
            paused: false,
            geometry: None,
            map: String::new(),
            uavs: Vec::new(),
            log_dir,
            robot_classes: None,
            log: Default::default(),
            next_id: 1,
            next_seq: 1,
        }
    }

    /// The UAV with this id.
    pub fn uav(&mut self, id: u32) -> Result<&mut Uav, String> {
        self.uavs
            .iter_mut()
            .find(|u| u.id == id)
            .ok_or_else(|| format!("there is no UAV {id} (it was removed?)"))
    }

    /// Appends a line to a UAV's log.
    pub fn log(&mut self, uav: u32, level: &'static str, text: String) {
        let seq = self.next_seq;
        self.next_seq += 1;
        self.log.push_back(LogLine {
            seq,
            level,
            uav,
            text,
        });
        while self.log.len() > MAX_LOG * 4 {
            self.log.pop_front();
        }
    }

    /// Whether any UAV is flying.
    pub fn busy(&self) -> bool {
        self.uavs
            .iter()
            .any(|u| matches!(u.status, Status::Running | Status::Stopping))
    }

    /// Checks a request and applies what can be applied under the lock. `Err` is a message
    /// for the user.
    pub fn apply(&mut self, request: Request) -> Result<Action, String> {
        match request {
            Request::Connect { host, port } => {
                let host = host.trim();
                if host.is_empty() {
                    return Err("server host: empty".into());
                }
                let port: u16 = port
                    .trim()
                    .parse()
                    .map_err(|_| format!("server port: {port:?} is not a port (1-65535)"))?;
                if port == 0 {
                    return Err("server port: 0 is not a port (1-65535)".into());
                }
                if self.busy() {
                    return Err("stop every UAV before changing the server".into());
                }
                Ok(Action::Connect(format!("{host}:{port}")))
            }
            Request::Speed { value } => {
                if !self.local {
                    return Err("the speed is set by the server (only a local server's speed can be changed here)".into());
                }
                value
                    .parse::<usar_server::TimeScale>()
                    .map_err(|e| format!("speed: {e}"))?;
                if self.busy() {
                    return Err("stop every UAV before changing the speed".into());
                }
                Ok(Action::Speed(value))
            }
            Request::Pause { paused } => {
                self.paused = paused;
                Ok(Action::None)
            }
            Request::Create {
                robot,
                agent,
                start,
                name,
            } => {
                let robot = robot.trim().to_owned();
                if robot.is_empty() || robot.contains(['{', '}', ' ']) {
                    return Err(format!("robot class: {robot:?} is not a class name"));
                }
                if let Some(known) = &self.robot_classes {
                    let full = usar_proto::Init::qualified_class(&robot);
                    if !known.iter().any(|k| k.eq_ignore_ascii_case(&full)) {
                        let names: Vec<&str> = known
                            .iter()
                            .map(|k| k.trim_start_matches("USARBot."))
                            .collect();
                        return Err(format!(
                            "robot class: {robot:?} is unknown to this server (it has: {})",
                            names.join(", ")
                        ));
                    }
                }
                flight::check_agent(&agent)?;
                let start: ucc_client::Start =
                    start.parse().map_err(|e| format!("start pose: {e}"))?;
                if let ucc_client::Start::Pose { location, rotation } = &start
                    && !(location
                        .iter()
                        .chain(rotation.iter())
                        .all(|v| v.is_finite()))
                {
                    return Err("start pose: every number must be finite".into());
                }
                let id = self.next_id;
                self.next_id += 1;
                let name = match name.trim() {
                    "" => format!("UAV{id}"),
                    n if n.contains(['{', '}', ' ']) => {
                        return Err(format!("name: {n:?} may not hold spaces or braces"));
                    }
                    n => n.to_owned(),
                };
                self.uavs.push(Uav {
                    id,
                    prefix: name.clone(),
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
                    trail: Vec::new(),
                    trail_epoch: 0,
                    past: Vec::new(),
                    past_epoch: 0,
                    history: Vec::new(),
                    hits: Vec::new(),
                    files: Vec::new(),
                    cancel: None,
                });
                Ok(Action::Created(id))
            }
            Request::Remove { uav } => {
                if matches!(self.uav(uav)?.status, Status::Running | Status::Stopping) {
                    return Err("stop the UAV before removing it".into());
                }
                self.uavs.retain(|u| u.id != uav);
                Ok(Action::None)
            }
            Request::AddMission {
                uav,
                kind,
                x,
                y,
                z,
                seconds,
            } => {
                let mission = match kind.as_str() {
                    "GotoXyz" => ucc_client::Mission::GotoXyz {
                        x: number("mission x", &x)?,
                        y: number("mission y", &y)?,
                        z: number("mission z", &z)?,
                    },
                    "Hover" => {
                        let s = number("hover seconds", &seconds)?;
                        if s <= 0.0 {
                            return Err(format!("hover seconds: {s} is not positive"));
                        }
                        ucc_client::Mission::Hover { seconds: s }
                    }
                    other => {
                        return Err(format!(
                            "mission type: {other:?} is unknown (GotoXyz or Hover)"
                        ));
                    }
                };
                let u = self.uav(uav)?;
                flight::check_mission(&u.agent, &mission)?;
                u.missions.push(mission);
                Ok(Action::None)
            }
            Request::RemoveMission { uav, index } => {
                let u = self.uav(uav)?;
                if index >= u.missions.len() {
                    return Err(format!("UAV {uav} has no mission {}", index + 1));
                }
                u.missions.remove(index);
                Ok(Action::None)
            }
            Request::Options {
                uav,
                prefix,
                pictures,
                autosave,
            } => {
                let prefix = prefix.trim().to_owned();
                if prefix.is_empty()
                    || !prefix
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
                    || prefix.starts_with('.')
                {
                    return Err(format!(
                        "file prefix: {prefix:?} (letters, digits, - _ . only)"
                    ));
                }
                let pictures = pictures.parse().map_err(|e| format!("pictures: {e}"))?;
                let u = self.uav(uav)?;
                u.prefix = prefix;
                u.pictures = pictures;
                u.autosave = autosave;
                Ok(Action::None)
            }
            Request::Start { uav, iterations } => {
                let n: usize = iterations
                    .trim()
                    .parse()
                    .ok()
                    .filter(|n| (1..=10_000).contains(n))
                    .ok_or_else(|| {
                        format!("iterations: {iterations:?} is not a whole number from 1 to 10000")
                    })?;
                let addr = self.addr.clone();
                let local = self.local;
                let log_dir = self.log_dir.clone();
                let geometry = self.geometry_settings();
                let u = self.uav(uav)?;
                if matches!(u.status, Status::Running | Status::Stopping) {
                    return Err(format!("{} is already flying", u.name));
                }
                if u.missions.is_empty() {
                    return Err(format!("{} has no missions: add a waypoint first", u.name));
                }
                let settings = flight::settings(u, n, addr, local, log_dir, geometry);
                let agent = u.agent.clone();
                u.iterations = n;
                u.status = Status::Running;
                u.error = None;
                u.iteration = 0;
                u.active = None;
                u.past.clear();
                u.past_epoch += 1;
                u.trail.clear();
                u.trail_epoch += 1;
                u.history.clear();
                u.files.clear();
                Ok(Action::Start(uav, Box::new(settings), agent))
            }
            Request::Stop { uav } => {
                let u = self.uav(uav)?;
                if let Some(cancel) = &u.cancel
                    && u.status == Status::Running
                {
                    cancel.cancel();
                    u.status = Status::Stopping;
                }
                Ok(Action::None)
            }
            Request::Quit => Ok(Action::Quit),
            Request::Select { uav } => {
                self.uav(uav)?;
                Ok(Action::None)
            }
        }
    }

    fn geometry_settings(&self) -> Option<ucc_client::picture::MapGeometry> {
        self.geometry.clone()
    }

    /// The map's solids for the page: `[{outline: [[x, y], ...], top, bottom}]`.
    pub fn geometry_json(&self) -> Value {
        self.geometry.as_ref().map_or(Value::Null, |g| {
            g.footprints
                .iter()
                .map(|f| json!({"outline": f.outline.iter().map(|p| [p.0, p.1]).collect::<Vec<_>>(), "z_min": f.z_min, "z_max": f.z_max}))
                .collect()
        })
    }

    /// A new state sample of a UAV: the live panel, the trail, the plots, the laser's hits.
    pub fn sample(&mut self, uav: u32, iteration: usize, live: Live) {
        let Ok(u) = self.uav(uav) else { return };
        if iteration != u.iteration {
            u.iteration = iteration;
        }
        if let Some(p) = live.position {
            let point = [p[0] as f32, p[1] as f32, p[2] as f32];
            if u.trail.len() >= MAX_TRAIL {
                // Keep every other point: the trail stays whole, only coarser.
                let thinned: Vec<_> = u.trail.iter().copied().step_by(2).collect();
                u.trail = thinned;
                u.trail_epoch += 1;
            }
            u.trail.push(point);
            if u.history.len() >= MAX_HISTORY {
                let thinned: Vec<_> = u.history.iter().copied().step_by(2).collect();
                u.history = thinned;
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

    /// A new iteration began: the last one's trail goes to the overlay.
    pub fn new_iteration(&mut self, uav: u32, iteration: usize) {
        let Ok(u) = self.uav(uav) else { return };
        if !u.trail.is_empty() {
            let trail = std::mem::take(&mut u.trail);
            u.past.push(trail);
        }
        u.history.clear();
        u.trail_epoch += 1;
        u.iteration = iteration;
        u.active = None;
    }

    /// The run of a UAV ended.
    pub fn finished(&mut self, uav: u32, status: Status, error: Option<String>) {
        let Ok(u) = self.uav(uav) else { return };
        u.status = status;
        u.error = error;
        u.cancel = None;
        u.active = None;
    }

    /// The JSON update for a page: everything it has not seen yet (per `cursor`).
    pub fn update(&self, cursor: &mut Cursor) -> Value {
        let uavs: Vec<Value> = self
            .uavs
            .iter()
            .map(|u| {
                let c = cursor.uavs.entry(u.id).or_default();
                let reset = c.epoch != u.trail_epoch;
                if reset {
                    *c = UavCursor {
                        epoch: u.trail_epoch,
                        past: c.past.min(u.past.len()),
                        hits: c.hits.min(u.hits.len()),
                        ..UavCursor::default()
                    };
                }
                let past_reset = c.past_epoch != u.past_epoch;
                if past_reset {
                    c.past_epoch = u.past_epoch;
                    c.past = 0;
                }
                let trail = &u.trail[c.trail.min(u.trail.len())..];
                let history = &u.history[c.history.min(u.history.len())..];
                let past = &u.past[c.past..];
                let hits = &u.hits[c.hits.min(u.hits.len())..];
                let selected = cursor.selected == Some(u.id);
                let value = json!({
                    "id": u.id,
                    "name": u.name,
                    "robot": u.robot,
                    "agent": u.agent,
                    "start": u.start.to_string(),
                    "status": u.status,
                    "error": u.error,
                    "iteration": u.iteration,
                    "iterations": u.iterations,
                    "active": u.active,
                    "prefix": u.prefix,
                    "pictures": match u.pictures { ucc_client::Pictures::All => "all", ucc_client::Pictures::Overlay => "overlay", ucc_client::Pictures::None => "none" },
                    "autosave": u.autosave,
                    "missions": u.missions.iter().map(mission_json).collect::<Vec<_>>(),
                    "live": u.live.as_ref().map(|l| l.to_json(selected)),
                    "trail_reset": reset,
                    "trail": trail,
                    "history_reset": reset,
                    "history": history.iter().map(|h| h.map(|v| if v.is_finite() { Value::from(v) } else { Value::Null })).collect::<Vec<_>>(),
                    "past_reset": past_reset,
                    "past": past,
                    "hits": hits,
                    "files": u.files.iter().enumerate().map(|(i, f)| json!({"index": i, "name": f.file_name().map(|n| n.to_string_lossy().into_owned())})).collect::<Vec<_>>(),
                });
                c.trail = u.trail.len();
                c.history = u.history.len();
                c.past = u.past.len();
                c.hits = u.hits.len();
                value
            })
            .collect();
        let log: Vec<&LogLine> = self.log.iter().filter(|l| l.seq > cursor.log_seq).collect();
        if let Some(last) = log.last() {
            cursor.log_seq = last.seq;
        }
        json!({
            "type": "state",
            "server": {
                "addr": self.addr,
                "local": self.local,
                "speed": self.speed,
                "paused": self.paused,
                "map": self.map,
            },
            "uavs": uavs,
            "log": log,
        })
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
                .map_or("?", |u| u.name.as_str());
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

fn mission_json(m: &ucc_client::Mission) -> Value {
    match m {
        ucc_client::Mission::GotoXyz { x, y, z } => {
            json!({"kind": "GotoXyz", "x": x, "y": y, "z": z, "text": format!("GotoXyz {x:.2},{y:.2},{z:.2}")})
        }
        ucc_client::Mission::Hover { seconds } => {
            json!({"kind": "Hover", "seconds": seconds, "text": format!("Hover {seconds} s")})
        }
    }
}

/// A finite number from what the user typed, or a message naming the field.
pub fn number(field: &str, text: &str) -> Result<f64, String> {
    let t = text.trim();
    if t.is_empty() {
        return Err(format!("{field}: empty (a number in metres)"));
    }
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("{field}: {t:?} is not a finite number")),
    }
}
