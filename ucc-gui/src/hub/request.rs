//! What the page may ask ([`Request`]), one function per kind that checks it and either
//! changes the hub or plans what to do outside the lock ([`Action`]). Bad input is a
//! [`RequestError`] whose text names the field and the problem.

use std::path::PathBuf;
use std::sync::Arc;

use serde::Deserialize;
use tokio_util::sync::CancellationToken;
use ucc_client::scenario::Prepared;
use ucc_client::{Lockstep, Mission, RunSettings, Start, agents};
use usar_server::TimeScale;

use super::{Hub, Status, Uav};

/// The farthest coordinate accepted, metres: beyond any map, and far enough from the range
/// where `f32` trails and the page's drawing lose their meaning.
pub const MAX_COORDINATE: f64 = 100_000.0;
/// The longest name, tag or class accepted, characters.
pub const MAX_NAME: usize = 64;
/// The longest hover accepted, seconds (a day).
pub const MAX_HOVER: f64 = 86_400.0;
/// The most iterations one Start may ask for.
pub const MAX_ITERATIONS: usize = 10_000;
/// The most UAVs a hub holds (a page cannot grow the server's memory without bound).
pub const MAX_UAVS: usize = 4_096;
/// The most missions one UAV holds.
pub const MAX_MISSIONS: usize = 1_000;

/// A request from the page, as JSON: `{"op": "create", ...}`. Numbers come as the text the
/// user typed, so that the Rust side says what is wrong with them.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case", deny_unknown_fields)]
pub enum Request {
    /// Use the server at `host:port` (checked by connecting).
    Connect {
        /// Host name or address.
        host: String,
        /// Port, as typed.
        port: String,
    },
    /// Restart the local server at this time scale: `1`, `2`, … (× real time) or `max`.
    TimeScale {
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
    /// The part of the world this page's map shows, metres (x north, y east): the hub sends
    /// full detail only for the UAVs in it (and the selected one), a light summary for the
    /// rest.
    View {
        /// South edge (smallest x).
        x0: f64,
        /// North edge.
        x1: f64,
        /// West edge (smallest y).
        y0: f64,
        /// East edge.
        y1: f64,
    },
    /// Start an embedded scenario: its UAVs are created and fly with their team agents.
    ScenarioStart {
        /// An embedded scenario's name.
        name: String,
        /// As typed (empty: 1).
        #[serde(default)]
        iterations: String,
        /// The first iteration's seed, as typed (empty: the scenario's).
        #[serde(default)]
        seed: String,
        /// `1`, `2`, … (× real time) or `max`, as typed (empty: real time).
        #[serde(default)]
        speed: String,
    },
    /// Stop the scenario's run.
    ScenarioStop,
    /// How fast the scenario flies: `1`, `2`, … (× real time) or `max`.
    ScenarioSpeed {
        /// As typed.
        value: String,
    },
}

/// Why a request was refused; the text is what the page shows.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RequestError {
    /// A field's value is wrong.
    #[error("{field}: {problem}")]
    Field {
        /// The field, as the page labels it.
        field: &'static str,
        /// What is wrong.
        problem: String,
    },
    /// No UAV has this id.
    #[error("there is no UAV {0} (it was removed?)")]
    NoUav(u32),
    /// The request does not fit the current state (a UAV flying, no local server).
    #[error("{0}")]
    State(String),
    /// The server could not be reached or restarted.
    #[error("{0}")]
    Server(String),
    /// The JSON is not a request.
    #[error("bad request: {0}")]
    Malformed(String),
}

pub(super) fn field(field: &'static str, problem: impl Into<String>) -> RequestError {
    RequestError::Field {
        field,
        problem: problem.into(),
    }
}

/// What the caller does outside the hub's lock after a request was applied.
#[derive(Debug)]
pub enum Action {
    /// Nothing more.
    None,
    /// A UAV was created (tell the page which).
    Created(u32),
    /// Check the server at `host:port` and switch to it.
    Connect(String),
    /// Restart the local server at this time scale.
    TimeScale(TimeScale),
    /// End the control center.
    Quit,
    /// Start this UAV's run with these settings and this agent.
    Start(u32, Box<RunSettings>, String),
    /// Start this scenario's run.
    Scenario(Box<ScenarioPlan>),
}

