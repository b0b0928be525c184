//! The logic behind `ucc decode` and `ucc encode`: protocol lines ⇄ typed JSON.
//!
//! * [`decode`] reads protocol lines of either direction and writes, for each, one JSON
//!   object per line (`{"server":{"Sta":{...}}}` or `{"client":{"Drive":{...}}}`), or, with
//!   `print`, the line printed back by `usar-proto`'s printer. The JSON carries the typed
//!   values (numbers as numbers), not the original text.
//! * [`encode`] reads those JSON objects and writes the protocol lines.
//!
//! Rules:
//!
//! * The direction of a line is decided by its message word: `NFO`, `STA`, `SEN`, `CONF`,
//!   `GEO`, `ASTA`, `EFF`, `DIE`, `MISSTA`, `BSTA`, `RES` are server messages
//!   ([`usar_proto::SERVER_WORDS`]); every other word, known or not, is a client command
//!   (UDK ignores unknown commands, and unknown words in the wild — `MULTIDRIVE` — come from
//!   clients). An unknown word therefore decodes as `{"client":{"Other":{...}}}`.
//! * Nothing a line says is lost. A line decodes in its typed form only when that form keeps
//!   all of it: a server line whose typed form prints back to other bytes (`{Range 4.5}`
//!   would print as `4.5000`), or a command with a key its type does not have (`INIT ...
//!   {Battery 3600}`), a number or vector that cannot be read, a boolean that is not exactly
//!   `true`/`false`, text outside braces, or a number beyond what UDK's 32-bit floats hold
//!   (`1e308`, which the printer holds to `f32::MAX`), decodes in the generic form (`Other`:
//!   the word and every key and value as text), which encodes back to the same line (server
//!   lines byte for byte, commands with canonical spacing).
//! * A command value that is not a number where a number belongs (`DRIVE {LinearVelocity
//!   abc}`) is kept as text and reported (`line N: ...`); so are lines that cannot be read
//!   or converted. Both functions return the number of lines reported (the program exits
//!   with 1 when it is not 0); the other lines go on.
//! * Blank lines and lines starting with `#` (comments in capture files) are skipped.
//! * Streaming with bounded memory, whatever the input: a line ends at `\r\n`, `\n` or a
//!   lone `\r`, and each output line ends the way its input line did (so `decode | encode`
//!   gives CRLF lines back as CRLF). A line longer than [`MAX_LINE`] bytes (the server's
//!   limit; [`MAX_JSON_LINE`] for `encode`) is skipped without being stored and reported
//!   with its number and length.
//! * `decode` stops, with exit status 1, where its input stops being the protocol, naming
//!   the line and the byte offset in the input (`line 3, byte 112: not the protocol: ...`):
//!   a line that is not UTF-8, holds a control character other than TAB, or does not begin
//!   with a message word (an ASCII letter, then letters, digits or `_`) followed by nothing
//!   or a `{` (`hello world`, `x#!`, binary garbage). Unknown message words (`MULTIDRIVE
//!   {...}`, `TEST`) are the protocol.
//! * `encode` refuses a message whose text value holds a brace or a control character (it
//!   would add a field or a line): commands by `Command::check`, server messages by the same
//!   rule on every text value; and a message that would print a control character other
//!   than TAB; naming the line and the key. Bytes of `encode`'s input that are not UTF-8 are
//!   a JSON error of their line.

use std::io::{self, BufRead, Write};

use serde::{Deserialize, Serialize};
use usar_proto::{Command, Deviation, Message, ServerMessage, TextError};

/// The longest protocol line `decode` reads: the server's limit
/// (`usar_proto::codec::DEFAULT_MAX_LINE`, 64 KiB).
pub(crate) const MAX_LINE: usize = usar_proto::codec::DEFAULT_MAX_LINE;

/// The longest JSON line `encode` reads (1 MiB): the JSON of a line of [`MAX_LINE`] bytes in
/// the generic form is at most about eight times longer.
pub(crate) const MAX_JSON_LINE: usize = 16 * MAX_LINE;

