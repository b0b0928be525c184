//! Property tests standing in for the cargo-fuzz targets of `fuzz/` (which need a nightly
//! toolchain): the map and robot loaders, the recording reader and the world driven by
//! arbitrary command sequences never panic, and nothing non-finite or absurd is ever
//! printed. Numbers are drawn from the whole f64 range (NaN, infinities, subnormals, 1e308).

use std::path::Path;

use proptest::prelude::*;
use usar_proto::{Act, Command, Drive, Init, ItemQuery, LinkValue, ServerMessage, Set, Vec3};
use usar_server::replay;
use usar_server::sim::{ClientId, Map, RobotCatalog, SimConfig, World};

/// Any f64 at all, with the interesting ones often.
fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        proptest::num::f64::ANY,
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(1e308),
        Just(-1.5e308),
        Just(1e39),
        Just(f64::MIN_POSITIVE / 2.0),
        -20.0..20.0f64,
    ]
}

/// A TOML float literal for any f64 (TOML spells `nan`, `inf`, `-inf`).
fn toml_f64(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else if x.is_infinite() {
        if x > 0.0 { "inf".into() } else { "-inf".into() }
    } else {
        format!("{x:e}")
    }
}

fn triple(v: [f64; 3]) -> String {
    format!(
        "[{}, {}, {}]",
        toml_f64(v[0]),
        toml_f64(v[1]),
        toml_f64(v[2])
    )
}

/// Checks a printed line: every number finite, within ±10^6, no `NaN`, no saturated i32.
fn check_line(line: &str) {
    assert!(!line.contains("NaN") && !line.contains("inf"), "{line}");
    assert!(
        !line.contains("2147483647") && !line.contains("2147483648"),
        "{line}"
    );
    for token in line.split([' ', '{', '}', ',']) {
        if let Ok(x) = token.parse::<f64>() {
            assert!(x.is_finite() && x.abs() < 1e6, "{x} in {line}");
        }
    }
}

