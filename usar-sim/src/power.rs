//! The quadrotor's energy: rotor power from momentum theory with a figure of merit, and a
//! lithium-polymer battery with an open-circuit voltage curve and internal resistance whose
//! terminal voltage limits the rotor speed (docs/quadrotor.md#energy, sources in
//! docs/robots.md). The kinematic robots keep USARSim's battery timer.

use serde::Deserialize;

/// The battery pack (`[robot.quadrotor.battery]`); defaults: a 3-cell 4 Ah LiPo, about
/// 20 minutes of hover for the default vehicle.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BatteryConfig {
    /// Cells in series.
    pub cells: u32,
    /// Ah, rated capacity.
    pub capacity: f64,
    /// Ω, internal resistance of the pack.
    pub internal_resistance: f64,
    /// Fraction of the capacity at which the autopilot lands (the battery then reads 0,
    /// USARSim's empty state).
    pub reserve: f64,
    /// Fraction of the electrical power the motors and ESCs turn into shaft power.
    pub motor_efficiency: f64,
    /// W drawn by the autopilot, radios and sensors.
    pub avionics_power: f64,
    /// Fraction of the capacity charged at spawn.
    pub charge: f64,
}

impl Default for BatteryConfig {
    fn default() -> Self {
        Self {
            cells: 3,
            capacity: 4.0,
            internal_resistance: 0.03,
            reserve: 0.05,
            motor_efficiency: 0.8,
            avionics_power: 5.0,
            charge: 1.0,
        }
    }
}

/// A LiPo cell's open-circuit voltage (V) at charge fractions 0, 0.1, ..., 1 (a typical
/// resting-voltage chart, docs/robots.md).
const CELL_VOLTAGE: [f64; 11] = [
    3.27, 3.69, 3.73, 3.77, 3.79, 3.82, 3.87, 3.92, 3.97, 4.10, 4.20,
];

/// s: the time constant of the current average the time left is computed from.
const AVERAGE_TIME: f64 = 2.0;

impl BatteryConfig {
    /// Checks the numbers; the message names the bad one.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=100).contains(&self.cells) {
            return Err(format!(
                "quadrotor.battery.cells must be 1 to 100, got {}",
                self.cells
            ));
        }
        for (what, v, lo, hi) in [
            ("capacity", self.capacity, 1e-6, 1e4),
            ("internal_resistance", self.internal_resistance, 0.0, 100.0),
            ("reserve", self.reserve, 0.0, 0.9),
            ("motor_efficiency", self.motor_efficiency, 0.01, 1.0),
            ("avionics_power", self.avionics_power, 0.0, 1e5),
            ("charge", self.charge, 0.0, 1.0),
        ] {
            if !(v.is_finite() && (lo..=hi).contains(&v)) {
                return Err(format!(
                    "quadrotor.battery.{what} must be within [{lo}, {hi}], got {v}"
                ));
            }
        }
        Ok(())
    }

    /// V, the pack's open-circuit voltage at the charge fraction `soc`.
    pub fn open_voltage(&self, soc: f64) -> f64 {
        let x = soc.clamp(0.0, 1.0) * 10.0;
        let i = (x.floor() as usize).min(9);
        let t = x - i as f64;
        f64::from(self.cells) * (CELL_VOLTAGE[i] + t * (CELL_VOLTAGE[i + 1] - CELL_VOLTAGE[i]))
    }

    /// V, the full pack's open-circuit voltage (the rotors reach `rotor_speed_max` there).
    pub fn full_voltage(&self) -> f64 {
        f64::from(self.cells) * CELL_VOLTAGE[10]
    }
}

/// The battery's state.
#[derive(Debug, Clone)]
pub(crate) struct Battery {
    config: BatteryConfig,
    /// Fraction of the capacity left.
    soc: f64,
    /// A, the last draw.
    current: f64,
    /// V, the terminal voltage under the last draw.
    voltage: f64,
    /// A, the draw averaged over [`AVERAGE_TIME`] (`None` before the first step).
    average: Option<f64>,
}

