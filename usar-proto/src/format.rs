//! The three number formatters of UDK-USARSim (protocol.md §1.4), plus the client-side one.
//!
//! | function | engine formatter | example |
//! |---|---|---|
//! | [`push_fixed`] with 4 decimals | implicit float→string (`%.4f`) | `477.7582` |
//! | [`push_implicit_vector`] | implicit vector→string (`%.2f,%.2f,%.2f`) | `0.21,-0.00,-0.20` |
//! | [`push_float_string`] / [`push_float_string_vector`] | `UnitsConverter.FloatString` (truncating) | `1.2999` |
//! | [`push_shortest`] | client commands: Rust's shortest round-trip `{}` | `0.1` |
//!
//! # FloatString and exact decimals
//!
//! The engine computes FloatString in 32-bit floats: `ip = int(v); frac = int((v - ip) * 10^p)`.
//! Emulating that on every input is not idempotent: about half of all p-decimal strings `t`
//! would print as something else after being read (`"0.53"` reads as the f64 nearest 0.53,
//! whose f32 is 0.52999997, which truncates to `0.52`). So [`push_float_string`] works in two
//! steps:
//!
//! 1. if the value is within 1e-9 (relative; absolute floor 1e-12) of a point of the p-decimal
//!    grid, it *is* that exact decimal (for instance a number read from a line) and that grid
//!    point is printed;
//! 2. otherwise the engine's f32 truncation is emulated exactly.
//!
//! Consequence: to reproduce the engine's f32 quirks, pass what the engine held, an
//! f32-derived value: `1.3f32 as f64` prints `1.2999` (the captured `{MaxSpeed 1.2999}`),
//! while `1.3` prints `1.3000`. Some captured quirks come from the engine's integer rotation
//! units rather than from f32 alone: the SICK `{Resolution 0.0174}` is
//! `int(0.01745 * 10430.378) / 10430.378`, not `0.01745f32`.
//!
//! The sign always comes from [`f64::is_sign_negative`], so a captured `-0.0000` reads as
//! `-0.0` and prints back as `-0.0000`. The implicit float and vector formatters round
//! correctly and keep `-0.00` the same way. Non-finite values never panic: implicit floats
//! print Rust's `NaN`/`inf`, FloatString prints what the f32 emulation gives with saturating
//! conversions (the engine printed `-2147483648`-like garbage).
//!
//! # Huge and tiny numbers
//!
//! UDK holds every number in a 32-bit float: it cannot hold, so never prints, a number beyond
//! ±3.4028235e38 (`f32::MAX`, 39 digits); such a value overflows to infinity in the engine.
//! An f64 can be far larger (`1e308`, 309 digits). The formatters hold a finite value to the
//! f32 range ([`udk_range`]): `1e308` prints as `f32::MAX` (`340282346638528859811704183484516925440.0000`
//! with 4 decimals), a number every reader (ours, UDK's `atof`) reads as a number, where
//! `inf` would read as 0 or an error. [`push_shortest`] also prints a value below the
//! smallest f32 (1.4e-45) as `0`: no number printed here is longer than about 60 characters.
//! Values inside the f32 range, every value the simulation prints, are untouched.
//!
//! All formatters append to a [`WireBuf`] (a `String`, a `Vec<u8>` or a `bytes::BytesMut`)
//! without allocating.

use crate::primitive::Vec3;

/// Something protocol text can be appended to: `String`, `Vec<u8>`, `bytes::BytesMut`.
pub trait WireBuf {
    /// Appends text.
    fn push_text(&mut self, s: &str);
    /// Appends ASCII bytes (digits, signs, points): byte buffers skip the UTF-8 check a
    /// `&str` would need.
    fn push_ascii(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.push_text(char::from(b).encode_utf8(&mut [0; 4]));
        }
    }
    /// Appends the first `len` bytes of `buf` (ASCII; `len` at most 32): the number
    /// formatters' output. Byte buffers copy the whole array and cut the excess, which is
    /// faster than a copy of variable length.
    fn push_ascii_head(&mut self, buf: &[u8; 32], len: usize) {
        self.push_ascii(&buf[..len.min(32)]);
    }
    /// Appends formatted text (only used on rare slow paths).
    fn push_args(&mut self, args: std::fmt::Arguments<'_>);
}

