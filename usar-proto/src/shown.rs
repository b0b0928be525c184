//! Logging what a peer sends without letting it write the log: its bytes are escaped and
//! shortened ([`Shown`]), and repeated warnings about one peer are summarised
//! ([`Repeats`]). Every program of the workspace logs a peer's text through these
//! (docs/limits.md, "The log"): the server about its clients, `ucc tap` about both sides,
//! the client library about its server.
//!
//! ```
//! use usar_proto::shown::{Repeats, Shown};
//! assert_eq!(Shown("DRIVE\u{1b}[2J").to_string(), "DRIVE\\u{1b}[2J");
//! let mut bad_lines = Repeats::default();
//! let logged = (0..1000).filter(|_| bad_lines.note().is_some()).count();
//! assert_eq!(logged, 8 + 6); // the first 8, then the 16th, 32nd, ..., 512th
//! ```

use std::fmt;

/// How many characters of a client line a log entry shows.
const SHOWN_CHARS: usize = 120;

/// How many warnings of one kind a client gets in full before they are summarised.
const FULL_WARNINGS: u64 = 8;

/// A client's text as the log shows it: control bytes escaped (`\u{1b}`, `\0`), at most
/// [`SHOWN_CHARS`] characters, then the total length.
pub struct Shown<'a>(pub &'a str);

impl fmt::Display for Shown<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut chars = self.0.chars();
        for c in chars.by_ref().take(SHOWN_CHARS) {
            if c.is_control() || c == '\u{fffd}' {
                write!(f, "{}", c.escape_default())?;
            } else {
                write!(f, "{c}")?;
            }
        }
        if chars.next().is_some() {
            write!(f, "… ({} bytes)", self.0.len())?;
        }
        Ok(())
    }
}

/// A number as an error message shows it: as written for everyday sizes, with an exponent
/// past a billion or below a ten-thousandth (`1e308`, not 309 digits).
pub struct Number(pub f64);

impl fmt::Display for Number {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        if v == 0.0 || !v.is_finite() || (1e-4..1e9).contains(&v.abs()) {
            write!(f, "{v}")
        } else {
            write!(f, "{v:e}")
        }
    }
}

/// Counts one kind of warning about one client and says which ones to log: the first
/// [`FULL_WARNINGS`], then only the 16th, 32nd, 64th, ... (each with the count so far), so
/// a flood of N bad lines writes O(log N) log lines.
#[derive(Debug, Default, Clone, Copy)]
pub struct Repeats {
    count: u64,
}

impl Repeats {
    /// Counts one more; `Some(count)` when this one should be logged.
    pub fn note(&mut self) -> Option<u64> {
        self.count += 1;
        (self.count <= FULL_WARNINGS || self.count.is_power_of_two()).then_some(self.count)
    }

    /// How many there were.
    pub fn count(self) -> u64 {
        self.count
    }

    /// How many were not logged.
    pub fn suppressed(self) -> u64 {
        // Powers of two above FULL_WARNINGS (8 = 2^3) up to count: 2^4 ..= 2^floor(log2 count).
        let powers = u64::from(self.count.checked_ilog2().unwrap_or(0).saturating_sub(3));
        let logged = self.count.min(FULL_WARNINGS) + powers;
        self.count - logged
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_and_tiny_numbers_are_shown_with_an_exponent() {
        let shown = |v: f64| Number(v).to_string();
        assert_eq!(shown(1e308), "1e308");
        assert_eq!(shown(-2.5e12), "-2.5e12");
        assert_eq!(shown(1e-300), "1e-300");
        assert_eq!(shown(1500.25), "1500.25");
        assert_eq!(shown(-3.0), "-3");
        assert_eq!(shown(f64::NAN), "NaN");
    }

    #[test]
    fn control_bytes_are_escaped_and_long_lines_cut() {
        assert_eq!(
            Shown("DRIVE\u{1b}[2J\0x").to_string(),
            "DRIVE\\u{1b}[2J\\u{0}x"
        );
        let long = "A".repeat(1000);
        let shown = Shown(&long).to_string();
        assert!(shown.ends_with("… (1000 bytes)"), "{shown}");
        assert!(shown.len() < 200);
    }

    #[test]
    fn a_flood_is_logged_logarithmically() {
        let mut r = Repeats::default();
        let logged = (0..1_000_000).filter(|_| r.note().is_some()).count();
        assert_eq!(logged, 8 + 16); // 1..=8, then 16, 32, ..., 2^19
        assert_eq!(r.count(), 1_000_000);
        assert_eq!(r.suppressed(), 1_000_000 - 24);
    }
}
