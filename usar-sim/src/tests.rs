//! World-level tests: flight, collisions, output timing, commands, determinism.

// Angles are written as they appear in the robot catalog (1.5708), not as π/2.
#![allow(clippy::approx_constant)]

use usar_proto::{
    Act, Command, Conf, ConfItem, Drive, Geo, Init, ItemQuery, Nfo, SenData, ServerMessage, Set,
    Vec3,
};

use super::scene::direction;
use super::*;

const STS: &str = "USARBot.stsAirRobot";
const AIR: &str = "USARBot.AirRobot";

fn world() -> World {
    World::new(
        Map::default_map(),
        RobotCatalog::embedded(),
        SimConfig::default(),
    )
}

fn init(class: &str, location: [f64; 3], yaw: f64) -> Command {
    Command::Init(Init {
        class_name: class.to_string(),
        name: Some("UAV".to_string()),
        location: Some(location.into()),
        rotation: Some([0.0, 0.0, yaw].into()),
        start: None,
    })
}

fn spawn(world: &mut World, class: &str, location: [f64; 3], yaw: f64) -> ClientId {
    let client = world.connect();
    assert!(world.command(client, init(class, location, yaw)).is_empty());
    client
}

fn run(world: &mut World, seconds: f64) -> Vec<(ClientId, ServerMessage)> {
    let mut out = Vec::new();
    for _ in 0..(seconds / world.dt()).round() as u64 {
        world.step(&mut out);
    }
    out
}

fn drive(world: &mut World, client: ClientId, drive: Drive) {
    assert!(world.command(client, Command::Drive(drive)).is_empty());
}

fn pose(world: &World, client: ClientId) -> ([f64; 3], [f64; 3]) {
    world.robot(client).expect("robot").pose()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// Sonar readings of `name` sent to `client`.
fn sonar(out: &[(ClientId, ServerMessage)], client: ClientId, name: &str) -> Vec<f64> {
    out.iter()
        .filter(|(c, _)| *c == client)
        .filter_map(|(_, m)| match m {
            ServerMessage::Sen(sen) => match &sen.data {
                SenData::Sonar { readings, .. } if readings[0].name == name => {
                    Some(readings[0].range)
                }
                _ => None,
            },
            _ => None,
        })
        .collect()
}

#[test]
fn linear_velocity_moves_along_the_heading() {
    let mut w = world();
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], std::f64::consts::FRAC_PI_2);
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(1.0),
            ..Drive::default()
        },
    );
    run(&mut w, 2.0);
    let (p, _) = pose(&w, c);
    assert!(
        close(p[0], 0.0, 1e-6) && close(p[1], 2.0, 1e-3) && close(p[2], -1.0, 1e-9),
        "{p:?}"
    );
    // Sticky: an unrelated key keeps the speed; LateralVelocity goes right.
    drive(
        &mut w,
        c,
        Drive {
            lateral_velocity: Some(1.0),
            linear_velocity: Some(0.0),
            ..Drive::default()
        },
    );
    run(&mut w, 1.0);
    let (p, _) = pose(&w, c);
    assert!(close(p[0], -1.0, 1e-3) && close(p[1], 2.0, 1e-3), "{p:?}");
}

#[test]
fn rotational_velocity_is_whole_degrees_per_second() {
    let mut w = world();
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            rotational_velocity: Some(45.0),
            ..Drive::default()
        },
    );
    run(&mut w, 2.0);
    assert!(close(pose(&w, c).1[2], std::f64::consts::FRAC_PI_2, 1e-9));
    drive(
        &mut w,
        c,
        Drive {
            rotational_velocity: Some(0.5),
            ..Drive::default()
        },
    );
    run(&mut w, 2.0);
    assert!(close(pose(&w, c).1[2], std::f64::consts::FRAC_PI_2, 1e-9));
    drive(
        &mut w,
        c,
        Drive {
            rotational_velocity: Some(-1.5),
            ..Drive::default()
        },
    );
    run(&mut w, 1.0);
    assert!(close(
        pose(&w, c).1[2],
        std::f64::consts::FRAC_PI_2 - 1f64.to_radians(),
        1e-9
    ));
}

#[test]
fn normalized_altitude_velocity_climbs_two_metres_per_second() {
    let mut w = world();
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    let up = Drive {
        altitude_velocity: Some(100.0),
        normalized: Some(true),
        ..Drive::default()
    };
    drive(&mut w, c, up);
    run(&mut w, 1.0);
    assert!(close(pose(&w, c).0[2], -3.0, 1e-6), "{:?}", pose(&w, c));
    // Clamped at ±100; without Normalized no clamping (3 m/s down).
    drive(
        &mut w,
        c,
        Drive {
            altitude_velocity: Some(-500.0),
            normalized: Some(true),
            ..Drive::default()
        },
    );
    run(&mut w, 0.5);
    assert!(close(pose(&w, c).0[2], -2.0, 1e-6));
    drive(
        &mut w,
        c,
        Drive {
            altitude_velocity: Some(-3.0),
            normalized: Some(false),
            ..Drive::default()
        },
    );
    run(&mut w, 0.5);
    assert!(close(pose(&w, c).0[2], -0.5, 1e-6));
}

#[test]
fn forward_flight_tilts_the_nose_down_visibly_in_the_imu() {
    let mut w = world();
    let c = spawn(&mut w, AIR, [0.0, 0.0, -1.0], 0.0);
    // Forward: nose down (pitch −25°); left: roll −25° (right would be +25°).
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(1.0),
            lateral_velocity: Some(-1.0),
            ..Drive::default()
        },
    );
    let out = run(&mut w, 1.0);
    let (_, r) = pose(&w, c);
    assert!(
        close(r[1], -25f64.to_radians(), 0.02) && close(r[0], -25f64.to_radians(), 0.02),
        "{r:?}"
    );
    let last_imu = out.iter().rev().find_map(|(_, m)| match m {
        ServerMessage::Sen(s) => match &s.data {
            SenData::Imu { rotation, .. } => Some(*rotation),
            _ => None,
        },
        _ => None,
    });
    assert!(last_imu.expect("IMU").y < -0.4);
    // Normalized: 25° scaled again → −6°.
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(50.0),
            normalized: Some(true),
            ..Drive::default()
        },
    );
    run(&mut w, 2.0);
    assert!(close(pose(&w, c).1[1], -6f64.to_radians(), 0.02));
}

