//! Reading values out of pairs: strict for server lines (errors say what and where), lenient
//! for client commands (never fails; deviations say what was tolerated).
//!
//! # Lenient numbers (client commands)
//!
//! A plain number, or with a leading `+` ([`Deviation::LeadingPlus`]), or with one decimal
//! comma ([`Deviation::DecimalComma`]). Anything else reads as 0 ([`Deviation::BadNumber`]),
//! like UDK's `float("")`.
//!
//! # Lenient vectors (client commands)
//!
//! * Value with whitespace: components are separated by `,?\s+`. So `.4, .4, 1.8` and
//!   `0.0 0.0 1.0` ([`Deviation::SpaceSeparatedVector`]) read as expected, and in
//!   `0,0000, 0,0000, 0,0000` the commas glued to digits are decimal commas: (0, 0, 0) with
//!   [`Deviation::AmbiguousVector`].
//! * Otherwise split on commas: 3 parts are 3 numbers; 6 parts are three decimal-comma
//!   numbers (`1,5,2,5,3,5` = (1.5, 2.5, 3.5), [`Deviation::AmbiguousVector`]).
//! * Anything else is read the way UDK's `ParseVector` does (split at the first two commas,
//!   `atof` each part, missing parts 0) with [`Deviation::BadVector`].
//!
//! For reference, UDK itself reads `0,0000, 0,0000, 0,0000` as (0, 0, 0) only by luck (its
//! parts are `0`, `0000` and `0,0000, ...`); `1,5, 2,5, 3,5` is (1, 5, 2) for UDK. The
//! deviation carries UDK's reading so a server can log both.

use crate::error::{ParseError, ParseErrorKind};
use crate::message::{Deviation, RawPair, find};
use crate::primitive::{Time, Vec3};

fn is_ws(c: char) -> bool {
    matches!(c, ' ' | '\t' | '\r' | '\n')
}

/// A finite number in Rust's syntax (also accepts a leading `+`).
fn number(s: &str) -> Option<f64> {
    let s = s.trim_ascii();
    plain_decimal(s.as_bytes()).or_else(|| s.parse::<f64>().ok().filter(|v| v.is_finite()))
}

/// A laser scan's ranges, fast: plain decimals separated by single commas, read in one pass
/// (`None` for anything else, which then takes the general path).
fn plain_list(s: &[u8]) -> Option<Vec<f64>> {
    // A range is at least two bytes and a comma.
    let mut out = Vec::with_capacity(s.len() / 3 + 1);
    let mut rest = s;
    loop {
        let (v, used, _) = decimal_prefix(rest)?;
        out.push(v);
        match rest.get(used) {
            None => return Some(out),
            Some(b',') => rest = &rest[used + 1..],
            Some(_) => return None,
        }
    }
}

/// Three plain decimals separated by commas, or `None` (the general path decides).
fn plain_vec3(s: &[u8]) -> Option<Vec3> {
    let (x, a, _) = decimal_prefix(s)?;
    let s = s.get(a..)?.strip_prefix(b",")?;
    let (y, b, _) = decimal_prefix(s)?;
    let s = s.get(b..)?.strip_prefix(b",")?;
    let (z, c, _) = decimal_prefix(s)?;
    (c == s.len()).then_some(Vec3::new(x, y, z))
}

/// The common case, fast: `[+-]digits[.digits]` with at most 15 digits, read as an integer
/// divided by a power of ten. Both are exact in f64 and IEEE division rounds correctly, so
/// the result is bit for bit what `str::parse` gives.
fn plain_decimal(s: &[u8]) -> Option<f64> {
    decimal_prefix(s).and_then(|(v, used, _)| (used == s.len()).then_some(v))
}

/// A plain decimal and its number of decimals (`12.3456` → 4), or `None`.
pub(crate) fn plain_decimal_places(s: &str) -> Option<(f64, u8)> {
    let (v, used, places) = decimal_prefix(s.as_bytes())?;
    (used == s.len()).then_some((v, places.min(9) as u8))
}

