//! `Camera`: an empty SEN line (images came from the image server, which is not simulated).

use serde::Deserialize;
use usar_proto::{ConfItem, SenData};

use super::{Reading, Sensor, settings};
use crate::noise::Noise;
use crate::part::PartConfig;

/// Camera settings (`[USARSensor.USARCamera]`, degrees as CONF reports them).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// Pixels.
    pub width: i64,
    /// Pixels.
    pub height: i64,
    /// Default field of view, degrees.
    pub fov: f64,
    /// Degrees.
    pub min_fov: f64,
    /// Degrees.
    pub max_fov: f64,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            width: 320,
            height: 240,
            fov: 80.0,
            min_fov: 20.0,
            max_fov: 120.0,
        }
    }
}

#[derive(Debug, Clone)]
struct Camera(CameraConfig);

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    Ok(Box::new(Camera(settings(part)?)))
}

impl Sensor for Camera {
    fn read(&mut self, _at: &Reading<'_>, _noise: &mut Noise) -> SenData {
        SenData::Camera
    }

    fn conf(&self, name: &str, _interval: f64) -> ConfItem {
        let c = &self.0;
        ConfItem::Camera {
            name: name.to_string(),
            texture_offset_x: 0,
            texture_offset_y: 0,
            texture_resolution_x: c.width,
            texture_resolution_y: c.height,
            default_fov: c.fov,
            min_fov: c.min_fov,
            max_fov: c.max_fov,
            fov: c.fov,
        }
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
}