/// What a battery sensor reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Gauge {
    /// V at the terminals.
    pub(crate) voltage: f64,
    /// A drawn.
    pub(crate) current: f64,
    /// Fraction of the capacity left.
    pub(crate) charge: f64,
    /// s of flight left above the reserve at the average draw.
    pub(crate) time_left: f64,
}

impl Battery {
    pub(crate) fn new(config: BatteryConfig) -> Self {
        let soc = config.charge;
        let voltage = config.open_voltage(soc);
        Self {
            config,
            soc,
            current: 0.0,
            voltage,
            average: None,
        }
    }

    /// Draws the electrical power `power` (W) for `dt` seconds: the current that gives it
    /// at the terminals, `P = I·(V_oc − I·R)`, at most the battery's maximum power
    /// `V_oc²/(4R)`. Returns the terminal voltage.
    pub(crate) fn draw(&mut self, power: f64, dt: f64) -> f64 {
        let c = &self.config;
        if self.soc <= 0.0 {
            self.current = 0.0;
            self.voltage = 0.0;
            return 0.0;
        }
        let v = c.open_voltage(self.soc);
        let r = c.internal_resistance;
        let power = power.max(0.0);
        let current = if r > 0.0 {
            let disc = v * v - 4.0 * r * power;
            (v - disc.max(0.0).sqrt()) / (2.0 * r)
        } else {
            power / v
        };
        self.current = current;
        self.voltage = v - current * r;
        self.soc = (self.soc - current * dt / (c.capacity * 3600.0)).max(0.0);
        let k = 1.0 - (-dt / AVERAGE_TIME).exp();
        let average = self.average.get_or_insert(current);
        *average += (current - *average) * k;
        self.voltage
    }

    /// Fraction of the full voltage at the terminals (the rotors' top speed scales by it).
    pub(crate) fn voltage_ratio(&self) -> f64 {
        self.voltage / self.config.full_voltage()
    }

    /// Whether the charge is at or below the reserve (the autopilot lands).
    pub(crate) fn at_reserve(&self) -> bool {
        self.soc <= self.config.reserve
    }

    /// Whether no charge is left (the motors stop).
    pub(crate) fn empty(&self) -> bool {
        self.soc <= 0.0
    }

    /// Loses a fraction of the charge left (a fault).
    pub(crate) fn lose(&mut self, fraction: f64) {
        self.soc *= 1.0 - fraction.clamp(0.0, 1.0);
    }

    pub(crate) fn gauge(&self) -> Gauge {
        let above = (self.soc - self.config.reserve).max(0.0) * self.config.capacity * 3600.0;
        let average = self.average.unwrap_or(0.0);
        Gauge {
            voltage: self.voltage,
            current: self.current,
            charge: self.soc,
            time_left: if average > 1e-9 {
                above / average
            } else {
                f64::INFINITY
            },
        }
    }

    /// W, the electrical power of the rotors' shaft power `shaft` (W).
    pub(crate) fn electrical(&self, shaft: f64) -> f64 {
        shaft / self.config.motor_efficiency + self.config.avionics_power
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn voltage_curve_and_sag() {
        let c = BatteryConfig::default();
        assert!((c.open_voltage(1.0) - 12.6).abs() < 1e-9);
        assert!((c.open_voltage(0.0) - 9.81).abs() < 1e-9);
        assert!((c.open_voltage(0.55) - 3.0 * 3.845).abs() < 1e-9);
        let mut b = Battery::new(c.clone());
        let v = b.draw(120.0, 0.005);
        // P = V·I at the terminals, and V = V_oc − I·R.
        let g = b.gauge();
        assert!((g.voltage * g.current - 120.0).abs() < 1e-9);
        assert!((v - (12.6 - g.current * 0.03)).abs() < 1e-12);
        // Charge used: I·dt over the capacity.
        assert!((1.0 - g.charge - g.current * 0.005 / (4.0 * 3600.0)).abs() < 1e-15);
        assert!(c.check().is_ok());
        let bad = BatteryConfig {
            capacity: -1.0,
            ..c
        };
        assert!(bad.check().unwrap_err().contains("capacity"));
    }
}