/// Reads [`plain_decimal`]'s syntax at the start of `s`, up to the first byte that cannot
/// continue it: the value, the bytes read and the number of decimals. `None` without a
/// digit or with more than 15.
#[inline(always)]
fn decimal_prefix(s: &[u8]) -> Option<(f64, usize, usize)> {
    const POW10: [f64; 16] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
    ];
    /// Appends the leading digits of `s` to `mantissa` (wrapping: more than 15 digits are
    /// refused anyway); returns how many.
    #[inline(always)]
    fn digits(s: &[u8], mantissa: &mut u64) -> usize {
        let mut count = 0;
        for &b in s {
            let d = b.wrapping_sub(b'0');
            if d >= 10 {
                break;
            }
            *mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(d));
            count += 1;
        }
        count
    }
    let negative = s.first() == Some(&b'-');
    let mut i = usize::from(matches!(s.first(), Some(b'-' | b'+')));
    let mut mantissa = 0u64;
    let whole = digits(&s[i..], &mut mantissa);
    i += whole;
    let mut decimals = 0;
    if s.get(i) == Some(&b'.') {
        i += 1;
        decimals = digits(&s[i..], &mut mantissa);
        i += decimals;
    }
    if whole + decimals == 0 || whole + decimals > 15 {
        return None;
    }
    let v = mantissa as i64 as f64 / POW10[decimals];
    Some((if negative { -v } else { v }, i, decimals))
}

/// C `atof`: the longest numeric prefix after leading spaces, else 0.
fn atof(s: &str) -> f64 {
    let s = s.trim_start_matches(is_ws);
    let b = s.as_bytes();
    let mut end = 0;
    let mut best = 0.0;
    while end < b.len() && (b[end].is_ascii_digit() || b".+-eE".contains(&b[end])) {
        end += 1;
        if let Some(v) = number(&s[..end]) {
            best = v;
        }
    }
    best
}

/// What UDK's `ParseVector` reads: split at the first two commas, `atof` each part.
fn udk_vector(s: &str) -> Vec3 {
    let mut parts = s.splitn(3, ',');
    let mut next = || parts.next().map_or(0.0, atof);
    Vec3::new(next(), next(), next())
}

/// Reads a value of a client command; never fails.
pub(crate) fn lenient_f64(key: &str, value: &str, devs: &mut Vec<Deviation>) -> f64 {
    let t = value.trim_matches(is_ws);
    let dev = |kind: fn(String, String) -> Deviation| kind(key.to_owned(), value.to_owned());
    if t.starts_with('+') {
        devs.push(dev(|key, value| Deviation::LeadingPlus { key, value }));
    }
    if let Some(v) = number(t) {
        return v;
    }
    if t.matches(',').count() == 1
        && let Some(v) = number(&t.replacen(',', ".", 1))
    {
        devs.push(dev(|key, value| Deviation::DecimalComma { key, value }));
        return v;
    }
    devs.push(dev(|key, value| Deviation::BadNumber { key, value }));
    0.0
}

/// An integer of a client command: a plain integer, else a lenient number truncated.
pub(crate) fn lenient_i64(key: &str, value: &str, devs: &mut Vec<Deviation>) -> i64 {
    match value.trim_matches(is_ws).parse::<i64>() {
        Ok(v) => v,
        Err(_) => lenient_f64(key, value, devs) as i64,
    }
}