impl WireBuf for String {
    #[inline]
    fn push_text(&mut self, s: &str) {
        self.push_str(s);
    }
    #[inline]
    fn push_ascii(&mut self, bytes: &[u8]) {
        if let Ok(s) = std::str::from_utf8(bytes) {
            self.push_str(s);
        }
    }
    fn push_args(&mut self, args: std::fmt::Arguments<'_>) {
        // Writing into a String cannot fail.
        let _ = std::fmt::Write::write_fmt(self, args);
    }
}

impl WireBuf for Vec<u8> {
    #[inline]
    fn push_text(&mut self, s: &str) {
        self.extend_from_slice(s.as_bytes());
    }
    #[inline]
    fn push_ascii(&mut self, bytes: &[u8]) {
        self.extend_from_slice(bytes);
    }
    #[inline]
    fn push_ascii_head(&mut self, buf: &[u8; 32], len: usize) {
        let end = self.len() + len.min(32);
        self.extend_from_slice(buf);
        self.truncate(end);
    }
    fn push_args(&mut self, args: std::fmt::Arguments<'_>) {
        // Writing into a Vec cannot fail.
        let _ = std::io::Write::write_fmt(self, args);
    }
}

#[cfg(feature = "codec")]
impl WireBuf for bytes::BytesMut {
    #[inline]
    fn push_text(&mut self, s: &str) {
        self.extend_from_slice(s.as_bytes());
    }
    #[inline]
    fn push_ascii(&mut self, bytes: &[u8]) {
        self.extend_from_slice(bytes);
    }
    #[inline]
    fn push_ascii_head(&mut self, buf: &[u8; 32], len: usize) {
        let end = self.len() + len.min(32);
        self.extend_from_slice(buf);
        self.truncate(end);
    }
    fn push_args(&mut self, args: std::fmt::Arguments<'_>) {
        // Writing into a BytesMut cannot fail.
        let _ = std::fmt::Write::write_fmt(self, args);
    }
}

const POW10: [u64; 10] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
    1_000_000_000,
];

/// The same powers as `f64` (a table load instead of a `u64` → `f64` conversion).
const POW10_F64: [f64; 10] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9];

/// `00`, `01`, ... `99`: two digits per division.
const PAIRS: &[u8; 200] = b"\
0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// A number to print: `[-]ip.frac`, `frac` zero-padded to `decimals` digits (at most 9;
/// no point for 0).
struct Decimal {
    negative: bool,
    ip: u64,
    frac: u64,
    decimals: usize,
}

/// The text of one number (and its separator), built on the stack: at most 32 bytes (a
/// comma, a sign, 20 integer digits, a point and 9 decimals).
struct Digits<const N: usize = 32> {
    buf: [u8; N],
    len: usize,
}

impl<const N: usize> Digits<N> {
    fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
        }
    }

    fn byte(&mut self, b: u8) {
        self.buf[self.len] = b;
        self.len += 1;
    }

    /// Two digits of `n` (< 100).
    fn pair(&mut self, n: u64) {
        let at = (n % 100) as usize * 2;
        self.buf[self.len..self.len + 2].copy_from_slice(&PAIRS[at..at + 2]);
        self.len += 2;
    }

    /// The last `count` digits of `n`, zero-padded.
    fn digits(&mut self, mut n: u64, count: usize) {
        let start = self.len;
        let mut end = start + count;
        self.len = end;
        while end >= start + 2 {
            let at = (n % 100) as usize * 2;
            n /= 100;
            end -= 2;
            self.buf[end..end + 2].copy_from_slice(&PAIRS[at..at + 2]);
        }
        if end > start {
            self.buf[start] = b'0' + (n % 10) as u8;
        }
    }

    fn int(&mut self, n: u64) {
        if n < 10 {
            self.byte(b'0' + n as u8);
        } else if n < 100 {
            self.pair(n);
        } else {
            let mut count = 3;
            let mut rest = n / 1000;
            while rest > 0 {
                rest /= 10;
                count += 1;
            }
            self.digits(n, count);
        }
    }

    fn decimal(&mut self, d: &Decimal) {
        if d.negative {
            self.byte(b'-');
        }
        self.int(d.ip);
        match d.decimals {
            0 => {}
            2 => {
                self.byte(b'.');
                self.pair(d.frac);
            }
            4 => {
                self.byte(b'.');
                self.pair(d.frac / 100);
                self.pair(d.frac);
            }
            n => {
                self.byte(b'.');
                self.digits(d.frac, n.min(9));
            }
        }
    }

    /// Hands what it holds to `out` and starts again (the buffer of a list).
    fn flush_to(&mut self, out: &mut impl WireBuf) {
        out.push_ascii(&self.buf[..self.len]);
        self.len = 0;
    }
}

