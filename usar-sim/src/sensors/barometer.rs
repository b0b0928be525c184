//! `Barometer` (ours, docs/robots.md#barometer): static pressure from the ICAO standard
//! atmosphere at the robot's height, with its own errors and a drift of the ambient
//! pressure, and the pressure altitude a flight controller computes from it:
//! `SEN {Time t} {Type Barometer} {Name n} {Pressure 101325.00} {Altitude 111.000}`.
//!
//! ISA troposphere (ICAO Doc 7488, *Manual of the ICAO Standard Atmosphere*):
//! `p = p₀·(1 − L·h/T₀)^(g₀M/(RL))`, p₀ = 101 325 Pa, T₀ = 288.15 K, L = 0.0065 K/m,
//! g₀M/(RL) = 5.255 88; the altitude is the same formula inverted.

use serde::Deserialize;
use usar_proto::SenData;

use super::battery::pair;
use super::{Reading, Sensor, settings};
use crate::noise::{ErrorModel, Errors, Noise};
use crate::part::PartConfig;

/// Sea-level standard pressure, Pa.
const P0: f64 = 101_325.0;
/// Sea-level standard temperature, K.
const T0: f64 = 288.15;
/// Temperature lapse rate, K/m.
const LAPSE: f64 = 0.0065;
/// g₀·M/(R·L).
const EXPONENT: f64 = 5.255_88;

/// Barometer settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct BarometerConfig {
    /// Height of the spawn point above sea level, m.
    pub sea_level: f64,
    /// Pressure errors, Pa (noise, bias, bias walk, quantum, ...). Default: the white noise
    /// of an MS5611 at its finest oversampling (RMS resolution 0.012 mbar, TE Connectivity
    /// MS5611-01BA03 datasheet), about 0.1 m of altitude.
    pub error: ErrorModel,
    /// Change of the ambient pressure, Pa/s (weather: −0.03 Pa/s is −1 hPa in an hour,
    /// which reads as about +8 m of altitude).
    pub drift: f64,
}

impl Default for BarometerConfig {
    fn default() -> Self {
        Self {
            sea_level: 111.0,
            error: ErrorModel {
                noise: 1.2,
                ..ErrorModel::default()
            },
            drift: 0.0,
        }
    }
}

#[derive(Debug, Clone)]
struct Barometer(BarometerConfig, Errors<1>);

pub(super) fn build(part: &PartConfig) -> Result<Box<dyn Sensor>, String> {
    let c: BarometerConfig = settings(part)?;
    c.error.check(&format!("part `{}`: error", part.name))?;
    if !(c.sea_level.is_finite() && (-500.0..=11_000.0).contains(&c.sea_level)) {
        return Err(format!(
            "part `{}`: sea_level must be within [-500, 11000] m (the ISA troposphere), got {}",
            part.name, c.sea_level
        ));
    }
    if !(c.drift.is_finite() && c.drift.abs() <= 100.0) {
        return Err(format!(
            "part `{}`: drift must be within ±100 Pa/s, got {}",
            part.name, c.drift
        ));
    }
    let errors = Errors::new(c.error.clone());
    Ok(Box::new(Barometer(c, errors)))
}

/// ISA static pressure at `h` metres above sea level, Pa.
pub(crate) fn isa_pressure(h: f64) -> f64 {
    P0 * (1.0 - LAPSE * h / T0).max(1e-6).powf(EXPONENT)
}

/// The pressure altitude of `p` Pa, metres.
pub(crate) fn pressure_altitude(p: f64) -> f64 {
    T0 / LAPSE * (1.0 - (p.max(1.0) / P0).powf(1.0 / EXPONENT))
}

impl Sensor for Barometer {
    fn read(&mut self, at: &Reading<'_>, noise: &mut Noise) -> SenData {
        let height = self.0.sea_level + at.spawn_z - at.position[2];
        let truth = isa_pressure(height) + self.0.drift * at.since_spawn;
        let [p] = self.1.apply([truth], at.time, noise);
        let p = noise.apply(p).max(1.0);
        SenData::Other {
            kind: "Barometer".into(),
            groups: vec![
                pair("Name", at.name.to_string()),
                pair("Pressure", format!("{p:.2}")),
                pair("Altitude", format!("{:.3}", pressure_altitude(p))),
            ],
        }
    }

    fn scale_noise(&mut self, k: f64) {
        self.1.scale(k);
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    fn read(sensor: &mut Box<dyn Sensor>, z: f64, time: f64, noise: &mut Noise) -> (f64, f64) {
        let (scene, me) = scene_with_wall(2.0);
        let at = Reading {
            position: [0.0, 0.0, z],
            ..reading(&scene, me, time)
        };
        let SenData::Other { groups, .. } = sensor.read(&at, noise) else {
            panic!()
        };
        let value = |k: &str| -> f64 {
            groups
                .iter()
                .flat_map(|g| &g.pairs)
                .find(|p| p.key == k)
                .unwrap()
                .value
                .parse()
                .unwrap()
        };
        (value("Pressure"), value("Altitude"))
    }

    #[test]
    fn the_standard_atmosphere_and_its_errors() {
        // ICAO table values: 101 325 Pa at 0 m, 89 874.6 Pa at 1000 m.
        assert!((isa_pressure(0.0) - 101_325.0).abs() < 1e-6);
        assert!((isa_pressure(1000.0) - 89_874.6).abs() < 1.0);
        assert!((pressure_altitude(isa_pressure(2345.0)) - 2345.0).abs() < 1e-6);
        // Without errors: 10 m above a spawn at sea level reads 10 m.
        let mut exact = make("Barometer", "sea_level = 0.0\n[error]\n");
        let (p, h) = read(&mut exact, -10.0, 1.0, &mut quiet());
        assert!(
            (p - isa_pressure(10.0)).abs() < 0.01 && (h - 10.0).abs() < 0.002,
            "{p} {h}"
        );
        // Default noise (1.2 Pa): about 0.1 m of altitude, σ within 10 %.
        let mut noisy = make("Barometer", "sea_level = 0.0");
        let mut rng = Noise::new(1, 2, 3, 0.0);
        let hs: Vec<f64> = (0..4000)
            .map(|k| read(&mut noisy, -10.0, f64::from(k) * 0.1, &mut rng).1)
            .collect();
        let mean = hs.iter().sum::<f64>() / hs.len() as f64;
        let std = (hs.iter().map(|h| (h - mean).powi(2)).sum::<f64>() / hs.len() as f64).sqrt();
        let per_pa = 1.0 / 12.0; // m per Pa near sea level (ρg ≈ 12 Pa/m)
        assert!((mean - 10.0).abs() < 0.01, "{mean}");
        assert!((std / (1.2 * per_pa) - 1.0).abs() < 0.1, "{std}");
        // A falling ambient pressure reads as a climb: −0.03 Pa/s for 100 s ≈ +0.25 m.
        let mut drifting = make("Barometer", "sea_level = 0.0\ndrift = -0.03\n[error]\n");
        let (_, h) = read(&mut drifting, -10.0, 100.0, &mut quiet());
        let expected = pressure_altitude(isa_pressure(10.0) - 3.0);
        assert!((h - expected).abs() < 0.002 && h > 10.2, "{h} {expected}");
        let e = build(&part("Barometer", "drift = 1e9")).unwrap_err();
        assert!(e.contains("drift"), "{e}");
    }
}
