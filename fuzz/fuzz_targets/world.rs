//! The world driven by arbitrary command lines (as clients send them) and steps: never a
//! panic, never a non-finite number printed.
//!
//! Kept fast (issue #26: it ran at 67 executions/s): the map (a 6 m room with one pillar) and
//! the robot catalog are built once and cloned, the sensors run on the fuzzing thread, and
//! an input steps the world at most 100 ticks in all.
#![no_main]

use std::path::Path;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use usar_proto::Command;
use usar_sim::{Map, RobotCatalog, SimConfig, World};

/// A small map: walls around 6 m × 6 m, a pillar and a PlayerStart.
const MAP: &str = r#"
level = "Fuzz"
[[box]]
center = [0.0, 0.0, 0.5]
size = [6.0, 6.0, 0.2]
[[box]]
center = [3.0, 0.0, -1.0]
size = [0.2, 6.0, 3.0]
[[cylinder]]
center = [1.0, 1.0, -1.0]
radius = 0.3
height = 3.0
[[start]]
tag = "Start1"
location = [0.0, 0.0, -1.0]
"#;

/// Ticks one input may step the world, in all.
const MAX_TICKS: u32 = 100;

fn setup() -> &'static (Map, RobotCatalog) {
    static SETUP: OnceLock<(Map, RobotCatalog)> = OnceLock::new();
    SETUP.get_or_init(|| {
        (
            Map::from_toml(MAP, Path::new("fuzz.toml")).expect("the fuzz map"),
            RobotCatalog::embedded(),
        )
    })
}

fuzz_target!(|text: &str| {
    let (map, robots) = setup();
    let config = SimConfig {
        threads: 1,
        ..SimConfig::default()
    };
    let mut world = World::new(map.clone(), robots.clone(), config);
    let clients = [world.connect(), world.connect()];
    let mut out = Vec::new();
    let mut replies = Vec::new();
    let mut ticks = 0;
    for (i, line) in text.lines().take(100).enumerate() {
        // `STEP n` (not a protocol word) advances the world n ticks.
        if let Some(n) = line.strip_prefix("STEP ") {
            let n = u32::from(n.trim().parse::<u8>().unwrap_or(1));
            for _ in 0..n.min(MAX_TICKS - ticks) {
                world.step(&mut out);
            }
            ticks = (ticks + n).min(MAX_TICKS);
            continue;
        }
        if let Ok(parsed) = Command::parse(line) {
            replies.extend(world.command(clients[i % 2], parsed.message));
        }
    }
    for m in replies.iter().chain(out.iter().map(|(_, m)| m)) {
        let line = m.to_string();
        assert!(!line.contains("NaN") && !line.contains("inf"), "{line}");
    }
});
