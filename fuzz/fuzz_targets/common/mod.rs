//! What the side-server targets share: a world with robots and victims, built once.

use usar_proto::{Command, Init};
use usar_server::sim::{Map, RobotCatalog, SimConfig, World};

thread_local! {
    /// The `rescue` map (four victims, objects) with three AirRobots flying, and the
    /// number of actors (robots, victims, objects).
    static WORLD: (World, usize) = {
        let config = SimConfig {
            threads: 1,
            ..SimConfig::default()
        };
        let map = Map::embedded("rescue").expect("the rescue map");
        let mut world = World::new(map, RobotCatalog::embedded(), config);
        for (i, start) in ["Start1", "Start2", "Start3"].into_iter().enumerate() {
            let c = world.connect();
            world.command(
                c,
                Command::Init(Init {
                    class_name: "USARBot.AirRobot".into(),
                    name: Some(format!("R{i}")),
                    start: Some(start.into()),
                    ..Init::default()
                }),
            );
        }
        let mut out = Vec::new();
        for _ in 0..10 {
            world.step(&mut out);
        }
        let actors = world.robots_truth().len() + world.placed().len();
        assert_eq!(world.robots_truth().len(), 3, "three robots");
        (world, actors)
    };
}

/// Runs `f` with the world and its number of actors.
pub fn with(f: impl FnOnce(&World, usize)) {
    WORLD.with(|(world, actors)| f(world, *actors));
}

/// Every number of `line` is finite and printed without an exponent or `NaN`.
pub fn check_numbers(line: &str) {
    assert!(
        !line.contains("NaN") && !line.contains("inf") && !line.contains("e+"),
        "{line}"
    );
    for token in line.split([' ', '{', '}', ',']) {
        if let Ok(x) = token.parse::<f64>() {
            assert!(x.is_finite(), "{x} in {line}");
        }
    }
}