fn fly_into_north_wall(speed: f64) -> f64 {
    let mut w = world();
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(speed),
            ..Drive::default()
        },
    );
    run(&mut w, 12.0);
    let (p, _) = pose(&w, c);
    // Nothing else moved it.
    assert!(
        close(p[1], 0.0, 1e-3) && close(p[2], -1.0, 1e-3),
        "speed {speed}: {p:?}"
    );
    p[0]
}

#[test]
fn flying_into_a_wall_stops_in_front_of_it_at_any_speed() {
    // North wall's inner face at x = 10, body radius 0.45.
    for speed in [2.0, 1000.0, 1e9] {
        let x = fly_into_north_wall(speed);
        assert!((9.5..=9.55).contains(&x), "speed {speed}: x = {x}");
    }
}

#[test]
fn take_touched_says_whether_the_body_touched_anything_since_it_was_last_asked() {
    let mut w = world();
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    let touched = |w: &mut World| {
        let mut said = Vec::new();
        w.take_touched(|client, touched| said.push((client, touched)));
        said
    };
    run(&mut w, 1.0);
    assert_eq!(touched(&mut w), [(c, false)], "hovering in open air");
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(5.0),
            ..Drive::default()
        },
    );
    run(&mut w, 3.0);
    assert_eq!(
        touched(&mut w),
        [(c, true)],
        "pressed against the north wall"
    );
    assert_eq!(touched(&mut w), [(c, false)], "cleared once taken");
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(-1.0),
            ..Drive::default()
        },
    );
    run(&mut w, 0.5);
    touched(&mut w);
    run(&mut w, 0.5);
    assert_eq!(touched(&mut w), [(c, false)], "backing away from the wall");
}

#[test]
fn cannot_leave_through_floor_or_ceiling_and_slides_along_walls() {
    let mut w = world();
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            altitude_velocity: Some(-1000.0),
            ..Drive::default()
        },
    );
    run(&mut w, 1.0);
    let z = pose(&w, c).0[2];
    assert!((-0.115..=-0.1).contains(&z), "floor: {z}");
    drive(
        &mut w,
        c,
        Drive {
            altitude_velocity: Some(1000.0),
            ..Drive::default()
        },
    );
    run(&mut w, 1.0);
    let z = pose(&w, c).0[2];
    assert!((-4.9..=-4.885).contains(&z), "ceiling: {z}");
    // Diagonal into the north wall: slides east.
    let c2 = spawn(&mut w, STS, [0.0, -5.0, -1.0], std::f64::consts::FRAC_PI_4);
    drive(
        &mut w,
        c2,
        Drive {
            linear_velocity: Some(2.0),
            ..Drive::default()
        },
    );
    run(&mut w, 10.0);
    let p = pose(&w, c2).0;
    assert!(p[0] > 9.4 && p[0] <= 9.55 && p[1] > 3.0, "{p:?}");
}

#[test]
fn robots_see_each_other_and_do_not_pass_through_each_other() {
    let mut w = world();
    let a = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    let b = spawn(&mut w, STS, [3.0, 0.0, -1.0], std::f64::consts::PI);
    let out = run(&mut w, 0.5);
    // Sonar0 sits 0.4 m ahead of each centre; the other body's near side is 0.45 from its.
    let expected = 3.0 - 0.4 - 0.45;
    for c in [a, b] {
        let ranges = sonar(&out, c, "Sonar0");
        assert!(
            !ranges.is_empty() && ranges.iter().all(|&r| close(r, expected, 1e-3)),
            "{ranges:?}"
        );
        // Its own body never shows: Sonar4 looks back through it to the wall.
        assert!(sonar(&out, c, "Sonar4").iter().all(|&r| r == 5.0));
    }
    drive(
        &mut w,
        a,
        Drive {
            linear_velocity: Some(1000.0),
            ..Drive::default()
        },
    );
    drive(
        &mut w,
        b,
        Drive {
            linear_velocity: Some(1000.0),
            ..Drive::default()
        },
    );
    run(&mut w, 1.0);
    let (pa, pb) = (pose(&w, a).0, pose(&w, b).0);
    assert!(pb[0] - pa[0] >= 0.9, "{pa:?} {pb:?}");
}

#[test]
fn spawn_failures_are_silent() {
    let mut w = world();
    let unknown = spawn(&mut w, "USARBot.Nope", [0.0, 0.0, -1.0], 0.0);
    let no_package = spawn(&mut w, "stsAirRobot", [0.0, 0.0, -1.0], 0.0);
    let in_wall = spawn(&mut w, STS, [10.0, 0.0, -1.0], 0.0);
    let ok = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    let on_top = spawn(&mut w, STS, [0.2, 0.0, -1.0], 0.0);
    assert_eq!(w.robot_count(), 1);
    let out = run(&mut w, 1.0);
    assert!(out.iter().all(|(c, _)| *c == ok));
    for c in [unknown, no_package, in_wall, on_top] {
        assert!(
            w.command(
                c,
                Command::GetConf(ItemQuery {
                    kind: "Robot".into(),
                    name: None
                })
            )
            .is_empty()
        );
    }
}

#[test]
fn non_finite_numbers_do_not_poison_the_world() {
    let mut w = world();
    let c = w.connect();
    w.command(c, init(STS, [f64::NAN, f64::INFINITY, -1.0], f64::NAN));
    assert_eq!(pose(&w, c), ([0.0, 0.0, -1.0], [0.0; 3]));
    let bad = Drive {
        linear_velocity: Some(f64::INFINITY),
        altitude_velocity: Some(f64::NAN),
        rotational_velocity: Some(f64::NEG_INFINITY),
        pitch_angle: Some(f64::NAN),
        ..Drive::default()
    };
    drive(&mut w, c, bad);
    w.command(
        c,
        Command::Act(Act {
            name: "cam".into(),
            links: vec![usar_proto::LinkValue {
                link: 0,
                value: f64::NAN,
            }],
            ..Act::default()
        }),
    );
    let out = run(&mut w, 1.0);
    // NaN reads as 0; infinities are held to the robot's limits: it circles at 50 m/s,
    // turning at -1800 deg/s, inside the room.
    let (p, r) = pose(&w, c);
    assert!(p.iter().chain(&r).all(|x| x.is_finite()), "{p:?} {r:?}");
    assert!(
        p[0].abs() < 10.0 && p[1].abs() < 10.0 && p[2] == -1.0,
        "{p:?}"
    );
    assert!(!out.is_empty());
}

