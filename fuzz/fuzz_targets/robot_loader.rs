//! Arbitrary text as a robot file: never a panic; every class that loads spawns and flies.
#![no_main]

use libfuzzer_sys::fuzz_target;
use usar_proto::{Command, Init};
use usar_sim::{Map, RobotCatalog, SimConfig, World};

fuzz_target!(|text: &str| {
    let Ok(robots) = RobotCatalog::from_toml(text, std::path::Path::new("fuzz.toml")) else {
        return;
    };
    let classes: Vec<String> = robots.classes().iter().map(|c| c.class.clone()).collect();
    let mut world = World::new(Map::default_map(), robots, SimConfig::default());
    for class in classes.into_iter().take(4) {
        let c = world.connect();
        world.command(
            c,
            Command::Init(Init {
                class_name: class,
                start: Some("Start1".into()),
                ..Init::default()
            }),
        );
    }
    let mut out = Vec::new();
    for _ in 0..40 {
        world.step(&mut out);
    }
    for (_, m) in out {
        let line = m.to_string();
        assert!(!line.contains("NaN") && !line.contains("inf"), "{line}");
    }
});