/// What the scenario's thread is given: the scenario loaded, the hub's ids of its UAVs (in
/// the scenario's order), the iterations and the first seed, and its stop.
#[derive(Debug)]
pub struct ScenarioPlan {
    /// The scenario with its map and classes.
    pub prepared: Arc<Prepared>,
    /// The hub's UAV of each scenario UAV.
    pub uavs: Vec<u32>,
    /// Iterations to fly.
    pub iterations: usize,
    /// The first iteration's seed (iteration i flies seed + i - 1).
    pub seed: u64,
    /// Stops the run.
    pub cancel: CancellationToken,
}

/// The map's rectangle of a [`Request::View`], `[x0, x1, y0, y1]`, checked: finite numbers,
/// each edge before the opposite one.
pub fn view_rect(x0: f64, x1: f64, y0: f64, y1: f64) -> Result<[f64; 4], RequestError> {
    for (name, v) in [
        ("view x0", x0),
        ("view x1", x1),
        ("view y0", y0),
        ("view y1", y1),
    ] {
        if !v.is_finite() {
            return Err(field(name, format!("{v} is not a finite number")));
        }
    }
    if x0 > x1 || y0 > y1 {
        return Err(field(
            "view",
            "the south and west edges (x0, y0) must not be beyond the north and east ones (x1, y1)",
        ));
    }
    Ok([x0, x1, y0, y1])
}

impl Hub {
    /// Checks a request and applies what can be applied under the lock.
    pub fn apply(&mut self, request: Request) -> Result<Action, RequestError> {
        match request {
            Request::Connect { host, port } => self.connect(&host, &port),
            Request::TimeScale { value } => self.set_time_scale(&value),
            Request::Pause { paused } => {
                self.paused = paused;
                Ok(Action::None)
            }
            Request::Create {
                robot,
                agent,
                start,
                name,
            } => self.create(&robot, &agent, &start, &name),
            Request::Remove { uav } => self.remove(uav),
            Request::AddMission {
                uav,
                kind,
                x,
                y,
                z,
                seconds,
            } => self.add_mission(uav, &kind, [&x, &y, &z], &seconds),
            Request::RemoveMission { uav, index } => self.remove_mission(uav, index),
            Request::Options {
                uav,
                prefix,
                pictures,
                autosave,
            } => self.options(uav, &prefix, &pictures, autosave),
            Request::Start { uav, iterations } => self.start(uav, &iterations),
            Request::Stop { uav } => self.stop(uav),
            Request::Quit => Ok(Action::Quit),
            Request::Select { uav } => self.uav(uav).map(|_| Action::None),
            Request::View { x0, x1, y0, y1 } => view_rect(x0, x1, y0, y1).map(|_| Action::None),
            Request::ScenarioStart {
                name,
                iterations,
                seed,
                speed,
            } => self.scenario_start(&name, &iterations, &seed, &speed),
            Request::ScenarioStop => self.scenario_stop(),
            Request::ScenarioSpeed { value } => self.scenario_speed(&value),
        }
    }

    fn connect(&self, host: &str, port: &str) -> Result<Action, RequestError> {
        let host = plain("server host", host, 253)?;
        if host.is_empty() {
            return Err(field("server host", "empty"));
        }
        let port = port
            .trim()
            .parse::<u16>()
            .ok()
            .filter(|p| *p != 0)
            .ok_or_else(|| {
                field(
                    "server port",
                    format!("{} is not a port (1-65535)", shown(port)),
                )
            })?;
        if self.busy() {
            return Err(RequestError::State(
                "stop every UAV before changing the server".into(),
            ));
        }
        Ok(Action::Connect(format!("{host}:{port}")))
    }

    fn set_time_scale(&self, value: &str) -> Result<Action, RequestError> {
        if !self.local {
            return Err(RequestError::State(
                "the time scale is set by the server (only a local server's can be changed here)"
                    .into(),
            ));
        }
        let scale = value
            .trim()
            .parse::<TimeScale>()
            .map_err(|e| field("time scale", e.to_string()))?;
        if self.busy() {
            return Err(RequestError::State(
                "stop every UAV before changing the time scale".into(),
            ));
        }
        Ok(Action::TimeScale(scale))
    }

