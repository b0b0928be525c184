//! The world driven by arbitrary command lines (as clients send them) and steps: never a
//! panic, never a non-finite number printed.
#![no_main]

use libfuzzer_sys::fuzz_target;
use usar_proto::Command;
use usar_sim::{Map, RobotCatalog, SimConfig, World};

fuzz_target!(|text: &str| {
    let mut world = World::new(Map::default_map(), RobotCatalog::embedded(), SimConfig::default());
    let clients = [world.connect(), world.connect()];
    let mut out = Vec::new();
    let mut replies = Vec::new();
    for (i, line) in text.lines().take(200).enumerate() {
        // `STEP n` (not a protocol word) advances the world n ticks.
        if let Some(n) = line.strip_prefix("STEP ") {
            for _ in 0..n.trim().parse::<u16>().unwrap_or(1).min(400) {
                world.step(&mut out);
            }
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
