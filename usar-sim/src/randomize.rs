//! Domain randomisation (`--randomize FILE`, docs/quadrotor.md#domain-randomisation): each
//! robot spawned draws its parameters from uniform ranges, seeded by the world's seed and
//! its spawn number, so the same seed gives the same draws.
//!
//! ```toml
//! mass = [0.9, 1.2]      # × the class's mass
//! wind = [0.0, 3.0]      # m/s, mean wind, direction uniform
//! ```

use super::noise::Noise;
use super::quadrotor::QuadrotorConfig;
use super::wind::WindConfig;

/// The keys, in the order they are drawn, and what they scale or set.
pub const KEYS: [(&str, &str); 9] = [
    ("mass", "× the class's mass"),
    ("inertia", "× each principal moment of inertia"),
    ("kf", "× the thrust coefficient k_F"),
    ("km", "× the drag-torque coefficient k_M"),
    ("motor_time_constant", "× both motor time constants"),
    ("drag", "× both drag coefficients"),
    ("wind", "mean horizontal wind, m/s (direction uniform)"),
    ("gusts", "gust intensity σ, m/s"),
    ("noise", "× every sensor's noise, bias and bias walk"),
];

/// Stream number of the draws (apart from every part's and fault's).
const STREAM: u64 = 1 << 41;

/// The ranges of a randomisation file: `[min, max]` per key (absent keys are not drawn).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Randomization {
    ranges: [Option<(f64, f64)>; KEYS.len()],
}

/// One robot's draws: each configured key and its value.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Drawn(pub Vec<(&'static str, f64)>);

impl Drawn {
    /// The value of `key`, if it was drawn.
    pub fn get(&self, key: &str) -> Option<f64> {
        self.0.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)
    }
}

/// The line of the text where `key` is set (1-based), for messages.
fn line_of(text: &str, key: &str) -> usize {
    text.lines()
        .position(|l| {
            l.trim_start()
                .strip_prefix(key)
                .is_some_and(|r| r.trim_start().starts_with('='))
        })
        .map_or(0, |i| i + 1)
}