/// One decoded line: which direction, and the typed message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(crate) enum WireLine {
    /// A client → server command.
    Client(Command),
    /// A server → client message.
    Server(ServerMessage),
}

impl WireLine {
    /// Reads one protocol line, choosing the direction by its message word, in the typed
    /// form only when it keeps everything the line says (module docs). The strings are what
    /// is worth reporting about the line (a command's value that is not a number).
    pub(crate) fn parse(line: &str) -> Result<(Self, Vec<String>), usar_proto::ParseError> {
        if ServerMessage::is_server_word(Message::word(line)) {
            let typed = ServerMessage::parse(line)?.message;
            if matches!(typed, ServerMessage::Other(_)) || typed.to_string() == line {
                return Ok((Self::Server(typed), Vec::new()));
            }
            let mut generic = Message::parse(line)?.message;
            if generic.to_string() != line {
                generic.verbatim = Some(line.to_owned());
            }
            return Ok((Self::Server(ServerMessage::Other(generic)), Vec::new()));
        }
        let parsed = Command::parse(line)?;
        let mut problems = Vec::new();
        let mut lossy = false;
        for deviation in &parsed.deviations {
            match deviation {
                // Spelling and spacing: the typed form says the same.
                Deviation::ExtraWhitespace
                | Deviation::MissingSpace
                | Deviation::UnclosedGroup
                | Deviation::CommandCase(_)
                | Deviation::KeyCase { .. }
                | Deviation::UnknownCommand(_)
                | Deviation::DecimalComma { .. }
                | Deviation::LeadingPlus { .. } => {}
                Deviation::BadNumber { key, value } => {
                    lossy = true;
                    problems.push(format!(
                        "{{{key} {value}}}: {value:?} is not a number (kept as written)"
                    ));
                }
                Deviation::BadVector { key, value } => {
                    lossy = true;
                    problems.push(format!(
                        "{{{key} {value}}}: not three numbers x,y,z (kept as written)"
                    ));
                }
                _ => lossy = true,
            }
        }
        // A key given twice: the typed form keeps the first only.
        let pairs = |m: &Message| m.groups.iter().map(|g| g.pairs.len()).sum::<usize>();
        let generic = Message::parse_udk(line)?.message;
        if !lossy
            && !matches!(parsed.message, Command::Other(_))
            && pairs(&Message::parse_udk(&parsed.message.to_string())?.message) != pairs(&generic)
        {
            lossy = true;
        }
        // A number the printer holds to UDK's range (`1e308`): the typed form would change it.
        if !lossy
            && !matches!(parsed.message, Command::Other(_))
            && Command::parse(&parsed.message.to_string())?.message != parsed.message
        {
            lossy = true;
        }
        let command = if lossy {
            Command::Other(generic)
        } else {
            parsed.message
        };
        Ok((Self::Client(command), problems))
    }
}

impl std::fmt::Display for WireLine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Client(c) => c.fmt(f),
            Self::Server(m) => m.fmt(f),
        }
    }
}

/// One line of input.
enum Item<'a> {
    /// A line: its bytes and its terminator (`"\r\n"`, `"\n"`, `"\r"`, or `""` at the end of
    /// the input).
    Line(&'a [u8], &'static str),
    /// A line longer than the limit: how many bytes it had (its text was not kept).
    TooLong(u64),
}

/// Splits a byte stream into lines, keeping at most `limit` bytes of any line in memory.
struct Lines<R> {
    input: R,
    limit: usize,
    line: Vec<u8>,
    /// Bytes of the current line, including those not kept.
    length: u64,
    /// 1-based number of the last line returned.
    number: usize,
    /// Bytes of the input consumed so far.
    consumed: u64,
}

impl<R: BufRead> Lines<R> {
    fn new(input: R, limit: usize) -> Self {
        Self {
            input,
            limit,
            line: Vec::new(),
            length: 0,
            number: 0,
            consumed: 0,
        }
    }