#[test]
fn huge_drive_and_init_numbers_are_held_to_the_limits() {
    let mut w = world();
    let c = w.connect();
    w.command(c, init(STS, [1e308, -1e308, 1e308], 1e308));
    let (p, r) = pose(&w, c);
    let edge = map::LIMIT - map::EDGE_MARGIN;
    assert_eq!(p, [edge, -edge, edge]);
    assert!((0.0..std::f64::consts::TAU).contains(&r[2]), "{r:?}");
    // The attack: a NaN position at once, printed as -0.0000 and NaN.
    let d = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    drive(
        &mut w,
        d,
        Drive {
            linear_velocity: Some(1.5e308),
            lateral_velocity: Some(-1.5e308),
            rotational_velocity: Some(1e308),
            ..Drive::default()
        },
    );
    let out = run(&mut w, 2.0);
    let (p, r) = pose(&w, d);
    assert!(p.iter().chain(&r).all(|x| x.is_finite()), "{p:?} {r:?}");
    for (_, m) in &out {
        let line = m.to_string();
        assert!(!line.contains("NaN") && !line.contains("inf"), "{line}");
        assert!(!line.contains("2147483647"), "{line}");
    }
    // DRIVE 0 stops it.
    drive(
        &mut w,
        d,
        Drive {
            linear_velocity: Some(0.0),
            lateral_velocity: Some(0.0),
            rotational_velocity: Some(0.0),
            ..Drive::default()
        },
    );
    run(&mut w, 0.1);
    let before = pose(&w, d);
    run(&mut w, 0.5);
    assert_eq!(pose(&w, d).0, before.0);
}

#[test]
fn start_tags_and_start_poses() {
    let mut w = world();
    let c = w.connect();
    let replies = w.command(c, Command::GetStartPoses);
    let [ServerMessage::Nfo(Nfo::StartPoses { poses, .. })] = replies.as_slice() else {
        panic!("{replies:?}")
    };
    assert_eq!(poses[0].name, "Start1");
    assert_eq!(poses[0].location, Vec3::new(0.0, 0.0, -1.0));
    let by_tag = Init {
        class_name: STS.into(),
        start: Some("start3".into()),
        ..Init::default()
    };
    w.command(c, Command::Init(by_tag));
    assert_eq!(pose(&w, c).0, [5.0, 5.0, -1.0]);
    let d = w.connect();
    let unknown = Init {
        class_name: STS.into(),
        start: Some("Nowhere".into()),
        location: Some([1.0, 1.0, -1.0].into()),
        ..Init::default()
    };
    // No such start: UU (0,0,0), which is the floor's top here, so the spawn fails.
    w.command(d, Command::Init(unknown));
    assert!(w.robot(d).is_none());
    assert_eq!(w.robot_count(), 1);
}

#[test]
fn default_map_start_has_room_to_fly() {
    let w = world();
    let start = Map::default_map().starts()[0].location;
    for k in 0..16 {
        let yaw = f64::from(k) * std::f64::consts::TAU / 16.0;
        let d = w.scene_ray(start, direction(0.0, yaw), 100.0);
        assert!(d.is_some_and(|d| d >= 5.0), "yaw {yaw}: {d:?}");
    }
    let up = w.scene_ray(start, direction(std::f64::consts::FRAC_PI_2, 0.0), 100.0);
    assert!(up.is_some_and(|d| d >= 3.0), "{up:?}");
}

#[test]
fn nothing_flies_past_the_end_of_the_world() {
    let mut w = world();
    let c = spawn(&mut w, STS, [map::LIMIT - 30.0, 0.0, -1.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(1e9),
            ..Drive::default()
        },
    );
    run(&mut w, 2.0);
    assert_eq!(pose(&w, c).0, [map::LIMIT, 0.0, -1.0]);
}

#[test]
fn a_second_init_is_ignored_like_usarsim() {
    let mut w = world();
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    for i in 0..100 {
        w.command(c, init(AIR, [-5.0, f64::from(i) * 0.1 - 5.0, -1.0], 0.0));
    }
    assert_eq!(w.robot_count(), 1);
    assert_eq!(pose(&w, c).0, [0.0, 0.0, -1.0]);
}

#[test]
fn second_init_rebinds_and_disconnect_removes_all() {
    let mut w = World::new(
        Map::default_map(),
        RobotCatalog::embedded(),
        SimConfig {
            robots_per_connection: 2,
            ..SimConfig::default()
        },
    );
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    let other = spawn(&mut w, AIR, [-5.0, -5.0, -1.0], 0.0);
    w.command(c, init(AIR, [5.0, 0.0, -1.0], 0.0));
    assert_eq!(w.robot_count(), 3);
    assert_eq!(pose(&w, c).0, [5.0, 0.0, -1.0]);
    let out = run(&mut w, 1.0);
    // Only the new robot's output (an AirRobot: no sonar) reaches the connection.
    assert!(sonar(&out, c, "Sonar0").is_empty());
    assert!(
        out.iter()
            .any(|(k, m)| *k == c && matches!(m, ServerMessage::Asta(_)))
    );
    w.disconnect(c);
    assert_eq!(w.robot_count(), 1);
    assert!(run(&mut w, 0.5).iter().all(|(k, _)| *k == other));
    // The place is free again.
    spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    assert_eq!(w.robot_count(), 2);
}

fn count(
    out: &[(ClientId, ServerMessage)],
    pick: impl Fn(&ServerMessage) -> Option<String>,
) -> std::collections::BTreeMap<String, usize> {
    let mut counts = std::collections::BTreeMap::new();
    for (_, m) in out {
        if let Some(key) = pick(m) {
            *counts.entry(key).or_insert(0) += 1;
        }
    }
    counts
}

fn kind_of(m: &ServerMessage) -> Option<String> {
    Some(match m {
        ServerMessage::Sta(_) => "STA".to_string(),
        ServerMessage::Asta(a) => format!("ASTA {}", a.name),
        ServerMessage::Sen(s) => match &s.data {
            SenData::Sonar { readings, .. } => readings[0].name.clone(),
            SenData::RangeScanner(scan) => scan.name.clone(),
            SenData::Imu { name, .. }
            | SenData::Position { name, .. }
            | SenData::Velocity { name, .. }
            | SenData::AltitudeSensor { name, .. }
            | SenData::MagneticCompass { name, .. }
            | SenData::MissionTime { name, .. } => name.clone(),
            SenData::Camera => "Camera".to_string(),
            other => format!("{other:?}"),
        },
        _ => return None,
    })
}

