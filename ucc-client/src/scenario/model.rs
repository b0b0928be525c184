//! The scenario as data: what the file says once parsed ([`super::spec`] reads and checks
//! it), and the physics the engine and the metrics share (a landing on a pad, a payload's
//! fall). Team agents see these types; nothing here depends on the agents or the engine.

use std::path::PathBuf;

use serde::Deserialize;

/// m/s²: a dropped payload falls at this.
const GRAVITY: f64 = 9.81;

/// What a scenario is about; it decides its metrics and its picture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// Find victims or objects in an area.
    Search,
    /// Keep two endpoints connected through UAVs.
    Relay,
    /// Follow a moving target, or circle a spreading fire's perimeter.
    Tracking,
    /// Carry a payload to a pad and land.
    Delivery,
}

impl Kind {
    /// The name in files and tables.
    pub fn name(self) -> &'static str {
        match self {
            Self::Search => "search",
            Self::Relay => "relay",
            Self::Tracking => "tracking",
            Self::Delivery => "delivery",
        }
    }
}

/// A parsed and checked scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Its name (`name`, else the file's stem).
    pub name: String,
    /// What it is about.
    pub kind: Kind,
    /// One line for `--list`.
    pub description: String,
    /// An embedded map's name or a map file (relative paths are taken from the scenario
    /// file's folder).
    pub map: String,
    /// Simulated seconds an iteration lasts at most.
    pub time_limit: f64,
    /// The seed of the first iteration (iteration i flies seed + i).
    pub seed: u64,
    /// Seconds between two agent steps.
    pub period: f64,
    /// The UAV groups, in spawn order.
    pub uavs: Vec<UavGroup>,
    /// The base station: the charging pad and where searches start and end.
    pub base: Option<Pad>,
    /// The downward sensor footprint that finds victims, sees targets and covers area.
    pub sensor: Sensor,
    /// What the agents share: nothing, a blackboard (each other's positions and posted
    /// notes), or what a radio link carries (only from UAVs in range).
    pub sharing: Sharing,
    /// The search section.
    pub search: Option<Search>,
    /// Moving targets.
    pub targets: Vec<Target>,
    /// A spreading fire.
    pub fire: Option<Fire>,
    /// The relay section.
    pub relay: Option<Relay>,
    /// The radio model for links between UAVs and endpoints.
    pub radio: Radio,
    /// The delivery section.
    pub delivery: Option<Delivery>,
    /// The metrics to report (`None`: all of its kind; `time_s` is always reported).
    pub metrics: Option<Vec<String>>,
    /// The file it came from (`None`: embedded).
    pub path: Option<PathBuf>,
}

/// What the agents of a scenario know of each other (`blackboard = false | true | "radio"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sharing {
    /// Each agent knows only itself (and the scenario's shared facts).
    Nothing,
    /// Every agent sees every UAV's position and battery and every posted note.
    Blackboard,
    /// As the blackboard, but an agent sees only the UAVs (and their notes) its radio
    /// reaches: directly (the `[radio]` model, walls counted by the scene's rays) or
    /// forwarded by the UAVs in between, as a mesh of relays does.
    Radio,
}

/// UAVs of one class flown by one agent.
#[derive(Debug, Clone, PartialEq)]
pub struct UavGroup {
    /// `USARBot.stsAirRobot` etc.
    pub class: String,
    /// A team agent's name (`ucc scenario --list` shows them).
    pub agent: String,
    /// How many.
    pub count: usize,
    /// The first one's start, metres, z down.
    pub start: [f64; 3],
    /// Between two starts of the group.
    pub spacing: [f64; 3],
    /// Cruise height above the ground, metres.
    pub altitude: f64,
    /// Seconds of battery (the stsAirRobot's timer), overriding the class's.
    pub battery: Option<f64>,
}

/// A pad on the ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pad {
    /// Centre on the ground, metres, z down.
    pub location: [f64; 3],
    /// Metres.
    pub radius: f64,
    /// Seconds landed on it to be charged full (base pads only).
    pub charge_time: f64,
}

