//! The Wireless Simulation Server's obstacle propagation model (docs/wss.md), sans I/O: the
//! one formula the WSS (`usar-server wss`), the scenarios' radio links and the Python
//! package's `signals` compute a signal with.

/// The WSS's obstacle model: the signal falls with the logarithm of the distance and a
/// fixed loss per wall between the two ends. The defaults are the original WSS's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathLoss {
    /// Signal at the reference distance `d0`, dBm.
    pub pd0: f64,
    /// Reference distance, m.
    pub d0: f64,
    /// Path-loss exponent.
    pub n: f64,
    /// Attenuation per wall, dB.
    pub attenuation: f64,
    /// Weakest usable signal, dBm.
    pub cutoff: f64,
}

impl Default for PathLoss {
    fn default() -> Self {
        Self {
            pd0: -49.67,
            d0: 2.0,
            n: 1.0,
            attenuation: 6.325,
            cutoff: -93.0,
        }
    }
}

impl PathLoss {
    /// The signal in dBm between two points with `walls` walls between them (+∞ at
    /// distance 0, as the original's).
    pub fn strength(&self, a: [f64; 3], b: [f64; 3], walls: f64) -> f64 {
        let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        self.pd0 - 10.0 * self.n * (d / self.d0).log10() - walls * self.attenuation
    }

    /// Whether a link between the two points is usable: its signal is at least `cutoff`.
    pub fn reaches(&self, a: [f64; 3], b: [f64; 3], walls: f64) -> bool {
        self.strength(a, b, walls) >= self.cutoff
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_obstacle_model_has_the_wss_defaults() {
        let c = PathLoss::default();
        let s = |d: f64, walls: f64| c.strength([0.0; 3], [d, 0.0, 0.0], walls);
        assert!((s(2.0, 0.0) - -49.67).abs() < 1e-9);
        // Five walls: in range up to about 29.6 m.
        assert!(s(29.0, 5.0) >= c.cutoff && s(30.5, 5.0) < c.cutoff);
        let at = |d: f64| [d, 0.0, 0.0];
        assert!(c.reaches([0.0; 3], at(29.0), 5.0));
        assert!(!c.reaches([0.0; 3], at(30.5), 5.0));
        assert!(
            s(2.0, 7.0) < c.cutoff,
            "seven walls cut any link of 2 m or more"
        );
        assert!(s(0.0, 0.0).is_infinite());
        assert_eq!(c.strength([1.0; 3], [1.0; 3], 3.0), f64::INFINITY);
    }
}