impl Digits {
    fn push_to(&self, out: &mut impl WireBuf) {
        out.push_ascii_head(&self.buf, self.len);
    }
}

/// Appends a signed integer.
pub fn push_int(out: &mut impl WireBuf, v: i64) {
    let mut t = Digits::new();
    t.decimal(&Decimal {
        negative: v < 0,
        ip: v.unsigned_abs(),
        frac: 0,
        decimals: 0,
    });
    t.push_to(out);
}

/// Appends `True` or `False`, the engine's spelling of booleans.
pub fn push_bool(out: &mut impl WireBuf, v: bool) {
    out.push_text(if v { "True" } else { "False" });
}

/// `n / 10^d` and `n % 10^d`, with constant divisors for the protocol's 2 and 4 decimals.
fn split_scaled(n: u64, d: usize) -> (u64, u64) {
    match d {
        4 => (n / 10_000, n % 10_000),
        2 => (n / 100, n % 100),
        _ => (n / POW10[d], n % POW10[d]),
    }
}

/// `v` rounded to `d` decimals, or `None` for the exact slow path (non-finite, huge, more
/// than 9 decimals, or within 1e-5 of a tie).
fn fixed_decimal(v: f64, d: usize) -> Option<Decimal> {
    if !v.is_finite() || d >= POW10.len() {
        return None;
    }
    let scaled = v.abs() * POW10_F64[d];
    // Below 1e10 the product's error is < 2e-6, so rounding it is exact unless the
    // fractional part is near .5; those rare cases take the exact slow path. The truncating
    // cast and the subtraction are exact there (no libm call).
    if scaled >= 1e10 {
        return None;
    }
    let whole = scaled as i64;
    let fraction = scaled - whole as f64;
    if (fraction - 0.5).abs() <= 1e-5 {
        return None;
    }
    let (ip, frac) = split_scaled(whole as u64 + u64::from(fraction > 0.5), d);
    Some(Decimal {
        negative: v.is_sign_negative(),
        ip,
        frac,
        decimals: d,
    })
}

/// `v` held to the range of UDK's 32-bit floats (module docs): ±`f32::MAX` for a finite
/// value beyond it; anything else unchanged.
pub fn udk_range(v: f64) -> f64 {
    const MAX: f64 = f32::MAX as f64;
    if v.is_finite() { v.clamp(-MAX, MAX) } else { v }
}

/// Appends `v` rounded to `decimals` digits (C `%.Nf`): the engine's implicit float→string
/// with 4 decimals (UT2004 used 2); a finite value beyond the f32 range as ±`f32::MAX`.
pub fn push_fixed(out: &mut impl WireBuf, v: f64, decimals: u8) {
    push_fixed_after(out, None, v, decimals);
}

/// [`push_fixed`] preceded by `sep`.
fn push_fixed_after(out: &mut impl WireBuf, sep: Option<u8>, v: f64, decimals: u8) {
    let d = usize::from(decimals);
    let mut t = Digits::new();
    if let Some(sep) = sep {
        t.byte(sep);
    }
    match fixed_decimal(v, d) {
        Some(n) => {
            t.decimal(&n);
            t.push_to(out);
        }
        None => {
            t.push_to(out);
            let v = udk_range(v);
            out.push_args(format_args!("{v:.d$}"));
        }
    }
}

/// Appends the engine's implicit vector→string: `%.2f,%.2f,%.2f`.
pub fn push_implicit_vector(out: &mut impl WireBuf, v: Vec3) {
    push_fixed_list(out, &[v.x, v.y, v.z], 2);
}

/// Appends numbers with [`push_fixed`], comma separated, no spaces.
pub fn push_fixed_list(out: &mut impl WireBuf, values: &[f64], decimals: u8) {
    for (i, &v) in values.iter().enumerate() {
        push_fixed_after(out, (i > 0).then_some(b','), v, decimals);
    }
}

