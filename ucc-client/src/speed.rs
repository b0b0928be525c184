//! [`SpeedCommand`]: what an agent asks of the UAV, in percent of its maximum speeds, and
//! the DRIVE line it becomes.

use usar_proto::Drive;

/// m/s at a linear, lateral or altitude command of 100 % (the AirRobot's maximum,
/// protocol.md §2.3).
pub const FULL_SPEED: f64 = 2.0;

/// deg/s at a yaw command of 100 % (the AirRobot's maximum).
pub const FULL_TURN: f64 = 100.0;

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

/// `x.round()` (half away from zero) for |x| below 2⁵², up to the sign of a zero result:
/// through an integer, where `round` is a library call on baseline x86-64 (a DRIVE per UAV
/// and step of a Python batch).
fn round_small(x: f64) -> f64 {
    // Truncation through i64 is exact here, and so is the fraction left.
    let t = x as i64 as f64;
    let f = x - t;
    if f >= 0.5 {
        t + 1.0
    } else if f <= -0.5 {
        t - 1.0
    } else {
        t
    }
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
        let percent = |v: f64| round_small(v * 100.0) / 100.0 + 0.0; // + 0.0: no "-0"
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_through_an_integer_is_round() {
        let mut seed = 0x2545_F491_4F6C_DD1D_u64;
        let mut values = vec![
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            0.49999999999999994,
            -0.49999999999999994,
        ];
        values.extend([
            4503599627370495.5,
            -4503599627370495.5,
            9999.5,
            -9999.5,
            1e4,
            -1e4,
        ]);
        for _ in 0..100_000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
            values.push((u - 0.5) * 2e4);
            // Percentages of a clamped command, as to_drive rounds them.
            values.push(((u - 0.5) * 200.0) * 100.0);
        }
        for x in values {
            let (ours, rounded) = (round_small(x), x.round());
            if rounded == 0.0 {
                // (A zero may differ in sign: to_drive adds 0.0.)
                assert_eq!(ours, 0.0, "{x}");
            } else {
                assert_eq!(ours.to_bits(), rounded.to_bits(), "{x}");
            }
        }
    }
}
