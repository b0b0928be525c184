//! USARTruth, TCP 3989: ground truth of every robot and victim, as scoring and metric tools
//! read it (docs/usartruth.md; the wire reference is side-servers.md §2).
//!
//! A request is one line of `{key value}` blocks: `{class C}` keeps the actors of class `C`
//! and its subclasses, `{name N}` those named `N`; without them (an empty line, unknown keys,
//! garbage) the answer is the default query, every robot and every victim. Each matching
//! actor is one line, then `{End}`:
//!
//! ```text
//! {Name Victim1} {Class FemaleVictim} {Time 12.3400} {Location -4.00,-3.50,-0.15} {Rotation 0.00,0.00,1.20}
//! {End}
//! ```

use std::sync::mpsc::Sender;

use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use usar_proto::format::{push_fixed, push_fixed_list};

use super::request::Request;
use super::side;
use crate::sim::World;

/// What a query asks for.
#[derive(Debug, Default, PartialEq)]
struct Query {
    class: Option<String>,
    name: Option<String>,
}

impl Query {
    fn parse(line: &str) -> Self {
        let mut query = Self::default();
        for (key, value) in side::blocks(line) {
            if key.eq_ignore_ascii_case("class") {
                query.class = Some(value.to_owned());
            } else if key.eq_ignore_ascii_case("name") {
                query.name = Some(value.to_owned());
            }
        }
        query
    }
}

/// What an actor's class matches: its own name and its superclasses' (docs/usartruth.md).
fn class_matches(query: &str, class: &str, kind: Kind) -> bool {
    // `USARBot.P3AT`, `USARVictim.FemaleVictim`: the package does not matter here.
    let short = query.rsplit('.').next().unwrap_or(query);
    let same = |name: &str| short.eq_ignore_ascii_case(name);
    same(class)
        || same("Actor")
        || match kind {
            Kind::Robot => same("Pawn") || same("USARVehicle") || same("AerialVehicle"),
            Kind::Victim => same("Pawn") || same("USARVictim"),
            Kind::Object => false,
        }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Robot,
    Victim,
    Object,
}

/// The answer to `query`: one line per matching actor (robots in spawn order, then
/// victims, then objects), then `{End}`, each ended by CR LF.
fn answer(world: &World, query: &Query) -> String {
    let time = world.time();
    let mut out = String::new();
    let robots = world
        .robots_truth()
        .into_iter()
        .map(|r| (Kind::Robot, r.name, r.class, r.location, r.rotation));
    let placed = world.placed().iter().map(|p| {
        let kind = if p.victim { Kind::Victim } else { Kind::Object };
        (
            kind,
            p.name.clone(),
            p.class.clone(),
            p.center,
            [0.0, 0.0, p.yaw],
        )
    });
    for (kind, name, class, location, rotation) in robots.chain(placed) {
        let wanted = match &query.class {
            Some(c) => class_matches(c, &class, kind),
            None => kind != Kind::Object,
        };
        if !wanted || query.name.as_ref().is_some_and(|n| *n != name) {
            continue;
        }
        out.push_str("{Name ");
        out.push_str(&name);
        out.push_str("} {Class ");
        out.push_str(&class);
        out.push_str("} {Time ");
        push_fixed(&mut out, time, 4);
        out.push_str("} {Location ");
        push_fixed_list(&mut out, &location, 2);
        out.push_str("} {Rotation ");
        push_fixed_list(&mut out, &rotation, 2);
        out.push_str("}\r\n");
    }
    out.push_str("{End}\r\n");
    out
}

/// The answer to one request line (see the module's documentation), ending in `{End}`
/// and CR LF.
pub fn reply(world: &World, line: &str) -> String {
    answer(world, &Query::parse(line))
}

/// Serves USARTruth on `listener` until `shutdown` (a blank or unreadable line is the
/// default query, as USARSim answers it).
pub(super) async fn serve(
    listener: TcpListener,
    requests: Sender<Request>,
    (tracker, limits): (TaskTracker, side::Limits),
    shutdown: CancellationToken,
) {
    side::serve_lines(
        "USARTruth",
        listener,
        requests,
        (tracker, limits),
        shutdown,
        |world, line| Some(reply(world, line)),
    )
    .await;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queries_read_class_and_name_in_any_case_and_ignore_the_rest() {
        assert_eq!(
            Query::parse("{class USARBot.AirRobot} {Name AirRobot_0}"),
            Query {
                class: Some("USARBot.AirRobot".into()),
                name: Some("AirRobot_0".into())
            }
        );
        assert_eq!(Query::parse("{Actors}"), Query::default());
        assert_eq!(Query::parse("\u{1}\u{2}garbage"), Query::default());
        assert!(class_matches(
            "USARVictim.FemaleVictim",
            "FemaleVictim",
            Kind::Victim
        ));
        assert!(class_matches("Pawn", "FemaleVictim", Kind::Victim));
        assert!(!class_matches("Pawn", "Sedan", Kind::Object));
        assert!(class_matches("USARPhysObj.Sedan", "Sedan", Kind::Object));
        assert!(!class_matches("MaleVictim", "FemaleVictim", Kind::Victim));
    }
}