    fn create(
        &mut self,
        robot: &str,
        agent: &str,
        start: &str,
        name: &str,
    ) -> Result<Action, RequestError> {
        if self.uavs.len() >= MAX_UAVS {
            return Err(RequestError::State(format!(
                "at most {MAX_UAVS} UAVs: remove one first"
            )));
        }
        let robot = plain("robot class", robot, MAX_NAME)?;
        if robot.is_empty() {
            return Err(field("robot class", "empty"));
        }
        if let Some(known) = &self.robot_classes {
            let full = usar_proto::Init::qualified_class(robot);
            if !known.iter().any(|k| k.eq_ignore_ascii_case(&full)) {
                let names: Vec<&str> = known
                    .iter()
                    .map(|k| k.trim_start_matches("USARBot."))
                    .collect();
                return Err(field(
                    "robot class",
                    format!(
                        "{robot:?} is unknown to this server (it has: {})",
                        names.join(", ")
                    ),
                ));
            }
        }
        agents::info(agent).ok_or_else(|| {
            field(
                "agent type",
                format!(
                    "unknown agent {} (known agents: {})",
                    shown(agent),
                    agents::names()
                ),
            )
        })?;
        let start_text = plain("start pose", start, 200)?;
        let start: Start = start_text.parse().map_err(|e| field("start pose", e))?;
        match &start {
            Start::Pose { location, rotation } => {
                if !location
                    .iter()
                    .chain(rotation.iter())
                    .all(|v| v.is_finite())
                {
                    return Err(field("start pose", "every number must be finite"));
                }
                if location.iter().any(|v| v.abs() > MAX_COORDINATE) {
                    return Err(field("start pose", format!("beyond ±{MAX_COORDINATE} m")));
                }
            }
            Start::Tag(tag) if tag.chars().count() > MAX_NAME => {
                return Err(field(
                    "start pose",
                    format!("a tag of at most {MAX_NAME} characters"),
                ));
            }
            Start::Tag(_) => {}
        }
        let id = self.next_id;
        let name = match plain("name", name, MAX_NAME)? {
            "" => self.free_name(&format!("UAV{id}")),
            n => {
                self.check_name(n, &prefix_of(n), None)
                    .map_err(|e| field("name", e))?;
                n.to_owned()
            }
        };
        self.next_id += 1;
        let prefix = prefix_of(&name);
        self.uavs.push(Uav::new(
            id,
            name,
            prefix,
            robot.to_owned(),
            agent.to_owned(),
            start,
        ));
        Ok(Action::Created(id))
    }

    /// Whether a UAV named `name` writing its files as `prefix` may join the others (all but
    /// `except`): no other UAV has that name or that prefix (either without case: a
    /// file system may not tell `A` from `a`), so no two UAVs overwrite each other's files.
    /// The reason, naming both, when not.
    pub(super) fn check_name(
        &self,
        name: &str,
        prefix: &str,
        except: Option<u32>,
    ) -> Result<(), String> {
        let others = self.uavs.iter().filter(|u| Some(u.id) != except);
        for u in others {
            if u.name.eq_ignore_ascii_case(name) && except.is_none() {
                return Err(format!(
                    "{} is taken by UAV {} ({}): choose another name",
                    shown(name),
                    u.id,
                    shown(&u.name)
                ));
            }
            if u.prefix.eq_ignore_ascii_case(prefix) {
                let (what, field) = match except {
                    None => (name, "name"),
                    Some(_) => (prefix, "prefix"),
                };
                return Err(format!(
                    "{} would write over the files of UAV {} ({}), {}-NN.log…: choose another \
                     {field}",
                    shown(what),
                    u.id,
                    shown(&u.name),
                    u.prefix
                ));
            }
        }
        // Files of a removed UAV, or of an earlier prefix of a UAV, stay as they are (a UAV
        // may go back to a prefix of its own).
        for (id, owner, old) in &self.retired {
            if Some(*id) != except && old.eq_ignore_ascii_case(prefix) {
                let (what, field) = match except {
                    None => (name, "name"),
                    Some(_) => (prefix, "prefix"),
                };
                return Err(format!(
                    "{} would write over the files that UAV {id} ({}) wrote earlier, \
                     {old}-NN.log…: choose another {field}",
                    shown(what),
                    shown(owner),
                ));
            }
        }
        Ok(())
    }

    /// `base`, or `base-2`, `base-3`… the first that no UAV has as name or file prefix.
    pub(super) fn free_name(&self, base: &str) -> String {
        let free = |n: &str| self.check_name(n, &prefix_of(n), None).is_ok();
        if free(base) {
            return base.to_owned();
        }
        (2..)
            .map(|k| format!("{base}-{k}"))
            .find(|n| free(n))
            .unwrap_or_else(|| base.to_owned())
    }