/// A vector of a client command (module docs); never fails.
pub(crate) fn lenient_vec3(key: &str, value: &str, devs: &mut Vec<Deviation>) -> Vec3 {
    let t = value.trim_matches(is_ws);
    let mut parts: Vec<String> = Vec::with_capacity(3);
    let mut ambiguous = false;
    if t.contains(is_ws) {
        for token in t.split(is_ws) {
            let token = token.trim_matches(',');
            if !token.is_empty() {
                ambiguous |= token.contains(',');
                parts.push(token.to_owned());
            }
        }
        if !t.contains(',') {
            devs.push(Deviation::SpaceSeparatedVector {
                key: key.to_owned(),
                value: value.to_owned(),
            });
        }
    } else if !t.is_empty() {
        let split: Vec<&str> = t.split(',').collect();
        if split.len() == 6 {
            ambiguous = true;
            parts.extend(split.chunks(2).map(|c| c.join(",")));
        } else {
            parts.extend(split.iter().map(|s| (*s).to_owned()));
        }
    }
    if parts.len() != 3 {
        devs.push(Deviation::BadVector {
            key: key.to_owned(),
            value: value.to_owned(),
        });
        return udk_vector(t);
    }
    if ambiguous {
        let udk = udk_vector(t);
        let mut udk_reads = String::new();
        crate::format::push_shortest(&mut udk_reads, udk.x);
        udk_reads.push(',');
        crate::format::push_shortest(&mut udk_reads, udk.y);
        udk_reads.push(',');
        crate::format::push_shortest(&mut udk_reads, udk.z);
        devs.push(Deviation::AmbiguousVector {
            key: key.to_owned(),
            value: value.to_owned(),
            udk_reads,
        });
    }
    let mut c = parts.iter().map(|p| lenient_f64(key, p, devs));
    let mut next = || c.next().unwrap_or(0.0);
    Vec3::new(next(), next(), next())
}

/// Lenient access to the pairs of a client command.
pub(crate) struct Lenient<'r, 'a> {
    pub(crate) pairs: &'r [RawPair<'a>],
    pub(crate) devs: Vec<Deviation>,
}

impl<'a> Lenient<'_, 'a> {
    /// The value of `key` (canonical spelling); records a differently-cased key.
    pub(crate) fn text(&mut self, key: &str) -> Option<&'a str> {
        let p = find(self.pairs, key)?;
        if p.key != key {
            self.devs.push(Deviation::KeyCase {
                found: p.key.to_owned(),
                expected: key.to_owned(),
            });
        }
        Some(p.value)
    }

    pub(crate) fn string(&mut self, key: &str) -> Option<String> {
        self.text(key).map(str::to_owned)
    }

    pub(crate) fn f64(&mut self, key: &str) -> Option<f64> {
        let v = self.text(key)?;
        Some(lenient_f64(key, v, &mut self.devs))
    }

    pub(crate) fn i64(&mut self, key: &str) -> Option<i64> {
        let v = self.text(key)?;
        Some(lenient_i64(key, v, &mut self.devs))
    }

    pub(crate) fn vec3(&mut self, key: &str) -> Option<Vec3> {
        let v = self.text(key)?;
        Some(lenient_vec3(key, v, &mut self.devs))
    }

    /// `true` only for the exact lower-case `true`, as UDK compares.
    pub(crate) fn flag(&mut self, key: &str) -> Option<bool> {
        let v = self.text(key)?;
        if v != "true" && v.eq_ignore_ascii_case("true") {
            self.devs.push(Deviation::BoolCase {
                key: key.to_owned(),
                value: v.to_owned(),
            });
        }
        Some(v == "true")
    }

    /// Records every key not in `known` as unknown.
    pub(crate) fn finish(mut self, known: &[&str]) -> Vec<Deviation> {
        for p in self.pairs {
            if !known.iter().any(|k| k.eq_ignore_ascii_case(p.key)) {
                self.devs.push(Deviation::UnknownKey(p.key.to_owned()));
            }
        }
        self.devs
    }
}

/// Strict access to the pairs of (a part of) a server line.
#[derive(Clone, Copy)]
pub(crate) struct Reader<'r, 'a> {
    /// What is being read, for error messages (`sen`).
    what: &'static str,
    /// Which kind of it (`IMU`), or empty.
    part: &'r str,
    pub(crate) pairs: &'r [RawPair<'a>],
}

