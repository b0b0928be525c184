//! [`PartConfig`]: one sensor part of a robot class as the catalog describes it. Its own
//! module because both the catalog (`robots`) and every sensor (`sensors/`) read it, and
//! the catalog builds the sensors.

use serde::Deserialize;

/// A sensor part: where it is and what it is; type-specific settings stay in `settings` and
/// are checked against the sensor's `XxxConfig` when the catalog is read.
#[derive(Debug, Clone, Deserialize)]
pub struct PartConfig {
    /// The sensor type (`Sonar`, `RangeScanner`, `IMU`, ...; case-insensitive).
    #[serde(rename = "type")]
    pub kind: String,
    /// The part name (`{Name ..}`).
    pub name: String,
    /// Mount position, body frame (x forward, y right, z down), m.
    #[serde(default)]
    pub position: [f64; 3],
    /// Mount direction: roll, pitch (+ = up), yaw (+ = right), rad.
    #[serde(default)]
    pub direction: [f64; 3],
    /// Seconds between readings; the type's default when absent.
    #[serde(default)]
    pub interval: Option<f64>,
    /// Gaussian noise standard deviation (0 = off), in the reading's unit.
    #[serde(default)]
    pub noise: f64,
    /// The type-specific settings (the sensor's `XxxConfig` fields).
    #[serde(flatten)]
    pub settings: toml::Table,
}
