//! Telling an HTTP request from the protocol by its first line, so that a server can close a
//! connection a web page opened (docs/security.md).
//!
//! A page the user visits can make the browser send a `text/plain` form POST to
//! `http://127.0.0.1:3000`: its body lines would be read as commands (`INIT`, `DRIVE`) by a
//! server that skips the request line and the headers. No USARSim client's first line looks
//! like HTTP (it is `INIT`, `GETSTARTPOSES`, a USARTruth query, a WSS `INIT`, …), so the
//! servers close a connection whose first line does (as Redis does for the same reason).

/// The methods of HTTP/1.1 (RFC 9110, with `PATCH` of RFC 5789).
const METHODS: [&str; 9] = [
    "GET", "HEAD", "POST", "PUT", "DELETE", "CONNECT", "OPTIONS", "TRACE", "PATCH",
];

/// Whether `line` (a connection's first line, without its end) is an HTTP request line or
/// header: a method, a space and a target that starts with `/`, `*` or `http` (`GET /
/// HTTP/1.1`, `POST http://127.0.0.1:3000/ HTTP/1.1`, `OPTIONS * HTTP/1.1`), or a header
/// field `Name: value` (`Host: 127.0.0.1:3000`, `Origin: …`, `User-Agent: …`: a name of
/// letters, digits and `-` right before a colon). No line of the Gamebots protocol, of
/// USARTruth, of the robot monitor or of the WSS has either form.
///
/// ```
/// use usar_proto::http::looks_like_http;
/// assert!(looks_like_http(b"POST / HTTP/1.1"));
/// assert!(looks_like_http(b"Host: 127.0.0.1:3000"));
/// assert!(!looks_like_http(b"INIT {ClassName USARBot.stsAirRobot} {Location 0,0,-1}"));
/// assert!(!looks_like_http(b"GETSTARTPOSES"));
/// ```
pub fn looks_like_http(line: &[u8]) -> bool {
    request_line(line) || header(line)
}

fn request_line(line: &[u8]) -> bool {
    METHODS.iter().any(|method| {
        let Some(rest) = line
            .strip_prefix(method.as_bytes())
            .and_then(|rest| rest.strip_prefix(b" "))
        else {
            return false;
        };
        let rest = rest.trim_ascii_start();
        rest.starts_with(b"/")
            || rest.starts_with(b"*")
            || rest
                .get(..4)
                .is_some_and(|scheme| scheme.eq_ignore_ascii_case(b"http"))
    })
}

fn header(line: &[u8]) -> bool {
    let Some(colon) = line.iter().position(|&b| b == b':') else {
        return false;
    };
    let name = &line[..colon];
    name.first().is_some_and(u8::is_ascii_alphabetic)
        && name.iter().all(|&b| b.is_ascii_alphanumeric() || b == b'-')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn request_lines_and_headers_look_like_http() {
        for line in [
            "GET / HTTP/1.1",
            "POST / HTTP/1.1",
            "POST /x?y=1 HTTP/1.0",
            "PUT http://127.0.0.1:3000/ HTTP/1.1",
            "OPTIONS * HTTP/1.1",
            "HEAD /",
            "DELETE  /a",
            "PATCH HTTPS://example.org/",
            "Host: 127.0.0.1:3000",
            "Origin: http://evil.example",
            "User-Agent: Mozilla/5.0",
            "content-type: text/plain",
            "X-Forwarded-For:1.2.3.4",
            "Host:",
        ] {
            assert!(looks_like_http(line.as_bytes()), "{line:?}");
        }
    }

    #[test]
    fn protocol_lines_do_not() {
        for line in [
            "",
            "INIT {ClassName USARBot.stsAirRobot} {Name UAV} {Location 0,0,-1}",
            "GETSTARTPOSES",
            "DRIVE {LinearVelocity 1}",
            "GETPOS",
            "GETOBS {From A} {To B}",
            "{class USARVictim} {name V1}",
            "INIT {Robot R1} {Port 8001,8002}",
            "GET",
            "GETCONF {Type Sonar}",
            "POST",
            "GET x",
            "post / HTTP/1.1",
            "SYNC {Time 1.5}",
            "{Name: x}",
            ": y",
            "9a: b",
            "MISPKG {Name A} {Location 1:2}",
            "\u{0}\u{ff}",
        ] {
            assert!(!looks_like_http(line.as_bytes()), "{line:?}");
        }
        assert!(!looks_like_http(&[0xff, b':']));
    }
}
