//! Deterministic Gaussian noise: one generator per part, seeded from `SimConfig::seed`.

/// A small deterministic random source (SplitMix64) with a Gaussian sampler.
#[derive(Debug, Clone)]
pub(crate) struct Noise {
    state: u64,
    /// Standard deviation; 0 disables the noise (and draws no numbers).
    std_dev: f64,
}

impl Noise {
    /// A generator for one part: the world seed, the robot serial and the part index are
    /// mixed so that every part gets its own repeatable stream.
    pub(crate) fn new(seed: u64, robot: u64, part: u64, std_dev: f64) -> Self {
        let mut state = seed ^ 0x9E37_79B9_7F4A_7C15;
        for v in [robot, part] {
            state = splitmix(&mut state) ^ v.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        }
        let std_dev = if std_dev.is_finite() && std_dev > 0.0 {
            std_dev
        } else {
            0.0
        };
        Self { state, std_dev }
    }

    /// `value` plus a Gaussian sample (value unchanged when the noise is off).
    pub(crate) fn apply(&mut self, value: f64) -> f64 {
        if self.std_dev == 0.0 {
            return value;
        }
        value + self.std_dev * self.gaussian()
    }

    /// A standard normal sample, whatever the standard deviation (wind gusts).
    pub(crate) fn draw(&mut self) -> f64 {
        self.gaussian()
    }

    /// A standard normal sample (Box–Muller).
    fn gaussian(&mut self) -> f64 {
        // 53 random bits → (0, 1]; never 0 so the logarithm is finite.
        let u1 = ((splitmix(&mut self.state) >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
        let u2 = (splitmix(&mut self.state) >> 11) as f64 / (1u64 << 53) as f64;
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn off_by_default_and_repeatable() {
        let mut off = Noise::new(1, 2, 3, 0.0);
        assert_eq!(off.apply(1.5), 1.5);
        let mut a = Noise::new(7, 1, 0, 0.1);
        let mut b = Noise::new(7, 1, 0, 0.1);
        let mut c = Noise::new(7, 1, 1, 0.1);
        let xs: Vec<f64> = (0..100).map(|_| a.apply(0.0)).collect();
        let ys: Vec<f64> = (0..100).map(|_| b.apply(0.0)).collect();
        let zs: Vec<f64> = (0..100).map(|_| c.apply(0.0)).collect();
        assert_eq!(xs, ys);
        assert_ne!(xs, zs);
        let mean = xs.iter().sum::<f64>() / 100.0;
        assert!(mean.abs() < 0.05, "mean {mean}");
    }
}