    fn fill(input: &mut R) -> io::Result<&[u8]> {
        loop {
            match input.fill_buf() {
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                // Asked again: the borrow checker cannot see that the loop ends here.
                Ok(_) => return input.fill_buf(),
                Err(e) => return Err(e),
            }
        }
    }

    /// Keeps a piece of the current line, unless the line is already over the limit.
    fn keep(line: &mut Vec<u8>, length: &mut u64, limit: usize, piece: &[u8]) {
        *length += piece.len() as u64;
        if *length <= limit as u64 {
            line.extend_from_slice(piece);
        } else {
            line.clear();
        }
    }

    /// The offset in the input of the next line's first byte.
    fn start_of_next(&self) -> u64 {
        self.consumed
    }

    /// The next line with its 1-based number, `None` at the end of the input.
    fn next(&mut self) -> io::Result<Option<(usize, Item<'_>)>> {
        self.line.clear();
        self.length = 0;
        let end = loop {
            let buf = Self::fill(&mut self.input)?;
            if buf.is_empty() {
                if self.length == 0 {
                    return Ok(None);
                }
                break "";
            }
            let Some(i) = buf.iter().position(|&b| b == b'\n' || b == b'\r') else {
                let n = buf.len();
                Self::keep(&mut self.line, &mut self.length, self.limit, buf);
                self.input.consume(n);
                self.consumed += n as u64;
                continue;
            };
            let ending = buf[i];
            Self::keep(&mut self.line, &mut self.length, self.limit, &buf[..i]);
            self.input.consume(i + 1);
            self.consumed += i as u64 + 1;
            if ending == b'\n' {
                break "\n";
            }
            // A CR: one more byte tells CR LF from a lone CR.
            if Self::fill(&mut self.input)?.first() == Some(&b'\n') {
                self.input.consume(1);
                self.consumed += 1;
                break "\r\n";
            }
            break "\r";
        };
        self.number += 1;
        let item = if self.length > self.limit as u64 {
            Item::TooLong(self.length)
        } else {
            Item::Line(&self.line, end)
        };
        Ok(Some((self.number, item)))
    }
}

/// What a line gave to report.
enum Report {
    /// A problem with the line; the next lines go on.
    Line(String),
    /// The input stops being the protocol at this byte offset (of the whole input): why.
    /// Nothing more is read.
    Stop(u64, String),
}

/// Calls `each(text, terminator, offset)` for every non-blank, non-comment line (`offset`:
/// of its first byte in the input), and reports on `err` what it returns, and over-long
/// lines. Returns how many were reported.
fn for_each_line(
    input: impl BufRead,
    limit: usize,
    mut err: impl Write,
    mut each: impl FnMut(&[u8], &str, u64) -> io::Result<Option<Report>>,
) -> io::Result<usize> {
    let mut lines = Lines::new(input, limit);
    let mut reported = 0;
    loop {
        let start = lines.start_of_next();
        let Some((number, item)) = lines.next()? else {
            break;
        };
        let report = match item {
            Item::TooLong(length) => Some(Report::Line(format!(
                "{length} bytes, longer than the limit of {limit}: skipped"
            ))),
            Item::Line(text, _) if text.trim_ascii().is_empty() || text.starts_with(b"#") => None,
            Item::Line(text, end) => each(text, end, start)?,
        };
        match report {
            None => {}
            Some(Report::Line(problem)) => {
                reported += 1;
                writeln!(err, "line {number}: {problem}")?;
            }
            Some(Report::Stop(offset, why)) => {
                writeln!(
                    err,
                    "line {number}, byte {offset}: not the protocol: {why}; nothing after it \
                     was read"
                )?;
                return Ok(reported + 1);
            }
        }
    }
    Ok(reported)
}