    fn remove(&mut self, uav: u32) -> Result<Action, RequestError> {
        if self.uav(uav)?.flying() {
            return Err(RequestError::State(
                "stop the UAV before removing it".into(),
            ));
        }
        if let Some(u) = self.uavs.iter().find(|u| u.id == uav)
            && !u.files.is_empty()
        {
            self.retired.push((u.id, u.name.clone(), u.prefix.clone()));
        }
        self.uavs.retain(|u| u.id != uav);
        Ok(Action::None)
    }

    fn add_mission(
        &mut self,
        uav: u32,
        kind: &str,
        [x, y, z]: [&str; 3],
        seconds: &str,
    ) -> Result<Action, RequestError> {
        let mission = match kind {
            "GotoXyz" => Mission::GotoXyz {
                x: coordinate("mission x", x)?,
                y: coordinate("mission y", y)?,
                z: coordinate("mission z", z)?,
            },
            "Hover" => {
                let s = number("hover seconds", seconds)?;
                if !(s > 0.0 && s <= MAX_HOVER) {
                    return Err(field(
                        "hover seconds",
                        format!("{s} is not from 0 to {MAX_HOVER} (a day)"),
                    ));
                }
                Mission::Hover { seconds: s }
            }
            other => {
                return Err(field(
                    "mission type",
                    format!("{} is unknown (GotoXyz or Hover)", shown(other)),
                ));
            }
        };
        let u = self.uav(uav)?;
        if u.missions.len() >= MAX_MISSIONS {
            return Err(RequestError::State(format!(
                "{} has {MAX_MISSIONS} missions, the most a UAV may have",
                u.name
            )));
        }
        let info = agents::info(&u.agent)
            .ok_or_else(|| RequestError::State(format!("unknown agent {:?}", u.agent)))?;
        (info.create)()
            .add_mission(mission.clone())
            .map_err(|e| RequestError::State(e.to_string()))?;
        u.missions.push(mission);
        u.touch();
        Ok(Action::None)
    }

    fn remove_mission(&mut self, uav: u32, index: usize) -> Result<Action, RequestError> {
        let u = self.uav(uav)?;
        if index >= u.missions.len() {
            return Err(RequestError::State(format!(
                "UAV {uav} has no mission {}",
                index.saturating_add(1)
            )));
        }
        u.missions.remove(index);
        u.touch();
        Ok(Action::None)
    }

    fn options(
        &mut self,
        uav: u32,
        prefix: &str,
        pictures: &str,
        autosave: bool,
    ) -> Result<Action, RequestError> {
        let prefix = prefix.trim();
        if !is_prefix(prefix) {
            return Err(field(
                "file prefix",
                format!(
                    "{} (1 to {MAX_NAME} letters, digits, - _ . not starting with .)",
                    shown(prefix)
                ),
            ));
        }
        let pictures = pictures.parse().map_err(|e: String| field("pictures", e))?;
        let name = self.uav(uav)?.name.clone();
        self.check_name(&name, prefix, Some(uav))
            .map_err(|e| field("file prefix", e))?;
        let u = self.uav(uav)?;
        let retired = (!u.files.is_empty() && !u.prefix.eq_ignore_ascii_case(prefix))
            .then(|| (u.id, u.name.clone(), u.prefix.clone()));
        u.prefix = prefix.to_owned();
        u.pictures = pictures;
        u.autosave = autosave;
        u.touch();
        self.retired.extend(retired);
        Ok(Action::None)
    }

    fn start(&mut self, uav: u32, iterations: &str) -> Result<Action, RequestError> {
        let n: usize = iterations
            .trim()
            .parse()
            .ok()
            .filter(|n| (1..=MAX_ITERATIONS).contains(n))
            .ok_or_else(|| {
                field(
                    "iterations",
                    format!(
                        "{} is not a whole number from 1 to {MAX_ITERATIONS}",
                        shown(iterations)
                    ),
                )
            })?;
        let (addr, local, log_dir, map) = (
            self.addr.clone(),
            self.local,
            self.log_dir.clone(),
            self.geometry.clone(),
        );
        let image_server = self.image_server.clone();
        let cameras = self.camera_classes.clone();
        let u = self.uav(uav)?;
        if u.flying() {
            return Err(RequestError::State(format!("{} is already flying", u.name)));
        }
        if u.missions.is_empty() {
            return Err(RequestError::State(format!(
                "{} has no missions: add a waypoint first",
                u.name
            )));
        }
        let mut settings = run_settings(u, n, addr, local, log_dir, map);
        // The camera panel's frames, read only while a page shows them (robots with a camera).
        let has_camera = cameras
            .iter()
            .any(|c| c.eq_ignore_ascii_case(&settings.class_name()));
        settings.camera =
            image_server
                .filter(|_| has_camera)
                .map(|server| ucc_client::CameraSettings {
                    server,
                    active: Some(u.camera_on.clone()),
                    ..ucc_client::CameraSettings::default()
                });
        let agent = u.agent.clone();
        u.iterations = n;
        u.status = Status::Running;
        u.error = None;
        u.iteration = 0;
        u.active = None;
        u.touch();
        u.past.clear();
        u.past_epoch += 1;
        u.trail.clear();
        u.trail_epoch += 1;
        u.history.clear();
        Ok(Action::Start(uav, Box::new(settings), agent))
    }

