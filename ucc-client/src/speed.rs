//! [`SpeedCommand`]: what an agent asks of the UAV, in percent of its maximum speeds, and
//! the DRIVE line it becomes.

use usar_proto::Drive;

/// A speed command, each component a percentage of the maximum speed in -100..=100
/// (the AirRobot's maximum is 2 m/s and 100 deg/s, protocol.md §2.3).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpeedCommand {
    /// + = forward along the heading.
    pub forward: f64,
    /// + = right of the heading.
    pub right: f64,
    /// + = climb.
    pub up: f64,
    /// + = turn clockwise seen from above (to the right).
    pub yaw: f64,
}

impl SpeedCommand {
    /// Hover in place.
    pub const STOP: Self = Self {
        forward: 0.0,
        right: 0.0,
        up: 0.0,
        yaw: 0.0,
    };

    /// The same command with every component clamped to -100..=100 (NaN becomes 0).
    pub fn clamped(self) -> Self {
        let c = |v: f64| {
            if v.is_nan() {
                0.0
            } else {
                v.clamp(-100.0, 100.0)
            }
        };
        Self {
            forward: c(self.forward),
            right: c(self.right),
            up: c(self.up),
            yaw: c(self.yaw),
        }
    }

    /// The normalized DRIVE message:
    /// `DRIVE {AltitudeVelocity up} {LinearVelocity forward} {LateralVelocity right} {RotationalVelocity yaw} {Normalized true}`,
    /// each percentage rounded to 0.01 (a readable line; finer steps are below what the
    /// server resolves).
    pub fn to_drive(self) -> Drive {
        let c = self.clamped();
        let percent = |v: f64| (v * 100.0).round() / 100.0 + 0.0; // + 0.0: no "-0"
        Drive {
            altitude_velocity: Some(percent(c.up)),
            linear_velocity: Some(percent(c.forward)),
            lateral_velocity: Some(percent(c.right)),
            rotational_velocity: Some(percent(c.yaw)),
            normalized: Some(true),
            ..Drive::default()
        }
    }
}