impl Randomization {
    /// Parses a randomisation file; the error names the line and the key.
    pub fn from_toml(text: &str) -> Result<Self, String> {
        let table: toml::Table = text.parse().map_err(|e: toml::de::Error| e.to_string())?;
        let mut ranges = [None; KEYS.len()];
        for (key, value) in &table {
            let at = format!("line {}: key `{key}`", line_of(text, key));
            let Some(i) = KEYS.iter().position(|(k, _)| k == key) else {
                let known: Vec<&str> = KEYS.iter().map(|k| k.0).collect();
                return Err(format!("{at}: unknown key (known: {})", known.join(", ")));
            };
            let numbers: Option<Vec<f64>> = value.as_array().and_then(|a| {
                a.iter()
                    .map(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
                    .collect()
            });
            let (lo, hi) = match numbers.as_deref() {
                Some(&[lo, hi]) => (lo, hi),
                _ => return Err(format!("{at}: expected [min, max], got {value}")),
            };
            let absolute = matches!(key.as_str(), "wind" | "gusts");
            let ok = lo.is_finite()
                && hi.is_finite()
                && lo <= hi
                && if absolute {
                    lo >= 0.0 && hi <= 100.0
                } else {
                    lo > 0.0 && hi <= 100.0
                };
            if !ok {
                let rule = if absolute {
                    "0 <= min <= max <= 100"
                } else {
                    "0 < min <= max <= 100 (a factor)"
                };
                return Err(format!(
                    "{at}: expected [min, max] with {rule}, got {value}"
                ));
            }
            ranges[i] = Some((lo, hi));
        }
        Ok(Self { ranges })
    }

    /// Reads and parses a randomisation file; the error names the file.
    pub fn from_file(path: &std::path::Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::from_toml(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// The draws of robot `serial` (spawn number from 0) in a world seeded `seed`: one
    /// uniform number per key whether it is configured or not (adding a key leaves the
    /// others' draws as they were).
    pub fn draw(&self, seed: u64, serial: u64) -> Drawn {
        let mut rng = Noise::new(seed, serial, STREAM, 0.0);
        let mut out = Vec::new();
        for ((key, _), range) in KEYS.iter().zip(&self.ranges) {
            let u = rng.uniform();
            if let Some((lo, hi)) = range {
                out.push((*key, lo + (hi - lo) * u));
            }
        }
        if self.ranges[6].is_some() {
            out.push(("wind_direction", rng.uniform() * std::f64::consts::TAU));
        }
        Drawn(out)
    }
}

impl Drawn {
    /// Applies the draws to a quadrotor's parameters.
    pub(crate) fn apply(&self, q: &mut QuadrotorConfig) {
        let f = |k: &str| self.get(k).unwrap_or(1.0);
        q.mass *= f("mass");
        q.inertia = q.inertia.map(|i| i * f("inertia"));
        q.thrust_coefficient *= f("kf");
        q.torque_coefficient *= f("km");
        q.motor_time_constant *= f("motor_time_constant");
        q.motor_time_constant_down *= f("motor_time_constant");
        q.drag_linear *= f("drag");
        q.drag_quadratic *= f("drag");
    }

    /// The wind with the drawn mean and gusts (the rest as given).
    pub(crate) fn wind(&self, mut wind: WindConfig) -> WindConfig {
        if let (Some(speed), Some(dir)) = (self.get("wind"), self.get("wind_direction")) {
            wind.velocity = [speed * dir.cos(), speed * dir.sin(), 0.0];
        }
        if let Some(g) = self.get("gusts") {
            wind.gusts = g;
        }
        wind
    }

    /// The `{Key value}` groups of the notice to the robot's connection.
    pub(crate) fn groups(&self) -> Vec<usar_proto::Group> {
        self.0
            .iter()
            .map(|(k, v)| {
                let mut value = String::new();
                usar_proto::format::push_fixed(&mut value, *v, 4);
                usar_proto::Group {
                    pairs: vec![usar_proto::Pair {
                        key: (*k).to_string(),
                        value,
                    }],
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_files_name_the_line_and_key() {
        let e = Randomization::from_toml("mass = [0.9, 1.1]\nkf = [1.2, 1.1]\n").unwrap_err();
        assert!(
            e.contains("line 2: key `kf`") && e.contains("min <= max"),
            "{e}"
        );
        let e = Randomization::from_toml("# x\nmas = [1, 2]\n").unwrap_err();
        assert!(e.contains("line 2: key `mas`: unknown key"), "{e}");
        let e = Randomization::from_toml("wind = 3\n").unwrap_err();
        assert!(e.contains("line 1: key `wind`: expected [min, max]"), "{e}");
        let e = Randomization::from_toml("mass = [0, 1]\n").unwrap_err();
        assert!(e.contains("a factor"), "{e}");
        assert!(Randomization::from_toml("mass = [").is_err());
    }

    #[test]
    fn the_same_seed_draws_the_same_and_robots_differ() {
        let r = Randomization::from_toml("mass = [0.8, 1.2]\nwind = [0, 3]\n").unwrap();
        let a = r.draw(7, 0);
        assert_eq!(a, r.draw(7, 0));
        assert_ne!(a.get("mass"), r.draw(7, 1).get("mass"));
        assert_ne!(a.get("mass"), r.draw(8, 0).get("mass"));
        let masses: Vec<f64> = (0..2000).filter_map(|s| r.draw(s, 0).get("mass")).collect();
        assert!(masses.iter().all(|m| (0.8..1.2).contains(m)));
        let mean = masses.iter().sum::<f64>() / masses.len() as f64;
        assert!((mean - 1.0).abs() < 0.01, "uniform: mean {mean}");
        // Adding a key leaves the others' draws.
        let more =
            Randomization::from_toml("mass = [0.8, 1.2]\nwind = [0, 3]\nkf = [0.9, 1]\n").unwrap();
        assert_eq!(a.get("mass"), more.draw(7, 0).get("mass"));
    }
}