/// The text of a line that is the protocol, or where (the byte offset in the line) and why
/// it is not (module docs): it must be UTF-8, hold no control character but TAB, and
/// begin with a message word (an ASCII letter, then letters, digits or `_`) followed by
/// nothing or a `{`.
fn protocol_text(line: &[u8]) -> Result<&str, (usize, String)> {
    let text = std::str::from_utf8(line).map_err(|e| {
        let at = e.valid_up_to();
        (at, format!("the byte 0x{:02x} is not UTF-8", line[at]))
    })?;
    if let Some((at, c)) = text
        .char_indices()
        .find(|(_, c)| c.is_control() && *c != '\t')
    {
        return Err((at, format!("the control character {c:?}")));
    }
    let begin = text.len() - text.trim_start().len();
    let word = text[begin..]
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .map_or(text.len(), |n| begin + n);
    let next = text[word..]
        .find(|c: char| !c.is_whitespace())
        .map(|n| word + n);
    let starts_with_letter = text[begin..].starts_with(|c: char| c.is_ascii_alphabetic());
    match next {
        _ if !starts_with_letter => Err((
            begin,
            "a line begins with its message word (a letter, then letters, digits or _)".into(),
        )),
        Some(at) if !text[at..].starts_with('{') => {
            let found: String = text[at..].chars().take(20).collect();
            Err((
                at,
                format!("{found:?} where the message word ends or a `{{` begins"),
            ))
        }
        _ => Ok(text),
    }
}

/// `ucc decode`: protocol lines to JSON objects (or, with `print`, to printed lines).
/// Returns the number of lines reported on `err`.
pub(crate) fn decode(
    input: impl BufRead,
    mut out: impl Write,
    err: impl Write,
    print: bool,
) -> io::Result<usize> {
    let reported = for_each_line(input, MAX_LINE, err, |line, end, start| {
        let line = match protocol_text(line) {
            Ok(text) => text,
            Err((at, why)) => return Ok(Some(Report::Stop(start + at as u64, why))),
        };
        let (m, problems) = match WireLine::parse(line) {
            Ok(parsed) => parsed,
            Err(e) => return Ok(Some(Report::Line(e.to_string()))),
        };
        if print {
            write!(out, "{m}")?;
        } else {
            serde_json::to_writer(&mut out, &m).map_err(io::Error::other)?;
        }
        out.write_all(end.as_bytes())?;
        Ok((!problems.is_empty()).then(|| Report::Line(problems.join("; "))))
    })?;
    out.flush()?;
    Ok(reported)
}

/// Why `m` cannot be printed into one line of its own: a text value holding a brace or a
/// control character (it would add a field or a line). Commands are checked by
/// [`Command::check`]; server messages by the same rule on every text value (`verbatim`, a
/// whole line kept as read, may hold braces).
fn unprintable(m: &WireLine) -> Option<String> {
    fn walk(word: &str, key: &str, value: &serde_json::Value) -> Result<(), TextError> {
        match value {
            serde_json::Value::String(s) if key == "verbatim" => {
                TextError::check(word, key, &s.replace(['{', '}'], ""))
            }
            serde_json::Value::String(s) => TextError::check(word, key, s),
            serde_json::Value::Array(items) => items.iter().try_for_each(|v| walk(word, key, v)),
            serde_json::Value::Object(fields) => {
                fields.iter().try_for_each(|(k, v)| walk(word, k, v))
            }
            _ => Ok(()),
        }
    }
    let checked = match m {
        WireLine::Client(c) => c.check(),
        WireLine::Server(s) => {
            let text = s.to_string();
            let word = Message::word(&text);
            serde_json::to_value(s)
                .map_err(|e| TextError {
                    command: word.to_owned(),
                    key: String::new(),
                    value: String::new(),
                    what: e.to_string(),
                })
                .and_then(|v| walk(word, "", &v))
        }
    };
    checked.err().map(|e| e.to_string())
}