/// FloatString of `v` with `p` (at most 9) decimals (module docs).
fn float_string_decimal(v: f64, p: usize) -> Decimal {
    let negative = v.is_sign_negative();
    let pow = POW10_F64[p];
    let scaled = v.abs() * pow;
    // Rounding by a cast (saturating; NaN gives 0 and fails the test below): no libm call.
    let n = (scaled + 0.5) as i64;
    let grid = n as f64;
    if grid < 1e17 && (scaled - grid).abs() <= (scaled * 1e-9).max(1e-12 * pow) {
        let (ip, frac) = split_scaled(n as u64, p);
        return Decimal {
            negative,
            ip,
            frac,
            decimals: p,
        };
    }
    // The engine's algorithm, in f32, with its int() truncations (saturating here).
    // `10f32.powi(p)` is exact for p <= 9, so the table holds the same values.
    const POW10_F32: [f32; 10] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9];
    let f = (v as f32).abs();
    let ip = f as i32;
    let frac = ((f - ip as f32) * POW10_F32[p]) as i32;
    Decimal {
        negative,
        ip: u64::from(ip.unsigned_abs()),
        frac: u64::from(frac.unsigned_abs()),
        decimals: p,
    }
}

/// Appends `UnitsConverter.FloatString(v, p)`: truncation to `p` decimals (see the module
/// docs for the exact-decimal rule). `p` above 9 is treated as 9.
pub fn push_float_string(out: &mut impl WireBuf, v: f64, p: u8) {
    let mut t = Digits::new();
    t.decimal(&float_string_decimal(v, usize::from(p.min(9))));
    t.push_to(out);
}

/// Appends `UnitsConverter.VectorString`: three FloatStrings joined by commas.
pub fn push_float_string_vector(out: &mut impl WireBuf, v: Vec3, p: u8) {
    push_float_string_list(out, &[v.x, v.y, v.z], p);
}

/// Appends FloatStrings joined by commas (laser ranges).
pub fn push_float_string_list(out: &mut impl WireBuf, values: &[f64], p: u8) {
    let p = usize::from(p.min(9));
    // The numbers go into one buffer, handed over when it is nearly full (one number with
    // its comma takes at most 32 bytes): one copy per ~20 laser ranges, not one per range.
    let mut t = Digits::<512>::new();
    for (i, &v) in values.iter().enumerate() {
        if t.len > 512 - 32 {
            t.flush_to(out);
        }
        if i > 0 {
            t.byte(b',');
        }
        t.decimal(&float_string_decimal(v, p));
    }
    t.flush_to(out);
}

