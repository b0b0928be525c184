//! What a page is sent: only what changed since its [`Cursor`]. A UAV appears in an update
//! only when something of it changed, and then only with what changed: `info` (name,
//! status, missions, options…) when it differs from what the page has, `live` when there is
//! a new sample, `files` when the list changed, and the new trail, plot, overlay and laser
//! points. UAVs removed since are listed in `removed`.

use std::collections::HashMap;

use serde_json::{Map, Value, json};

use super::{Hub, LogLine, Uav};

/// Files named in an update: the most recent ones (the rest are in the log directory).
pub const RECENT_FILES: usize = 12;

/// What a page has already received, so that each update carries only what is new.
#[derive(Debug, Default, Clone)]
pub struct Cursor {
    uavs: HashMap<u32, UavCursor>,
    log_seq: u64,
    /// The UAV shown in detail.
    pub selected: Option<u32>,
    /// The detail sent was for this UAV (a new selection sends its live state again).
    detail_sent: Option<u32>,
    /// What the page has of the scenario.
    scenario: super::ScenarioCursor,
}

#[derive(Debug, Default, Clone, Copy)]
struct UavCursor {
    epoch: u64,
    past_epoch: u64,
    trail: usize,
    past: usize,
    history: usize,
    hits: usize,
    info: u64,
    samples: u64,
    files: u64,
}

fn info_json(u: &Uav) -> Value {
    json!({
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
        "pictures": match u.pictures {
            ucc_client::Pictures::All => "all",
            ucc_client::Pictures::Overlay => "overlay",
            ucc_client::Pictures::None => "none",
        },
        "autosave": u.autosave,
        "missions": u.missions.iter().map(mission_json).collect::<Vec<_>>(),
    })
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

impl Hub {
    /// The map's solids for the page: `[{outline: [[x, y], ...], z_min, z_max}]`, the
    /// victims after them with `victim` (the name) and `class`.
    pub fn geometry_json(&self) -> Value {
        geometry_json(self.geometry.as_ref())
    }

    /// The JSON update for a page: everything it has not seen yet (per `cursor`).
    pub fn update(&self, cursor: &mut Cursor) -> Value {
        let detail_changed = cursor.detail_sent != cursor.selected;
        cursor.detail_sent = cursor.selected;
        let mut uavs = Vec::new();
        for u in &self.uavs {
            let c = cursor.uavs.entry(u.id).or_default();
            let mut out = Map::new();
            let reset = c.epoch != u.trail_epoch;
            if reset {
                *c = UavCursor {
                    epoch: u.trail_epoch,
                    past: c.past.min(u.past.len()),
                    hits: c.hits.min(u.hits.len()),
                    ..*c
                };
                c.trail = 0;
                c.history = 0;
                out.insert("trail_reset".into(), true.into());
                out.insert("history_reset".into(), true.into());
            }
            if c.past_epoch != u.past_epoch {
                c.past_epoch = u.past_epoch;
                c.past = 0;
                out.insert("past_reset".into(), true.into());
            }
            if u.info_version != c.info {
                c.info = u.info_version;
                out.insert("info".into(), info_json(u));
            }
            let selected = cursor.selected == Some(u.id);
            if u.samples != c.samples || (selected && detail_changed) {
                c.samples = u.samples;
                out.insert(
                    "live".into(),
                    u.live.as_ref().map_or(Value::Null, |l| l.to_json(selected)),
                );
            }
            if u.files_version != c.files {
                c.files = u.files_version;
                let first = u.files.len().saturating_sub(RECENT_FILES);
                out.insert(
                    "files".into(),
                    json!({
                        "total": u.files.len(),
                        "recent": u.files[first..].iter().enumerate().map(|(i, f)| json!({
                            "index": first + i,
                            "name": f.file_name().map(|n| n.to_string_lossy().into_owned()),
                        })).collect::<Vec<_>>(),
                    }),
                );
            }
            let trail = &u.trail[c.trail.min(u.trail.len())..];
            if !trail.is_empty() {
                out.insert("trail".into(), json!(trail));
            }
            let history = &u.history[c.history.min(u.history.len())..];
            if !history.is_empty() {
                let h: Vec<_> = history
                    .iter()
                    .map(|h| {
                        h.map(|v| {
                            if v.is_finite() {
                                Value::from(v)
                            } else {
                                Value::Null
                            }
                        })
                    })
                    .collect();
                out.insert("history".into(), h.into());
            }
            let past = &u.past[c.past.min(u.past.len())..];
            if !past.is_empty() {
                out.insert("past".into(), json!(past));
            }
            let hits = &u.hits[c.hits.min(u.hits.len())..];
            if !hits.is_empty() {
                out.insert("hits".into(), json!(hits));
            }
            c.trail = u.trail.len();
            c.history = u.history.len();
            c.past = u.past.len();
            c.hits = u.hits.len();
            if !out.is_empty() {
                out.insert("id".into(), u.id.into());
                uavs.push(Value::Object(out));
            }
        }
        let removed: Vec<u32> = cursor
            .uavs
            .keys()
            .copied()
            .filter(|id| !self.uavs.iter().any(|u| u.id == *id))
            .collect();
        for id in &removed {
            cursor.uavs.remove(id);
        }
        let first = self.log.partition_point(|l| l.seq <= cursor.log_seq);
        let log: Vec<&LogLine> = self.log.range(first..).collect();
        if let Some(last) = log.last() {
            cursor.log_seq = last.seq;
        }
        let scenario = self.scenario_json(&mut cursor.scenario);
        let mut update = json!({
            "type": "state",
            "server": {
                "addr": self.addr,
                "local": self.local,
                "time_scale": self.time_scale.to_string(),
                "paused": self.paused,
                "map": self.map,
            },
            "uavs": uavs,
            "removed": removed,
            "log": log,
        });
        if let Some(s) = scenario {
            update["scenario"] = s;
        }
        update
    }
}

/// A map's solids for the page: `[{outline: [[x, y], ...], z_min, z_max}]`, the victims
/// after them with `victim` (the name) and `class`.
pub fn geometry_json(geometry: Option<&ucc_client::picture::MapGeometry>) -> Value {
    let solid = |f: &ucc_client::picture::Footprint| json!({"outline": f.outline.iter().map(|p| [p.0, p.1]).collect::<Vec<_>>(), "z_min": f.z_min, "z_max": f.z_max});
    geometry.map_or(Value::Null, |g| {
        // Victims are among the footprints too: drawn once, as victims.
        let victim_outlines: Vec<_> = g.victims.iter().map(|v| &v.footprint).collect();
        let solids = g
            .footprints
            .iter()
            .filter(|f| !victim_outlines.contains(f))
            .map(solid);
        let victims = g.victims.iter().map(|v| {
            let mut j = solid(&v.footprint);
            j["victim"] = v.name.clone().into();
            j["class"] = v.class.clone().into();
            j
        });
        solids.chain(victims).collect()
    })
}
