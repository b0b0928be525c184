//! `random-search`: flies to points drawn at random in the area (or this UAV's strip),
//! seeded by the scenario's seed and the UAV's index, so a run repeats; it goes home to
//! recharge like the lane searcher. The baseline the patterns are measured against.

use super::TeamAgentInfo;
use super::searcher::{Pattern, Searcher};

/// The registry entry.
pub const INFO: TeamAgentInfo = TeamAgentInfo {
    name: PATTERN.name,
    description: "flies to random points of the area (seeded), recharging at the base",
    create: || Box::new(Searcher::new(PATTERN)),
};

/// The pattern of `random-search`: points drawn at random in the strip.
pub const PATTERN: Pattern = Pattern {
    name: "random-search",
    weighted: false,
    route: |strip, _, z, brief| points(strip, brief.seed, brief.index, z),
};

/// Points drawn per iteration (the route; the time limit usually ends it first).
const POINTS: usize = 2000;

/// A small deterministic generator (SplitMix64).
#[derive(Debug, Clone)]
pub struct SplitMix(pub u64);

impl SplitMix {
    /// The next number in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// [`POINTS`] points drawn in `strip` at height `z`, from `seed` and the UAV's `index`.
pub fn points(strip: [[f64; 2]; 2], seed: u64, index: usize, z: f64) -> Vec<[f64; 3]> {
    let [[x0, y0], [x1, y1]] = strip;
    let mut rng = SplitMix(seed ^ (index as u64).wrapping_mul(0x2545_F491_4F6C_DD1D));
    (0..POINTS)
        .map(|_| {
            [
                x0 + rng.next_f64() * (x1 - x0),
                y0 + rng.next_f64() * (y1 - y0),
                z,
            ]
        })
        .collect()
}