#[test]
fn output_intervals_over_five_seconds() {
    let mut w = world();
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    // The first robot's timers start at its spawn, as UDK's: each stream speaks first one
    // interval after it (STA and the 0.1 s sensors, then the sonars, then the laser).
    let mut seen = Vec::new();
    for (seconds, expected) in [(0.1, 1 + 3), (0.2, 1 + 3 + 10), (0.3, 1 + 3 + 10 + 1)] {
        while w.time() < seconds - 1e-9 {
            w.step(&mut seen);
        }
        let kinds = count(&seen, kind_of);
        assert_eq!(kinds.len(), expected, "by {seconds} s: {kinds:?}");
    }
    let out = run(&mut w, 4.7);
    let all = count(&[seen, out].concat(), kind_of);
    assert_eq!(all["STA"], 50);
    assert_eq!(all["IMU"], 50);
    assert_eq!(all["Position"], 50);
    assert_eq!(all["Sonar0"], 25);
    assert_eq!(all["SonarBottom"], 25);
    assert_eq!(all["Scanner"], 16); // every 0.3 s from 0.3 s to 4.8 s
    let air = spawn(&mut w, AIR, [5.0, 5.0, -1.0], 0.0);
    let out = run(&mut w, 5.0);
    let mine: Vec<_> = out.into_iter().filter(|(k, _)| *k == air).collect();
    let all = count(&mine, kind_of);
    for key in ["STA", "IMU", "GPS", "Compass", "Time", "Camera", "ASTA cam"] {
        assert_eq!(all[key], 50, "{key}: {all:?}");
    }
    let _ = c;
}

#[test]
fn time_stamps_are_world_time() {
    let mut w = world();
    run(&mut w, 1.0);
    spawn(&mut w, AIR, [0.0, 0.0, -1.0], 0.0);
    let out = run(&mut w, 0.1);
    let ServerMessage::Sta(sta) = &out[0].1 else {
        panic!("{out:?}")
    };
    assert!(close(sta.time.seconds, 1.1, 1e-9));
    assert_eq!(sta.battery, 99_999);
}

#[test]
fn battery_empty_silences_sensors_but_not_sta() {
    let mut catalog = RobotCatalog::embedded();
    catalog.get_mut(STS).expect("sts").battery = Some(1.0);
    let mut w = World::new(Map::default_map(), catalog, SimConfig::default());
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(1.0),
            ..Drive::default()
        },
    );
    let before = run(&mut w, 0.95);
    let batteries: Vec<i64> = before
        .iter()
        .filter_map(|(_, m)| match m {
            ServerMessage::Sta(s) => Some(s.battery),
            _ => None,
        })
        .collect();
    assert_eq!(batteries.first(), Some(&1));
    assert!(
        before
            .iter()
            .any(|(_, m)| matches!(m, ServerMessage::Sen(_)))
    );
    let after = run(&mut w, 2.0);
    assert!(
        after
            .iter()
            .all(|(_, m)| matches!(m, ServerMessage::Sta(s) if s.battery == 0))
    );
    assert_eq!(after.len(), 20);
    // Stopped, and commands are ignored.
    let x = pose(&w, c).0[0];
    assert!(close(x, 1.0, 0.01), "{x}");
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(1.0),
            ..Drive::default()
        },
    );
    run(&mut w, 1.0);
    assert_eq!(pose(&w, c).0[0], x);
    assert!(
        w.command(
            c,
            Command::GetConf(ItemQuery {
                kind: "Robot".into(),
                name: None
            })
        )
        .is_empty()
    );
}

fn query(kind: &str, name: Option<&str>) -> ItemQuery {
    ItemQuery {
        kind: kind.to_string(),
        name: name.map(str::to_string),
    }
}

#[test]
fn getconf_and_getgeo() {
    let mut w = world();
    let c = spawn(&mut w, STS, [0.0, 0.0, -1.0], std::f64::consts::FRAC_PI_2);
    assert_eq!(
        w.command(c, Command::GetConf(query("Robot", None))),
        vec![ServerMessage::Conf(Conf::Robot {
            name: "stsAirRobot".into()
        })]
    );
    assert_eq!(
        w.command(c, Command::GetGeo(query("Robot", None))),
        vec![ServerMessage::Geo(Geo::Robot {
            name: "stsAirRobot".into()
        })]
    );
    // `robot` is not `Robot`: no part has that type → no reply.
    assert!(
        w.command(c, Command::GetConf(query("robot", None)))
            .is_empty()
    );
    let replies = w.command(c, Command::GetConf(query("sonar", None)));
    let [ServerMessage::Conf(Conf::Items { kind, items })] = replies.as_slice() else {
        panic!()
    };
    assert_eq!((kind.as_str(), items.len()), ("sonar", 10));
    assert_eq!(
        items[0],
        ConfItem::Sonar {
            name: "Sonar0".into(),
            max_range: 5.0,
            min_range: f64::from(0.1f32),
            scan_interval: f64::from(0.2f32),
            // Through whole rotation units, as the engine: 3640 / 10430.378.
            beam_angle: f64::from(3640f32 / 10_430.378),
            max_angle_of_incidence: f64::from(0.174_532_925_2_f64 as f32),
            traces_per_cone: 16,
            number_of_cones: 10,
        }
    );
    let replies = w.command(c, Command::GetConf(query("Position", None)));
    assert_eq!(
        replies,
        vec![ServerMessage::Conf(Conf::Items {
            kind: "Position".into(),
            items: vec![ConfItem::Interval {
                name: "Position".into(),
                scan_interval: f64::from(0.1f32)
            }],
        })]
    );
    let replies = w.command(c, Command::GetGeo(query("Sonar", Some("sonar2"))));
    let [ServerMessage::Geo(Geo::Items { items, .. })] = replies.as_slice() else {
        panic!()
    };
    assert_eq!(items.len(), 1);
    // Sonar2 points right; the robot faces east, so it sits 0.4 m south of the centre.
    let g = &items[0];
    assert!(
        close(g.location.x, -0.4, 1e-4) && close(g.location.y, 0.0, 1e-4),
        "{g:?}"
    );
    assert_eq!((g.orientation.z, g.mount.as_str()), (1.5708, "stsAirRobot"));
    assert!(
        w.command(c, Command::GetGeo(query("Sonar", Some("nope"))))
            .is_empty()
    );
    assert!(
        w.command(c, Command::GetConf(query("Laser", None)))
            .is_empty()
    );
    let replies = w.command(c, Command::GetConf(query("RangeScanner", None)));
    assert!(
        matches!(&replies[0], ServerMessage::Conf(Conf::Items { items, .. }) if matches!(items[0], ConfItem::Scanner { .. }))
    );
}