/// `ucc encode`: JSON objects (as written by [`decode`]) to protocol lines. Returns the
/// number of lines reported on `err`.
pub(crate) fn encode(
    input: impl BufRead,
    mut out: impl Write,
    err: impl Write,
) -> io::Result<usize> {
    let mut text = String::new();
    let reported = for_each_line(input, MAX_JSON_LINE, err, |line, end, _| {
        let m = match serde_json::from_slice::<WireLine>(line) {
            Ok(m) => m,
            Err(e) => return Ok(Some(Report::Line(e.to_string()))),
        };
        if let Some(problem) = unprintable(&m) {
            return Ok(Some(Report::Line(format!("{problem}: not written"))));
        }
        text.clear();
        match &m {
            WireLine::Client(c) => c.write_to(&mut text),
            WireLine::Server(s) => s.write_to(&mut text),
        }
        if let Some(c) = text.chars().find(|c| c.is_control() && *c != '\t') {
            return Ok(Some(Report::Line(format!(
                "the message would print the control character {c:?} into the line: not written"
            ))));
        }
        out.write_all(text.as_bytes())?;
        out.write_all(end.as_bytes())?;
        Ok(None)
    })?;
    out.flush()?;
    Ok(reported)
}

/// A reader or writer whose errors name what it reads or writes (`standard output`), keeping
/// their kind (a closed pipe stays [`io::ErrorKind::BrokenPipe`]).
pub(crate) struct Named<T> {
    inner: T,
    name: &'static str,
}

impl<T> Named<T> {
    pub(crate) fn new(inner: T, name: &'static str) -> Self {
        Self { inner, name }
    }

    fn error(&self, verb: &str, e: io::Error) -> io::Error {
        io::Error::new(e.kind(), format!("cannot {verb} {}: {e}", self.name))
    }
}

impl<W: Write> Write for Named<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.inner.write(buf).map_err(|e| self.error("write", e))
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush().map_err(|e| self.error("write", e))
    }
}

impl<R: io::Read> io::Read for Named<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.inner.read(buf).map_err(|e| self.error("read", e))
    }
}

