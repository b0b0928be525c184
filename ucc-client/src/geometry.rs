//! Coordinates and the rotations between the world frame and the body frame.
//!
//! Both frames follow USARSim (protocol.md §4): right-handed, **x forward/north, y right/east,
//! z down**. Orientations are (roll, pitch, yaw) in radians; a positive yaw turns clockwise
//! seen from above, a positive pitch lifts the nose. The rotation from the body frame to the
//! world frame is `Rz(yaw)·Ry(pitch)·Rx(roll)`.

use nalgebra::{Rotation3, Vector2, Vector3};
use usar_proto::Vec3;

/// A position or a velocity in metres (per second), in the world or the body frame.
pub type Coordinates = Vector3<f64>;

/// A number as messages show it: `.1` decimals (`Num(x, 2)` → `3.14`), or scientific notation
/// from a million on (`1.00e308`: never hundreds of digits for an absurd value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64, pub usize);

impl std::fmt::Display for Num {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let Self(v, decimals) = *self;
        if v.is_finite() && v.abs() >= 1e6 {
            write!(f, "{v:.decimals$e}")
        } else {
            write!(f, "{v:.decimals$}")
        }
    }
}

/// `x,y,z` as messages show them (each a [`Num`]).
pub fn triple(v: &Coordinates, decimals: usize) -> String {
    format!(
        "{},{},{}",
        Num(v.x, decimals),
        Num(v.y, decimals),
        Num(v.z, decimals)
    )
}

/// Converts a protocol triple to a nalgebra vector.
pub fn from_wire(v: Vec3) -> Coordinates {
    Coordinates::new(v.x, v.y, v.z)
}

/// Converts a nalgebra vector to a protocol triple.
pub fn to_wire(v: &Coordinates) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

/// The rotation from the body frame to the world frame for an orientation (roll, pitch, yaw).
pub fn body_to_world(orientation: &Coordinates) -> Rotation3<f64> {
    Rotation3::from_euler_angles(orientation.x, orientation.y, orientation.z)
}

/// Expresses a world-frame vector in the body frame of a UAV with this orientation.
pub fn world_to_body_vector(v: &Coordinates, orientation: &Coordinates) -> Coordinates {
    body_to_world(orientation).inverse() * v
}

/// Expresses a body-frame vector in the world frame.
pub fn body_to_world_vector(v: &Coordinates, orientation: &Coordinates) -> Coordinates {
    body_to_world(orientation) * v
}

/// Expresses a world-frame vector in the yaw-only ("heading") frame: x along the heading,
/// y to its right, z down. The control law works in this frame, since the DRIVE set-points
/// are relative to the heading only (protocol.md §2.3).
pub fn world_to_heading(v: &Coordinates, yaw: f64) -> Coordinates {
    Rotation3::from_axis_angle(&Vector3::z_axis(), -yaw) * v
}

/// The horizontal part (x, y) of a vector.
pub fn horizontal(v: &Coordinates) -> Vector2<f64> {
    Vector2::new(v.x, v.y)
}

/// Wraps an angle to (-π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_numbers_are_shown_short() {
        assert_eq!(Num(1.23456, 2).to_string(), "1.23");
        assert_eq!(Num(-999_999.0, 1).to_string(), "-999999.0");
        assert_eq!(Num(1e308, 2).to_string(), "1.00e308");
        assert_eq!(Num(-2.5e6, 1).to_string(), "-2.5e6");
        assert_eq!(Num(f64::INFINITY, 2).to_string(), "inf");
        assert_eq!(
            triple(&Coordinates::new(1e308, 0.0, -1.0), 2),
            "1.00e308,0.00,-1.00"
        );
    }
    use std::f64::consts::FRAC_PI_2;

    fn close(a: &Coordinates, b: &Coordinates) -> bool {
        (a - b).norm() < 1e-9
    }

    #[test]
    fn yaw_right_turns_forward_to_east() {
        let o = Coordinates::new(0.0, 0.0, FRAC_PI_2);
        let forward = Coordinates::new(1.0, 0.0, 0.0);
        assert!(close(
            &body_to_world_vector(&forward, &o),
            &Coordinates::new(0.0, 1.0, 0.0)
        ));
        // A point to the east is straight ahead of a UAV heading east.
        let east = Coordinates::new(0.0, 1.0, 0.0);
        assert!(close(&world_to_heading(&east, FRAC_PI_2), &forward));
        assert!(close(&world_to_body_vector(&east, &o), &forward));
    }

    #[test]
    fn positive_pitch_lifts_the_nose() {
        let o = Coordinates::new(0.0, 0.3, 0.0);
        let nose = body_to_world_vector(&Coordinates::new(1.0, 0.0, 0.0), &o);
        assert!(nose.z < 0.0, "z is down, so a raised nose has negative z");
    }

    #[test]
    fn round_trip() {
        let o = Coordinates::new(0.1, -0.2, 2.5);
        let v = Coordinates::new(1.0, -2.0, 3.0);
        assert!(close(
            &world_to_body_vector(&body_to_world_vector(&v, &o), &o),
            &v
        ));
    }

    #[test]
    fn wraps() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-FRAC_PI_2) + FRAC_PI_2).abs() < 1e-12);
    }
}
