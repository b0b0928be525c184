//! Value types shared by the typed messages, the number formatters and the value reader
//! (a module of their own, which imports nothing of the crate).

/// A plain triple of numbers: a position (metres), a velocity, a rotation (roll, pitch, yaw in
/// radians)... `usar-proto` stays free of math libraries; callers convert.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Vec3 {
    /// First component (x, or roll).
    pub x: f64,
    /// Second component (y, or pitch).
    pub y: f64,
    /// Third component (z, or yaw).
    pub z: f64,
}

impl Vec3 {
    /// A vector from its three components.
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Self { x, y, z }
    }
}

impl From<[f64; 3]> for Vec3 {
    fn from([x, y, z]: [f64; 3]) -> Self {
        Self { x, y, z }
    }
}

impl From<Vec3> for [f64; 3] {
    fn from(v: Vec3) -> Self {
        [v.x, v.y, v.z]
    }
}

/// A `{Time t}` stamp: game seconds, and how many decimals the server printed.
///
/// UDK-USARSim prints 4 decimals (`{Time 477.7582}`); UT2004-era servers printed 2
/// (`{Time 45.14}`). Keeping the count lets a parsed line be printed back byte for byte.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Time {
    /// Game seconds since the map was loaded.
    pub seconds: f64,
    /// Decimals printed: 4 for UDK (the default), 2 for UT2004.
    #[cfg_attr(feature = "serde", serde(default = "udk_time_decimals"))]
    pub decimals: u8,
}

#[cfg(feature = "serde")]
fn udk_time_decimals() -> u8 {
    4
}

impl Time {
    /// A UDK time stamp (printed with 4 decimals).
    pub const fn udk(seconds: f64) -> Self {
        Self {
            seconds,
            decimals: 4,
        }
    }
}