impl<'r, 'a> Reader<'r, 'a> {
    pub(crate) fn new(what: &'static str, pairs: &'r [RawPair<'a>]) -> Self {
        Self {
            what,
            part: "",
            pairs,
        }
    }

    /// The same kind of reader over other pairs, naming the part (`sen IMU`).
    pub(crate) fn sub(&self, part: &'r str, pairs: &'r [RawPair<'a>]) -> Self {
        Self {
            what: self.what,
            part,
            pairs,
        }
    }

    /// An error about this message: `sen IMU: ...`.
    pub(crate) fn error(&self, text: &str) -> ParseError {
        if self.part.is_empty() {
            ParseError::new(format!("{}: {text}", self.what))
        } else {
            ParseError::new(format!("{} {}: {text}", self.what, self.part))
        }
    }

    pub(crate) fn missing(&self, key: &str) -> ParseError {
        let message = self.error(&format!("missing {{{key} ..}}")).message;
        ParseError::about(ParseErrorKind::MissingKey, key, message)
    }

    fn bad(&self, kind: &str, key: &str, value: &str) -> ParseError {
        self.bad_value(key, &format!("bad {kind} {value:?} in {{{key} ..}}"))
    }

    pub(crate) fn bad_value(&self, key: &str, text: &str) -> ParseError {
        ParseError::about(ParseErrorKind::BadValue, key, self.error(text).message)
    }

    pub(crate) fn has(&self, key: &str) -> bool {
        find(self.pairs, key).is_some()
    }

    pub(crate) fn opt_text(&self, key: &str) -> Option<&'a str> {
        find(self.pairs, key).map(|p| p.value)
    }

    pub(crate) fn text(&self, key: &str) -> Result<&'a str, ParseError> {
        self.opt_text(key).ok_or_else(|| self.missing(key))
    }

    pub(crate) fn string(&self, key: &str) -> Result<String, ParseError> {
        self.text(key).map(str::to_owned)
    }

    pub(crate) fn number_in(&self, key: &str, v: &str) -> Result<f64, ParseError> {
        number(v).ok_or_else(|| self.bad("number", key, v))
    }

    pub(crate) fn f64(&self, key: &str) -> Result<f64, ParseError> {
        self.number_in(key, self.text(key)?)
    }

    pub(crate) fn opt_f64(&self, key: &str) -> Result<Option<f64>, ParseError> {
        self.opt_text(key)
            .map(|v| self.number_in(key, v))
            .transpose()
    }

    pub(crate) fn int_in(&self, key: &str, v: &str) -> Result<i64, ParseError> {
        v.trim_matches(is_ws)
            .parse()
            .map_err(|_| self.bad("integer", key, v))
    }

    pub(crate) fn i64(&self, key: &str) -> Result<i64, ParseError> {
        self.int_in(key, self.text(key)?)
    }

    pub(crate) fn opt_i64(&self, key: &str) -> Result<Option<i64>, ParseError> {
        self.opt_text(key).map(|v| self.int_in(key, v)).transpose()
    }

    fn bool_in(&self, key: &str, v: &str) -> Result<bool, ParseError> {
        match v {
            _ if v.eq_ignore_ascii_case("true") => Ok(true),
            _ if v.eq_ignore_ascii_case("false") => Ok(false),
            _ => Err(self.bad("boolean", key, v)),
        }
    }

    pub(crate) fn bool(&self, key: &str) -> Result<bool, ParseError> {
        self.bool_in(key, self.text(key)?)
    }

    pub(crate) fn opt_bool(&self, key: &str) -> Result<Option<bool>, ParseError> {
        self.opt_text(key).map(|v| self.bool_in(key, v)).transpose()
    }

    /// Comma-separated numbers; an empty value is an empty list.
    pub(crate) fn list_in(&self, key: &str, v: &str) -> Result<Vec<f64>, ParseError> {
        if v.is_empty() {
            return Ok(Vec::new());
        }
        if let Some(list) = plain_list(v.as_bytes()) {
            return Ok(list);
        }
        v.split(',').map(|n| self.number_in(key, n)).collect()
    }

    pub(crate) fn list(&self, key: &str) -> Result<Vec<f64>, ParseError> {
        self.list_in(key, self.text(key)?)
    }

    pub(crate) fn vec3_in(&self, key: &str, v: &str) -> Result<Vec3, ParseError> {
        match plain_vec3(v.as_bytes()) {
            Some(r) => Ok(r),
            None => self.vec3_general(key, v),
        }
    }

    /// [`Reader::vec3_in`] for any value: three numbers of any syntax [`number`] reads.
    fn vec3_general(&self, key: &str, v: &str) -> Result<Vec3, ParseError> {
        let mut parts = v.split(',');
        let mut next = || {
            parts
                .next()
                .ok_or_else(|| self.bad("vector", key, v))
                .and_then(|n| self.number_in(key, n))
        };
        let r = Vec3::new(next()?, next()?, next()?);
        if parts.next().is_some() {
            return Err(self.bad("vector", key, v));
        }
        Ok(r)
    }