#[test]
fn act_moves_the_camera_joint_and_set_scan_forces_a_scan() {
    let mut w = world();
    let air = spawn(&mut w, AIR, [0.0, 0.0, -1.0], 0.0);
    let act = Act {
        name: "CAM".into(),
        links: vec![usar_proto::LinkValue {
            link: 0,
            value: -0.5,
        }],
        ..Act::default()
    };
    w.command(air, Command::Act(act));
    let out = run(&mut w, 0.1);
    let asta = out.iter().find_map(|(_, m)| match m {
        ServerMessage::Asta(a) => Some(a.clone()),
        _ => None,
    });
    let asta = asta.expect("ASTA");
    assert_eq!(
        (asta.name.as_str(), asta.links[0].link, asta.links[0].value),
        ("cam", 1, -0.5)
    );
    let conf = w.command(air, Command::GetConf(query("Actuator", None)));
    assert!(
        matches!(&conf[0], ServerMessage::Conf(Conf::Items { items, .. }) if matches!(&items[0], ConfItem::Actuator { joints, .. } if joints.len() == 1))
    );

    let sts = spawn(&mut w, STS, [5.0, 5.0, -1.0], 0.0);
    run(&mut w, 0.15); // after its first scan (0.115 s, its phase), before the second (0.415 s)
    let set = Set {
        kind: "RangeScanner".into(),
        name: None,
        opcode: "SCAN".into(),
        params: None,
    };
    assert!(w.command(sts, Command::Set(set)).is_empty());
    let mut out = Vec::new();
    w.step(&mut out);
    assert!(out.iter().any(
        |(_, m)| matches!(m, ServerMessage::Sen(s) if matches!(s.data, SenData::RangeScanner(_)))
    ));
}

#[test]
fn deterministic_with_noise() {
    let run_once = || {
        let mut catalog = RobotCatalog::embedded();
        for part in &mut catalog.get_mut(STS).expect("sts").parts {
            part.noise = 0.05;
        }
        let mut w = World::new(
            Map::embedded("arena").expect("arena"),
            catalog,
            SimConfig {
                seed: 42,
                ..SimConfig::default()
            },
        );
        let a = w.connect();
        let b = w.connect();
        w.command(
            a,
            Command::Init(Init {
                class_name: STS.into(),
                start: Some("Start1".into()),
                ..Init::default()
            }),
        );
        w.command(
            b,
            Command::Init(Init {
                class_name: STS.into(),
                start: Some("Start2".into()),
                ..Init::default()
            }),
        );
        w.command(
            a,
            Command::Drive(Drive {
                linear_velocity: Some(3.0),
                rotational_velocity: Some(20.0),
                ..Drive::default()
            }),
        );
        w.command(
            b,
            Command::Drive(Drive {
                linear_velocity: Some(2.0),
                altitude_velocity: Some(0.5),
                ..Drive::default()
            }),
        );
        let out = run(&mut w, 3.0);
        format!("{out:?}")
    };
    let (x, y) = (run_once(), run_once());
    assert!(x.len() > 10_000);
    assert!(x == y, "two runs differ");
    // The noise is really on: two sonar readings of the same still wall differ.
    assert!(x.contains("Sonar"));
}

/// 200 noisy robots (a third of them quadrotors) packed in the city's plaza, flying into
/// each other and the buildings,
/// stepped with `threads` sensor threads (and, if `shortcuts` is off, with one tree walk per
/// ray and a shape cast per move; if `printed`, by [`World::step_printed`]): the whole output
/// as text.
fn crowd_output(threads: usize, shortcuts: bool, printed: bool) -> String {
    let mut catalog = RobotCatalog::embedded();
    for part in &mut catalog.get_mut(STS).expect("sts").parts {
        part.noise = 0.02;
    }
    let mut w = World::new(
        Map::embedded("city").expect("city"),
        catalog,
        SimConfig {
            seed: 7,
            threads,
            ..SimConfig::default()
        },
    );
    w.set_shortcuts(shortcuts);
    let mut clients = Vec::new();
    for i in 0..200 {
        let (x, y, z) = ((i % 10) as f64, ((i / 10) % 10) as f64, (i / 100) as f64);
        let location = [x * 1.0 - 5.0, y * 1.0 - 5.0, -2.0 - 0.5 * z];
        // Every third one a quadrotor: its sensors tilt with its body.
        let class = if i % 3 == 0 {
            "USARBot.stsQuadrotor"
        } else {
            STS
        };
        clients.push(spawn(&mut w, class, location, 0.3 * i as f64));
    }
    assert_eq!(w.robot_count(), 200);
    let mut out = Vec::new();
    for (i, &c) in clients.iter().enumerate() {
        // Every twentieth one, at the crowd's edge, descends straight down and then presses
        // on the ground, among the others flying past it (the resting sweeps).
        if i % 20 == 9 && i < 100 {
            let down = Drive {
                altitude_velocity: Some(-5.0),
                ..Drive::default()
            };
            drive(&mut w, c, down);
            continue;
        }
        drive(
            &mut w,
            c,
            Drive {
                linear_velocity: Some(1.0 + (i % 3) as f64),
                lateral_velocity: Some((i % 5) as f64 - 2.0),
                altitude_velocity: Some((i % 4) as f64 - 1.5),
                rotational_velocity: Some(30.0 * ((i % 7) as f64 - 3.0)),
                ..Drive::default()
            },
        );
    }
    let mut text = String::new();
    let mut lines = Printed::default();
    for _ in 0..(1.5 / w.dt()) as u64 {
        if printed {
            w.step_printed(&mut lines);
            for (c, robot) in lines.robots() {
                let robot = std::str::from_utf8(robot).expect("UTF-8");
                let robot = robot.strip_suffix("\r\n").expect("ends in CRLF");
                for line in robot.split("\r\n") {
                    text.push_str(&format!("{} {line}\n", c.0));
                }
            }
        } else {
            w.step(&mut out);
        }
    }
    text.extend(out.iter().map(|(c, m)| format!("{} {m}\n", c.0)));
    text
}

#[test]
fn output_is_identical_at_any_thread_count_and_without_shortcuts() {
    let reference = crowd_output(1, false, false);
    assert!(reference.len() > 1_000_000, "{} bytes", reference.len());
    // The crowd really sees itself: some scanner beams end short of the 4 m maximum.
    assert!(reference.contains("{Name Scanner}"));
    for (threads, shortcuts, printed) in [
        (1, true, false),
        (2, true, false),
        (3, true, false),
        (8, true, false),
        (1, true, true),
        (2, true, true),
        (3, false, true),
    ] {
        let out = crowd_output(threads, shortcuts, printed);
        assert!(
            out == reference,
            "output differs at {threads} threads (shortcuts {shortcuts}, printed {printed})"
        );
    }
}

