//! `Camera`: an empty SEN line on the control port (as USARSim); its pictures are rendered
//! on the CPU ([`crate::render`]) when asked for (`World::render_cameras`: the image server,
//! Python), from the world as it is at that moment.

use serde::Deserialize;
use usar_proto::{ConfItem, SenData};

use super::{Reading, Sensor, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

/// The largest camera side, pixels (a 10 000 × 10 000 camera is refused when the robot
/// file is read, not rendered).
pub const MAX_CAMERA_SIDE: i64 = 4096;

/// Camera settings (`[USARSensor.USARCamera]`, degrees as CONF reports them).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// Pixels, 1 to [`MAX_CAMERA_SIDE`].
    pub width: i64,
    /// Pixels, 1 to [`MAX_CAMERA_SIDE`].
    pub height: i64,
    /// Default (horizontal) field of view, degrees.
    pub fov: f64,
    /// Degrees.
    pub min_fov: f64,
    /// Degrees.
    pub max_fov: f64,
    /// The farthest depth the camera sees, m (beyond: sky).
    pub range: f64,
    /// The actuator the camera sits on (`ACT {Name ..}`, the AirRobot's `cam`): its joint
    /// 1 tilts the camera (pitch, + = up), its joint 2, if any, pans it (yaw, + = right).
    pub mount: Option<String>,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            width: 320,
            height: 240,
            fov: 80.0,
            min_fov: 20.0,
            max_fov: 120.0,
            range: 1000.0,
            mount: None,
        }
    }
}

/// A camera on a robot: its settings, its current field of view and its tile in the image
/// server's frame.
#[derive(Debug, Clone)]
pub(crate) struct Camera {
    pub(crate) config: CameraConfig,
    /// Current field of view, degrees (SET `FOV`/`Zoom`).
    pub(crate) fov: f64,
    /// Its tile in the image server's frame (cameras in spawn order, the lowest free one).
    pub(crate) tile: usize,
    /// That tile's top-left pixel (CONF `TextureOffsetX/Y`).
    pub(crate) offset: (i64, i64),
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let config: CameraConfig = settings(part)?;
    let name = &part.name;
    for (what, side) in [("width", config.width), ("height", config.height)] {
        if !(1..=MAX_CAMERA_SIDE).contains(&side) {
            return Err(format!(
                "part `{name}`: camera {what} must be 1 to {MAX_CAMERA_SIDE} pixels, got {side}"
            ));
        }
    }
    let (lo, def, hi) = (config.min_fov, config.fov, config.max_fov);
    if !(0.0 < lo && lo <= def && def <= hi && hi < 180.0) {
        return Err(format!(
            "part `{name}`: camera fields of view must satisfy 0 < min_fov <= fov <= max_fov \
             < 180 degrees, got {lo}, {def}, {hi}"
        ));
    }
    if !(config.range > 0.0 && config.range <= crate::scene::LIMIT * 4.0) {
        return Err(format!(
            "part `{name}`: camera range must be positive and at most 400000 m, got {}",
            config.range
        ));
    }
    Ok(Box::new(Camera {
        fov: config.fov,
        config,
        tile: 0,
        offset: (0, 0),
    }))
}

impl Sensor for Camera {
    fn read(&mut self, _at: &Reading<'_>, _noise: &mut Noise) -> SenData {
        SenData::Camera
    }

    fn conf(&self, name: &str, _interval: f64) -> ConfItem {
        let c = &self.config;
        ConfItem::Camera {
            name: name.to_string(),
            texture_offset_x: self.offset.0,
            texture_offset_y: self.offset.1,
            texture_resolution_x: c.width,
            texture_resolution_y: c.height,
            default_fov: c.fov,
            min_fov: c.min_fov,
            max_fov: c.max_fov,
            fov: self.fov,
        }
    }

    /// `FOV` and `Zoom`: the field of view in radians, held to the camera's limits; 0 is
    /// the default (protocol.md §2.5). No extra reading.
    fn set(&mut self, opcode: &str, params: Option<&str>) -> bool {
        if !(opcode.eq_ignore_ascii_case("FOV") || opcode.eq_ignore_ascii_case("Zoom")) {
            return false;
        }
        let Some(rad) = params.and_then(|p| p.trim().parse::<f64>().ok()) else {
            tracing::debug!(?params, "camera {opcode} without a number ignored");
            return false;
        };
        if !rad.is_finite() {
            return false;
        }
        let c = &self.config;
        self.fov = if rad == 0.0 {
            c.fov
        } else {
            rad.to_degrees().clamp(c.min_fov, c.max_fov)
        };
        false
    }

    fn camera(&self) -> Option<&Camera> {
        Some(self)
    }

    fn camera_mut(&mut self) -> Option<&mut Camera> {
        Some(self)
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    #[test]
    fn empty_reading_and_conf() {
        let (scene, me) = scene_with_wall(2.0);
        let mut camera = make("Camera", "");
        assert_eq!(
            camera.read(&reading(&scene, me, 0.1), &mut quiet()),
            SenData::Camera
        );
        let ConfItem::Camera {
            texture_resolution_x,
            fov,
            ..
        } = camera.conf("cams", 0.1)
        else {
            panic!()
        };
        assert_eq!((texture_resolution_x, fov), (320, 80.0));
    }

    #[test]
    fn fov_is_set_in_radians_within_the_limits() {
        let mut camera = make("Camera", "");
        let fov = |c: &dyn Sensor| c.camera().unwrap().fov;
        camera.set("FOV", Some("1.0"));
        assert!((fov(&*camera) - 1.0f64.to_degrees()).abs() < 1e-9);
        camera.set("Zoom", Some("3.0"));
        assert_eq!(fov(&*camera), 120.0);
        camera.set("FOV", Some("nonsense"));
        assert_eq!(fov(&*camera), 120.0);
        camera.set("FOV", Some("0"));
        assert_eq!(fov(&*camera), 80.0);
    }

    #[test]
    fn absurd_cameras_are_refused_with_the_part_named() {
        let e = (super::super::find("Camera").unwrap().build)(&part(
            "Camera",
            "width = 10000\nheight = 10000",
        ))
        .unwrap_err();
        assert!(
            e.contains("`S`") && e.contains("width") && e.contains("10000"),
            "{e}"
        );
        let e = (super::super::find("Camera").unwrap().build)(&part("Camera", "fov = 0.0"))
            .unwrap_err();
        assert!(e.contains("field"), "{e}");
    }
}
