//! Logging what clients send without letting them write the log: their bytes are escaped
//! and shortened, and repeated warnings about one client are summarised.

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