/// The scanner readings of each tick of `seconds` (after `skip` seconds), `robots`
/// stsAirRobots spawned on one tick in a grid on the city's plaza.
fn scans_per_tick(robots: usize, skip: f64, seconds: f64) -> Vec<usize> {
    let mut w = World::new(
        Map::embedded("city").expect("city"),
        RobotCatalog::embedded(),
        SimConfig::default(),
    );
    for i in 0..robots {
        let (x, y) = ((i % 12) as f64, (i / 12) as f64);
        spawn(&mut w, STS, [x * 1.5 - 8.0, y * 1.5 - 8.0, -2.0], 0.0);
    }
    assert_eq!(w.robot_count(), robots);
    run(&mut w, skip);
    (0..(seconds / w.dt()).round() as u64)
        .map(|_| {
            let mut out = Vec::new();
            w.step(&mut out);
            count(&out, kind_of).get("Scanner").copied().unwrap_or(0)
        })
        .collect()
}

#[test]
fn robots_spawned_on_one_tick_read_their_lasers_on_different_ticks() {
    // 120 lasers every 0.3 s (60 ticks): two or three per tick, never all on one.
    let scans = scans_per_tick(120, 0.5, 0.6);
    assert_eq!(scans.iter().sum::<usize>(), 240, "{scans:?}");
    assert!(scans.iter().all(|&n| (1..=3).contains(&n)), "{scans:?}");
}

#[test]
fn the_phases_are_the_same_for_the_same_spawn_order() {
    assert_eq!(scans_per_tick(50, 0.0, 0.4), scans_per_tick(50, 0.0, 0.4));
}

/// The conf item of the robot's camera.
fn camera_conf(world: &mut World, client: ClientId) -> ConfItem {
    let replies = world.command(client, Command::GetConf(query("Camera", None)));
    let [ServerMessage::Conf(Conf::Items { items, .. })] = &replies[..] else {
        panic!("{replies:?}")
    };
    items[0].clone()
}

fn offsets(item: &ConfItem) -> (i64, i64, f64) {
    let ConfItem::Camera {
        texture_offset_x,
        texture_offset_y,
        fov,
        ..
    } = item
    else {
        panic!("{item:?}")
    };
    (*texture_offset_x, *texture_offset_y, *fov)
}

#[test]
fn the_airrobot_camera_sees_the_room_and_reports_its_tile() {
    let mut w = world();
    let a = spawn(&mut w, AIR, [0.0, 0.0, -1.0], 0.0);
    let b = spawn(&mut w, AIR, [-5.0, -5.0, -1.0], 0.0);
    let c = spawn(&mut w, AIR, [5.0, 5.0, -1.0], 0.0);
    assert_eq!(offsets(&camera_conf(&mut w, a)), (0, 0, 80.0));
    assert_eq!(offsets(&camera_conf(&mut w, b)), (320, 0, 80.0));
    assert_eq!(offsets(&camera_conf(&mut w, c)), (0, 240, 80.0));
    let mut frames = Vec::new();
    w.render_cameras(&mut frames);
    let tiles: Vec<(usize, &str)> = frames.iter().map(|f| (f.tile, f.name.as_str())).collect();
    assert_eq!(tiles, [(0, "cams"), (1, "cams"), (2, "cams")]);
    let image = &frames[0].image;
    assert_eq!((image.width, image.height), (320, 240));
    // Looking north from 0.1 m ahead of the centre: the wall's face at x = 10 is a plane
    // at depth 9.9 across the middle row; the bottom row shows the floor, nearer.
    let depth = |x: usize, y: usize| image.depth[y * 320 + x];
    for x in [0, 100, 160, 319] {
        assert!((depth(x, 120) - 9.9).abs() < 1e-4, "{}", depth(x, 120));
    }
    let column: Vec<f32> = (0..240).step_by(20).map(|y| depth(160, y)).collect();
    assert!(depth(160, 239) < 2.0, "{column:?}");
    let rgb = |x: usize, y: usize| &image.rgb[3 * (y * 320 + x)..3 * (y * 320 + x) + 3];
    assert_ne!(rgb(160, 120), rgb(160, 239), "walls and floor look alike");
    // Robot a sees robot c's body? c is at (5, 5), a looks north: c is 45° to the right,
    // beyond the 40° half field of view. Robot b's camera looks north past a's side.
    // Tilted down by the `cam` actuator (ACT link 0 = joint 1): the middle sees the floor.
    w.command(
        a,
        Command::Act(Act {
            name: "cam".into(),
            links: vec![usar_proto::LinkValue {
                link: 0,
                value: -1.0,
            }],
            ..Act::default()
        }),
    );
    w.render_cameras(&mut frames);
    let tilted = frames[0].image.depth[120 * 320 + 160];
    // Down by 1 rad from 0.9 m above the floor: depth 0.9 / (sin 1 + v cos 1) along the
    // axis, v the pixel row's offset (half a pixel below the axis).
    let v = (241.0 / 240.0 - 1.0) * 40f64.to_radians().tan() * 0.75;
    let expect = 0.9 / (1.0f64.sin() + v * 1.0f64.cos());
    assert!(
        (f64::from(tilted) - expect).abs() < 1e-4,
        "{tilted} vs {expect}"
    );
    // A narrower field of view (SET FOV, radians): CONF says so, and the image zooms in.
    w.command(
        b,
        Command::Set(Set {
            kind: "Camera".into(),
            name: None,
            opcode: "FOV".into(),
            params: Some("0.5".into()),
        }),
    );
    assert_eq!(offsets(&camera_conf(&mut w, b)).2, 0.5f64.to_degrees());
    let before = frames[1].image.clone();
    w.render_cameras(&mut frames);
    assert_ne!(before.depth, frames[1].image.depth);
}