    fn stop(&mut self, uav: u32) -> Result<Action, RequestError> {
        let u = self.uav(uav)?;
        if let Some(cancel) = &u.cancel
            && u.status == Status::Running
        {
            cancel.cancel();
            u.status = Status::Stopping;
            u.touch();
        }
        Ok(Action::None)
    }
}

/// The settings of a run of `uav`: its files go to `log_dir` under its prefix.
fn run_settings(
    uav: &Uav,
    iterations: usize,
    addr: String,
    local: bool,
    log_dir: PathBuf,
    map: Option<ucc_client::picture::MapGeometry>,
) -> RunSettings {
    // The prefix is checked when set; a file name of one normal component either way.
    let prefix = if is_prefix(&uav.prefix) {
        uav.prefix.clone()
    } else {
        prefix_of(&uav.prefix)
    };
    RunSettings {
        addr,
        robot: uav.robot.clone(),
        name: uav.name.clone(),
        start: uav.start.clone(),
        missions: uav.missions.clone(),
        iterations,
        log_dir: uav.autosave.then_some(log_dir),
        prefix,
        // A local server always offers lockstep; a real USARSim never does.
        lockstep: if local {
            Lockstep::Required
        } else {
            Lockstep::IfOffered
        },
        keep_going: true,
        pictures: uav.pictures,
        map,
        ..RunSettings::default()
    }
}

/// Whether `p` is a file prefix: letters, digits, `-`, `_`, `.`, not starting with a dot, at
/// most [`MAX_NAME`] characters — one plain file name in the log directory.
pub fn is_prefix(p: &str) -> bool {
    !p.is_empty()
        && p.len() <= MAX_NAME
        && !p.starts_with('.')
        && p.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
}

/// The default file prefix of a UAV name: every character but letters, digits, `-` and `_`
/// becomes `_`, so a UAV named `../escaped` writes `___escaped-01.log` in the log directory.
pub fn prefix_of(name: &str) -> String {
    let p: String = name
        .chars()
        .take(MAX_NAME)
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if p.is_empty() { "UAV".into() } else { p }
}

/// A value that goes into a protocol line or a file name as typed: trimmed, without control
/// characters, spaces or braces (which end a Gamebots value), at most `max` characters.
fn plain<'a>(name: &'static str, text: &'a str, max: usize) -> Result<&'a str, RequestError> {
    let t = text.trim();
    if let Some((i, c)) = t.char_indices().find(|(_, c)| c.is_control()) {
        return Err(field(
            name,
            format!("a control character (U+{:04X}) at byte {i}", c as u32),
        ));
    }
    if t.chars().count() > max {
        return Err(field(name, format!("longer than {max} characters")));
    }
    if t.contains(['{', '}', ' ']) {
        return Err(field(name, format!("{t:?} may not hold spaces or braces")));
    }
    Ok(t)
}

/// The user's text in a message: quoted, and cut when long.
pub(super) fn shown(text: &str) -> String {
    const MAX: usize = 40;
    if text.chars().count() <= MAX {
        format!("{text:?}")
    } else {
        let cut: String = text.chars().take(MAX).collect();
        format!("{cut:?}…")
    }
}

/// A finite number from what the user typed, or a message naming the field.
pub fn number(name: &'static str, text: &str) -> Result<f64, RequestError> {
    let t = text.trim();
    if t.is_empty() {
        return Err(field(name, "empty (a number in metres)"));
    }
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(field(name, format!("{} is not a finite number", shown(t)))),
    }
}

/// A coordinate (metres) within ±[`MAX_COORDINATE`].
fn coordinate(name: &'static str, text: &str) -> Result<f64, RequestError> {
    let v = number(name, text)?;
    if v.abs() > MAX_COORDINATE {
        return Err(field(
            name,
            format!("{} is beyond ±{MAX_COORDINATE} m", shown(text.trim())),
        ));
    }
    Ok(v)
}
