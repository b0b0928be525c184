//! Steps an embedded world without a server: spawn a stsAirRobot at the map's first
//! PlayerStart, climb for a second, and print where its sensors say it is.
//!
//! ```text
//! cargo run -p usar-sim --example step_world
//! ```

use usar_proto::{Command, Drive, Init, SenData, ServerMessage};
use usar_sim::{Map, RobotCatalog, SimConfig, World};

fn main() {
    let map = Map::embedded("arena").expect("an embedded map");
    let start = map.starts()[0].tag.clone();
    let mut world = World::new(map, RobotCatalog::embedded(), SimConfig::default());
    let client = world.connect();
    let init = Init {
        class_name: Init::qualified_class("stsAirRobot"),
        start: Some(start.clone()),
        ..Init::default()
    };
    for reply in world.command(client, Command::Init(init)) {
        println!("{reply}");
    }
    let climb = Drive {
        altitude_velocity: Some(0.5),
        ..Drive::default()
    };
    world.command(client, Command::Drive(climb));
    let mut out = Vec::new();
    for _ in 0..200 {
        world.step(&mut out); // 200 ticks of 5 ms: one simulated second
    }
    let position = out.iter().rev().find_map(|(_, message)| match message {
        ServerMessage::Sen(sen) => match &sen.data {
            SenData::Position { location, .. } => Some(*location),
            _ => None,
        },
        _ => None,
    });
    println!(
        "{} messages in one simulated second from {start}; last position {position:?}",
        out.len()
    );
}
