//! WSS (TCP 50000) control lines from arbitrary text, on up to four control connections,
//! against the robot monitor's replies (given, or from the input): never a panic; one
//! reply line per request, of the WSS's reply kinds, with a strength that is a number,
//! `INF` or `NaN` as the WSS spells them.
//!
//! Input: lines ended by CR LF (as the WSS reads them); a first line starting `POSITIONS`
//! replaces the monitor's `GETPOS` reply, a next one starting `NUMOBS` its `GETOBS` reply;
//! a line starting with a digit is sent on that connection (mod 4), otherwise on 0.
#![no_main]

use libfuzzer_sys::fuzz_target;
use usar_server::net::wss;

const POSITIONS: &str = "POSITIONS {Robots 3} {Name A Location 0.0000,0.0000,-1.0000 BatteryEmpty False} \
{Name B Location 10.0000,0.0000,-1.0000 BatteryEmpty False} {Name C Location 1e3,0,0 BatteryEmpty True}";
const WALLS: &str = "NUMOBS {From A} {To B} {ObstCount 2.0000}";

fuzz_target!(|text: &str| {
    let mut lines = text.split("\r\n").take(64).peekable();
    let positions = lines
        .next_if(|l| l.starts_with("POSITIONS"))
        .unwrap_or(POSITIONS);
    let walls = lines.next_if(|l| l.starts_with("NUMOBS")).unwrap_or(WALLS);
    let requests: Vec<(usize, &str)> = lines
        .map(|l| match l.as_bytes().first() {
            Some(d @ b'0'..=b'9') => (usize::from(d - b'0') % 4, &l[1..]),
            _ => (0, l),
        })
        .collect();
    let replies = wss::answer_offline(positions, walls, &requests);
    assert_eq!(replies.len(), requests.len());
    for reply in &replies {
        assert!(!reply.contains(['\r', '\n']), "{reply:?}");
        let kind = reply.split(' ').next().unwrap_or("");
        assert!(
            matches!(
                kind,
                "ERROR" | "INITREPLY" | "SS" | "DNSREPLY" | "REVERSEDNSREPLY"
            ),
            "{reply:?}"
        );
        if let Some(rest) = reply.split("{Strength ").nth(1) {
            let s = rest.split('}').next().unwrap_or("");
            let ok = s == "INF"
                || s == "NaN"
                || s.parse::<f64>().is_ok_and(|v| v.is_finite() && v <= 0.0);
            assert!(ok, "{reply:?}");
        }
    }
});
