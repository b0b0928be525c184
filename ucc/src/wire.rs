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
//! * Blank lines and lines starting with `#` (comments in capture files) are skipped.
//! * Every protocol line decodes: a server line that does not fit its typed message decodes
//!   in the generic form, which encodes back to the same bytes. A line that cannot be read
//!   (JSON for `encode`) is reported on `err` as `line N: reason` and the others go on; both
//!   functions return the number of such lines (the program exits with 1 when it is not 0).
//! * Output lines end with `\n` only (no `\r`). Input may be any mix of `\r\n`/`\n`; bytes
//!   that are not UTF-8 are read lossily.

use serde::{Deserialize, Serialize};
use std::io::{self, BufRead, Write};
use usar_proto::{Command, Message, ServerMessage};

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
    /// Reads one protocol line, choosing the direction by its message word.
    pub(crate) fn parse(line: &str) -> Result<Self, usar_proto::ParseError> {
        if ServerMessage::is_server_word(Message::word(line)) {
            Ok(Self::Server(ServerMessage::parse(line)?.message))
        } else {
            Ok(Self::Client(Command::parse(line)?.message))
        }
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

/// Calls `each(line_number, text)` for every non-blank, non-comment line.
fn for_each_line(
    mut input: impl BufRead,
    mut each: impl FnMut(usize, &str) -> io::Result<()>,
) -> io::Result<()> {
    let mut buf = Vec::new();
    let mut number = 0;
    loop {
        buf.clear();
        if input.read_until(b'\n', &mut buf)? == 0 {
            return Ok(());
        }
        number += 1;
        let text = String::from_utf8_lossy(&buf);
        let line = text.trim_end_matches(['\r', '\n']);
        if line.trim().is_empty() || line.starts_with('#') {
            continue;
        }
        each(number, line)?;
    }
}

/// `ucc decode`: protocol lines to JSON objects (or, with `print`, to printed lines).
/// Returns the number of lines that could not be read.
pub(crate) fn decode(
    input: impl BufRead,
    mut out: impl Write,
    mut err: impl Write,
    print: bool,
) -> io::Result<usize> {
    let mut failed = 0;
    for_each_line(input, |number, line| {
        match WireLine::parse(line) {
            Ok(m) if print => writeln!(out, "{m}")?,
            Ok(m) => {
                serde_json::to_writer(&mut out, &m).map_err(io::Error::other)?;
                out.write_all(b"\n")?;
            }
            Err(e) => {
                failed += 1;
                writeln!(err, "line {number}: {e}")?;
            }
        }
        Ok(())
    })?;
    out.flush()?;
    Ok(failed)
}

/// `ucc encode`: JSON objects (as written by [`decode`]) to protocol lines. Returns the
/// number of lines that could not be read.
pub(crate) fn encode(
    input: impl BufRead,
    mut out: impl Write,
    mut err: impl Write,
) -> io::Result<usize> {
    let mut failed = 0;
    for_each_line(input, |number, line| {
        match serde_json::from_str::<WireLine>(line) {
            Ok(m) => writeln!(out, "{m}")?,
            Err(e) => {
                failed += 1;
                writeln!(err, "line {number}: {e}")?;
            }
        }
        Ok(())
    })?;
    out.flush()?;
    Ok(failed)
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
            "{\"server\":{\"Sta\":{\"time\":{\"seconds\":477.7582,\"decimals\":4},\"battery\":99999,\"vehicle\":null,\"layout\":\"Udk\"}}}\n"
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
        assert_eq!(text.lines().collect::<Vec<_>>(), lines);
        assert!(!text.contains('\r'));
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
    fn bad_lines_are_reported_and_the_rest_go_on() {
        let (out, err, failed) = run_encode("{\"client\":\"GetStartPoses\"}\nnot json\n");
        assert_eq!((out.as_str(), failed), ("GETSTARTPOSES\n", 1));
        assert!(err.starts_with("line 2: "), "{err}");
    }
}
