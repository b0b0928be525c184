//! The robot monitor, TCP 7435: robot positions and wall counts for a Wireless Simulation
//! Server (docs/wss.md; the wire reference is side-servers.md §3.2).
//!
//! * `GETPOS` → `POSITIONS {Robots n} {Name R Location x,y,z BatteryEmpty False} ...`
//!   (` Radio Off` after `BatteryEmpty ..` while a robot's radio has failed: ours)
//! * `GETOBS {From A} {To B}` → `NUMOBS {From A} {To B} {ObstCount 3.0000}` (−1 for an
//!   unknown robot); `GETOBS {Start x,y,z} {End x,y,z}` → `NUMOBS {Start ..} {End ..}
//!   {ObstCount n}`; neither pair: an empty line.
//!
//! Lines end in CR and/or LF; replies in CR LF; commands match in any case; unknown commands
//! get no reply.

use std::sync::mpsc::Sender;

use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use usar_proto::format::{push_fixed, push_fixed_list};

use super::request::Request;
use super::side;
use crate::sim::World;

/// The reply to one request line, without its CR LF; `None`: no reply.
pub fn reply(world: &World, line: &str) -> Option<String> {
    let line = line.trim();
    let word = line.split([' ', '{']).next().unwrap_or("");
    if word.eq_ignore_ascii_case("GETPOS") {
        let robots = world.robots_truth();
        let mut out = format!("POSITIONS {{Robots {}}}", robots.len());
        for r in &robots {
            out.push_str(" {Name ");
            out.push_str(&r.name);
            out.push_str(" Location ");
            push_fixed_list(&mut out, &r.location, 4);
            out.push_str(if r.battery_empty {
                " BatteryEmpty True"
            } else {
                " BatteryEmpty False"
            });
            // Ours: a robot whose radio failed (docs/wss.md); the WSS sees it out of range.
            out.push_str(if r.radio_off { " Radio Off}" } else { "}" });
        }
        return Some(out);
    }
    if !word.eq_ignore_ascii_case("GETOBS") {
        return None;
    }
    let blocks = side::blocks(line);
    let get = |key: &str| {
        blocks
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(key))
            .map(|(_, v)| *v)
    };
    let mut out = String::from("NUMOBS");
    let count = if let (Some(from), Some(to)) = (get("From"), get("To")) {
        out.push_str(&format!(" {{From {from}}} {{To {to}}}"));
        let robots = world.robots_truth();
        let at = |name: &str| robots.iter().find(|r| r.name == name).map(|r| r.location);
        match (at(from), at(to)) {
            (Some(a), Some(b)) => f64::from(world.obstacles_between(a, b)),
            _ => -1.0,
        }
    } else if let (Some(start), Some(end)) = (get("Start"), get("End")) {
        out.push_str(&format!(" {{Start {start}}} {{End {end}}}"));
        match (point(start), point(end)) {
            (Some(a), Some(b)) => f64::from(world.obstacles_between(a, b)),
            _ => -1.0,
        }
    } else {
        return Some(String::new());
    };
    out.push_str(" {ObstCount ");
    push_fixed(&mut out, count, 4);
    out.push('}');
    Some(out)
}

/// `x,y,z` in metres, finite.
fn point(text: &str) -> Option<[f64; 3]> {
    let mut parts = text.split(',').map(|p| p.trim().parse::<f64>().ok());
    let p = [parts.next()??, parts.next()??, parts.next()??];
    (parts.next().is_none() && p.iter().all(|x| x.is_finite())).then_some(p)
}

/// Serves the robot monitor on `listener` until `shutdown`.
pub(super) async fn serve(
    listener: TcpListener,
    requests: Sender<Request>,
    (tracker, limits): (TaskTracker, side::Limits),
    shutdown: CancellationToken,
) {
    side::serve_lines(
        "robot monitor",
        listener,
        requests,
        (tracker, limits),
        shutdown,
        |world, line| {
            // A blank line gets no answer; an answer ends with CR LF.
            if line.is_empty() {
                return None;
            }
            let mut text = reply(world, line)?;
            text.push_str("\r\n");
            Some(text)
        },
    )
    .await;
}
