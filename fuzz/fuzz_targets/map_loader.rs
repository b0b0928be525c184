//! Arbitrary text as a map file: never a panic; a map that loads can be flown in.
#![no_main]

use libfuzzer_sys::fuzz_target;
use usar_proto::{Command, Drive, Init};
use usar_sim::{Map, RobotCatalog, SimConfig, World};

fuzz_target!(|text: &str| {
    let Ok(map) = Map::from_toml(text, std::path::Path::new("fuzz.toml")) else {
        return;
    };
    let start = map.starts().first().map_or([0.0; 3], |s| s.location);
    let mut world = World::new(map, RobotCatalog::embedded(), SimConfig::default());
    let c = world.connect();
    world.command(
        c,
        Command::Init(Init {
            class_name: "USARBot.stsAirRobot".into(),
            location: Some(start.into()),
            ..Init::default()
        }),
    );
    world.command(
        c,
        Command::Drive(Drive {
            linear_velocity: Some(1e9),
            ..Drive::default()
        }),
    );
    let mut out = Vec::new();
    for _ in 0..40 {
        world.step(&mut out);
    }
    for (_, m) in out {
        let line = m.to_string();
        assert!(!line.contains("NaN") && !line.contains("inf"), "{line}");
    }
});