/// The downward footprint sensor (a camera looking down, as the thesis's search assumes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensor {
    /// Full field of view, degrees.
    pub fov: f64,
    /// Metres: nothing farther is seen.
    pub range: f64,
}

/// The area to search and what hides in it.
#[derive(Debug, Clone, PartialEq)]
pub struct Search {
    /// `[[x_min, y_min], [x_max, y_max]]`, metres.
    pub area: [[f64; 2]; 2],
    /// Coverage grid cell, metres.
    pub cell: f64,
    /// Victims drawn at random in the area (seeded per iteration), besides the map's.
    pub victims: usize,
    /// Their class.
    pub victim_class: String,
    /// Battery fraction at which searchers go home to recharge.
    pub reserve: f64,
}

/// A target that moves.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// Its name (USARTruth lists it).
    pub name: String,
    /// Where it starts (height above ground from z).
    pub start: [f64; 3],
    /// m/s.
    pub speed: f64,
    /// Points to visit in order (metres; z of the start is kept); empty: a random walk.
    pub path: Vec<[f64; 2]>,
    /// Back to the first point after the last.
    pub looped: bool,
    /// A random walk's area `[[x_min, y_min], [x_max, y_max]]`.
    pub bounds: Option<[[f64; 2]; 2]>,
}

/// A fire whose perimeter (a circle) grows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fire {
    /// Centre, metres.
    pub center: [f64; 2],
    /// Metres at the start.
    pub radius: f64,
    /// m/s the radius grows.
    pub rate: f64,
    /// Points along the perimeter whose revisit time is measured.
    pub samples: usize,
}

/// Two ground stations to connect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relay {
    /// The endpoints, metres, z down.
    pub endpoints: [[f64; 3]; 2],
    /// UAVs that hold the chain at once (the rest are spares that rotate in).
    pub chain: usize,
}

/// The WSS obstacle model (docs/wss.md) with the scenario's figures: the WSS's own
/// ([`usar_proto::wss::PathLoss`]), so that a scenario's links are those the WSS keeps.
pub type Radio = usar_proto::wss::PathLoss;

/// What to deliver where.
#[derive(Debug, Clone, PartialEq)]
pub struct Delivery {
    /// Where the payload waits (on the ground).
    pub pickup: Pad,
    /// Where it must go.
    pub dropoff: Pad,
    /// kg.
    pub payload: f64,
    /// Points to fly through between them (metres, z down), past the obstacles.
    pub waypoints: Vec<[f64; 3]>,
    /// Land on the pad before releasing (else drop it from the air).
    pub land: bool,
}

/// Landed on the pad: within its radius, less than half a metre above it, nearly still.
pub fn on_pad(pad: &Pad, p: [f64; 3], speed: f64) -> bool {
    (p[0] - pad.location[0]).hypot(p[1] - pad.location[1]) <= pad.radius
        && pad.location[2] - p[2] < 0.5
        && speed < 0.3
}

/// Where a payload released at `p` with velocity `v` (world frame, z down) lands on ground
/// at `ground_z`, and after how many seconds.
pub fn fall(p: [f64; 3], v: [f64; 3], ground_z: f64) -> ([f64; 3], f64) {
    let h = (ground_z - p[2]).max(0.0);
    // z down: h = v_z t + g t² / 2.
    let t = (-v[2] + (v[2] * v[2] + 2.0 * GRAVITY * h).sqrt()) / GRAVITY;
    ([p[0] + v[0] * t, p[1] + v[1] * t, ground_z], t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dropped_payload_falls_with_the_uavs_velocity() {
        // 4.905 m above the ground: 1 s of fall; moving north at 2 m/s.
        let (at, t) = fall([0.0, 0.0, -4.905], [2.0, 0.0, 0.0], 0.0);
        assert!((t - 1.0).abs() < 1e-9);
        assert!((at[0] - 2.0).abs() < 1e-9 && at[2] == 0.0);
    }
}
