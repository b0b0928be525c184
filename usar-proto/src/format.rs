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
//! All formatters append to a [`WireBuf`] (a `String`, a `Vec<u8>` or a `bytes::BytesMut`)
//! without allocating.

use crate::messages::Vec3;

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
    /// Appends formatted text (only used on rare slow paths).
    fn push_args(&mut self, args: std::fmt::Arguments<'_>);
}

impl WireBuf for String {
    fn push_text(&mut self, s: &str) {
        self.push_str(s);
    }
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
    fn push_text(&mut self, s: &str) {
        self.extend_from_slice(s.as_bytes());
    }
    fn push_ascii(&mut self, bytes: &[u8]) {
        self.extend_from_slice(bytes);
    }
    fn push_args(&mut self, args: std::fmt::Arguments<'_>) {
        // Writing into a Vec cannot fail.
        let _ = std::io::Write::write_fmt(self, args);
    }
}

#[cfg(feature = "codec")]
impl WireBuf for bytes::BytesMut {
    fn push_text(&mut self, s: &str) {
        self.extend_from_slice(s.as_bytes());
    }
    fn push_ascii(&mut self, bytes: &[u8]) {
        self.extend_from_slice(bytes);
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

/// Appends `ip.frac` with `frac` zero-padded to `decimals` digits (or just `ip` for 0).
fn push_decimal(out: &mut impl WireBuf, negative: bool, ip: u64, frac: u64, decimals: usize) {
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
    out.push_ascii(&buf[pos..]);
}

/// Appends a signed integer.
pub fn push_int(out: &mut impl WireBuf, v: i64) {
    push_decimal(out, v < 0, v.unsigned_abs(), 0, 0);
}

/// Appends `True` or `False`, the engine's spelling of booleans.
pub fn push_bool(out: &mut impl WireBuf, v: bool) {
    out.push_text(if v { "True" } else { "False" });
}

/// Appends `v` rounded to `decimals` digits (C `%.Nf`): the engine's implicit float→string
/// with 4 decimals (UT2004 used 2).
pub fn push_fixed(out: &mut impl WireBuf, v: f64, decimals: u8) {
    let d = usize::from(decimals);
    if v.is_finite() && d < POW10.len() {
        let scaled = v.abs() * POW10[d] as f64;
        // Below 1e10 the product's error is < 2e-6, so rounding it is exact unless the
        // fractional part is near .5; those rare cases take the exact slow path.
        let fraction = scaled - scaled.floor();
        if scaled < 1e10 && (fraction - 0.5).abs() > 1e-5 {
            // Positive and not near .5: adding a half and truncating is rounding, without a
            // call into libm.
            let n = (scaled + 0.5) as u64;
            push_decimal(out, v.is_sign_negative(), n / POW10[d], n % POW10[d], d);
            return;
        }
    }
    out.push_args(format_args!("{v:.d$}"));
}

/// Appends the engine's implicit vector→string: `%.2f,%.2f,%.2f`.
pub fn push_implicit_vector(out: &mut impl WireBuf, v: Vec3) {
    push_fixed_list(out, &[v.x, v.y, v.z], 2);
}

/// Appends numbers with [`push_fixed`], comma separated, no spaces.
pub fn push_fixed_list(out: &mut impl WireBuf, values: &[f64], decimals: u8) {
    for (i, &v) in values.iter().enumerate() {
        if i > 0 {
            out.push_text(",");
        }
        push_fixed(out, v, decimals);
    }
}

/// Appends `UnitsConverter.FloatString(v, p)`: truncation to `p` decimals (see the module
/// docs for the exact-decimal rule). `p` above 9 is treated as 9.
pub fn push_float_string(out: &mut impl WireBuf, v: f64, p: u8) {
    let p = usize::from(p.min(9));
    let negative = v.is_sign_negative();
    let a = v.abs();
    let pow = POW10[p] as f64;
    let scaled = a * pow;
    // Rounding by a cast (saturating; NaN gives 0 and fails the test below): no libm call.
    let n = (scaled + 0.5) as u64;
    let grid = n as f64;
    if grid < 1e17 && (scaled - grid).abs() <= (scaled * 1e-9).max(1e-12 * pow) {
        push_decimal(out, negative, n / POW10[p], n % POW10[p], p);
        return;
    }
    // The engine's algorithm, in f32, with its int() truncations (saturating here).
    let f = (v as f32).abs();
    let ip = f as i32;
    let frac = ((f - ip as f32) * 10f32.powi(p as i32)) as i32;
    push_decimal(
        out,
        negative,
        u64::from(ip.unsigned_abs()),
        u64::from(frac.unsigned_abs()),
        p,
    );
}

/// Appends `UnitsConverter.VectorString`: three FloatStrings joined by commas.
pub fn push_float_string_vector(out: &mut impl WireBuf, v: Vec3, p: u8) {
    push_float_string_list(out, &[v.x, v.y, v.z], p);
}

/// Appends FloatStrings joined by commas (laser ranges).
pub fn push_float_string_list(out: &mut impl WireBuf, values: &[f64], p: u8) {
    for (i, &v) in values.iter().enumerate() {
        if i > 0 {
            out.push_text(",");
        }
        push_float_string(out, v, p);
    }
}

/// Appends Rust's shortest round-trip form (`{}`: never exponent notation), used for the
/// numbers of client commands so that reading them back gives the same `f64`.
pub fn push_shortest(out: &mut impl WireBuf, v: f64) {
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
        assert_eq!(fixed(1e300, 2), format!("{:.2}", 1e300));
        assert_eq!(fixed(f64::NAN, 4), "NaN");
        let mut s = String::new();
        push_implicit_vector(&mut s, Vec3::new(0.21, -0.0, -0.2));
        assert_eq!(s, "0.21,-0.00,-0.20");
    }

    #[test]
    fn shortest_never_uses_exponents() {
        let mut s = String::new();
        for v in [1.0, 0.1, -2.5, 1e21, 1e-7, 0.0] {
            s.clear();
            push_shortest(&mut s, v);
            assert!(!s.contains('e'), "{s}");
            assert_eq!(s.parse::<f64>().unwrap(), v);
        }
    }
}
