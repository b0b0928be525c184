//! The one writer of `{Key value}` groups, used by every typed printer.

use crate::format::{self, WireBuf};
use crate::primitive::{Time, Vec3};

/// Writes a line group by group: ` {Key value}`, or `{Key value}` right after [`Line::glue`].
pub(crate) struct Line<'o, B: WireBuf> {
    out: &'o mut B,
    glue: bool,
}

impl<'o, B: WireBuf> Line<'o, B> {
    /// Starts a line with its message word.
    pub(crate) fn new(out: &'o mut B, word: &str) -> Self {
        out.push_text(word);
        Self { out, glue: false }
    }

    /// The next group follows the previous one without a space.
    pub(crate) fn glue(&mut self) -> &mut Self {
        self.glue = true;
        self
    }

    /// Appends raw text.
    pub(crate) fn raw(&mut self, s: &str) -> &mut Self {
        self.out.push_text(s);
        self
    }

    // Inlined so that the constant keys are copied as constants, not by memcpy calls.
    #[inline(always)]
    fn open(&mut self, key: &str) -> &mut B {
        self.out.push_text(if self.glue { "{" } else { " {" });
        self.glue = false;
        self.out.push_text(key);
        self.out.push_text(" ");
        self.out
    }

    #[inline(always)]
    fn with(&mut self, key: &str, value: impl FnOnce(&mut B)) -> &mut Self {
        value(self.open(key));
        self.out.push_text("}");
        self
    }

    /// `{Key}` with no value (`{On}`).
    pub(crate) fn bare(&mut self, key: &str) -> &mut Self {
        if !self.glue {
            self.out.push_text(" ");
        }
        self.glue = false;
        self.out.push_text("{");
        self.out.push_text(key);
        self.out.push_text("}");
        self
    }

    pub(crate) fn text(&mut self, key: &str, v: &str) -> &mut Self {
        self.with(key, |o| o.push_text(v))
    }

    pub(crate) fn int(&mut self, key: &str, v: i64) -> &mut Self {
        self.with(key, |o| format::push_int(o, v))
    }

    pub(crate) fn bool(&mut self, key: &str, v: bool) -> &mut Self {
        self.with(key, |o| format::push_bool(o, v))
    }

    /// Implicit float (`%.Nf`).
    pub(crate) fn fixed(&mut self, key: &str, v: f64, decimals: u8) -> &mut Self {
        self.with(key, |o| format::push_fixed(o, v, decimals))
    }

    /// Implicit floats joined by commas.
    pub(crate) fn fixed_list(&mut self, key: &str, v: &[f64], decimals: u8) -> &mut Self {
        self.with(key, |o| format::push_fixed_list(o, v, decimals))
    }

    /// Implicit vector (`%.2f,%.2f,%.2f`).
    pub(crate) fn ivec(&mut self, key: &str, v: Vec3) -> &mut Self {
        self.with(key, |o| format::push_implicit_vector(o, v))
    }

    /// FloatString.
    pub(crate) fn fs(&mut self, key: &str, v: f64, p: u8) -> &mut Self {
        self.with(key, |o| format::push_float_string(o, v, p))
    }

    /// VectorString.
    pub(crate) fn fs_vec(&mut self, key: &str, v: Vec3, p: u8) -> &mut Self {
        self.with(key, |o| format::push_float_string_vector(o, v, p))
    }

    /// FloatStrings joined by commas.
    pub(crate) fn fs_list(&mut self, key: &str, v: &[f64], p: u8) -> &mut Self {
        self.with(key, |o| format::push_float_string_list(o, v, p))
    }

    /// `{Time t}` with its decimals.
    pub(crate) fn time(&mut self, t: Time) -> &mut Self {
        self.fixed("Time", t.seconds, t.decimals)
    }

    /// A client-command number (shortest round trip).
    pub(crate) fn num(&mut self, key: &str, v: f64) -> &mut Self {
        self.with(key, |o| format::push_shortest(o, v))
    }

    /// A client-command vector `x,y,z` (shortest round trip).
    pub(crate) fn vec(&mut self, key: &str, v: Vec3) -> &mut Self {
        self.with(key, |o| {
            format::push_shortest(o, v.x);
            o.push_text(",");
            format::push_shortest(o, v.y);
            o.push_text(",");
            format::push_shortest(o, v.z);
        })
    }
}