/// Appends Rust's shortest round-trip form (`{}`: never exponent notation), used for the
/// numbers of client commands so that reading them back gives the same `f64`; a finite value
/// beyond the f32 range as ±`f32::MAX`, one below the smallest f32 (1.4e-45) as `0` (module
/// docs: UDK reads neither).
pub fn push_shortest(out: &mut impl WireBuf, v: f64) {
    let v = if v.abs() < f64::from(f32::from_bits(1)) {
        0.0f64.copysign(v)
    } else {
        udk_range(v)
    };
    if v.is_finite() && v == v.trunc() && v.abs() < 1e15 {
        if v == 0.0 && v.is_sign_negative() {
            out.push_text("-0");
        } else {
            push_int(out, v as i64);
        }
        return;
    }
    out.push_args(format_args!("{v}"));
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fs(v: f64, p: u8) -> String {
        let mut s = String::new();
        push_float_string(&mut s, v, p);
        s
    }

    fn fixed(v: f64, d: u8) -> String {
        let mut s = String::new();
        push_fixed(&mut s, v, d);
        s
    }

    #[test]
    fn float_string_reproduces_engine_values() {
        assert_eq!(fs(f64::from(1.3f32), 4), "1.2999");
        assert_eq!(fs(1.3, 4), "1.3000");
        assert_eq!(fs(0.53, 2), "0.53");
        assert_eq!(fs(-0.0, 4), "-0.0000");
        assert_eq!(fs(-0.00001, 4), "-0.0000");
        assert_eq!(fs(9.389, 2), "9.38");
        assert_eq!(fs(5.0, 4), "5.0000");
        assert_eq!(fs(-1.0, 4), "-1.0000");
        // SICK: Resolution and FOV go through integer rotation units (protocol.md §5.2).
        let uu = 10430.378f32;
        assert_eq!(
            fs(f64::from((0.01745f32 * uu) as i32 as f32 / uu), 4),
            "0.0174"
        );
        assert_eq!(fs(f64::from(32767.0f32 / uu), 4), "3.1414");
        assert_eq!(
            fs(f64::from((0.349f32 * uu) as i32 as f32 / uu), 4),
            "0.3489"
        );
    }

    #[test]
    fn float_string_is_idempotent_on_decimal_strings() {
        for i in 0..20000u32 {
            let text = format!("{}.{:02}", i / 100, i % 100);
            let v: f64 = text.parse().unwrap();
            assert_eq!(fs(v, 2), text);
        }
    }

    #[test]
    fn fixed_rounds_like_printf() {
        assert_eq!(fixed(477.7582, 4), "477.7582");
        assert_eq!(fixed(80.0, 4), "80.0000");
        assert_eq!(fixed(-0.001, 2), "-0.00");
        assert_eq!(fixed(0.209, 2), "0.21");
        // UDK's floats are 32-bit: nothing beyond f32::MAX (#56: 1e308 printed 309 digits).
        assert_eq!(fixed(1e300, 2), format!("{:.2}", f32::MAX));
        assert_eq!(fixed(-1e308, 4), format!("-{:.4}", f32::MAX));
        assert_eq!(fixed(1e38, 0), "99999999999999997748809823456034029568");
        assert_eq!(fixed(-1e17, 0), "-100000000000000000");
        assert_eq!(
            fs(-1e17, 0),
            "-2147483647",
            "beyond the grid: the saturating f32 path"
        );
        let mut s = String::new();
        push_int(&mut s, -100_000_000_000_000_000);
        assert_eq!(s, "-100000000000000000");
        assert_eq!(fixed(f64::NAN, 4), "NaN");
        let mut s = String::new();
        push_implicit_vector(&mut s, Vec3::new(0.21, -0.0, -0.2));
        assert_eq!(s, "0.21,-0.00,-0.20");
    }

    /// The formatters as they were before the digit-pair writer (commit 01ceb9f), kept as
    /// the reference the fast ones must match byte for byte.
    mod reference {
        use super::super::POW10;

        fn decimal(negative: bool, ip: u64, frac: u64, decimals: usize) -> String {
            let mut buf = [0u8; 48];
            let mut pos = buf.len();
            let mut f = frac;
            for _ in 0..decimals {
                pos -= 1;
                buf[pos] = b'0' + (f % 10) as u8;
                f /= 10;
            }
            if decimals > 0 {
                pos -= 1;
                buf[pos] = b'.';
            }
            let mut i = ip;
            loop {
                pos -= 1;
                buf[pos] = b'0' + (i % 10) as u8;
                i /= 10;
                if i == 0 {
                    break;
                }
            }
            if negative {
                pos -= 1;
                buf[pos] = b'-';
            }
            String::from_utf8(buf[pos..].to_vec()).unwrap()
        }

        pub(super) fn fixed(v: f64, decimals: u8) -> String {
            let d = usize::from(decimals);
            if v.is_finite() && d < POW10.len() {
                let scaled = v.abs() * POW10[d] as f64;
                let fraction = scaled - scaled.floor();
                if scaled < 1e10 && (fraction - 0.5).abs() > 1e-5 {
                    let n = (scaled + 0.5) as u64;
                    return decimal(v.is_sign_negative(), n / POW10[d], n % POW10[d], d);
                }
            }
            // Since #56: held to the f32 range.
            let v = if v.is_finite() {
                v.clamp(-f64::from(f32::MAX), f64::from(f32::MAX))
            } else {
                v
            };
            format!("{v:.d$}")
        }

        pub(super) fn float_string(v: f64, p: u8) -> String {
            let p = usize::from(p.min(9));
            let negative = v.is_sign_negative();
            let a = v.abs();
            let pow = POW10[p] as f64;
            let scaled = a * pow;
            let n = (scaled + 0.5) as u64;
            let grid = n as f64;
            if grid < 1e17 && (scaled - grid).abs() <= (scaled * 1e-9).max(1e-12 * pow) {
                return decimal(negative, n / POW10[p], n % POW10[p], p);
            }
            let f = (v as f32).abs();
            let ip = f as i32;
            let frac = ((f - ip as f32) * 10f32.powi(p as i32)) as i32;
            decimal(
                negative,
                u64::from(ip.unsigned_abs()),
                u64::from(frac.unsigned_abs()),
                p,
            )
        }
    }

    /// Values of every kind: small readings, grid points and near-ties of 2 and 4 decimals,
    /// huge and tiny magnitudes, signed zeros, non-finite values, and any bit pattern.
    fn any_value() -> impl proptest::strategy::Strategy<Value = f64> {
        use proptest::prelude::*;
        prop_oneof![
            -10.0..10.0f64,
            -1e6..1e6f64,
            (-1_000_000i64..1_000_000, 0u32..3).prop_map(|(n, k)| {
                // A point of the 2- or 4-decimal grid, or the tie halfway past it.
                let ties = [0.0, 0.5, 0.05];
                (n as f64 + ties[k as usize]) / 1e4
            }),
            (-1_000_000i64..1_000_000).prop_map(|n| (n as f64 + 0.5) / 100.0),
            prop_oneof![Just(0.0), Just(-0.0), Just(f64::NAN), Just(-f64::NAN)],
            prop_oneof![Just(f64::INFINITY), Just(f64::NEG_INFINITY), Just(f64::MAX)],
            prop_oneof![Just(f64::MIN_POSITIVE), Just(-5e-324), Just(9.999999999e9)],
            prop_oneof![Just(1.8446744073709552e19), Just(2147483648.0), Just(-1e17)],
            any::<u64>().prop_map(f64::from_bits),
            any::<f32>().prop_map(f64::from),
        ]
    }

    proptest::proptest! {
        /// A laser scan's list is printed through one buffer handed over in pieces: any
        /// length, into text or bytes, the same as the numbers one by one.
        #[test]
        fn long_lists_match_the_reference(
            values in proptest::collection::vec(any_value(), 0..400),
            d in 0u8..12,
        ) {
            let expected = values
                .iter()
                .map(|&v| reference::float_string(v, d))
                .collect::<Vec<_>>()
                .join(",");
            let mut text = String::from("x");
            push_float_string_list(&mut text, &values, d);
            proptest::prop_assert_eq!(&text[1..], expected.as_str());
            let mut bytes = b"x".to_vec();
            push_float_string_list(&mut bytes, &values, d);
            proptest::prop_assert_eq!(&bytes[1..], expected.as_bytes());
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(20_000))]

        #[test]
        fn fast_formatters_match_the_reference(v in any_value(), w in any_value(), d in 0u8..12) {
            let mut list = String::new();
            push_fixed_list(&mut list, &[v, w], d);
            proptest::prop_assert_eq!(
                list,
                format!("{},{}", reference::fixed(v, d), reference::fixed(w, d))
            );
            let mut list = String::new();
            push_float_string_list(&mut list, &[v, w], d);
            proptest::prop_assert_eq!(
                list,
                format!("{},{}", reference::float_string(v, d), reference::float_string(w, d))
            );
            proptest::prop_assert_eq!(fixed(v, d), reference::fixed(v, d));
            proptest::prop_assert_eq!(fs(v, d), reference::float_string(v, d));
            // Byte buffers take their own copy path: after other text, the same bytes.
            let mut bytes = b"x".to_vec();
            push_fixed(&mut bytes, v, d);
            push_float_string(&mut bytes, v, d);
            let expected = format!("x{}{}", fixed(v, d), fs(v, d));
            proptest::prop_assert_eq!(&bytes, expected.as_bytes());
            #[cfg(feature = "codec")]
            {
                let mut buf = bytes::BytesMut::from("x");
                push_fixed(&mut buf, v, d);
                push_float_string(&mut buf, v, d);
                proptest::prop_assert_eq!(&buf[..], expected.as_bytes());
            }
            let mut s = String::new();
            push_int(&mut s, v as i64);
            proptest::prop_assert_eq!(s, (v as i64).to_string());
        }
    }

    #[test]
    fn shortest_never_uses_exponents() {
        let mut s = String::new();
        for v in [1.0, 0.1, -2.5, 1e21, 1e-7, 0.0, 1e38, 1e-44] {
            s.clear();
            push_shortest(&mut s, v);
            assert!(!s.contains('e'), "{s}");
            assert_eq!(s.parse::<f64>().unwrap(), v);
        }
    }

    /// #56: `1e308` was printed as 309 digits, `5e-324` as 326 characters.
    #[test]
    fn no_number_is_printed_longer_than_udk_could() {
        let mut s = String::new();
        for v in [1e308, -1e308, f64::MAX, 5e-324, -1e-300, 3.5e38, 1e-46] {
            for d in [0, 2, 4] {
                s.clear();
                push_fixed(&mut s, v, d);
                assert!(s.len() <= 45, "{v:e}: {s}");
                s.clear();
                push_float_string(&mut s, v, d);
                assert!(s.len() <= 45, "{v:e}: {s}");
            }
            s.clear();
            push_shortest(&mut s, v);
            assert!(s.len() <= 64, "{v:e}: {s}");
            let back: f64 = s.parse().unwrap();
            assert!(back.abs() <= f64::from(f32::MAX), "{v:e}: {s}");
        }
        s.clear();
        push_shortest(&mut s, 1e308);
        assert_eq!(s, "340282346638528860000000000000000000000");
        s.clear();
        push_shortest(&mut s, -1e-300);
        assert_eq!(s, "-0");
    }
}
