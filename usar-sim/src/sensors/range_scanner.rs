//! `RangeScanner` (USARSim RangeScanner / HokuyoURG04LX / SICK): a horizontal fan of beams;
//! beam angles in integer Unreal rotation units exactly as the engine computes them, index 0
//! the rightmost.

use std::sync::Arc;

use serde::Deserialize;
use usar_proto::{ConfItem, Scan, SenData};

use super::{Reading, Sensor, f32ish, from_uu, settings, to_uu};
use crate::noise::Noise;
use crate::part::PartConfig;
use crate::scene::direction;

/// Scanner settings (defaults: `[USARSensor.RangeScanner]`; the Hokuyo sets fov 4.189,
/// resolution 0.0184086914, interval 0.3).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RangeScannerConfig {
    /// Metres; also the reading of a beam that hits nothing.
    pub max_range: f64,
    /// Metres.
    pub min_range: f64,
    /// rad between beams (rounded down to whole Unreal units).
    pub resolution: f64,
    /// rad, whole field of view (rounded down to whole Unreal units).
    pub fov: f64,
}

// 3.14 is the ini's `ScanFov`, not π.
#[allow(clippy::approx_constant)]
impl Default for RangeScannerConfig {
    fn default() -> Self {
        Self {
            max_range: 4.0,
            min_range: 0.1,
            resolution: 0.157,
            fov: 3.14,
        }
    }
}

#[derive(Debug, Clone)]
struct RangeScanner {
    config: RangeScannerConfig,
    /// The reported `{Resolution}` and `{FOV}`: the whole-unit values, as the engine's f32.
    resolution: f64,
    fov: f64,
    /// Cosine and sine of each beam's yaw offset (+ = right); index 0 is the rightmost.
    /// Precomputed: a scan then costs one sin/cos instead of 228. Shared by every robot of
    /// the class.
    beams: Arc<[(f64, f64)]>,
    /// Each beam's yaw offset, rad (largest first, as `beams`).
    offsets: Arc<[f64]>,
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let config: RangeScannerConfig = settings(part)?;
    if !(config.min_range >= 0.0 && config.max_range > config.min_range) {
        return Err(format!(
            "part `{}`: need 0 <= min_range < max_range",
            part.name
        ));
    }
    if config.max_range > crate::map::LIMIT {
        return Err(format!(
            "part `{}`: max_range must be at most {} m",
            part.name,
            crate::map::LIMIT
        ));
    }
    let fov_uu = to_uu(config.fov);
    let res_uu = to_uu(config.resolution);
    if !(1..=65_536).contains(&fov_uu) || !(1..=fov_uu).contains(&res_uu) {
        return Err(format!(
            "part `{}`: need 0 < resolution <= fov <= 2π",
            part.name
        ));
    }
    let offsets: Arc<[f64]> = (0..)
        .map(|k| fov_uu / 2 - k * res_uu)
        .take_while(|&uu| uu >= -fov_uu / 2)
        .map(from_uu)
        .collect();
    let beams = offsets
        .iter()
        .map(|a| {
            let (sin, cos) = a.sin_cos();
            (cos, sin)
        })
        .collect();
    Ok(Box::new(RangeScanner {
        offsets,
        resolution: from_uu(res_uu),
        fov: from_uu(fov_uu),
        config,
        beams,
    }))
}

impl Sensor for RangeScanner {
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let (min, max) = (self.config.min_range, self.config.max_range);
        let [cx, cy, z] = direction(at.pitch, at.yaw);
        // The heading's direction turned by each beam's offset about the vertical.
        let dirs: Vec<_> = self
            .beams
            .iter()
            .map(|&(cos, sin)| [cx * cos - cy * sin, cy * cos + cx * sin, z])
            .collect();
        let mut hits = Vec::with_capacity(dirs.len());
        at.trace_fan(&dirs, at.yaw, &self.offsets, max, &mut hits);
        let ranges = hits
            .into_iter()
            .map(|hit| noise.apply(hit.unwrap_or(max)).clamp(min, max))
            .collect();
        SenData::RangeScanner(Scan {
            kind: "RangeScanner".to_string(),
            name: at.name.to_string(),
            resolution: self.resolution,
            fov: self.fov,
            ranges,
            range_decimals: 2,
        })
    }

    fn conf(&self, name: &str, _interval: f64) -> ConfItem {
        ConfItem::Scanner {
            name: name.to_string(),
            max_range: f32ish(self.config.max_range),
            min_range: f32ish(self.config.min_range),
            resolution: self.resolution,
            fov: self.fov,
            panning: true,
            tilting: false,
            paning_typo: false,
        }
    }

    fn set(&mut self, opcode: &str, _params: Option<&str>) -> bool {
        opcode.eq_ignore_ascii_case("SCAN")
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    const HOKUYO: &str = "fov = 4.189\nresolution = 0.0184086914\n";

    fn scan(data: SenData) -> Scan {
        match data {
            SenData::RangeScanner(scan) => scan,
            other => panic!("not a scan: {other:?}"),
        }
    }

    #[test]
    fn hokuyo_beams_match_the_engine() {
        let (scene, me) = scene_with_wall(2.0);
        let mut hokuyo = make("RangeScanner", HOKUYO);
        let s = scan(hokuyo.read(&reading(&scene, me, 0.3), &mut quiet()));
        assert_eq!(s.ranges.len(), 228);
        assert_eq!(format!("{:.4}", s.resolution), "0.0184");
        assert!((s.fov - 43_692.0 / 10_430.378).abs() < 1e-6);
        // The middle beam (index 114: 21846 - 114*192 = -42 UU) sees the wall at 2 m.
        assert!((s.ranges[114] - 2.0).abs() < 1e-3, "{}", s.ranges[114]);
        // Beams past ±90° see nothing within 4 m.
        assert_eq!(s.ranges[0], 4.0);
        assert_eq!(s.ranges[227], 4.0);
    }

    #[test]
    fn index_zero_looks_right() {
        // Face west: the wall (north) is then on the right; the first beams (rightmost,
        // +120°..+90°) do not reach it but the beam at +90° (index 11 or so) does.
        let (scene, me) = scene_with_wall(1.0);
        let mut hokuyo = make("RangeScanner", HOKUYO);
        let west = Reading {
            yaw: -std::f64::consts::FRAC_PI_2,
            ..reading(&scene, me, 0.3)
        };
        let s = scan(hokuyo.read(&west, &mut quiet()));
        let first_hit = s.ranges.iter().position(|&r| r < 4.0).unwrap();
        assert!(first_hit < 20, "first hit at {first_hit}");
        assert!(s.ranges[200..].iter().all(|&r| r == 4.0));
        // Exactly right of a west-facing robot is north: +90° is 21846-192*k = 16384 → k≈28.
        assert!((s.ranges[28] - 1.0).abs() < 0.01, "{}", s.ranges[28]);
    }

    #[test]
    fn scan_opcode_and_conf() {
        let mut sensor = make("RangeScanner", HOKUYO);
        assert!(sensor.set("scan", None));
        assert!(!sensor.set("RESET", None));
        let ConfItem::Scanner { fov, max_range, .. } = sensor.conf("Scanner", 0.3) else {
            panic!("not a scanner conf")
        };
        assert_eq!(format!("{fov:.4}"), "4.1889");
        assert_eq!(max_range, 4.0);
    }
}