#[test]
fn camera_tiles_go_to_the_lowest_free_slot_and_pictures_do_not_depend_on_threads() {
    let picture = |threads: usize| {
        let mut w = World::new(
            Map::embedded("city").unwrap(),
            RobotCatalog::embedded(),
            SimConfig {
                threads,
                ..SimConfig::default()
            },
        );
        let mut clients = Vec::new();
        for i in 0..5 {
            let at = [f64::from(i) * 3.0, -2.0, -2.0 - f64::from(i)];
            clients.push(spawn(&mut w, AIR, at, 0.3 * f64::from(i)));
        }
        w.disconnect(clients[1]);
        let late = spawn(&mut w, AIR, [0.0, 8.0, -3.0], 1.0);
        assert_eq!(
            offsets(&camera_conf(&mut w, late)).0,
            320,
            "tile 1 is free again"
        );
        run(&mut w, 0.5);
        let mut frames = Vec::new();
        w.render_cameras(&mut frames);
        frames
    };
    let one = picture(1);
    let four = picture(4);
    assert_eq!(one.len(), 5);
    assert_eq!(
        one.iter().map(|f| f.tile).collect::<Vec<_>>(),
        [0, 2, 3, 4, 1]
    );
    for (a, b) in one.iter().zip(&four) {
        assert_eq!(a.image, b.image);
    }
}

/// A world reset in place with a seed flies as a new world with that seed, bit for bit,
/// whatever flew in it before (the Python package's resets).
#[test]
fn a_reset_world_flies_as_a_new_one() {
    let episode = |w: &mut World| {
        let mut text = String::new();
        for (i, class) in [STS, "USARBot.stsQuadrotor", STS].into_iter().enumerate() {
            let c = spawn(w, class, [i as f64 * 2.0 - 2.0, 0.0, -1.5], 0.3 * i as f64);
            // Where the scene holds the new body (a body taken back from the last episode
            // is moved to its spawn, as a new one is placed there).
            text.push_str(&format!("{:?}\n", w.body_boxes()));
            drive(
                w,
                c,
                Drive {
                    linear_velocity: Some(1.0),
                    altitude_velocity: Some(-0.5 + i as f64 * 0.5),
                    rotational_velocity: Some(20.0),
                    ..Drive::default()
                },
            );
        }
        for (c, m) in run(w, 1.0) {
            text.push_str(&format!("{} {m}\n", c.0));
        }
        text
    };
    let config = |seed| SimConfig {
        seed,
        ..SimConfig::default()
    };
    let map = || Map::embedded("city").expect("city");
    let mut fresh = World::new(map(), RobotCatalog::embedded(), config(9));
    let expected = episode(&mut fresh);
    assert!(expected.len() > 10_000, "{} bytes", expected.len());
    // Reset in place (the bodies taken out of the scene), and after a robot left (the
    // scene copied whole).
    for leaves in [false, true] {
        let mut reused = World::new(map(), RobotCatalog::embedded(), config(1));
        let clients: Vec<_> = (0..5)
            .map(|i| spawn(&mut reused, STS, [i as f64 * 1.5, 4.0, -1.0], 0.0))
            .collect();
        run(&mut reused, 0.5);
        if leaves {
            reused.disconnect(clients[1]);
        }
        for _ in 0..2 {
            reused.reset(9);
            assert_eq!(reused.robot_count(), 0);
            assert_eq!(reused.time(), 0.0);
            let got = episode(&mut reused);
            // The same tree leaves as in a new world: the tree's boxes depend on them.
            assert_eq!(reused.body_leaves(), fresh.body_leaves(), "leaves {leaves}");
            assert!(
                got == expected,
                "a reset world's output differs from a new world's (a robot left: {leaves})"
            );
        }
    }
}

/// Worlds made from one shared catalog (a Python batch's) fly as worlds with their own
/// copies, share each class's built parts, and a class changed in the catalog afterwards is
/// what the next world spawns (the shared parts are built again, not reused stale).
#[test]
fn worlds_sharing_a_catalog_fly_as_their_own_and_see_its_changes() {
    let laser = |out: &[(ClientId, ServerMessage)]| {
        out.iter().any(|(_, m)| {
                matches!(m, ServerMessage::Sen(s) if matches!(s.data, SenData::RangeScanner(_)))
            })
    };
    let fly = |world: &mut World| {
        let c = spawn(world, STS, [0.0, 0.0, -1.0], 0.0);
        drive(
            world,
            c,
            Drive {
                linear_velocity: Some(0.5),
                ..Drive::default()
            },
        );
        format!("{:?}", run(world, 1.0))
    };
    use std::sync::Arc;
    let mut shared = Arc::new(RobotCatalog::embedded());
    let mut a = World::new(Map::default_map(), shared.clone(), SimConfig::default());
    let mut b = World::new(Map::default_map(), shared.clone(), SimConfig::default());
    let (out_a, out_b) = (fly(&mut a), fly(&mut b));
    assert_eq!(
        out_a,
        fly(&mut world()),
        "a world with its own catalog flies the same"
    );
    assert_eq!(out_a, out_b);
    let (ma, mb) = (a.model(STS).unwrap(), b.model(STS).unwrap());
    assert!(Arc::ptr_eq(ma, mb), "one model");
    drop((a, b));
    // The catalog is no longer shared: changed in place, its built models are dropped.
    let class = Arc::get_mut(&mut shared).unwrap().get_mut(STS).unwrap();
    class.parts.retain(|p| p.kind != "RangeScanner");
    let mut c = World::new(Map::default_map(), shared.clone(), SimConfig::default());
    spawn(&mut c, STS, [0.0, 0.0, -1.0], 0.0);
    assert!(!laser(&run(&mut c, 1.0)), "the changed class has no laser");
    let mut d = world();
    spawn(&mut d, STS, [0.0, 0.0, -1.0], 0.0);
    assert!(laser(&run(&mut d, 1.0)), "the embedded class has one");
}