    pub(crate) fn vec3(&self, key: &str) -> Result<Vec3, ParseError> {
        self.vec3_in(key, self.text(key)?)
    }

    /// The pairs split before every `Name` key (the parts of a CONF/GEO line, the readings
    /// of a UT2004 sonar line); pairs before the first `Name` form the first slice.
    pub(crate) fn items(&self) -> impl Iterator<Item = Self> + use<'r, 'a> {
        let this = *self;
        let mut start = 0;
        std::iter::from_fn(move || {
            let rest = this.pairs.get(start..).filter(|r| !r.is_empty())?;
            let len = rest[1..]
                .iter()
                .position(|p| p.key.eq_ignore_ascii_case("Name"))
                .map_or(rest.len(), |i| i + 1);
            start += len;
            Some(this.sub(this.part, &rest[..len]))
        })
    }

    /// Whether the keys are exactly `keys`, in order (case-insensitive).
    pub(crate) fn keys_are(&self, keys: &[&str]) -> bool {
        self.pairs.len() == keys.len()
            && self
                .pairs
                .iter()
                .zip(keys)
                .all(|(p, k)| p.key.eq_ignore_ascii_case(k))
    }

    /// Whether the pairs span more than one group each (UT2004 grouped layout).
    pub(crate) fn grouped(&self) -> bool {
        self.pairs.windows(2).any(|w| w[0].group == w[1].group)
    }
}

/// Digits after the decimal point of the first number in `v` (`477.7582` → 4).
pub(crate) fn decimals_of(v: &str) -> u8 {
    let first = v.split(',').next().unwrap_or("");
    first
        .split_once('.')
        .map_or(0, |(_, f)| f.bytes().take_while(u8::is_ascii_digit).count())
        .min(9) as u8
}

/// Reads `{Time t}` keeping its decimals.
pub(crate) fn read_time(r: &Reader<'_, '_>) -> Result<Option<Time>, ParseError> {
    r.opt_text("Time")
        .map(|v| {
            if let Some((seconds, decimals)) = plain_decimal_places(v) {
                return Ok(Time { seconds, decimals });
            }
            Ok(Time {
                seconds: r.number_in("Time", v)?,
                decimals: decimals_of(v),
            })
        })
        .transpose()
}

