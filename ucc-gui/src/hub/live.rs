//! The latest state of a UAV as the live panel shows it, made from the client's [`UavState`].

use serde_json::{Value, json};
use ucc_client::UavState;

/// A number for the page: `null` when not finite (JSON has no NaN).
fn finite(v: f64) -> Value {
    if v.is_finite() {
        Value::from(v)
    } else {
        Value::Null
    }
}

/// The latest state of a UAV, as the live panel shows it.
#[derive(Debug, Clone, Default)]
pub struct Live {
    /// Simulated seconds.
    pub time: f64,
    /// Metres, world frame, z down.
    pub position: Option<[f64; 3]>,
    /// Roll, pitch, yaw, radians.
    pub attitude: Option<[f64; 3]>,
    /// m/s, world frame.
    pub velocity: Option<[f64; 3]>,
    /// Level (1 = full) and remaining seconds.
    pub battery: Option<(f64, i64)>,
    /// Ranges (index 0 rightmost), resolution and field of view (radians).
    pub laser: Option<(Vec<f64>, f64, f64)>,
    /// The horizontal sonars, metres.
    pub sonars: Vec<Option<f64>>,
    /// Free space above and below, metres.
    pub free: (Option<f64>, Option<f64>),
    /// Altitude sensor, metres.
    pub altitude: Option<f64>,
    /// The command in force: forward, right, up, yaw.
    pub command: Option<[f64; 4]>,
    /// Laser hits of this sample in the world frame (x, y).
    pub hits: Vec<[f64; 2]>,
    /// Faults the server applied so far (`--faults`) and the latest: time and what.
    pub faults: (usize, Option<(f64, String)>),
}

impl Live {
    /// The live state of `uav` at simulated `time`; with `hits`, the laser's hits in the
    /// world frame (the map of a server without geometry).
    pub fn of(
        time: f64,
        uav: &UavState,
        command: Option<ucc_client::SpeedCommand>,
        hits: bool,
    ) -> Self {
        let v3 = |c: &ucc_client::Coordinates| [c.x, c.y, c.z];
        let position = uav.position.as_ref().map(|p| v3(&p.value));
        let laser = uav.laser.as_ref().map(|l| l.value.clone());
        let mut live = Self {
            time,
            position,
            attitude: uav.orientation.as_ref().map(|o| v3(&o.value)),
            velocity: uav.velocity.as_ref().map(|v| v3(&v.value)),
            battery: uav
                .battery
                .as_ref()
                .map(|b| (b.value.level, b.value.remaining)),
            laser: laser
                .as_ref()
                .map(|l| (l.ranges.clone(), l.resolution, l.fov)),
            sonars: uav
                .sonars
                .iter()
                .map(|s| s.as_ref().map(|r| r.value))
                .collect(),
            free: (
                uav.free_above.as_ref().map(|r| r.value),
                uav.free_below.as_ref().map(|r| r.value),
            ),
            altitude: uav.altitude.as_ref().map(|r| r.value),
            command: command.map(|c| [c.forward, c.right, c.up, c.yaw]),
            hits: Vec::new(),
            faults: (
                uav.faults.len(),
                uav.faults.last().map(|f| (f.time, f.value.clone())),
            ),
        };
        if hits && let (Some(p), Some(l)) = (uav.position.as_ref(), laser) {
            let hits = l.hits(&p.value, uav.yaw());
            live.hits.extend(hits.map(|(_, h)| [h.x, h.y]));
        }
        live
    }

    /// The light summary of a UAV out of the page's view: time, position, attitude.
    pub fn summary_json(&self) -> Value {
        let arr = |a: &Option<[f64; 3]>| a.map(|a| a.map(finite));
        json!({
            "time": finite(self.time),
            "position": arr(&self.position),
            "attitude": arr(&self.attitude),
            "summary": true,
        })
    }

    /// The JSON of the live panel; the laser and sonars only for the selected UAV.
    pub fn to_json(&self, detail: bool) -> Value {
        let arr = |a: &Option<[f64; 3]>| a.map(|a| a.map(finite));
        let mut v = json!({
            "time": finite(self.time),
            "position": arr(&self.position),
            "attitude": arr(&self.attitude),
            "velocity": arr(&self.velocity),
            "battery": self.battery.map(|b| json!({"level": finite(b.0), "remaining": b.1})),
        });
        if let (count, Some((time, what))) = &self.faults {
            v["faults"] = json!({"count": count, "time": finite(*time), "last": what});
        }
        if detail {
            v["laser"] = self
                .laser
                .as_ref()
                .map_or(Value::Null, |l| json!({"ranges": l.0.iter().map(|r| finite(*r)).collect::<Vec<_>>(), "resolution": finite(l.1), "fov": finite(l.2)}));
            v["sonars"] = self
                .sonars
                .iter()
                .map(|s| s.map_or(Value::Null, finite))
                .collect();
            v["free_above"] = self.free.0.map_or(Value::Null, finite);
            v["free_below"] = self.free.1.map_or(Value::Null, finite);
            v["altitude"] = self.altitude.map_or(Value::Null, finite);
            v["command"] = self
                .command
                .map_or(Value::Null, |c| c.map(finite).into_iter().collect());
        }
        v
    }
}
