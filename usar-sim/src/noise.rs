//! Deterministic Gaussian noise: one generator per part, seeded from `SimConfig::seed`;
//! and the sensor error model ([`ErrorModel`]) the IMU, altimeter, compass and position
//! sensors take from their part settings (docs/robots.md#sensor-error-models).

use std::collections::VecDeque;

use serde::Deserialize;

/// A sensor's errors (all off by default, as in USARSim): reading =
/// `quantise(saturate((1 + scale)·truth(t − latency) + bias(t) + noise·n))`, `n` standard
/// normal per reading; `bias(t)` starts at `bias·n₀` (turn-on bias) and walks by
/// `bias_walk·sqrt(Δt)·n` between readings (rate random walk).
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ErrorModel {
    /// Standard deviation of the white noise of one reading, in the reading's unit.
    pub noise: f64,
    /// Standard deviation of the turn-on bias.
    pub bias: f64,
    /// Bias random walk, unit/√s.
    pub bias_walk: f64,
    /// Scale-factor error (0.01: readings 1 % too large).
    pub scale: f64,
    /// Largest magnitude a reading can have (0: none).
    pub saturation: f64,
    /// Resolution: readings are whole multiples of it (0: continuous).
    pub quantum: f64,
    /// s: a reading reports the truth this long ago (rounded up to whole readings).
    pub latency: f64,
}

impl ErrorModel {
    /// Checks the numbers; `what` names the part and setting in the message.
    pub fn check(&self, what: &str) -> Result<(), String> {
        for (key, v, max) in [
            ("noise", self.noise, 1e6),
            ("bias", self.bias, 1e6),
            ("bias_walk", self.bias_walk, 1e6),
            ("saturation", self.saturation, 1e9),
            ("quantum", self.quantum, 1e6),
            ("latency", self.latency, 10.0),
        ] {
            if !(v.is_finite() && (0.0..=max).contains(&v)) {
                return Err(format!("{what}.{key} must be within [0, {max}], got {v}"));
            }
        }
        if !(self.scale.is_finite() && self.scale.abs() <= 1.0) {
            return Err(format!(
                "{what}.scale must be within [-1, 1], got {}",
                self.scale
            ));
        }
        Ok(())
    }

    fn is_off(&self) -> bool {
        *self == Self::default()
    }

    /// Noise, bias and bias walk times `k` (domain randomisation).
    pub(crate) fn scale(&mut self, k: f64) {
        self.noise *= k;
        self.bias *= k;
        self.bias_walk *= k;
    }
}

/// The state of an [`ErrorModel`] on `N` axes.
#[derive(Debug)]
pub(crate) struct Errors<const N: usize> {
    model: ErrorModel,
    bias: Option<[f64; N]>,
    last: f64,
    history: VecDeque<(f64, [f64; N])>,
}

impl<const N: usize> Clone for Errors<N> {
    /// The copy a robot's sensors take of its model's at each spawn: an empty history (any
    /// model without latency, and every model's before its first reading) without a call
    /// into `VecDeque::clone`.
    fn clone(&self) -> Self {
        Self {
            model: self.model.clone(),
            bias: self.bias,
            last: self.last,
            history: if self.history.is_empty() {
                VecDeque::new()
            } else {
                self.history.clone()
            },
        }
    }
}

impl<const N: usize> Errors<N> {
    pub(crate) fn new(model: ErrorModel) -> Self {
        Self {
            model,
            bias: None,
            last: 0.0,
            history: VecDeque::new(),
        }
    }

    /// Its noise, bias and bias walk times `k`.
    pub(crate) fn scale(&mut self, k: f64) {
        self.model.scale(k);
    }

