//! What a page is sent: only what changed since its [`Cursor`]. A UAV appears in an update
//! only when something of it changed, and then only with what changed: `info` (name,
//! status, missions, options…) when it differs from what the page has, `live` when there is
//! a new sample, `files` when the list changed, and the new trail, plot, overlay and laser
//! points. UAVs removed since are listed in `removed`.
//!
//! Only what is in view in detail: once the page has said which part of the world its map
//! shows ([`Cursor::view`]), the UAVs outside it (other than the selected one) get their
//! `info` and, at most every [`SUMMARY_PERIOD`], a light `live` (time, position, attitude)
//! for the list and the 3D view; their trails, overlay and plots wait, and come (the trail
//! thinned to [`MAX_TRAIL_CATCH_UP`] points) when they are in view again. The plots' samples
//! are sent for the selected UAV only, the overlay for it and, up to [`FEW_UAVS`] UAVs, for
//! the UAVs in view.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use serde_json::{Map, Value, json};

use super::{Hub, LogLine, Uav};

/// Files named in an update: the most recent ones (the rest are in the log directory).
pub const RECENT_FILES: usize = 12;
/// Trail points sent at most at once: a longer backlog (a UAV that comes into view, a new
/// page) is thinned to about this many, its last point kept.
pub const MAX_TRAIL_CATCH_UP: usize = 500;
/// A UAV out of view is sent its light summary at most this often.
pub const SUMMARY_PERIOD: Duration = Duration::from_secs(1);
/// Up to this many UAVs the page draws every UAV's past iterations (`many` in map2d.js), so
/// the UAVs in view are sent theirs; beyond, only the selected UAV's.
pub const FEW_UAVS: usize = 50;

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
    /// The part of the world the page's map shows, `[x0, x1, y0, y1]` metres; `None` until
    /// the page says (every UAV is then in view).
    pub view: Option<[f64; 4]>,
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
    /// The last `live` sent was the full one (not the summary).
    full: bool,
    /// When the last summary was sent.
    summary: Option<Instant>,
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
            let position = u.live.as_ref().and_then(|l| l.position);
            let in_view = selected
                || match (cursor.view, position) {
                    (Some([x0, x1, y0, y1]), Some(p)) => {
                        (x0..=x1).contains(&p[0]) && (y0..=y1).contains(&p[1])
                    }
                    _ => true,
                };
            if in_view {
                if u.samples != c.samples || (selected && detail_changed) || !c.full {
                    c.samples = u.samples;
                    c.full = true;
                    out.insert(
                        "live".into(),
                        u.live.as_ref().map_or(Value::Null, |l| l.to_json(selected)),
                    );
                }
            } else if u.samples != c.samples
                && c.summary.is_none_or(|t| t.elapsed() >= SUMMARY_PERIOD)
                && let Some(l) = &u.live
            {
                c.samples = u.samples;
                c.full = false;
                c.summary = Some(Instant::now());
                out.insert("live".into(), l.summary_json());
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
            if in_view && !trail.is_empty() {
                out.insert("trail".into(), json!(thinned(trail, MAX_TRAIL_CATCH_UP)));
            }
            let history = &u.history[c.history.min(u.history.len())..];
            if selected && !history.is_empty() {
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
            let send_past = selected || (in_view && self.uavs.len() <= FEW_UAVS);
            if send_past && !past.is_empty() {
                out.insert("past".into(), json!(past));
            }
            let hits = &u.hits[c.hits.min(u.hits.len())..];
            if !hits.is_empty() {
                out.insert("hits".into(), json!(hits));
            }
            if in_view {
                c.trail = u.trail.len();
            }
            if selected {
                c.history = u.history.len();
            }
            if send_past {
                c.past = u.past.len();
            }
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

/// `points` thinned to about `max` (every k-th point, the last one kept).
fn thinned(points: &[[f32; 3]], max: usize) -> Vec<[f32; 3]> {
    if points.len() <= max {
        return points.to_vec();
    }
    let step = points.len().div_ceil(max);
    let mut out: Vec<_> = points.iter().copied().step_by(step).collect();
    if let Some(last) = points.last()
        && out.last() != Some(last)
    {
        out.push(*last);
    }
    out
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