impl<R: BufRead> BufRead for Named<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        // Asked twice: the borrow checker cannot see that the error path does not borrow.
        if let Err(e) = self.inner.fill_buf() {
            return Err(self.error("read", e));
        }
        self.inner.fill_buf()
    }

    fn consume(&mut self, n: usize) {
        self.inner.consume(n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CAPTURE: &str = include_str!("../../usar-proto/tests/data/USARcommandSample.txt");
    const EXAMPLES: &str = include_str!("../../usar-proto/tests/data/protocol_examples.txt");

    fn run_decode(input: &str, print: bool) -> (String, String, usize) {
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let failed = decode(input.as_bytes(), &mut out, &mut err, print).unwrap();
        (
            String::from_utf8(out).unwrap(),
            String::from_utf8(err).unwrap(),
            failed,
        )
    }

    fn run_encode(input: &str) -> (String, String, usize) {
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let failed = encode(input.as_bytes(), &mut out, &mut err).unwrap();
        (
            String::from_utf8(out).unwrap(),
            String::from_utf8(err).unwrap(),
            failed,
        )
    }

    /// The UDK-era server lines of the capture and of protocol.md's examples.
    fn server_lines() -> Vec<&'static str> {
        let examples = EXAMPLES.lines().filter_map(|l| l.strip_prefix("S "));
        CAPTURE
            .lines()
            .filter(|l| ServerMessage::is_server_word(Message::word(l)))
            .chain(examples)
            .collect()
    }

    #[test]
    fn json_carries_the_numbers_of_the_line() {
        let (out, err, failed) = run_decode("STA {Time 477.7582} {Battery 99999}\r\n", false);
        assert_eq!((err.as_str(), failed), ("", 0));
        assert_eq!(
            out,
            "{\"server\":{\"Sta\":{\"time\":{\"seconds\":477.7582,\"decimals\":4},\"battery\":99999,\"vehicle\":null,\"layout\":\"Udk\"}}}\r\n"
        );
        let (out, _, _) = run_decode("DRIVE {Left 1.5}\n", false);
        assert!(out.starts_with("{\"client\":{\"Drive\":{"), "{out}");
        assert!(out.contains("\"left\":1.5"), "{out}");
    }

    #[test]
    fn the_whole_capture_decodes() {
        let (out, err, failed) = run_decode(CAPTURE, false);
        assert_eq!((err.as_str(), failed), ("", 0));
        assert_eq!(out.lines().count(), 46);
    }

    #[test]
    fn decode_then_encode_gives_server_lines_back_byte_for_byte() {
        let lines = server_lines();
        let input = lines.join("\r\n");
        let (json, err, failed) = run_decode(&input, false);
        assert_eq!((err.as_str(), failed), ("", 0));
        let (text, err, failed) = run_encode(&json);
        assert_eq!((err.as_str(), failed), ("", 0));
        assert_eq!(text, input, "the same bytes, CR LF and all");
        let (printed, _, _) = run_decode(&input, true);
        assert_eq!(printed, text);
    }

    #[test]
    fn server_lines_with_fields_missing_decode_and_encode_back_exactly() {
        // Real servers print such lines; they used to be dropped with exit status 1.
        let input = "SEN {Time 1.0000} {Type IMU} {Name IMU}\nGEO {Type Camera} {Name c} {Orientation 0.00,0.00,0.00}{Mount AirRobot}\nGETSTARTPOSES\n";
        let (printed, err, failed) = run_decode(input, true);
        assert_eq!((err.as_str(), failed), ("", 0));
        assert_eq!(printed, input);
        let (json, _, _) = run_decode(input, false);
        let (text, err, failed) = run_encode(&json);
        assert_eq!((err.as_str(), failed), ("", 0));
        assert_eq!(text, input);
    }

    #[test]
    fn geo_lines_with_a_space_before_mount_decode_typed_and_print_back_exactly() {
        // Real UDK lines (issue #55): typed, with the space kept.
        let input = "GEO {Type RangeScanner} {Name lms200} {Location 0.21,-0.00,-0.20} {Orientation 0.00,-0.00,-0.00} {Mount P3AT}\r\nGEO {Type Camera} {Name cams} {Location 0.10,-0.00,0.05} {Orientation 0.00,-0.79,0.00} {Mount cam}{MountLink 1}\r\n";
        let (json, err, failed) = run_decode(input, false);
        assert_eq!((err.as_str(), failed), ("", 0));
        for line in json.lines() {
            assert!(line.starts_with("{\"server\":{\"Geo\""), "{line}");
            assert!(line.contains("\"mount\":\""), "{line}");
        }
        let (text, err, failed) = run_encode(&json);
        assert_eq!((err.as_str(), failed), ("", 0));
        assert_eq!(text, input);
        assert_eq!(run_decode(input, true).0, input);
    }

    /// Decodes, checks the report, encodes back.
    fn through(input: &str, reported: usize) -> (String, String) {
        let (json, err, failed) = run_decode(input, false);
        assert_eq!(failed, reported, "{err}");
        let (text, err2, failed) = run_encode(&json);
        assert_eq!((err2.as_str(), failed), ("", 0));
        (text, err)
    }

    #[test]
    fn nothing_a_line_says_is_lost() {
        // The defects of #25: Battery dropped, `4.5` printed as `4.5000`, CR LF made LF.
        let init = "INIT {ClassName USARBot.P3AT} {Name p3} {Location 1,2,3} {Battery 3600}\r\n";
        let (json, _, _) = run_decode(init, false);
        assert!(json.contains("Battery"), "{json}");
        assert_eq!(through(init, 0).0, init);
        let sen =
            "SEN {Time 1.0000} {Type Sonar} {Name F1} {Range 4.5}\r\nSTA {Time 2} {Battery 99}\n";
        assert_eq!(through(sen, 0).0, sen);
        assert_eq!(run_decode(sen, true).0, sen);
        // Typed where nothing is lost, with the line's own ending.
        let (json, _, _) = run_decode("DRIVE {LinearVelocity 1.5}\r", false);
        assert!(json.starts_with("{\"client\":{\"Drive\""), "{json}");
        assert!(json.ends_with("}\r"), "{json:?}");
        for line in [
            "DRIVE {Normalized True}\n",
            "DRIVE {Left 1} {Left 2}\n",
            "INIT {ClassName X} junk {Name a}\n",
        ] {
            let (text, _) = through(line, 0);
            assert_eq!(
                Message::parse_udk(&text).unwrap().message.groups,
                Message::parse_udk(line).unwrap().message.groups,
                "{line}"
            );
        }
    }

    #[test]
    fn a_number_that_is_not_one_is_kept_and_reported() {
        let (text, err) = through("DRIVE {LinearVelocity abc}\nDRIVE {Left 1}\n", 1);
        assert_eq!(text, "DRIVE {LinearVelocity abc}\nDRIVE {Left 1}\n");
        assert_eq!(
            err,
            "line 1: {LinearVelocity abc}: \"abc\" is not a number (kept as written)\n"
        );
        let (text, err) = through("INIT {ClassName X} {Location 1,2}\n", 1);
        assert_eq!(text, "INIT {ClassName X} {Location 1,2}\n");
        assert!(err.contains("not three numbers"), "{err}");
    }

    #[test]
    fn any_line_ending_splits_and_long_lines_are_skipped() {
        let input = format!(
            "STA {{Time 1}} {{Battery 1}}\r{}\rSTA {{Time 2}} {{Battery 2}}\r\n{}",
            "X".repeat(MAX_LINE + 1),
            "STA {Time 3} {Battery 3}"
        );
        let (printed, err, failed) = run_decode(&input, true);
        assert_eq!(failed, 1);
        assert_eq!(
            err,
            format!(
                "line 2: {} bytes, longer than the limit of {MAX_LINE}: skipped\n",
                MAX_LINE + 1
            )
        );
        assert_eq!(
            printed,
            "STA {Time 1} {Battery 1}\rSTA {Time 2} {Battery 2}\r\nSTA {Time 3} {Battery 3}"
        );
        // A line that is just short enough is read.
        let (_, err, failed) = run_decode(&format!("{}\n", "Y".repeat(MAX_LINE)), false);
        assert_eq!((err.as_str(), failed), ("", 0));
    }

    #[test]
    fn lines_split_across_reads_are_read_whole() {
        // A reader that hands out one byte at a time: CR and LF arrive in separate reads.
        let input = "STA {Time 1} {Battery 1}\r\nSTA {Time 2} {Battery 2}\r";
        let slow = io::BufReader::with_capacity(1, input.as_bytes());
        let (mut out, mut err) = (Vec::new(), Vec::new());
        assert_eq!(decode(slow, &mut out, &mut err, true).unwrap(), 0);
        assert_eq!(String::from_utf8(out).unwrap(), input);
    }

    #[test]
    fn encode_refuses_to_inject_a_line() {
        let json = "{\"client\":{\"Init\":{\"class_name\":\"USARBot.stsAirRobot\",\"name\":\"UAV\\r\\nGETSTARTPOSES\",\"location\":null,\"rotation\":null,\"start\":null}}}\n{\"client\":\"GetStartPoses\"}\n";
        let (out, err, failed) = run_encode(json);
        assert_eq!((out.as_str(), failed), ("GETSTARTPOSES\n", 1));
        assert!(err.starts_with("line 1: "), "{err}");
        assert!(
            err.contains("INIT {Name ..}") && err.contains("carriage return"),
            "{err}"
        );
    }

    #[test]
    fn bad_lines_are_reported_and_the_rest_go_on() {
        let (out, err, failed) = run_encode("{\"client\":\"GetStartPoses\"}\nnot json\n");
        assert_eq!((out.as_str(), failed), ("GETSTARTPOSES\n", 1));
        assert!(err.starts_with("line 2: "), "{err}");
    }
}