/// Reads a required `{Time t}`.
pub(crate) fn time(r: &Reader<'_, '_>) -> Result<Time, ParseError> {
    read_time(r)?.ok_or_else(|| r.missing("Time"))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_fast_number_path_is_bit_for_bit_str_parse() {
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..100_000 {
            // xorshift: digits and decimals of every length the fast path takes.
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let digits = (x % 15 + 1) as usize;
            let mantissa = x % 10u64.pow(digits as u32);
            let decimals = ((x >> 40) % (digits as u64 + 1)) as usize;
            let text = format!("{mantissa:0digits$}");
            let text = format!(
                "{}{}.{}",
                if x & 1 == 1 { "-" } else { "" },
                &text[..digits - decimals],
                &text[digits - decimals..]
            );
            let fast = plain_decimal(text.as_bytes()).unwrap();
            let slow: f64 = text.parse().unwrap();
            assert_eq!(fast.to_bits(), slow.to_bits(), "{text}");
        }
        assert_eq!(
            plain_decimal(b"-0.0000").map(f64::to_bits),
            Some((-0.0f64).to_bits())
        );
        assert_eq!(plain_decimal(b"+1.5"), Some(1.5));
        assert_eq!(plain_decimal(b"1e5"), None);
        assert_eq!(plain_decimal(b"."), None);
        assert_eq!(
            plain_decimal(b"1234567890123456"),
            None,
            "16 digits: left to str::parse"
        );
    }

    use super::*;

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(20_000))]

        /// The one-pass readers of lists, vectors and time stamps agree with reading the
        /// items one by one (when they answer at all).
        #[test]
        fn one_pass_readers_agree_with_the_general_ones(v in "[-+0-9.,e ]{0,40}") {
            let items: Option<Vec<f64>> = v.split(',').map(number).collect();
            if let Some(list) = plain_list(v.as_bytes()) {
                let bits = |l: &[f64]| l.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                proptest::prop_assert_eq!(Some(bits(&list)), items.as_deref().map(bits));
            }
            if let Some(r) = plain_vec3(v.as_bytes()) {
                let general = Reader::new("t", &[]).vec3_general("k", &v).unwrap();
                proptest::prop_assert_eq!(
                    [r.x, r.y, r.z].map(f64::to_bits),
                    [general.x, general.y, general.z].map(f64::to_bits)
                );
            }
            if let Some((x, places)) = plain_decimal_places(&v) {
                proptest::prop_assert_eq!(Some(x.to_bits()), number(&v).map(f64::to_bits));
                proptest::prop_assert_eq!(places, decimals_of(&v));
            }
        }
    }

    #[test]
    fn one_pass_readers_take_plain_numbers() {
        assert_eq!(plain_list(b"1.25,-0.5,3"), Some(vec![1.25, -0.5, 3.0]));
        assert_eq!(plain_list(b"1.25,,3"), None);
        assert_eq!(
            plain_vec3(b"1,-2.5,0.125"),
            Some(Vec3::new(1.0, -2.5, 0.125))
        );
        assert_eq!(plain_vec3(b"1,2,3,4"), None);
        assert_eq!(plain_decimal_places("477.7582"), Some((477.7582, 4)));
    }

    fn vec(v: &str) -> (Vec3, Vec<Deviation>) {
        let mut d = Vec::new();
        (lenient_vec3("Location", v, &mut d), d)
    }

    #[test]
    fn lenient_numbers() {
        let mut d = Vec::new();
        assert_eq!(lenient_f64("Left", "1,00", &mut d), 1.0);
        assert_eq!(lenient_f64("Left", "+1,50", &mut d), 1.5);
        assert_eq!(lenient_f64("Left", "", &mut d), 0.0);
        assert_eq!(lenient_f64("Left", "abc", &mut d), 0.0);
        assert_eq!(lenient_i64("Link", "2", &mut d), 2);
        assert_eq!(d.len(), 5);
        assert_eq!(d[0].to_string(), "decimal comma in {Left 1,00}");
        assert_eq!(d[3].to_string(), "bad number in {Left } read as 0");
    }

    #[test]
    fn lenient_vectors() {
        assert_eq!(vec("1,-1,0"), (Vec3::new(1.0, -1.0, 0.0), vec![]));
        assert_eq!(vec(".4, .4, 1.8"), (Vec3::new(0.4, 0.4, 1.8), vec![]));
        let (v, d) = vec("0.000000 0.000000 1.000000");
        assert_eq!(v, Vec3::new(0.0, 0.0, 1.0));
        assert!(matches!(d[0], Deviation::SpaceSeparatedVector { .. }));
        let (v, d) = vec("1,5, 2,5, 3,5");
        assert_eq!(v, Vec3::new(1.5, 2.5, 3.5));
        assert_eq!(
            d[0].to_string(),
            "ambiguous vector {Location 1,5, 2,5, 3,5} read with decimal commas (udk reads 1,5,2)"
        );
        let (v, d) = vec("0,0000, 0,0000, 0,0000");
        assert_eq!(v, Vec3::new(0.0, 0.0, 0.0));
        assert_eq!(d.len(), 4);
        let (v, _) = vec("1,5,2,5,3,5");
        assert_eq!(v, Vec3::new(1.5, 2.5, 3.5));
        let (v, d) = vec("1,2");
        assert_eq!(v, Vec3::new(1.0, 2.0, 0.0));
        assert!(matches!(d[0], Deviation::BadVector { .. }));
    }

    #[test]
    fn decimals() {
        assert_eq!(decimals_of("477.7582"), 4);
        assert_eq!(decimals_of("45.14"), 2);
        assert_eq!(decimals_of("9.38,9.38"), 2);
        assert_eq!(decimals_of("12"), 0);
    }
}
