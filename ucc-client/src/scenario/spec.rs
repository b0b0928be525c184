//! The scenario file (TOML, docs/scenarios.md): what is flown, by whom, what is to be found,
//! followed, relayed or delivered, and for how long. Parsing checks every value and names
//! the file, the line and the key of what is wrong.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::mission::line_of;
use toml::Spanned;

pub use super::model::{
    Delivery, Fire, Kind, Pad, Radio, Relay, Scenario, Search, Sensor, Sharing, Target, UavGroup,
};

/// The longest scenario file read (bytes).
pub const MAX_FILE: u64 = 1 << 20;
/// UAVs in one scenario at most.
pub const MAX_UAVS: usize = 1000;
/// Simulated seconds of one iteration at most.
pub const MAX_TIME: f64 = 24.0 * 3600.0;
/// Metres: every coordinate within this (the maps' limit).
const LIMIT: f64 = 10_000.0;

/// A scenario file that is wrong: where and what.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ScenarioError {
    /// Not readable.
    #[error("cannot read scenario file {path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        error: String,
    },
    /// Readable but wrong.
    #[error("{path}:{line}: {message}")]
    Invalid {
        /// The file (or `embedded:NAME`).
        path: PathBuf,
        /// 1-based.
        line: usize,
        /// What is wrong, naming the key.
        message: String,
    },
    /// No embedded scenario or file of that name.
    #[error("no scenario {name:?}: not an embedded scenario ({known}) and no such file")]
    Unknown {
        /// What was asked for.
        name: String,
        /// The embedded names.
        known: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    kind: Kind,
    #[serde(default)]
    description: String,
    map: String,
    time_limit: Spanned<f64>,
    #[serde(default)]
    seed: u64,
    period: Option<Spanned<f64>>,
    blackboard: Option<Spanned<toml::Value>>,
    #[serde(default)]
    uav: Vec<Spanned<RawUav>>,
    base: Option<Spanned<RawPad>>,
    sensor: Option<Spanned<RawSensor>>,
    search: Option<Spanned<RawSearch>>,
    #[serde(default)]
    target: Vec<Spanned<RawTarget>>,
    fire: Option<Spanned<RawFire>>,
    relay: Option<Spanned<RawRelay>>,
    radio: Option<Spanned<RawRadio>>,
    delivery: Option<Spanned<RawDelivery>>,
    metrics: Option<Spanned<Vec<String>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawUav {
    #[serde(default = "default_class")]
    class: String,
    agent: String,
    #[serde(default = "one")]
    count: usize,
    start: [f64; 3],
    #[serde(default)]
    spacing: [f64; 3],
    #[serde(default = "default_altitude")]
    altitude: f64,
    battery: Option<f64>,
}

fn default_class() -> String {
    "USARBot.stsAirRobot".into()
}
fn one() -> usize {
    1
}
fn default_altitude() -> f64 {
    3.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPad {
    location: [f64; 3],
    #[serde(default = "default_pad")]
    radius: f64,
    #[serde(default)]
    charge_time: f64,
}

fn default_pad() -> f64 {
    1.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSensor {
    #[serde(default = "default_fov")]
    fov: f64,
    #[serde(default = "default_range")]
    range: f64,
}

fn default_fov() -> f64 {
    60.0
}
fn default_range() -> f64 {
    10.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSearch {
    area: [[f64; 2]; 2],
    #[serde(default = "default_cell")]
    cell: f64,
    #[serde(default)]
    victims: usize,
    #[serde(default = "default_victim")]
    victim_class: String,
    #[serde(default = "default_reserve")]
    reserve: f64,
}

fn default_cell() -> f64 {
    0.5
}
fn default_victim() -> String {
    "FemaleVictim".into()
}
fn default_reserve() -> f64 {
    0.25
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTarget {
    name: Option<String>,
    start: [f64; 3],
    speed: f64,
    #[serde(default)]
    path: Vec<[f64; 2]>,
    #[serde(default, rename = "loop")]
    looped: bool,
    bounds: Option<[[f64; 2]; 2]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFire {
    center: [f64; 2],
    radius: f64,
    #[serde(default)]
    rate: f64,
    #[serde(default = "default_samples")]
    samples: usize,
}

fn default_samples() -> usize {
    72
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRelay {
    endpoints: [[f64; 3]; 2],
    chain: Option<usize>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRadio {
    pd0: Option<f64>,
    d0: Option<f64>,
    n: Option<f64>,
    attenuation: Option<f64>,
    cutoff: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDelivery {
    pickup: RawPad,
    dropoff: RawPad,
    payload: f64,
    #[serde(default)]
    waypoints: Vec<[f64; 3]>,
    #[serde(default = "yes")]
    land: bool,
}

fn yes() -> bool {
    true
}

/// The embedded scenarios: (name, file text).
pub const EMBEDDED: &[(&str, &str)] = &[
    ("search", include_str!("../../scenarios/search.toml")),
    (
        "search-team",
        include_str!("../../scenarios/search-team.toml"),
    ),
    (
        "search-swarm",
        include_str!("../../scenarios/search-swarm.toml"),
    ),
    ("relay", include_str!("../../scenarios/relay.toml")),
    ("tracking", include_str!("../../scenarios/tracking.toml")),
    ("perimeter", include_str!("../../scenarios/perimeter.toml")),
    ("delivery", include_str!("../../scenarios/delivery.toml")),
];

impl Scenario {
    /// An embedded scenario by name (case-insensitive), else the file at `name`.
    pub fn lookup(name: &str) -> Result<Self, ScenarioError> {
        if let Some((n, text)) = EMBEDDED.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)) {
            return Self::from_toml(text, Path::new(&format!("embedded:{n}")), None);
        }
        let path = Path::new(name);
        if path.is_file() {
            return Self::from_file(path);
        }
        Err(ScenarioError::Unknown {
            name: name.to_owned(),
            known: EMBEDDED
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(", "),
        })
    }

    /// Reads and checks a scenario file.
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        let io = |error: String| ScenarioError::Io {
            path: path.to_path_buf(),
            error,
        };
        let meta = std::fs::metadata(path).map_err(|e| io(e.to_string()))?;
        if !meta.is_file() {
            return Err(io("not a regular file".into()));
        }
        if meta.len() > MAX_FILE {
            return Err(io(format!("larger than {MAX_FILE} bytes")));
        }
        let text = std::fs::read_to_string(path).map_err(|e| io(e.to_string()))?;
        Self::from_toml(&text, path, Some(path))
    }

    /// Parses and checks scenario text; `path` names it in errors, `file` (if any) is where
    /// relative map paths start.
    pub fn from_toml(text: &str, path: &Path, file: Option<&Path>) -> Result<Self, ScenarioError> {
        let invalid = |offset: usize, message: String| ScenarioError::Invalid {
            path: path.to_path_buf(),
            line: line_of(text, offset),
            message,
        };
        let raw: RawScenario = toml::from_str(text).map_err(|e| {
            invalid(
                e.span().map_or(0, |s| s.start),
                e.message().trim_end().to_string(),
            )
        })?;
        let name = raw.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map_or("scenario".into(), |s| s.to_string_lossy().into_owned())
        });
        if name.is_empty() || name.contains(|c: char| c.is_control() || c == '/') {
            return Err(invalid(0, format!("`name` {name:?} must be a plain word")));
        }
        let time_limit = *raw.time_limit.get_ref();
        if !(time_limit > 0.0 && time_limit <= MAX_TIME) {
            return Err(invalid(
                raw.time_limit.span().start,
                format!("`time_limit` must be in (0, {MAX_TIME}] seconds, got {time_limit}"),
            ));
        }
        let period = match &raw.period {
            Some(p) => {
                let v = *p.get_ref();
                if !(0.005..=10.0).contains(&v) {
                    return Err(invalid(
                        p.span().start,
                        format!("`period` must be in [0.005, 10] seconds, got {v}"),
                    ));
                }
                v
            }
            None => 0.1,
        };
        let mut uavs = Vec::new();
        for u in &raw.uav {
            let at = u.span().start;
            let r = u.get_ref();
            let bad = |m: String| invalid(at, format!("[[uav]]: {m}"));
            if r.count == 0 {
                return Err(bad("`count` must be at least 1".into()));
            }
            check_point(&r.start).map_err(|m| bad(format!("`start` {m}")))?;
            check_point(&r.spacing).map_err(|m| bad(format!("`spacing` {m}")))?;
            if !(r.altitude > 0.0 && r.altitude < 1000.0) {
                return Err(bad(format!(
                    "`altitude` must be in (0, 1000) m, got {}",
                    r.altitude
                )));
            }
            if let Some(b) = r.battery
                && !(b > 0.0 && b <= MAX_TIME)
            {
                return Err(bad(format!(
                    "`battery` must be in (0, {MAX_TIME}] s, got {b}"
                )));
            }
            if crate::agents::team::info(&r.agent).is_none() {
                return Err(bad(format!(
                    "unknown agent {:?}; team agents: {}",
                    r.agent,
                    crate::agents::team::names()
                )));
            }
            uavs.push(UavGroup {
                class: r.class.clone(),
                agent: r.agent.clone(),
                count: r.count,
                start: r.start,
                spacing: r.spacing,
                altitude: r.altitude,
                battery: r.battery,
            });
        }
        let total: usize = uavs.iter().map(|u| u.count).sum();
        if total == 0 {
            return Err(invalid(0, "a scenario needs at least one [[uav]]".into()));
        }
        if total > MAX_UAVS {
            return Err(invalid(0, format!("{total} UAVs: at most {MAX_UAVS}")));
        }
        let pad = |p: &RawPad, what: &str, at: usize| -> Result<Pad, ScenarioError> {
            check_point(&p.location).map_err(|m| invalid(at, format!("{what} `location` {m}")))?;
            if !(p.radius > 0.0 && p.radius < 1000.0) {
                return Err(invalid(
                    at,
                    format!("{what} `radius` must be in (0, 1000) m"),
                ));
            }
            if !(p.charge_time >= 0.0 && p.charge_time <= MAX_TIME) {
                return Err(invalid(at, format!("{what} `charge_time` must be ≥ 0 s")));
            }
            Ok(Pad {
                location: p.location,
                radius: p.radius,
                charge_time: p.charge_time,
            })
        };
        let base = match &raw.base {
            Some(b) => Some(pad(b.get_ref(), "[base]", b.span().start)?),
            None => None,
        };
        let sensor = match &raw.sensor {
            Some(s) => {
                let r = s.get_ref();
                if !(r.fov > 0.0 && r.fov < 180.0 && r.range > 0.0 && r.range < 1000.0) {
                    return Err(invalid(
                        s.span().start,
                        "[sensor]: `fov` must be in (0, 180) degrees and `range` in (0, 1000) m"
                            .into(),
                    ));
                }
                Sensor {
                    fov: r.fov,
                    range: r.range,
                }
            }
            None => Sensor {
                fov: default_fov(),
                range: default_range(),
            },
        };
        let search = match &raw.search {
            Some(s) => {
                let at = s.span().start;
                let r = s.get_ref();
                check_area(&r.area).map_err(|m| invalid(at, format!("[search] `area` {m}")))?;
                if !(r.cell >= 0.05 && r.cell <= 100.0) {
                    return Err(invalid(
                        at,
                        "[search] `cell` must be in [0.05, 100] m".into(),
                    ));
                }
                let cells =
                    (r.area[1][0] - r.area[0][0]) / r.cell * (r.area[1][1] - r.area[0][1]) / r.cell;
                if cells > 4e6 {
                    return Err(invalid(
                        at,
                        format!("[search] {cells:.0} cells: at most 4,000,000 (a larger `cell`)"),
                    ));
                }
                if r.victims > 1000 {
                    return Err(invalid(at, "[search] `victims`: at most 1000".into()));
                }
                if !usar_sim_victim_class(&r.victim_class) {
                    return Err(invalid(
                        at,
                        format!(
                            "[search] `victim_class` {:?}: FemaleVictim or MaleVictim",
                            r.victim_class
                        ),
                    ));
                }
                if !(0.0..1.0).contains(&r.reserve) {
                    return Err(invalid(at, "[search] `reserve` must be in [0, 1)".into()));
                }
                Some(Search {
                    area: r.area,
                    cell: r.cell,
                    victims: r.victims,
                    victim_class: r.victim_class.clone(),
                    reserve: r.reserve,
                })
            }
            None => None,
        };
        let mut targets = Vec::new();
        for (i, t) in raw.target.iter().enumerate() {
            let at = t.span().start;
            let r = t.get_ref();
            let bad = |m: String| invalid(at, format!("[[target]]: {m}"));
            check_point(&r.start).map_err(|m| bad(format!("`start` {m}")))?;
            if !(r.speed > 0.0 && r.speed <= 50.0) {
                return Err(bad(format!(
                    "`speed` must be in (0, 50] m/s, got {}",
                    r.speed
                )));
            }
            for p in &r.path {
                check_point(&[p[0], p[1], 0.0]).map_err(|m| bad(format!("`path` {m}")))?;
            }
            if let Some(b) = &r.bounds {
                check_area(b).map_err(|m| bad(format!("`bounds` {m}")))?;
            }
            if r.path.is_empty() && r.bounds.is_none() {
                return Err(bad("give a `path` or, for a random walk, `bounds`".into()));
            }
            let name = r.name.clone().unwrap_or_else(|| format!("Target{}", i + 1));
            if name.is_empty() || name.contains(['{', '}', ' ']) {
                return Err(bad(format!("`name` {name:?} must be one word")));
            }
            targets.push(Target {
                name,
                start: r.start,
                speed: r.speed,
                path: r.path.clone(),
                looped: r.looped,
                bounds: r.bounds,
            });
        }
        let fire = match &raw.fire {
            Some(f) => {
                let at = f.span().start;
                let r = f.get_ref();
                check_point(&[r.center[0], r.center[1], 0.0])
                    .map_err(|m| invalid(at, format!("[fire] `center` {m}")))?;
                if !(r.radius > 0.0 && r.radius < LIMIT && (0.0..=10.0).contains(&r.rate)) {
                    return Err(invalid(
                        at,
                        "[fire] `radius` must be in (0, 10000) m and `rate` in [0, 10] m/s".into(),
                    ));
                }
                if !(4..=10_000).contains(&r.samples) {
                    return Err(invalid(at, "[fire] `samples` must be in [4, 10000]".into()));
                }
                Some(Fire {
                    center: r.center,
                    radius: r.radius,
                    rate: r.rate,
                    samples: r.samples,
                })
            }
            None => None,
        };
        let relay = match &raw.relay {
            Some(s) => {
                let at = s.span().start;
                let r = s.get_ref();
                for e in &r.endpoints {
                    check_point(e).map_err(|m| invalid(at, format!("[relay] `endpoints` {m}")))?;
                }
                let chain = r.chain.unwrap_or(total);
                if chain == 0 || chain > total {
                    return Err(invalid(
                        at,
                        format!("[relay] `chain` must be in [1, {total}] (the UAVs), got {chain}"),
                    ));
                }
                Some(Relay {
                    endpoints: r.endpoints,
                    chain,
                })
            }
            None => None,
        };
        let radio = match &raw.radio {
            Some(s) => {
                let r = s.get_ref();
                let d = Radio::default();
                let radio = Radio {
                    pd0: r.pd0.unwrap_or(d.pd0),
                    d0: r.d0.unwrap_or(d.d0),
                    n: r.n.unwrap_or(d.n),
                    attenuation: r.attenuation.unwrap_or(d.attenuation),
                    cutoff: r.cutoff.unwrap_or(d.cutoff),
                };
                let ok = [radio.pd0, radio.cutoff]
                    .iter()
                    .all(|v| v.is_finite() && v.abs() < 1000.0)
                    && radio.d0 > 0.0
                    && radio.d0 < 1000.0
                    && (0.0..=10.0).contains(&radio.n)
                    && (0.0..=1000.0).contains(&radio.attenuation);
                if !ok {
                    return Err(invalid(
                        s.span().start,
                        "[radio]: `pd0`/`cutoff` in dBm (|x| < 1000), `d0` in (0, 1000) m, `n` in [0, 10], `attenuation` in [0, 1000] dB".into(),
                    ));
                }
                radio
            }
            None => Radio::default(),
        };
        let delivery = match &raw.delivery {
            Some(s) => {
                let at = s.span().start;
                let r = s.get_ref();
                if !(0.0..=100.0).contains(&r.payload) {
                    return Err(invalid(
                        at,
                        "[delivery] `payload` must be in [0, 100] kg".into(),
                    ));
                }
                for w in &r.waypoints {
                    check_point(w)
                        .map_err(|m| invalid(at, format!("[delivery] `waypoints` {m}")))?;
                }
                Some(Delivery {
                    pickup: pad(&r.pickup, "[delivery.pickup]", at)?,
                    dropoff: pad(&r.dropoff, "[delivery.dropoff]", at)?,
                    payload: r.payload,
                    waypoints: r.waypoints.clone(),
                    land: r.land,
                })
            }
            None => None,
        };
        let needs = |ok: bool, what: &str| {
            if ok {
                Ok(())
            } else {
                Err(invalid(
                    0,
                    format!("a {} scenario needs {what}", raw.kind.name()),
                ))
            }
        };
        match raw.kind {
            Kind::Search => needs(search.is_some(), "a [search] section")?,
            Kind::Relay => needs(relay.is_some(), "a [relay] section")?,
            Kind::Tracking => needs(
                !targets.is_empty() || fire.is_some(),
                "a [[target]] or a [fire]",
            )?,
            Kind::Delivery => needs(delivery.is_some(), "a [delivery] section")?,
        }
        let sharing = match &raw.blackboard {
            None => Sharing::Nothing,
            Some(v) => match v.get_ref() {
                toml::Value::Boolean(false) => Sharing::Nothing,
                toml::Value::Boolean(true) => Sharing::Blackboard,
                toml::Value::String(s) if s == "radio" => Sharing::Radio,
                other => {
                    return Err(invalid(
                        v.span().start,
                        format!("`blackboard` must be true, false or \"radio\", got {other}"),
                    ));
                }
            },
        };
        let map = match file.and_then(Path::parent) {
            Some(dir) if !usar_sim_map_embedded(&raw.map) && Path::new(&raw.map).is_relative() => {
                dir.join(&raw.map).to_string_lossy().into_owned()
            }
            _ => raw.map.clone(),
        };
        let mut scenario = Self {
            name,
            kind: raw.kind,
            description: raw.description,
            map,
            time_limit,
            seed: raw.seed,
            period,
            uavs,
            base,
            sensor,
            sharing,
            search,
            targets,
            fire,
            relay,
            radio,
            delivery,
            metrics: None,
            path: file.map(Path::to_path_buf),
        };
        if let Some(m) = &raw.metrics {
            let known: Vec<&str> = super::metrics::Tracker::new(&scenario, &[], 0)
                .finish(0.0, &scenario)
                .values
                .iter()
                .map(|(n, _)| *n)
                .collect();
            if let Some(bad) = m.get_ref().iter().find(|n| !known.contains(&n.as_str())) {
                return Err(invalid(
                    m.span().start,
                    format!(
                        "`metrics`: {bad:?} is not a metric of a {} scenario ({})",
                        raw.kind.name(),
                        known.join(", ")
                    ),
                ));
            }
            scenario.metrics = Some(m.get_ref().clone());
        }
        Ok(scenario)
    }

    /// UAVs in all.
    pub fn uav_count(&self) -> usize {
        self.uavs.iter().map(|u| u.count).sum()
    }
}

fn usar_sim_victim_class(c: &str) -> bool {
    usar_server::sim::map::VICTIM_CLASSES
        .iter()
        .any(|k| k.eq_ignore_ascii_case(c))
}

fn usar_sim_map_embedded(name: &str) -> bool {
    usar_server::sim::Map::embedded_names()
        .iter()
        .any(|n| n.eq_ignore_ascii_case(name))
}

fn check_point(p: &[f64; 3]) -> Result<(), String> {
    if p.iter().all(|v| v.is_finite() && v.abs() <= LIMIT) {
        Ok(())
    } else {
        Err(format!(
            "{p:?}: every coordinate must be a number within ±{LIMIT} m"
        ))
    }
}

fn check_area(a: &[[f64; 2]; 2]) -> Result<(), String> {
    check_point(&[a[0][0], a[0][1], 0.0])?;
    check_point(&[a[1][0], a[1][1], 0.0])?;
    if a[1][0] > a[0][0] && a[1][1] > a[0][1] {
        Ok(())
    } else {
        Err(format!(
            "{a:?}: must be [[x_min, y_min], [x_max, y_max]] with max > min"
        ))
    }
}
