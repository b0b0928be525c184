//! `GPS` (UDK's GPSSensor): latitude and longitude of the robot from the map's origin
//! (`[geo]`, docs/maps.md#geo), in UDK's format:
//! `{Name n} {Latitude d,mm.mmmm,N|S} {Longitude d,mm.mmmm,E|W} {Fix 1} {Satellites k}`, or
//! `{Name n} {Fix 0} {Satellites k}` without a fix (fewer than 4 satellites, or a map with
//! no origin).

use serde::Deserialize;
use usar_proto::{ConfItem, GpsFix, SenData};

use super::{Reading, Sensor, interval_conf, settings};
use crate::noise::{ErrorModel, Errors, Noise};
use crate::part::PartConfig;

/// WGS-84 semi-major axis, m.
const WGS84_A: f64 = 6_378_137.0;
/// WGS-84 first eccentricity squared.
const WGS84_E2: f64 = 6.694_379_990_14e-3;
/// Satellites a fix needs.
const MIN_SATELLITES: i64 = 4;

/// GPS settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GpsConfig {
    /// Errors of the horizontal position, m, on north and east (`noise` per reading, `bias`
    /// and `bias_walk` the slow wander of a fix, `latency` the delay of the receiver).
    pub error: ErrorModel,
    /// Satellites in view (`{Satellites k}`); below 4 there is no fix.
    pub satellites: i64,
}

impl Default for GpsConfig {
    fn default() -> Self {
        Self {
            error: ErrorModel::default(),
            satellites: 9,
        }
    }
}

#[derive(Debug, Clone)]
struct Gps {
    satellites: i64,
    errors: Errors<2>,
}

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let c: GpsConfig = settings(part)?;
    c.error.check(&format!("part `{}`: error", part.name))?;
    if !(0..=64).contains(&c.satellites) {
        return Err(format!(
            "part `{}`: satellites must be within [0, 64], got {}",
            part.name, c.satellites
        ));
    }
    Ok(Box::new(Gps {
        satellites: c.satellites,
        errors: Errors::new(c.error),
    }))
}

/// Latitude and longitude, degrees, of the point `north`, `east` metres from the origin
/// `lat0`, `lon0` (degrees): the local tangent plane with WGS-84's radii of curvature at the
/// origin (the meridian's and the prime vertical's), exact to a few millimetres within a
/// few kilometres. The longitude is wrapped to [-180, 180).
pub(crate) fn geodetic(lat0: f64, lon0: f64, north: f64, east: f64) -> (f64, f64) {
    let phi = lat0.to_radians();
    let w = 1.0 - WGS84_E2 * phi.sin().powi(2);
    let meridian = WGS84_A * (1.0 - WGS84_E2) / w.powf(1.5);
    let normal = WGS84_A / w.sqrt();
    let lat = lat0 + (north / meridian).to_degrees();
    let lon = lon0 + (east / (normal * phi.cos())).to_degrees();
    (lat, (lon + 180.0).rem_euclid(360.0) - 180.0)
}

/// Degrees as UDK's GPS prints them: whole degrees, minutes, hemisphere.
fn split(deg: f64, positive: char, negative: char) -> (i64, f64, char) {
    let hemisphere = if deg < 0.0 { negative } else { positive };
    let a = deg.abs();
    let whole = a.floor();
    (whole as i64, (a - whole) * 60.0, hemisphere)
}

impl Sensor for Gps {
    fn scale_noise(&mut self, k: f64) {
        self.errors.scale(k);
    }

    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let name = at.name.to_string();
        let origin = at.scene.geo.origin();
        let Some((lat0, lon0)) = origin.filter(|_| self.satellites >= MIN_SATELLITES) else {
            return SenData::Gps {
                name,
                fix: None,
                satellites: if origin.is_some() { self.satellites } else { 0 },
            };
        };
        let [north, east] = self
            .errors
            .apply([at.position[0], at.position[1]], at.time, noise)
            .map(|v| noise.apply(v));
        let (lat, lon) = geodetic(lat0, lon0, north, east);
        let (latitude_degrees, latitude_minutes, latitude_hemisphere) = split(lat, 'N', 'S');
        let (longitude_degrees, longitude_minutes, longitude_hemisphere) = split(lon, 'E', 'W');
        SenData::Gps {
            name,
            fix: Some(GpsFix {
                latitude_degrees,
                latitude_minutes,
                latitude_hemisphere,
                longitude_degrees,
                longitude_minutes,
                longitude_hemisphere,
            }),
            satellites: self.satellites,
        }
    }

    fn conf(&self, name: &str, interval: f64) -> ConfItem {
        interval_conf(name, interval)
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;
    use crate::map::GeoConfig;

    #[test]
    fn a_metre_north_and_east_is_the_wgs84_arc() {
        // At 45°: a degree of latitude is 111 132 m, of longitude 78 847 m (WGS-84).
        let (lat, lon) = geodetic(45.0, 7.0, 111_132.0, 78_847.0);
        assert!(
            (lat - 46.0).abs() < 1e-4 && (lon - 8.0).abs() < 1e-4,
            "{lat} {lon}"
        );
        assert!(geodetic(10.0, 179.9999, 0.0, 100.0).1 < -179.0, "wrapped");
    }

    #[test]
    fn prints_udks_line_and_no_fix_without_origin_or_satellites() {
        let (mut scene, me) = scene_with_wall(2.0);
        let line = |scene: &crate::scene::Scene, settings: &str| {
            let at = crate::sensors::Reading {
                position: [1852.0, 0.0, -3.0],
                ..reading(scene, me, 0.1)
            };
            let data = make("GPS", settings).read(&at, &mut quiet());
            usar_proto::ServerMessage::Sen(usar_proto::Sen { time: None, data }).to_string()
        };
        assert_eq!(
            line(&scene, ""),
            "SEN {Type GPS} {Name S} {Fix 0} {Satellites 0}"
        );
        scene.geo = GeoConfig {
            latitude: Some(47.0),
            longitude: Some(-122.5),
            ..GeoConfig::default()
        };
        // 1852 m north: a minute of latitude is 1852.85 m at 47° (WGS-84 meridian radius
        // 6 369 660 m), so 0.99954′, printed truncated to 4 decimals as UDK does.
        assert_eq!(
            line(&scene, ""),
            "SEN {Type GPS} {Name S} {Latitude 47,0.9995,N} {Longitude 122,30.0000,W} {Fix 1} {Satellites 9}"
        );
        assert_eq!(
            line(&scene, "satellites = 3"),
            "SEN {Type GPS} {Name S} {Fix 0} {Satellites 3}"
        );
    }
}
