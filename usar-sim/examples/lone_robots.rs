//! What the Python vector env's worlds cost in Rust alone: `WORLDS` worlds of one
//! state-only stsAirRobot each (no sonars, no laser) in `empty_room`, stepped one control
//! period (0.1 s, 20 ticks) at a time on one thread, each period with one of 8 random
//! normalized `DRIVE`s per robot in turn (the Python benchmark's "pressed" case: repeating
//! them, a robot flies into a wall, the floor or the ceiling and slides along it), or none
//! with `hover`. Prints the time per robot and tick and a digest of every message, which must not
//! change when only the speed does. With `resets`, every period is a new episode instead
//! (the Python env's autoreset with one-step episodes): each world is reset with a new seed,
//! its robot spawned again and hovered one period; it prints the time per reset.
//!
//! ```text
//! cargo run --release -p usar-sim --example lone_robots -- [WORLDS] [PERIODS] [hover|resets]
//! valgrind --tool=callgrind target/release/examples/lone_robots 256 100   # instructions
//! ```

use std::sync::Arc;
use std::time::Instant;

use usar_proto::{Command, Drive, Init, Vec3};
use usar_sim::{ClientId, Map, RobotCatalog, SimConfig, World};

const TICKS: u64 = 20;

/// The Python package's allocator (usarsim-py), so that the figures are its worlds'.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let number = |i: usize, default: usize| match args.get(i) {
        None => default,
        Some(s) => s.parse().unwrap_or_else(|_| {
            eprintln!("lone_robots: argument {}: not a count: {s:?}", i + 1);
            std::process::exit(2)
        }),
    };
    let (worlds, periods) = (number(0, 1024).max(1), number(1, 200));
    let mode = args.get(2).map_or("", String::as_str);
    if !["", "hover", "resets"].contains(&mode) {
        eprintln!("lone_robots: argument 3: expected hover or resets, got {mode:?}");
        std::process::exit(2)
    }
    let (hover, resets) = (!mode.is_empty(), mode == "resets");
    let map = Arc::new(Map::embedded("empty_room").expect("an embedded map"));
    let mut catalog = RobotCatalog::embedded();
    if let Some(class) = catalog.get_mut("USARBot.stsAirRobot") {
        class.parts.retain(|p| {
            !p.kind.eq_ignore_ascii_case("Sonar") && !p.kind.eq_ignore_ascii_case("RangeScanner")
        });
    }
    let catalog = Arc::new(catalog);
    let start = map.starts()[0].location;
    let spawn = |world: &mut World, i: usize| {
        let client = world.connect();
        world.command(
            client,
            Command::Init(Init {
                class_name: "USARBot.stsAirRobot".into(),
                name: Some(format!("UAV{i}")),
                location: Some(Vec3::new(start[0], start[1], start[2])),
                rotation: Some(Vec3::new(0.0, 0.0, 0.0)),
                start: None,
            }),
        );
        client
    };
    let mut sims: Vec<(World, ClientId)> = (0..worlds)
        .map(|i| {
            let config = SimConfig {
                seed: i as u64,
                ..SimConfig::default()
            };
            let mut world = World::new(map.clone(), catalog.clone(), config);
            let client = spawn(&mut world, i);
            (world, client)
        })
        .collect();
    let mut episodes = 0u64;
    // Eight sets of actions in turn, as the Python benchmark's pressed case: uniform in -1..=1
    // (SplitMix64).
    let mut seed = 12_345u64;
    let mut uniform = || {
        let bits = usar_sim::splitmix(&mut seed) >> 11;
        bits as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let actions: Vec<Vec<Drive>> = (0..8)
        .map(|_| {
            (0..worlds)
                .map(|_| {
                    let mut a = [0.0; 4];
                    if !hover {
                        a = a.map(|_| (uniform() * 100.0).round());
                    }
                    Drive {
                        linear_velocity: Some(a[0]),
                        lateral_velocity: Some(a[1]),
                        altitude_velocity: Some(a[2]),
                        rotational_velocity: Some(a[3]),
                        normalized: Some(true),
                        ..Drive::default()
                    }
                })
                .collect()
        })
        .collect();
    let mut digest = 0xcbf2_9ce4_8422_2325u64;
    let mut out = Vec::new();
    // The digest reads the messages of the periods before and after the timed ones (their
    // state follows from the timed ones); the timed ones drop theirs unread.
    let mut run = |periods: usize, digest: Option<&mut u64>| {
        let mut digest = digest;
        for k in 0..periods {
            for i in 0..sims.len() {
                // As the Python batch does: the next worlds' memory on its way meanwhile.
                if let Some((next, _)) = sims.get(i + 2) {
                    if resets {
                        next.prefetch_reset_early();
                    } else {
                        next.prefetch_early();
                    }
                }
                if let Some((next, _)) = sims.get(i + 1) {
                    if resets {
                        next.prefetch_reset();
                    } else {
                        next.prefetch();
                    }
                }
                let (world, client) = &mut sims[i];
                if resets {
                    episodes += 1;
                    world.reset(episodes);
                    *client = spawn(world, i);
                }
                world.command(*client, Command::Drive(actions[k % 8][i].clone()));
                world.run(TICKS, &mut out);
                world.take_touched(|_, _| {});
                for (_, message) in out.drain(..) {
                    if let Some(digest) = digest.as_deref_mut() {
                        for byte in message.to_string().bytes() {
                            *digest = (*digest ^ u64::from(byte)).wrapping_mul(0x100_0000_01b3);
                        }
                    }
                }
            }
        }
    };
    // Episodes of some age first, as in the Python benchmark's pressed case (UAVs against
    // walls, floor and ceiling).
    run(100, Some(&mut digest));
    let started = Instant::now();
    run(periods, None);
    let seconds = started.elapsed().as_secs_f64();
    run(10, Some(&mut digest));
    let per_step = seconds / (periods * worlds).max(1) as f64;
    println!(
        "{worlds} worlds x {periods} periods ({}): {:.0} ns per robot and tick, {:.2} µs per \
         UAV-step, {:.0} UAV-steps/s on one thread; digest {digest:016x}",
        if resets {
            "each a new episode: reset, spawn, hover"
        } else if hover {
            "hovering"
        } else {
            "random actions"
        },
        per_step * 1e9 / TICKS as f64,
        per_step * 1e6,
        1.0 / per_step,
    );
}