/// A change to the stsAirRobot's class, named.
type Tuning = (&'static str, fn(&mut RobotClass));

/// One robot's flight through `map` by a random DRIVE each period (speeds up to past the
/// limits, turns, dives into the floor, now and then only a turn or a hover), run `ticks` ticks at a time by [`World::run`], or
/// (`reference`) tick by tick with the shortcuts off; a second robot joins half-way (the
/// world is no longer a lone robot's). Every message, touch and pose, and the bodies'
/// colliders and tree boxes, as text.
fn flown(map: &str, tune: fn(&mut RobotClass), seed: u64, reference: bool) -> String {
    let mut catalog = RobotCatalog::embedded();
    tune(catalog.get_mut(STS).expect("sts"));
    let config = SimConfig {
        seed,
        ..SimConfig::default()
    };
    let map = Map::embedded(map).expect("an embedded map");
    let start = map.starts()[(seed % map.starts().len() as u64) as usize].location;
    let mut w = World::new(map, catalog, config);
    w.set_shortcuts(!reference);
    let mut clients = vec![spawn(&mut w, STS, start, 0.0)];
    let mut rng = seed ^ 0x5eed;
    let mut uniform = |scale: f64| {
        let bits = splitmix(&mut rng) >> 11;
        (bits as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * scale
    };
    let (mut text, mut out) = (String::new(), Vec::new());
    for period in 0..120 {
        if period == 60 {
            let beside = [start[0] + 3.0, start[1] - 2.0, start[2]];
            clients.push(spawn(&mut w, STS, beside, 1.0));
        }
        for &c in &clients {
            let down = uniform(1.0) < -0.6;
            // Now and then it only turns, or hovers.
            let still = if period % 7 == 3 { 0.0 } else { 1.0 };
            let turn = if period % 14 == 3 { 0.0 } else { 1.0 };
            let d = Drive {
                linear_velocity: Some(still * uniform(4.0)),
                lateral_velocity: Some(still * uniform(4.0)),
                altitude_velocity: Some(still * if down { -5.0 } else { uniform(3.0) }),
                rotational_velocity: Some(turn * uniform(90.0).round()),
                ..Drive::default()
            };
            w.command(c, Command::Drive(d));
        }
        let ticks = 1 + (uniform(1.0).abs() * 40.0) as u64;
        if reference {
            for _ in 0..ticks {
                w.step(&mut out);
            }
        } else {
            w.run(ticks, &mut out);
        }
        for (c, m) in out.drain(..) {
            text.push_str(&format!("{} {m}\n", c.0));
        }
        w.take_touched(|c, touched| text.push_str(&format!("{} touched {touched}\n", c.0)));
        for &c in &clients {
            let at = w.robot(c).map(|r| r.pose());
            text.push_str(&format!("{} at {at:?}\n", c.0));
        }
        // The bodies as the scene holds them (what other robots' queries read).
        text.push_str(&format!("bodies {:?}\n", w.body_boxes()));
    }
    text
}

#[test]
fn run_flies_a_lone_robot_as_the_reference_ticks_do() {
    let tunings: [Tuning; 4] = [
        ("as is", |_| {}),
        ("crashing on contact", |c| c.crash.on_contact = true),
        ("with a 4 s battery", |c| c.battery = Some(4.0)),
        // Empty between two outputs, in the lone robot's part of the flight.
        ("with a 1.2371 s battery", |c| c.battery = Some(1.2371)),
    ];
    let maps = ["empty_room", "city", "rescue", "arena"];
    let cases = maps
        .iter()
        .map(|&m| (m, tunings[0]))
        .chain(tunings[1..].iter().map(|&t| ("empty_room", t)));
    for (map, (tuned, tune)) in cases {
        for seed in 1..=3 {
            let reference = flown(map, tune, seed, true);
            let run = flown(map, tune, seed, false);
            // (A robot whose battery is empty after 12 periods may never touch.)
            assert!(
                reference.contains(" touched true") || tuned == tunings[3].0,
                "{map}, seed {seed}: no contact"
            );
            if let Some(line) = reference.lines().zip(run.lines()).position(|(a, b)| a != b) {
                panic!(
                    "{map}, {tuned}, seed {seed}: line {line} differs:\n{}\n{}",
                    reference.lines().nth(line).unwrap_or(""),
                    run.lines().nth(line).unwrap_or("")
                );
            }
            assert_eq!(reference.len(), run.len(), "{map}, {tuned}, seed {seed}");
        }
    }
}

/// A lone robot whose every tick moves it farther than the longest sweep (`MAX_STEP`,
/// 100 m: speeds of 5000 m/s on each axis, ticks of 0.025 s) is held to it in `run`'s
/// glides as in the reference ticks.
#[test]
fn run_holds_the_longest_sweep_as_the_reference_ticks_do() {
    let flight = |reference: bool| {
        let mut catalog = RobotCatalog::embedded();
        let class = catalog.get_mut(STS).expect("sts");
        // No sensors: outputs only now and then, the ticks between them glided.
        class.parts.clear();
        let f = &mut class.flight;
        (
            f.max_linear_speed,
            f.max_lateral_speed,
            f.max_altitude_speed,
        ) = (5e3, 5e3, 5e3);
        let config = SimConfig {
            dt: 0.025,
            ..SimConfig::default()
        };
        let mut w = World::new(Map::embedded("city").expect("city"), catalog, config);
        w.set_shortcuts(!reference);
        let c = spawn(&mut w, STS, [0.0, 0.0, -20.0], 0.3);
        let (mut text, mut out, mut first) = (String::new(), Vec::new(), None);
        for (forward, right, up) in [
            (100.0, 100.0, 0.0),
            (-100.0, 30.0, 100.0),
            (5.0, -100.0, -100.0),
        ] {
            let d = Drive {
                linear_velocity: Some(forward),
                lateral_velocity: Some(right),
                altitude_velocity: Some(up),
                normalized: Some(true),
                ..Drive::default()
            };
            w.command(c, Command::Drive(d));
            for _ in 0..3 {
                if reference {
                    (0..7).for_each(|_| w.step(&mut out));
                } else {
                    w.run(7, &mut out);
                }
                let pose = w.robot(c).map(|r| r.pose());
                first = first.or(pose.map(|p| p.0));
                text.push_str(&format!("{pose:?} {:?}\n", w.body_boxes()));
            }
        }
        (text, first.unwrap_or_default())
    };
    let (reference, first) = flight(true);
    assert_eq!(flight(false).0, reference);
    // Held: the first 7 ticks took it about 690 m, not the 1240 of 177 m per tick.
    let moved = first[0].hypot(first[1]);
    assert!((600.0..=700.0).contains(&moved), "{moved} m: {reference}");
}

#[test]
fn init_by_reference_spawns_as_the_command_does_and_only_for_known_connections() {
    let Command::Init(message) = init(STS, [1.0, 2.0, -1.5], 0.5) else {
        unreachable!()
    };
    let (mut a, mut b) = (world(), world());
    let client = spawn(&mut a, STS, [1.0, 2.0, -1.5], 0.5);
    let other = b.connect();
    b.init(other, &message);
    assert_eq!(b.robot_count(), 1);
    assert_eq!(run(&mut a, 1.0), run(&mut b, 1.0));
    assert_eq!(pose(&a, client), pose(&b, other));
    // An INIT from a connection the world does not know spawns nothing.
    let mut c = world();
    c.init(ClientId(7), &message);
    assert_eq!(c.robot_count(), 0);
}