    /// The reading at `time` of the true value `truth` (no random numbers are drawn when
    /// the model is off: outputs stay byte-identical).
    pub(crate) fn apply(&mut self, truth: [f64; N], time: f64, rng: &mut Noise) -> [f64; N] {
        let m = &self.model;
        if m.is_off() {
            return truth;
        }
        let mut value = truth;
        if m.latency > 0.0 {
            self.history.push_back((time, truth));
            while self
                .history
                .get(1)
                .is_some_and(|&(t, _)| t <= time - m.latency + 1e-9)
            {
                self.history.pop_front();
            }
            value = self.history.front().map_or(truth, |h| h.1);
        }
        let bias = match &mut self.bias {
            None => self
                .bias
                .insert(std::array::from_fn(|_| m.bias * rng.draw())),
            Some(b) => {
                let dt = (time - self.last).max(0.0);
                if m.bias_walk > 0.0 {
                    for x in b.iter_mut() {
                        *x += m.bias_walk * dt.sqrt() * rng.draw();
                    }
                }
                b
            }
        };
        self.last = time;
        std::array::from_fn(|i| {
            let mut v = (1.0 + m.scale) * value[i] + bias[i];
            if m.noise > 0.0 {
                v += m.noise * rng.draw();
            }
            if m.quantum > 0.0 {
                v = (v / m.quantum).round() * m.quantum;
            }
            if m.saturation > 0.0 {
                v = v.clamp(-m.saturation, m.saturation);
            }
            v
        })
    }
}

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

    /// Its standard deviation times `k`.
    pub(crate) fn scale(&mut self, k: f64) {
        self.std_dev *= k;
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

    /// A uniform sample in [0, 1).
    pub(crate) fn uniform(&mut self) -> f64 {
        (splitmix(&mut self.state) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A standard normal sample (Box–Muller).
    fn gaussian(&mut self) -> f64 {
        // 53 random bits → (0, 1]; never 0 so the logarithm is finite.
        let u1 = ((splitmix(&mut self.state) >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
        let u2 = (splitmix(&mut self.state) >> 11) as f64 / (1u64 << 53) as f64;
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// SplitMix64: advances `state` by the golden-ratio increment and returns its mix (the
/// Python package's per-sub-environment streams draw with it too).
pub fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Overlapping Allan deviation of `y` sampled every `t` seconds at `τ = m·t`.
    fn allan(y: &[f64], t: f64, m: usize) -> f64 {
        let mut x = vec![0.0];
        for v in y {
            x.push(x[x.len() - 1] + v * t);
        }
        let tau = m as f64 * t;
        let n = x.len() - 2 * m;
        let sum: f64 = (0..n)
            .map(|k| (x[k + 2 * m] - 2.0 * x[k + m] + x[k]).powi(2))
            .sum();
        (sum / (2.0 * tau * tau * n as f64)).sqrt()
    }

    /// Ten minutes of a still gyro read at 100 Hz.
    fn still_record(model: ErrorModel, seed: u64) -> Vec<f64> {
        let mut errors = Errors::<1>::new(model);
        let mut rng = Noise::new(seed, 1, 2, 0.0);
        (0..60_000)
            .map(|k| errors.apply([0.0], f64::from(k) * 0.01, &mut rng)[0])
            .collect()
    }

    #[test]
    fn allan_deviation_of_a_ten_minute_still_record_matches_the_configuration() {
        // White noise: σ(τ) = N/√τ with the density N = noise·√T.
        let noise = 0.003;
        let y = still_record(
            ErrorModel {
                noise,
                ..ErrorModel::default()
            },
            5,
        );
        for m in [10, 100, 300] {
            let tau = m as f64 * 0.01;
            let expected = noise * (0.01f64 / tau).sqrt();
            let got = allan(&y, 0.01, m);
            assert!(
                (got / expected - 1.0).abs() < 0.1,
                "white: τ {tau} s: σ {got:.3e}, N/√τ {expected:.3e}"
            );
        }
        // Bias random walk: σ(τ) = K·sqrt(τ/3).
        let k = 1e-4;
        let y = still_record(
            ErrorModel {
                bias_walk: k,
                ..ErrorModel::default()
            },
            6,
        );
        for m in [100, 1000] {
            let tau = m as f64 * 0.01;
            let expected = k * (tau / 3.0).sqrt();
            let got = allan(&y, 0.01, m);
            assert!(
                (got / expected - 1.0).abs() < 0.2,
                "walk: τ {tau} s: σ {got:.3e}, K·sqrt(τ/3) {expected:.3e}"
            );
        }
    }

    #[test]
    fn scale_bias_quantum_saturation_and_latency() {
        let mut rng = Noise::new(1, 1, 1, 0.0);
        let mut e = Errors::<1>::new(ErrorModel {
            scale: 0.1,
            quantum: 0.5,
            saturation: 4.0,
            latency: 0.2,
            ..ErrorModel::default()
        });
        // Truth 1, 2, 3, 10 at 0.1 s intervals; latency 0.2 s: two readings late.
        let out: Vec<f64> = [1.0, 2.0, 3.0, 10.0]
            .iter()
            .enumerate()
            .map(|(k, &v)| e.apply([v], k as f64 * 0.1, &mut rng)[0])
            .collect();
        assert_eq!(out, vec![1.0, 1.0, 1.0, 2.0]);
        let mut e = Errors::<1>::new(ErrorModel {
            scale: 0.1,
            quantum: 0.5,
            saturation: 4.0,
            ..ErrorModel::default()
        });
        assert_eq!(e.apply([3.0], 0.0, &mut rng), [3.5]);
        assert_eq!(e.apply([10.0], 0.1, &mut rng), [4.0]);
        assert!(
            ErrorModel {
                noise: -1.0,
                ..ErrorModel::default()
            }
            .check("IMU.accel")
            .unwrap_err()
            .contains("IMU.accel.noise")
        );
    }

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