/// Spawns a robot of every class at the first start (or the origin), drives each fast,
/// steps a second and checks every line.
fn fly_briefly(map: Map, robots: RobotCatalog) {
    let start = map.starts().first().map_or([0.0; 3], |s| s.location);
    let classes: Vec<String> = robots.classes().iter().map(|c| c.class.clone()).collect();
    let mut world = World::new(map, robots, SimConfig::default());
    for (i, class) in classes.iter().enumerate() {
        let c = world.connect();
        world.command(
            c,
            Command::Init(Init {
                class_name: class.clone(),
                location: Some(Vec3::new(start[0] + 3.0 * i as f64, start[1], start[2])),
                ..Init::default()
            }),
        );
        world.command(
            c,
            Command::Drive(Drive {
                linear_velocity: Some(1e9),
                rotational_velocity: Some(1e9),
                ..Drive::default()
            }),
        );
    }
    let mut out = Vec::new();
    for _ in 0..200 {
        world.step(&mut out);
    }
    for (_, m) in &out {
        check_line(&m.to_string());
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn maps_load_or_fail_cleanly_and_load_only_what_can_fly(
        center in prop::array::uniform3(any_f64()),
        size in prop::array::uniform3(any_f64()),
        radius in any_f64(),
        start in prop::array::uniform3(any_f64()),
        yaw in any_f64(),
    ) {
        let text = format!(
            "level = \"F\"\n[[start]]\ntag = \"S\"\nlocation = {}\n[[box]]\ncenter = {}\nsize = {}\nyaw = {}\n[[cylinder]]\ncenter = {}\nradius = {}\nheight = 1.0\n",
            triple(start), triple(center), triple(size), toml_f64(yaw), triple(center), toml_f64(radius)
        );
        if let Ok(map) = Map::from_toml(&text, Path::new("fuzz.toml")) {
            fly_briefly(map, RobotCatalog::embedded());
        }
    }

    #[test]
    fn map_text_never_panics_the_loader(text in "\\PC{0,400}") {
        let _ = Map::from_toml(&text, Path::new("fuzz.toml"));
        let with_level = format!("level = \"F\"\n{text}");
        if let Ok(map) = Map::from_toml(&with_level, Path::new("fuzz.toml")) {
            fly_briefly(map, RobotCatalog::embedded());
        }
    }

    #[test]
    fn robot_files_load_or_fail_cleanly(
        values in prop::collection::vec(prop::option::weighted(0.3, any_f64()), 12),
    ) {
        // Each key is given (any f64) or left to its default, so that valid files are common.
        let keys = [
            ("battery", 0), ("flight.max_linear_speed", 1), ("flight.speed_limit", 2),
            ("collision.radius", 3), ("S.interval", 4), ("S.noise", 5), ("S.max_range", 6),
            ("S.beam_angle", 7), ("L.max_range", 8), ("L.fov", 9), ("L.resolution", 10),
            ("L.noise", 11),
        ];
        let get = |section: &str| -> String {
            keys.iter()
                .filter_map(|(k, i)| {
                    let (s, key) = k.split_once('.').unwrap_or(("", k));
                    (s == section).then(|| values[*i].map(|v| format!("{key} = {}\n", toml_f64(v))))?
                })
                .collect()
        };
        let text = format!(
            "[[robot]]\nclass = \"USARBot.Fuzz\"\n{}[robot.flight]\n{}[robot.collision]\n{}[[robot.part]]\ntype = \"Sonar\"\nname = \"S\"\n{}[[robot.part]]\ntype = \"RangeScanner\"\nname = \"L\"\n{}",
            get(""), get("flight"), get("collision"), get("S"), get("L")
        );
        if let Ok(robots) = RobotCatalog::from_toml(&text, Path::new("fuzz.toml")) {
            fly_briefly(Map::default_map(), robots);
        }
    }

    #[test]
    fn robot_text_never_panics_the_loader(text in "\\PC{0,400}") {
        let _ = RobotCatalog::from_toml(&text, Path::new("fuzz.toml"));
    }

    #[test]
    fn recordings_read_or_fail_cleanly(
        lines in prop::collection::vec(("\\PC{0,12}", any_f64(), "[CS ]", "\\PC{0,40}"), 0..20),
        header in any::<bool>(),
    ) {
        let mut text = String::new();
        if header {
            text.push_str("# usar-record 1\n");
        }
        for (prefix, t, dir, rest) in &lines {
            text.push_str(&format!("{prefix}{t} {dir} {rest}\n"));
        }
        if let Ok(lines) = replay::parse(&text, "fuzz.usarlog") {
            prop_assert!(lines.iter().all(|l| l.time.is_none_or(f64::is_finite)));
        }
    }
}

/// One step of a command sequence.
#[derive(Debug, Clone)]
enum Op {
    Connect,
    Disconnect(usize),
    Init(usize, u8, [f64; 3], [f64; 3]),
    Drive(usize, [Option<f64>; 6], Option<bool>),
    Act(usize, i64, f64),
    Scan(usize),
    Query(usize),
    Step(u16),
}

/// Anywhere at all, or somewhere in the default map's room (where spawns succeed).
fn location() -> impl Strategy<Value = [f64; 3]> {
    prop_oneof![
        prop::array::uniform3(any_f64()),
        (-8.0..8.0f64, -8.0..8.0f64, -4.0..-0.5f64).prop_map(|(x, y, z)| [x, y, z]),
    ]
}

fn op() -> impl Strategy<Value = Op> {
    let opt = || prop::option::of(any_f64());
    prop_oneof![
        1 => Just(Op::Connect),
        1 => (0..4usize).prop_map(Op::Disconnect),
        3 => (0..4usize, 0..3u8, location(), prop::array::uniform3(any_f64()))
            .prop_map(|(c, k, l, r)| Op::Init(c, k, l, r)),
        4 => (0..4usize, [opt(), opt(), opt(), opt(), opt(), opt()], prop::option::of(any::<bool>()))
            .prop_map(|(c, v, n)| Op::Drive(c, v, n)),
        1 => (0..4usize, -2..3i64, any_f64()).prop_map(|(c, l, v)| Op::Act(c, l, v)),
        1 => (0..4usize).prop_map(Op::Scan),
        1 => (0..4usize).prop_map(Op::Query),
        3 => (1..400u16).prop_map(Op::Step),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn the_world_survives_any_command_sequence(ops in prop::collection::vec(op(), 1..30)) {
        let mut world = World::new(Map::default_map(), RobotCatalog::embedded(), SimConfig::default());
        let mut clients: Vec<ClientId> = vec![world.connect()];
        let mut out = Vec::new();
        let mut replies = Vec::new();
        let pick = |clients: &[ClientId], i: usize| clients.get(i % clients.len().max(1)).copied();
        for op in ops {
            match op {
                Op::Connect => clients.push(world.connect()),
                Op::Disconnect(i) => {
                    if let Some(c) = pick(&clients, i) {
                        world.disconnect(c);
                        clients.retain(|&k| k != c);
                    }
                }
                Op::Init(i, k, l, r) => if let Some(c) = pick(&clients, i) {
                    let class = ["USARBot.stsAirRobot", "USARBot.AirRobot", "USARBot.Nope"][k as usize];
                    replies.extend(world.command(c, Command::Init(Init {
                        class_name: class.into(),
                        location: Some(l.into()),
                        rotation: Some(r.into()),
                        ..Init::default()
                    })));
                },
                Op::Drive(i, v, normalized) => if let Some(c) = pick(&clients, i) {
                    replies.extend(world.command(c, Command::Drive(Drive {
                        altitude_velocity: v[0],
                        linear_velocity: v[1],
                        lateral_velocity: v[2],
                        rotational_velocity: v[3],
                        pitch_angle: v[4],
                        roll_angle: v[5],
                        normalized,
                        ..Drive::default()
                    })));
                },
                Op::Act(i, link, value) => if let Some(c) = pick(&clients, i) {
                    replies.extend(world.command(c, Command::Act(Act {
                        name: "cam".into(),
                        links: vec![LinkValue { link, value }],
                        ..Act::default()
                    })));
                },
                Op::Scan(i) => if let Some(c) = pick(&clients, i) {
                    replies.extend(world.command(c, Command::Set(Set {
                        kind: "RangeScanner".into(),
                        opcode: "SCAN".into(),
                        ..Set::default()
                    })));
                },
                Op::Query(i) => if let Some(c) = pick(&clients, i) {
                    for kind in ["Robot", "Sonar", "RangeScanner", "Actuator"] {
                        let q = ItemQuery { kind: kind.into(), name: None };
                        replies.extend(world.command(c, Command::GetConf(q.clone())));
                        replies.extend(world.command(c, Command::GetGeo(q)));
                    }
                    replies.extend(world.command(c, Command::GetStartPoses));
                },
                Op::Step(n) => for _ in 0..n {
                    world.step(&mut out);
                },
            }
        }
        for m in replies.iter().chain(out.iter().map(|(_, m)| m)) {
            check_line(&m.to_string());
            // And it reads back as what it is.
            let again = ServerMessage::parse(&m.to_string()).unwrap().message;
            prop_assert!(!matches!(again, ServerMessage::Other(_)) || matches!(m, ServerMessage::Other(_)));
        }
    }
}
