//! The quadrotor against physics: hover, tilt to accelerate, rotor-speed differences, wind,
//! crashes, sensors on the tilted body, determinism.

use usar_proto::{Command, Drive, Init, SenData, ServerMessage};

use super::dynamics::GRAVITY;
use super::*;

const QUAD: &str = "USARBot.stsQuadrotor";

fn world_with(catalog: RobotCatalog, wind: Option<WindConfig>, seed: u64) -> World {
    World::new(
        Map::default_map(),
        catalog,
        SimConfig {
            seed,
            wind,
            ..SimConfig::default()
        },
    )
}

fn world() -> World {
    world_with(RobotCatalog::embedded(), None, 0)
}

/// `catalog` with the stsQuadrotor's IMU errors off (tests of the dynamics' truth).
fn exact_imu(mut catalog: RobotCatalog) -> RobotCatalog {
    let q = catalog.get_mut(QUAD).expect("stsQuadrotor");
    for p in &mut q.parts {
        if p.kind == "IMU" {
            p.settings = toml::Table::new();
        }
    }
    catalog
}

/// The embedded catalog with the stsQuadrotor's drag set to zero.
fn without_drag() -> RobotCatalog {
    let mut catalog = RobotCatalog::embedded();
    let q = catalog.get_mut(QUAD).expect("stsQuadrotor");
    q.quadrotor.drag_linear = 0.0;
    q.quadrotor.drag_quadratic = 0.0;
    catalog
}

fn spawn(world: &mut World, location: [f64; 3], yaw: f64) -> ClientId {
    let client = world.connect();
    world.command(
        client,
        Command::Init(Init {
            class_name: QUAD.into(),
            name: Some("Q".into()),
            location: Some(location.into()),
            rotation: Some([0.0, 0.0, yaw].into()),
            start: None,
        }),
    );
    assert!(world.robot(client).is_some(), "spawned");
    client
}

fn step(world: &mut World, out: &mut Vec<(ClientId, ServerMessage)>) {
    world.step(out);
}

fn run(world: &mut World, seconds: f64) -> Vec<(ClientId, ServerMessage)> {
    let mut out = Vec::new();
    for _ in 0..(seconds / world.dt()).round() as u64 {
        step(world, &mut out);
    }
    out
}

fn drive(world: &mut World, client: ClientId, d: Drive) {
    world.command(client, Command::Drive(d));
}

fn command(world: &mut World, client: ClientId, line: &str) {
    let parsed = Command::parse(line).expect("a command").message;
    world.command(client, parsed);
}

/// (position, velocity, rotation).
fn state(world: &World, client: ClientId) -> ([f64; 3], [f64; 3], [f64; 3]) {
    let robot = world.robot(client).expect("robot");
    let (p, r) = robot.pose();
    (p, robot.velocity(), r)
}

fn imu_lines(out: &[(ClientId, ServerMessage)]) -> Vec<(usar_proto::Vec3, usar_proto::Vec3)> {
    out.iter()
        .filter_map(|(_, m)| match m {
            ServerMessage::Sen(sen) => match &sen.data {
                SenData::Imu {
                    acceleration,
                    angular_vel,
                    ..
                } => Some((*acceleration, *angular_vel)),
                _ => None,
            },
            _ => None,
        })
        .collect()
}

fn touch(out: &[(ClientId, ServerMessage)], name: &str) -> Vec<bool> {
    out.iter()
        .filter_map(|(_, m)| match m {
            ServerMessage::Sen(sen) => match &sen.data {
                SenData::Touch { name: n, touch } if n == name => Some(*touch),
                _ => None,
            },
            _ => None,
        })
        .collect()
}

#[test]
fn hover_holds_altitude_for_thirty_seconds_with_thrust_equal_to_weight() {
    let mut w = world_with(exact_imu(RobotCatalog::embedded()), None, 0);
    let c = spawn(&mut w, [0.0, 0.0, -2.0], 0.3);
    let mut out = Vec::new();
    let mut worst: f64 = 0.0;
    for _ in 0..(30.0 / w.dt()) as u64 {
        step(&mut w, &mut out);
        let (p, _, r) = state(&w, c);
        worst = worst
            .max((p[2] + 2.0).abs())
            .max(p[0].abs())
            .max(p[1].abs());
        assert!(r[0].abs() < 1e-6 && r[1].abs() < 1e-6, "stays level: {r:?}");
    }
    assert!(worst < 0.02, "drifted {worst} m in 30 s");
    // The accelerometer reads the specific force: thrust/mass = g, straight up.
    let imu = imu_lines(&out);
    assert!(imu.len() >= 299, "{} IMU lines", imu.len());
    for (a, rates) in &imu[10..] {
        assert!((a.z - GRAVITY).abs() < 0.01 * GRAVITY, "{a:?}");
        assert!(a.x.abs() < 0.01 && a.y.abs() < 0.01, "{a:?}");
        assert!(rates.x.abs() < 1e-3 && rates.y.abs() < 1e-3, "{rates:?}");
    }
    assert!(!w.crashed(c));
}

#[test]
fn the_accelerometer_reads_only_idle_thrust_and_drag_in_free_fall() {
    let catalog = exact_imu(RobotCatalog::embedded());
    let q = catalog.get(QUAD).expect("class").quadrotor.clone();
    let mut w = world_with(catalog, None, 0);
    let c = spawn(&mut w, [0.0, 0.0, -4.5], 0.0);
    // Idle rotors (the command is clamped to rotor_speed_min).
    command(&mut w, c, "QUAD {Rotors 0,0,0,0}");
    run(&mut w, 0.3);
    let idle = 4.0 * q.thrust_coefficient * q.rotor_speed_min.powi(2);
    let mut checked = 0;
    for _ in 0..140 {
        let mut out = Vec::new();
        step(&mut w, &mut out);
        let (_, v, _) = state(&w, c);
        if let Some((a, _)) = imu_lines(&out).pop() {
            // Falling level: idle thrust and drag push up; gravity does not show.
            let speed = v[2];
            // Rotor drag grows with the rotor speed (idle here), airframe drag with v².
            let spin = q.rotor_speed_min / q.hover_speed();
            let drag = (q.drag_linear * spin + q.drag_quadratic * speed) * speed;
            let expected = (idle + drag) / q.mass;
            assert!(a.x.abs() < 1e-9 && a.y.abs() < 1e-9, "{a:?}");
            assert!(
                (a.z - expected).abs() < 0.03 * expected,
                "{a:?} vs {expected}"
            );
            checked += 1;
        }
    }
    assert!(checked >= 6, "{checked} readings");
    assert!(state(&w, c).1[2] > 4.0, "fell fast");
}

#[test]
fn forward_step_pitches_and_accelerates_at_g_tan_theta_without_climbing() {
    // Without drag, thrust alone accelerates the body: a = g·tan θ when it holds altitude.
    let mut w = world_with(without_drag(), None, 0);
    let c = spawn(&mut w, [-8.0, 0.0, -2.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(2.0),
            ..Drive::default()
        },
    );
    let dt = w.dt();
    let mut out = Vec::new();
    let (mut last_v, mut last_pitch) = (state(&w, c).1, state(&w, c).2[1]);
    let mut checked = 0;
    let mut max_climb: f64 = 0.0;
    let mut min_pitch: f64 = 0.0;
    let mut speeds = Vec::new();
    for _ in 0..(8.0 / dt) as u64 {
        step(&mut w, &mut out);
        let (_, v, r) = state(&w, c);
        let pitch = 0.5 * (r[1] + last_pitch);
        let accel = (v[0] - last_v[0]) / dt;
        let accel_up = -(v[2] - last_v[2]) / dt;
        max_climb = max_climb.max(v[2].abs());
        min_pitch = min_pitch.min(r[1]);
        if pitch.abs() > 0.15 {
            // Nose down to go forward; the thrust along the tilted axis gives
            // a = (g + a_up)·tan θ at every tick ...
            assert!(pitch < 0.0, "nose down, pitch {pitch}");
            let tan = (-pitch).tan();
            let expected = (GRAVITY + accel_up) * tan;
            assert!(
                (accel - expected).abs() < 0.03 * expected,
                "a = {accel:.3} m/s², (g + a_up)·tan θ = {expected:.3} m/s² (θ = {:.1}°)",
                pitch.to_degrees()
            );
            // ... and g·tan θ while the altitude is held.
            if accel_up.abs() < 0.1 {
                let level = GRAVITY * tan;
                assert!(
                    (accel - level).abs() < 0.03 * level,
                    "a = {accel:.3} m/s², g·tan θ = {level:.3} m/s²"
                );
                checked += 1;
            }
        }
        assert!(
            r[0].abs() < 1e-6 && v[1].abs() < 1e-6,
            "no roll, no sideways motion"
        );
        (last_v, last_pitch) = (v, r[1]);
        speeds.push(v[0]);
    }
    assert!(
        checked > 20,
        "only {checked} ticks with a real tilt and no climb"
    );
    assert!(
        min_pitch < -15f64.to_radians(),
        "pitches visibly: {}°",
        min_pitch.to_degrees()
    );
    assert!(max_climb < 0.08, "climb rate up to {max_climb} m/s");
    // Some overshoot, then it settles at 2 m/s without sustained oscillation.
    let peak = speeds.iter().copied().fold(0.0, f64::max);
    assert!(peak > 2.0 && peak < 2.6, "peak {peak}");
    let tail = &speeds[speeds.len() - 600..];
    for v in tail {
        assert!((v - 2.0).abs() < 0.03, "not settled: {v}");
    }
    let crossings = tail
        .windows(2)
        .filter(|p| (p[0] - 2.0).signum() != (p[1] - 2.0).signum())
        .count();
    assert!(
        crossings <= 1,
        "oscillates around the target: {crossings} crossings"
    );
}

/// Attitude after 0.3 s of rotor speeds `delta` around hover (rotors 1 front-right,
/// 2 rear-right, 3 rear-left, 4 front-left; 1 and 3 turn counter-clockwise from above).
fn attitude_after(delta: [f64; 4]) -> [f64; 3] {
    attitude_after_in(RobotCatalog::embedded(), delta)
}

fn attitude_after_in(catalog: RobotCatalog, delta: [f64; 4]) -> [f64; 3] {
    let hover = catalog.get(QUAD).expect("class").quadrotor.hover_speed();
    let mut w = world_with(catalog, None, 0);
    let c = spawn(&mut w, [0.0, 0.0, -2.5], 0.0);
    let w4 = delta.map(|d| hover + d);
    command(
        &mut w,
        c,
        &format!("QUAD {{Rotors {},{},{},{}}}", w4[0], w4[1], w4[2], w4[3]),
    );
    run(&mut w, 0.3);
    state(&w, c).2
}

#[test]
fn rotor_speed_differences_roll_pitch_and_yaw_as_in_x_mode() {
    let small = 1e-3;
    // Left rotors faster than the right ones: roll to the right (right side down).
    let r = attitude_after([-10.0, -10.0, 10.0, 10.0]);
    assert!(
        r[0] > 0.1 && r[1].abs() < small && r[2].abs() < small,
        "{r:?}"
    );
    // Front rotors faster than the rear ones: nose up.
    let r = attitude_after([10.0, -10.0, -10.0, 10.0]);
    assert!(
        r[1] > 0.1 && r[0].abs() < small && r[2].abs() < small,
        "{r:?}"
    );
    // The counter-clockwise pair faster: its drag torque turns the body clockwise (yaw +).
    let r = attitude_after([60.0, -60.0, 60.0, -60.0]);
    assert!(
        r[2] > 0.02 && r[0].abs() < small && r[1].abs() < small,
        "{r:?}"
    );
    let r = attitude_after([-60.0, 60.0, -60.0, 60.0]);
    assert!(r[2] < -0.02, "{r:?}");
}

#[test]
fn plus_mode_rotors_sit_on_the_axes() {
    let plus = || {
        let mut catalog = RobotCatalog::embedded();
        catalog
            .get_mut(QUAD)
            .expect("class")
            .quadrotor
            .configuration = super::quadrotor::Configuration::Plus;
        catalog
    };
    let small = 1e-3;
    // 1 front, 2 right, 3 rear, 4 left: the front faster than the rear lifts the nose only.
    let r = attitude_after_in(plus(), [15.0, 0.0, -15.0, 0.0]);
    assert!(
        r[1] > 0.1 && r[0].abs() < small && r[2].abs() < small,
        "{r:?}"
    );
    // The left faster than the right rolls right only.
    let r = attitude_after_in(plus(), [0.0, -15.0, 0.0, 15.0]);
    assert!(
        r[0] > 0.1 && r[1].abs() < small && r[2].abs() < small,
        "{r:?}"
    );
}

#[test]
fn wind_drifts_an_uncommanded_quadrotor_downwind() {
    let wind = WindConfig {
        velocity: [0.0, 3.0, 0.0], // blowing east
        ..WindConfig::default()
    };
    let mut w = world_with(RobotCatalog::embedded(), Some(wind), 0);
    let c = spawn(&mut w, [0.0, -6.0, -2.0], 0.0);
    run(&mut w, 4.0);
    let (p, v, _) = state(&w, c);
    assert!(p[1] > -6.0 + 1.0 && v[1] > 0.5, "drifted east: {p:?} {v:?}");
    assert!(p[0].abs() < 0.05 && (p[2] + 2.0).abs() < 0.05, "{p:?}");
}

#[test]
fn holds_ground_speed_against_the_wind_leaning_into_it() {
    let wind = WindConfig {
        velocity: [0.0, 3.0, 0.0],
        ..WindConfig::default()
    };
    let catalog = RobotCatalog::embedded();
    let q = catalog.get(QUAD).expect("class").quadrotor.clone();
    let mut w = world_with(catalog, Some(wind), 0);
    let c = spawn(&mut w, [-8.0, 0.0, -2.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(1.0),
            ..Drive::default()
        },
    );
    run(&mut w, 12.0);
    let (p, v, r) = state(&w, c);
    assert!(
        (v[0] - 1.0).abs() < 0.02 && v[1].abs() < 0.02,
        "ground velocity {v:?}"
    );
    assert!(p[0] < 9.0, "still in the room: {p:?}");
    // Leaning west (left side down) into the east wind, by the tilt whose thrust balances
    // the drag: tan(tilt) = |D| / (m g).
    let air = [v[0], v[1] - 3.0, v[2]]; // ground velocity minus the wind
    let speed = (air[0] * air[0] + air[1] * air[1]).sqrt();
    let drag = (q.drag_linear + q.drag_quadratic * speed) * speed;
    let tilt = (r[0].cos() * r[1].cos()).acos();
    let expected = (drag / (q.mass * GRAVITY)).atan();
    assert!(r[0] < 0.0, "leans upwind: roll {}", r[0]);
    assert!(
        (tilt - expected).abs() < 0.05 * expected,
        "tilt {:.2}°, drag balance needs {:.2}°",
        tilt.to_degrees(),
        expected.to_degrees()
    );
}

/// Flies north into the room's north wall (inner face x = 10) at `speed`.
fn fly_into_wall(speed: f64) -> (World, ClientId, Vec<(ClientId, ServerMessage)>) {
    let mut w = world();
    let c = spawn(&mut w, [7.0, 0.0, -2.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(speed),
            ..Drive::default()
        },
    );
    let out = run(&mut w, 2.0 + 4.0 / speed);
    (w, c, out)
}

#[test]
fn three_metres_per_second_into_a_wall_is_a_crash() {
    let (mut w, c, out) = fly_into_wall(3.0);
    assert!(w.crashed(c));
    let crash = touch(&out, "Crash");
    assert!(crash.first() == Some(&false) && crash.last() == Some(&true));
    // It fell to the floor (z = 0, the body 0.1 m high) and stays there, commands ignored.
    run(&mut w, 3.0);
    let (p, v, r) = state(&w, c);
    assert!(
        p[2] > -0.15 && p[0] < 9.56,
        "on the floor by the wall: {p:?}"
    );
    assert!(
        r[0].abs() < 0.02 && r[1].abs() < 0.02,
        "at rest on its gear: {r:?}"
    );
    drive(
        &mut w,
        c,
        Drive {
            altitude_velocity: Some(1.0),
            ..Drive::default()
        },
    );
    let out = run(&mut w, 2.0);
    let (q, _, _) = state(&w, c);
    assert!(
        (q[2] - p[2]).abs() < 1e-3 && v[0].abs() < 1e-3,
        "{p:?} → {q:?}"
    );
    assert!(touch(&out, "Crash").iter().all(|&t| t));
}

#[test]
fn a_slow_touch_is_no_crash() {
    let (w, c, out) = fly_into_wall(0.2);
    assert!(!w.crashed(c));
    let (p, _, _) = state(&w, c);
    assert!(
        p[0] > 9.5 && (p[2] + 2.0).abs() < 0.05,
        "at the wall, flying: {p:?}"
    );
    assert!(touch(&out, "Crash").iter().all(|&t| !t));
}

#[test]
fn kinematic_robot_can_count_contact_as_a_crash() {
    let mut catalog = RobotCatalog::embedded();
    let sts = catalog.get_mut("USARBot.stsAirRobot").expect("sts");
    sts.crash.on_contact = true;
    let mut w = world_with(catalog, None, 0);
    let c = w.connect();
    w.command(
        c,
        Command::Init(Init {
            class_name: "USARBot.stsAirRobot".into(),
            location: Some([9.0, 0.0, -2.0].into()),
            ..Init::default()
        }),
    );
    run(&mut w, 0.5);
    assert!(!w.crashed(c));
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(1.0),
            ..Drive::default()
        },
    );
    run(&mut w, 2.0);
    assert!(w.crashed(c));
    run(&mut w, 2.0);
    let (p, _) = w.robot(c).unwrap().pose();
    assert!(p[2] > -0.15, "fell to the floor: {p:?}");
}

#[test]
fn sonars_and_laser_are_cast_from_the_tilted_body() {
    // Hold a 30° nose-down attitude for a moment: the forward sonar (0.4 m ahead of the
    // centre, 2 m above the floor) then sees the floor ahead instead of the far wall.
    let mut w = world();
    let c = spawn(&mut w, [0.0, 0.0, -2.0], 0.0);
    let weight = 1.3 * GRAVITY;
    let pitch: f64 = -0.5;
    command(
        &mut w,
        c,
        &format!(
            "QUAD {{Attitude 0,{pitch},0}} {{Thrust {}}}",
            weight / pitch.cos()
        ),
    );
    let out = run(&mut w, 1.0);
    let (p, _, r) = state(&w, c);
    assert!((r[1] - pitch).abs() < 0.02, "pitch {r:?}");
    let last_sonar = out
        .iter()
        .rev()
        .find_map(|(_, m)| match m {
            ServerMessage::Sen(sen) => match &sen.data {
                SenData::Sonar { readings, .. } if readings[0].name == "Sonar0" => {
                    Some(readings[0].range)
                }
                _ => None,
            },
            _ => None,
        })
        .expect("sonar");
    // The sonar sits 0.4 m ahead along the tilted body axis; its beam meets the floor at
    // height / sin(pitch) (a level sonar would read 5 m: the north wall is 10 m away).
    let height = -p[2] - 0.4 * (-pitch).sin();
    let expected = height / (-pitch).sin();
    assert!(
        (last_sonar - expected).abs() < 0.15,
        "sonar {last_sonar}, floor at {expected}"
    );
}

#[test]
fn quad_on_a_kinematic_robot_and_bad_quad_lines_are_ignored() {
    let mut w = world();
    let c = w.connect();
    w.command(
        c,
        Command::Init(Init {
            class_name: "USARBot.stsAirRobot".into(),
            location: Some([0.0, 0.0, -2.0].into()),
            ..Init::default()
        }),
    );
    command(&mut w, c, "QUAD {Rotors 0,0,0,0}");
    run(&mut w, 1.0);
    assert_eq!(w.robot(c).unwrap().pose().0, [0.0, 0.0, -2.0]);
    let q = spawn(&mut w, [3.0, 3.0, -2.0], 0.0);
    command(&mut w, q, "QUAD {Rotors 0,0,NaN,0}");
    command(&mut w, q, "QUAD {Thrust 3}");
    run(&mut w, 1.0);
    let (p, _, _) = state(&w, q);
    assert!((p[2] + 2.0).abs() < 0.01, "still hovering: {p:?}");
}

#[test]
fn absurd_commands_keep_every_number_finite() {
    let mut w = world();
    let c = spawn(&mut w, [0.0, 0.0, -2.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(1e300),
            lateral_velocity: Some(-1e300),
            altitude_velocity: Some(1e300),
            rotational_velocity: Some(1e300),
            ..Drive::default()
        },
    );
    let mut out = run(&mut w, 2.0);
    command(
        &mut w,
        c,
        "QUAD {Attitude 1e300,-1e300,1e300} {Thrust 1e300}",
    );
    out.extend(run(&mut w, 1.0));
    command(&mut w, c, "QUAD {Rotors 1e300,-1e300,0,1e300}");
    out.extend(run(&mut w, 1.0));
    let (p, v, r) = state(&w, c);
    assert!(
        p.iter().chain(&v).chain(&r).all(|x| x.is_finite()),
        "{p:?} {v:?} {r:?}"
    );
    let text = printed(&out);
    assert!(
        !text.contains("NaN") && !text.contains("inf"),
        "non-finite output"
    );
}

#[test]
fn parameters_the_integration_cannot_follow_stop_the_robot_instead_of_nan() {
    // Within the checked bounds but far from any vehicle: 10 g with 1000 N·s/m of drag.
    let mut catalog = RobotCatalog::embedded();
    let q = &mut catalog.get_mut(QUAD).expect("class").quadrotor;
    q.mass = 0.01;
    q.thrust_coefficient = 1e-6;
    q.drag_linear = 1000.0;
    q.check().expect("accepted by the catalog checks");
    // High above the city: nothing near to stop it.
    let mut w = World::new(
        Map::lookup("city").expect("city"),
        catalog,
        SimConfig::default(),
    );
    let c = spawn(&mut w, [0.0, 0.0, -2000.0], 0.0);
    drive(
        &mut w,
        c,
        Drive {
            linear_velocity: Some(2.0),
            ..Drive::default()
        },
    );
    let out = run(&mut w, 1.0);
    let (p, v, r) = state(&w, c);
    assert!(
        p.iter().chain(&v).chain(&r).all(|x| x.is_finite()),
        "{p:?} {v:?} {r:?}"
    );
    assert!(!printed(&out).contains("NaN"));
    assert!(w.crashed(c), "stopped and reported");
}

fn printed(out: &[(ClientId, ServerMessage)]) -> String {
    out.iter().map(|(c, m)| format!("{c:?} {m}\n")).collect()
}

fn gusty_flight(seed: u64) -> String {
    let wind = WindConfig {
        velocity: [1.0, 2.0, 0.0],
        gusts: 1.0,
        gust_length: 15.0,
    };
    let mut w = world_with(RobotCatalog::embedded(), Some(wind), seed);
    let a = spawn(&mut w, [-5.0, -5.0, -2.0], 0.0);
    let b = spawn(&mut w, [5.0, 5.0, -2.0], 3.0);
    let mut out = run(&mut w, 1.0);
    drive(
        &mut w,
        a,
        Drive {
            linear_velocity: Some(1.5),
            rotational_velocity: Some(20.0),
            ..Drive::default()
        },
    );
    drive(
        &mut w,
        b,
        Drive {
            lateral_velocity: Some(-1.0),
            altitude_velocity: Some(0.5),
            ..Drive::default()
        },
    );
    out.extend(run(&mut w, 4.0));
    printed(&out)
}

#[test]
fn gusts_are_seeded_and_repeat_bit_for_bit() {
    let first = gusty_flight(5);
    assert_eq!(first, gusty_flight(5));
    assert_ne!(first, gusty_flight(6), "the seed drives the gusts");
}

/// A map of one square floor `size` metres wide whose top is z = 0.
fn floor_map(size: f64) -> Map {
    let text = format!(
        "level = \"Floor\"\n[[start]]\ntag = \"S\"\nlocation = [0.0, 0.0, -3.0]\n\
         rotation = [0.0, 0.0, 0.0]\n[[box]]\ncenter = [0.0, 0.0, 0.5]\nsize = [{size}, {size}, 1.0]\n"
    );
    Map::from_toml(&text, std::path::Path::new("floor.toml")).expect("floor map")
}

#[test]
fn a_descent_rests_on_floors_of_ten_metres_to_a_kilometre_without_sinking() {
    // The body is 0.2 m high and stops a 1 cm skin above what it meets: its centre rests at
    // z = -0.11 over a floor whose top is z = 0, whatever the floor's size.
    for size in [10.0, 100.0, 200.0, 400.0, 1000.0] {
        let mut w = World::new(
            floor_map(size),
            RobotCatalog::embedded(),
            SimConfig::default(),
        );
        let c = spawn(&mut w, [0.0, 0.0, -3.0], 0.0);
        command(&mut w, c, "DRIVE {AltitudeVelocity -1.2}");
        run(&mut w, 5.0);
        let (p, _, _) = state(&w, c);
        assert!(
            (p[2] + 0.11).abs() < 0.002,
            "floor {size} m: rests at z {:.4}, expected -0.110",
            p[2]
        );
    }
}

// ---- contact: the quadrotor alone over a floor (top z = 0), without drag ----

/// A quadrotor on a floor, stepped directly (its velocity can be set).
struct Rig {
    scene: scene::Scene,
    body: rapier3d::prelude::ColliderHandle,
    shape: scene::BodyShape,
    quad: quadrotor::Quadrotor,
    p: [f64; 3],
    v: [f64; 3],
    r: [f64; 3],
}

const DT: f64 = 0.005;
/// The body's centre resting on the floor: half its height plus the 1 cm skin.
const REST_Z: f64 = -0.11;

fn rig(config: quadrotor::QuadrotorConfig, p: [f64; 3], r: [f64; 3]) -> Rig {
    let mut scene = scene::Scene::new();
    scene.insert(
        rapier3d::prelude::ColliderBuilder::cuboid(50.0, 50.0, 0.5)
            .position(rapier3d::math::Pose::translation(0.0, 0.0, 0.5)),
    );
    let shape = scene::BodyShape {
        radius: 0.45,
        half_height: 0.1,
    };
    let body = scene.insert_body(shape, p);
    let limits = quadrotor::Limits {
        max_tilt: 0.44,
        max_climb: 2.0,
        crash_speed: 1.0,
        crash_tilt: 1.05,
        battery: true,
    };
    let quad = quadrotor::Quadrotor::new(config, limits, r, WindConfig::default(), 0, 1, DT);
    Rig {
        scene,
        body,
        shape,
        quad,
        p,
        v: [0.0; 3],
        r,
    }
}

impl Rig {
    fn step(&mut self) -> Option<dynamics::Crash> {
        use dynamics::Dynamics;
        self.quad.step(dynamics::Flight {
            scene: &mut self.scene,
            body: self.body,
            shape: self.shape,
            position: &mut self.p,
            velocity: &mut self.v,
            rotation: &mut self.r,
            dt: DT,
        })
    }

    fn run(&mut self, seconds: f64) {
        for _ in 0..(seconds / DT).round() as u64 {
            self.step();
        }
    }

    /// Motors off (as after a crash).
    fn off(&mut self) {
        dynamics::Dynamics::crash(&mut self.quad);
    }
}

fn dragless() -> quadrotor::QuadrotorConfig {
    quadrotor::QuadrotorConfig {
        drag_linear: 0.0,
        drag_quadratic: 0.0,
        ..quadrotor::QuadrotorConfig::default()
    }
}

#[test]
fn a_body_sliding_on_the_floor_stops_after_v_squared_over_two_mu_g() {
    let config = dragless();
    let mu = config.friction;
    let mut rig = rig(config, [0.0, 0.0, REST_Z], [0.0; 3]);
    rig.off();
    rig.run(0.1); // settle on the floor
    rig.v = [2.0, 0.0, 0.0];
    let x0 = rig.p[0];
    let mut stopped = None;
    for i in 0..400 {
        rig.step();
        if stopped.is_none() && rig.v[0].abs() < 1e-9 {
            stopped = Some(f64::from(i + 1) * DT);
        }
    }
    let distance = rig.p[0] - x0;
    let expected = 2.0f64.powi(2) / (2.0 * mu * GRAVITY);
    assert!(
        (distance / expected - 1.0).abs() < 0.03,
        "slid {distance:.3} m, Coulomb friction says {expected:.3} m"
    );
    let t = stopped.expect("stopped");
    let expected = 2.0 / (mu * GRAVITY);
    assert!(
        (t / expected - 1.0).abs() < 0.03,
        "stopped after {t:.3} s, expected {expected:.3} s"
    );
    let at_rest = rig.p;
    rig.run(5.0);
    assert_eq!(rig.p, at_rest, "stands still");
    assert!(
        (rig.p[2] - REST_Z).abs() < 1e-3,
        "on the floor: {:?}",
        rig.p
    );
}

#[test]
fn a_dropped_body_bounces_to_e_squared_of_its_height() {
    let config = dragless();
    let e = config.restitution;
    let drop = 2.0;
    let mut rig = rig(config, [0.0, 0.0, REST_Z - drop], [0.0; 3]);
    rig.off();
    // Fall, bounce, and record the highest point after the bounce.
    let mut bounced = false;
    let mut apex = f64::INFINITY;
    for _ in 0..(1.2 / DT) as u64 {
        rig.step();
        bounced |= rig.v[2] < 0.0;
        if bounced {
            apex = apex.min(rig.p[2]);
        }
    }
    assert!(bounced, "bounced");
    let height = REST_Z - apex;
    let expected = e * e * drop;
    assert!(
        (height / expected - 1.0).abs() < 0.05,
        "bounced {height:.3} m up, e² h = {expected:.3} m"
    );
}

#[test]
fn a_body_dropped_tilted_rights_itself_on_its_gear_and_stands_still() {
    let mut rig = rig(dragless(), [0.0, 0.0, -0.6], [0.35, -0.2, 1.0]);
    rig.off();
    rig.run(3.0);
    let (p, r) = (rig.p, rig.r);
    assert!(
        r[0].abs() < 0.01 && r[1].abs() < 0.01,
        "level on its gear: roll {:.3}°, pitch {:.3}°",
        r[0].to_degrees(),
        r[1].to_degrees()
    );
    rig.run(5.0);
    let moved = (0..3).map(|i| (rig.p[i] - p[i]).abs()).fold(0.0, f64::max);
    assert!(moved < 1e-4, "stands still: moved {moved} m");
    assert!((rig.r[2] - r[2]).abs() < 1e-4, "no yaw creep");
}

#[test]
fn the_attitude_keeps_turning_after_a_crash() {
    // A crash stops the motors, not the body's spin: the rates carry on in the fall.
    let mut rig = rig(dragless(), [0.0, 0.0, -20.0], [0.0; 3]);
    command_rotors(&mut rig, [367.0, 318.0, 318.0, 367.0]);
    rig.run(0.1);
    rig.off();
    rig.run(0.3); // the rotors spin down
    let rates = dynamics::Dynamics::imu(&rig.quad).body_rates;
    assert!(rates[1].abs() > 0.5, "pitching: {rates:?}");
    let before = dynamics::Dynamics::attitude(&rig.quad);
    rig.run(0.2);
    let after = dynamics::Dynamics::attitude(&rig.quad);
    // The angle of the rotation between the two attitudes.
    let m = dynamics::mat_mul(&dynamics::transpose(&before), &after);
    let turned = ((m[0][0] + m[1][1] + m[2][2] - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos();
    let expected = dynamics::norm(rates) * 0.2;
    assert!(
        (turned / expected - 1.0).abs() < 0.05,
        "turned {turned:.3} rad in 0.2 s, rates {rates:?} give {expected:.3}"
    );
}

/// QUAD {Rates}: the rate loop alone follows the commanded body rates (IMU truth), the
/// attitude is the integral of them (no attitude loop pulls it back to level), and zero rates
/// hold whatever attitude the vehicle has.
#[test]
fn body_rates_and_thrust_fly_the_rate_loop() {
    let mut w = world_with(exact_imu(RobotCatalog::embedded()), None, 0);
    let c = spawn(&mut w, [0.0, 0.0, -3.0], 0.0);
    let weight = 1.3 * GRAVITY;
    // Yaw at 0.5 rad/s, level, thrust = weight: the heading turns at the commanded rate.
    command(
        &mut w,
        c,
        &format!("QUAD {{Rates 0,0,0.5}} {{Thrust {weight}}}"),
    );
    run(&mut w, 0.5);
    let (_, _, r0) = state(&w, c);
    let out = run(&mut w, 1.0);
    let (_, _, r1) = state(&w, c);
    let yaw_rate = imu_lines(&out).last().expect("IMU").1;
    assert!((yaw_rate.z - 0.5).abs() < 0.02, "yaw rate {yaw_rate:?}");
    assert!(
        (r1[2] - r0[2] - 0.5).abs() < 0.02,
        "turned {} rad in 1 s",
        r1[2] - r0[2]
    );
    assert!(r1[0].abs() < 0.02 && r1[1].abs() < 0.02, "level: {r1:?}");
    // Roll right at 0.4 rad/s for 0.5 s, then zero rates: the roll (≈ 0.2 rad less the
    // rise time) stays, where an attitude command of zero would level the vehicle.
    command(
        &mut w,
        c,
        &format!("QUAD {{Rates 0.4,0,0}} {{Thrust {weight}}}"),
    );
    let out = run(&mut w, 0.5);
    let roll_rate = imu_lines(&out).last().expect("IMU").1;
    assert!((roll_rate.x - 0.4).abs() < 0.02, "roll rate {roll_rate:?}");
    command(
        &mut w,
        c,
        &format!("QUAD {{Rates 0,0,0}} {{Thrust {weight}}}"),
    );
    run(&mut w, 0.2);
    let (_, _, a) = state(&w, c);
    run(&mut w, 0.3);
    let (_, v, b) = state(&w, c);
    assert!(a[0] > 0.15 && a[0] < 0.21, "rolled: {a:?}");
    assert!(
        (b[0] - a[0]).abs() < 0.01,
        "the roll holds: {a:?} then {b:?}"
    );
    // Rolled right, the thrust pushes it right (+y).
    assert!(v[1] > 0.3, "sliding right: {v:?}");
}

fn command_rotors(rig: &mut Rig, w: [f64; 4]) {
    dynamics::Dynamics::low_level(&mut rig.quad, dynamics::LowLevel::Rotors(w));
}

#[test]
fn a_landed_quadrotor_stands_still_under_zero_command() {
    for zero in [
        "DRIVE {AltitudeVelocity 0} {LinearVelocity 0} {LateralVelocity 0}",
        "QUAD {Rotors 0,0,0,0}",
    ] {
        let mut w = world();
        let c = spawn(&mut w, [0.0, 0.0, -1.0], 0.0);
        command(&mut w, c, "DRIVE {AltitudeVelocity -0.5}");
        run(&mut w, 3.0);
        command(&mut w, c, zero);
        run(&mut w, 3.0);
        let (p, _, r) = state(&w, c);
        // Holding the altitude, ground effect may lift it a few centimetres; idle, it sits.
        assert!((p[2] + 0.11).abs() < 0.05, "{zero}: landed: {p:?}");
        run(&mut w, 10.0);
        let (q, v, s) = state(&w, c);
        // No skating: the horizontal position stays within millimetres (vertically the
        // altitude hold settles against the ground effect, within the 5 cm above).
        let moved = (q[0] - p[0]).hypot(q[1] - p[1]);
        assert!(
            moved < 0.005,
            "{zero}: moved {moved} m: {p:?} → {q:?}, v {v:?}"
        );
        assert!((q[2] + 0.11).abs() < 0.05, "{zero}: on the ground: {q:?}");
        assert!(
            s[0].abs() < 0.02 && s[1].abs() < 0.02,
            "{zero}: level: {s:?} (was {r:?})"
        );
        assert!(!w.crashed(c));
    }
}

// ---- energy ----

/// The embedded catalog with Battery and Rotors parts on the stsQuadrotor and its battery
/// charged to `charge`.
fn with_gauges(charge: f64) -> RobotCatalog {
    let mut catalog = RobotCatalog::embedded();
    let q = catalog.get_mut(QUAD).expect("stsQuadrotor");
    q.quadrotor.battery.charge = charge;
    for kind in ["Battery", "Rotors"] {
        q.parts.push(part::PartConfig {
            kind: kind.into(),
            name: kind.into(),
            position: [0.0; 3],
            direction: [0.0; 3],
            interval: None,
            noise: 0.0,
            settings: toml::Table::new(),
        });
    }
    catalog
}

/// The last `{Type kind}` line's value of `key`.
fn last_value(out: &[(ClientId, ServerMessage)], kind: &str, key: &str) -> Vec<f64> {
    let line = out
        .iter()
        .rev()
        .find_map(|(_, m)| match m {
            ServerMessage::Sen(sen) => match &sen.data {
                SenData::Other { kind: k, groups } if k == kind => groups
                    .iter()
                    .flat_map(|g| &g.pairs)
                    .find(|p| p.key == key)
                    .map(|p| p.value.clone()),
                _ => None,
            },
            _ => None,
        })
        .expect("a reading");
    line.split(',')
        .map(|v| v.parse().expect("number"))
        .collect()
}

fn battery_status(out: &[(ClientId, ServerMessage)]) -> i64 {
    out.iter()
        .rev()
        .find_map(|(_, m)| match m {
            ServerMessage::Sta(sta) => Some(sta.battery),
            _ => None,
        })
        .expect("STA")
}

/// Issue #54: the battery is drained by the mechanical power the rotors deliver (each
/// rotor's drag torque km·ω², the torque that yaws the body, times its speed) over the
/// motors' efficiency, plus the avionics: one energy model. (It was charged momentum
/// theory's power while the torques implied 1.9 times that.)
#[test]
fn hover_drains_the_rotors_mechanical_power_over_the_efficiency() {
    let catalog = with_gauges(1.0);
    let q = catalog.get(QUAD).expect("class").quadrotor.clone();
    let mut w = world_with(catalog, None, 0);
    let c = spawn(&mut w, [0.0, 0.0, -3.0], 0.0);
    let out = run(&mut w, 5.0);
    let (v, i) = (
        last_value(&out, "Battery", "Voltage")[0],
        last_value(&out, "Battery", "Current")[0],
    );
    let speeds = last_value(&out, "Rotors", "Speeds");
    assert_eq!(speeds.len(), 4, "{speeds:?}");
    let mechanical: f64 = speeds
        .iter()
        .map(|w| q.torque_coefficient * w.powi(3))
        .sum();
    let electrical = (mechanical / q.battery.motor_efficiency) + q.battery.avionics_power;
    assert!(
        (v * i / electrical - 1.0).abs() < 0.02,
        "drawn {:.2} W, rotors' mechanical power {mechanical:.2} W over η {} plus {} W: {electrical:.2} W",
        v * i,
        q.battery.motor_efficiency,
        q.battery.avionics_power
    );
    // The propeller's figure of merit follows: momentum theory's ideal power over the
    // mechanical one, about 0.63 for the documented 12x4.5" propeller.
    let area = std::f64::consts::PI * q.rotor_radius.powi(2);
    let t = q.mass * GRAVITY / 4.0;
    let ideal = 4.0 * t.powf(1.5) / (2.0 * 1.225 * area).sqrt();
    let merit = ideal / mechanical;
    assert!((0.6..0.66).contains(&merit), "figure of merit {merit:.3}");
    // The STA's battery is the time left above the reserve at this draw.
    let charge = last_value(&out, "Battery", "Charge")[0];
    let left = (charge - q.battery.reserve) * q.battery.capacity * 3600.0 / i;
    let sta = battery_status(&out) as f64;
    assert!(
        (sta / left - 1.0).abs() < 0.02,
        "STA {sta} s, expected {left:.0} s"
    );
    assert!(
        (1200.0..1800.0).contains(&sta),
        "about 25 minutes of hover: {sta}"
    );
    // Climbing draws more: less time left.
    command(&mut w, c, "DRIVE {AltitudeVelocity 2}");
    let out = run(&mut w, 1.0);
    assert!(
        last_value(&out, "Battery", "Current")[0] > i * 1.1,
        "climbing draws more: {} A vs {i} A",
        last_value(&out, "Battery", "Current")[0]
    );
    assert!((battery_status(&out) as f64) < sta - 50.0);
}

#[test]
fn a_sagging_battery_lowers_the_rotors_top_speed_with_its_voltage() {
    for charge in [1.0, 0.3] {
        let mut w = world_with(with_gauges(charge), None, 0);
        let c = spawn(&mut w, [0.0, 0.0, -30.0], 0.0);
        let max = quadrotor::QuadrotorConfig::default().rotor_speed_max;
        command(
            &mut w,
            c,
            &format!("QUAD {{Rotors {max},{max},{max},{max}}}"),
        );
        let out = run(&mut w, 0.5);
        let v = last_value(&out, "Battery", "Voltage")[0];
        let speeds = last_value(&out, "Rotors", "Speeds");
        let top = max * v / 12.6;
        for s in speeds {
            assert!(
                (s / top - 1.0).abs() < 0.01,
                "charge {charge}: rotor at {s} rad/s, K_v·V gives {top:.1}"
            );
        }
        if charge < 1.0 {
            assert!(top < 900.0, "sagged: {v} V");
        }
    }
}

#[test]
fn a_battery_at_its_reserve_lands_the_quadrotor_and_reads_empty() {
    // 0.2 % above the 5 % reserve: about 3 s of hover.
    let mut w = world_with(with_gauges(0.052), None, 0);
    let c = spawn(&mut w, [0.0, 0.0, -3.0], 0.0);
    command(&mut w, c, "DRIVE {LinearVelocity 1}");
    let out = run(&mut w, 4.0);
    assert_eq!(battery_status(&out), 0, "USARSim's empty state");
    // Commands are ignored; the autopilot descends and lands.
    command(&mut w, c, "DRIVE {AltitudeVelocity 2}");
    run(&mut w, 8.0);
    let (p, v, r) = state(&w, c);
    assert!((p[2] + 0.11).abs() < 0.01, "landed: {p:?}");
    assert!(
        dynamics::norm(v) < 1e-3 && r[0].abs() < 0.02,
        "at rest: {v:?} {r:?}"
    );
    assert!(!w.crashed(c), "a landing, not a crash");
}

/// Issue #54: a crashed vehicle, its motors stopped, still powers its avionics, which
/// still report: it drew 0 W once its rotors had spun down.
#[test]
fn crashed_its_avionics_still_draw_their_power() {
    let catalog = with_gauges(1.0);
    let q = catalog.get(QUAD).expect("class").quadrotor.clone();
    let mut w = world_with(catalog, None, 0);
    let c = spawn(&mut w, [0.0, 0.0, -3.0], 0.0);
    // The rotors stop: it falls 3 m onto the floor.
    command(&mut w, c, "QUAD {Rotors 0,0,0,0}");
    run(&mut w, 3.0);
    assert!(w.crashed(c), "a fall from 3 m is a crash");
    let out = run(&mut w, 60.0);
    assert!(
        last_value(&out, "Rotors", "Speeds")
            .iter()
            .all(|s| *s < 1e-6),
        "the rotors stand still"
    );
    let (v, i) = (
        last_value(&out, "Battery", "Voltage")[0],
        last_value(&out, "Battery", "Current")[0],
    );
    let power = v * i;
    assert!(
        (power / q.battery.avionics_power - 1.0).abs() < 0.05,
        "{power:.2} W drawn, the avionics take {} W",
        q.battery.avionics_power
    );
}

// ---- rotor aerodynamics ----

#[test]
fn ground_effect_matches_cheeseman_bennett_at_half_one_and_two_radii() {
    // Rotors of 0.3 m radius held at hover speed above the floor; the thrust is read from the
    // body's acceleration in the first tick: T = m(g − a).
    let radius = 0.3;
    let thrust_at = |height: f64, ground_effect: bool| {
        let config = quadrotor::QuadrotorConfig {
            rotor_radius: radius,
            ground_effect,
            ..dragless()
        };
        let hover = config.hover_speed();
        let mass = config.mass;
        let mut rig = rig(config, [0.0, 0.0, -height], [0.0; 3]);
        command_rotors(&mut rig, [hover; 4]);
        rig.step();
        mass * (GRAVITY - rig.v[2] / DT)
    };
    for ratio in [0.5, 1.0, 2.0] {
        let h = ratio * radius;
        let ratio_measured = thrust_at(h, true) / thrust_at(h, false);
        let k = 1.0 / (4.0 * ratio);
        let expected = 1.0 / (1.0 - k * k);
        assert!(
            (ratio_measured - expected).abs() < 1e-3,
            "h/R {ratio}: thrust × {ratio_measured:.4}, Cheeseman–Bennett {expected:.4}"
        );
    }
    // Far from the ground, none.
    assert!((thrust_at(5.0, true) / thrust_at(5.0, false) - 1.0).abs() < 1e-12);
}

#[test]
fn rotors_spin_up_and_down_with_their_own_time_constants() {
    let config = quadrotor::QuadrotorConfig {
        motor_time_constant: 0.02,
        motor_time_constant_down: 0.08,
        ..dragless()
    };
    let mut rig = rig(config, [0.0, 0.0, -20.0], [0.0; 3]);
    let speed = |rig: &Rig| dynamics::Dynamics::rotor_speeds(&rig.quad).expect("rotors")[0];
    command_rotors(&mut rig, [200.0; 4]);
    rig.run(1.0);
    // A step 200 → 400: 63 % of the way after τ_up; then back: 63 % after τ_down.
    for (target, tau) in [(400.0, 0.02), (200.0, 0.08)] {
        let start = speed(&rig);
        command_rotors(&mut rig, [target; 4]);
        rig.run(tau);
        let done = (speed(&rig) - start) / (target - start);
        assert!(
            (done - (1.0 - (-1.0f64).exp())).abs() < 0.01,
            "after τ = {tau} s: {done:.3} of the step"
        );
        rig.run(1.0);
    }
}

#[test]
fn a_climb_demand_at_the_thrust_limit_leaves_the_forward_motion_its_tilt() {
    // A vehicle with little thrust in reserve (1.25 × its weight) asked to climb and fly
    // forward at once: the forward speed is reached, the climb gets what is left.
    let mut catalog = without_drag();
    let q = catalog.get_mut(QUAD).expect("class");
    q.quadrotor.rotor_speed_max = q.quadrotor.hover_speed() * 1.25f64.sqrt();
    q.battery = None;
    let mut w = world_with(catalog, None, 0);
    let c = spawn(&mut w, [-8.0, 0.0, -1.0], 0.0);
    command(&mut w, c, "DRIVE {LinearVelocity 2} {AltitudeVelocity 2}");
    run(&mut w, 3.0);
    let (_, v, _) = state(&w, c);
    assert!(v[0] > 1.8, "forward speed {:.2} m/s of 2", v[0]);
    assert!(v[2] < -0.3, "still climbing: {:.2} m/s", -v[2]);
}

// ---- parameters ----

/// Inertia (x, y, z) of a solid box of `mass` and sides `size` centred at `at`.
fn box_inertia(mass: f64, size: [f64; 3], at: [f64; 3]) -> [f64; 3] {
    let [a, b, c] = size.map(|s| s * s / 12.0);
    let [x, y, z] = at.map(|v| v * v);
    [
        mass * (b + c + y + z),
        mass * (a + c + x + z),
        mass * (a + b + x + y),
    ]
}

#[test]
fn the_default_inertia_is_that_of_the_documented_body() {
    // docs/robots.md, "Where the quadrotor defaults come from": an AR-100B-sized body of
    // 1.3 kg in x configuration (arms at 45°, 0.3 m), z down.
    let d = 0.3 * std::f64::consts::FRAC_1_SQRT_2;
    let mut total = [0.0; 3];
    let mut mass = 0.0;
    let mut add = |m: f64, i: [f64; 3]| {
        mass += m;
        for k in 0..3 {
            total[k] += i[k];
        }
    };
    for (sx, sy) in [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)] {
        // Motor and propeller, 75 g, a point at the arm's end.
        add(0.075, box_inertia(0.075, [0.0; 3], [sx * d, sy * d, 0.0]));
        // Arm, 35 g, a thin rod from the centre: ∫ r² dm = m·L²/3 per coordinate.
        add(
            0.035,
            [0.035 * d * d / 3.0, 0.035 * d * d / 3.0, 0.035 * 0.09 / 3.0],
        );
    }
    // Two skids of 50 g, 0.3 m long along x, at y = ±0.15 m, 0.12 m below the centre.
    for y in [0.15, -0.15] {
        add(0.05, box_inertia(0.05, [0.3, 0.0, 0.0], [0.0, y, 0.12]));
    }
    // The 3S 4 Ah battery, 330 g, 0.14 × 0.045 × 0.03 m, 5 cm below the centre.
    add(
        0.33,
        box_inertia(0.33, [0.14, 0.045, 0.03], [0.0, 0.0, 0.05]),
    );
    // The hub (frame plates, autopilot, ESCs, payload): the rest, a 0.2 × 0.2 × 0.06 m box.
    let hub = 1.3 - (4.0 * (0.075 + 0.035) + 2.0 * 0.05 + 0.33);
    add(hub, box_inertia(hub, [0.2, 0.2, 0.06], [0.0; 3]));
    let q = quadrotor::QuadrotorConfig::default();
    assert!((mass - q.mass).abs() < 1e-12);
    for (k, (body, default)) in total.iter().zip(q.inertia).enumerate() {
        assert!(
            (body - default).abs() < 5e-5,
            "axis {k}: body {body:.5} kg·m², default {default}"
        );
    }
    let catalog = RobotCatalog::embedded();
    assert_eq!(
        catalog.get(QUAD).expect("class").quadrotor.inertia,
        q.inertia
    );
}

#[test]
fn the_crazyflie_preset_hovers_at_gym_pybullet_drones_hover_rpm() {
    let mut w = world();
    let c = w.connect();
    w.command(
        c,
        Command::Init(Init {
            class_name: "USARBot.Crazyflie".into(),
            location: Some([0.0, 0.0, -1.0].into()),
            ..Init::default()
        }),
    );
    let out = run(&mut w, 10.0);
    let (p, _, _) = state(&w, c);
    assert!(
        (p[2] + 1.0).abs() < 0.02 && p[0].abs() < 0.02 && p[1].abs() < 0.02,
        "hovers: {p:?}"
    );
    // gym-pybullet-drones: HOVER_RPM = sqrt(m·g / (4·KF)) = 14468 rpm for the cf2x.
    let rpm = last_value(&out, "Rotors", "Speeds")[0] * 60.0 / std::f64::consts::TAU;
    assert!((rpm / 14468.0 - 1.0).abs() < 0.01, "hover at {rpm:.0} rpm");
    // One energy model (issue #54): the battery pays km·ω³ per rotor, and gym-pybullet-drones'
    // KM makes that 10 W of mechanical power in hover, about three times a real Crazyflie's
    // (docs/robots.md): under two minutes on its 250 mAh battery, not the real seven.
    let left = battery_status(&out) as f64;
    assert!((60.0..150.0).contains(&left), "{left} s left");
}

// ---- sensor errors ----

#[test]
fn the_imu_errors_are_seeded_per_part_and_average_out_to_the_truth() {
    // The stsQuadrotor's MPU-6000-class IMU hovering: readings scatter with the configured
    // noise around g (plus the turn-on bias), repeat for a seed, differ for another.
    let record = |seed: u64| {
        let mut w = world_with(RobotCatalog::embedded(), None, seed);
        spawn(&mut w, [0.0, 0.0, -2.0], 0.0);
        imu_lines(&run(&mut w, 20.0))
    };
    let (a, b, c) = (record(1), record(1), record(2));
    assert_eq!(a, b);
    assert_ne!(a, c);
    let z: Vec<f64> = a.iter().skip(20).map(|(acc, _)| acc.z).collect();
    let mean = z.iter().sum::<f64>() / z.len() as f64;
    let std = (z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / z.len() as f64).sqrt();
    // The turn-on bias: σ 0.16 m/s² (a third of the datasheet's ±50 mg).
    let bias = mean - GRAVITY;
    assert!(bias.abs() < 0.48 && bias.abs() > 0.0024, "mean {mean}");
    assert!(
        (std / 0.04 - 1.0).abs() < 0.3,
        "noise std {std}, configured 0.04"
    );
    // Quantised to the 16 g range's 0.0048 m/s² steps.
    assert!(
        z.iter()
            .all(|v| ((v / 0.0048).round() * 0.0048 - v).abs() < 1e-9)
    );
}

// ---- faults ----

#[test]
fn a_motor_failure_at_hover_yaw_spins_and_falls_as_the_torque_balance_predicts() {
    let q = quadrotor::QuadrotorConfig::default();
    let mut rig = rig(q.clone(), [0.0, 0.0, -40.0], [0.0; 3]);
    rig.run(1.0);
    // Rotor 1 (front-right, counter-clockwise) stops giving thrust and torque.
    let dead = dynamics::Fault::Motor {
        rotor: 0,
        thrust: 0.0,
    };
    assert!(dynamics::Dynamics::fault(&mut rig.quad, &dead));
    // The rotors' speeds are their true speeds: the dead one's spins down with the motor's
    // lag, and its drag torque with it.
    let spin = [1.0, -1.0, 1.0, -1.0];
    let yaw_torque = |w: [f64; 4]| -> f64 {
        (0..4)
            .map(|i| spin[i] * q.torque_coefficient * w[i] * w[i])
            .sum()
    };
    let state = |rig: &Rig| {
        (
            dynamics::Dynamics::imu(&rig.quad).body_rates,
            dynamics::Dynamics::rotor_speeds(&rig.quad).expect("rotors"),
        )
    };
    let (mut checked, mut worst) = (0, 0.0f64);
    for _ in 0..(1.5 / DT) as u64 {
        let (w0, s0) = state(&rig);
        rig.step();
        let (w1, s1) = state(&rig);
        // Euler's equation about z: Izz·ω̇z = τz − (ω × Iω)z.
        let gyro = |w: [f64; 3]| w[0] * w[1] * (q.inertia[1] - q.inertia[0]);
        let predicted =
            ((yaw_torque(s0) + yaw_torque(s1)) / 2.0 - (gyro(w0) + gyro(w1)) / 2.0) / q.inertia[2];
        let measured = (w1[2] - w0[2]) / DT;
        if predicted.abs() > 1.0 {
            worst = worst.max((measured / predicted - 1.0).abs());
            checked += 1;
        }
    }
    assert!(
        checked > 100 && worst < 0.1,
        "{checked} ticks, worst error {worst:.3}"
    );
    // The net drag torque of the surviving rotors turns it counter-clockwise (yaw −), with
    // nothing to stop it: a spin.
    let (w, speeds) = state(&rig);
    assert!(w[2] < -3.0, "spinning at {:.1} rad/s", w[2]);
    // Holding roll and pitch about the 2–4 diagonal would need rotor 3 as weak as the dead
    // rotor 1, so at most the clockwise pair lifts: less than the weight. It falls.
    let top = speeds.iter().fold(0.0f64, |a, &b| a.max(b));
    assert!(2.0 * q.thrust_coefficient * top * top < q.mass * GRAVITY * 1.02);
    // Issue #54: the dead rotor reports that it stands still (it said about 990 rad/s).
    assert!(
        speeds[0] < 1.0,
        "the dead rotor turns at {:.1} rad/s",
        speeds[0]
    );
    assert!(speeds[1] > 100.0, "the others turn: {speeds:?}");
    assert!(
        rig.v[2] > 0.5 && rig.p[2] > -39.0,
        "falling: {:?} {:?}",
        rig.p,
        rig.v
    );
}

#[test]
fn sensor_and_battery_faults() {
    let mut w = world_with(with_gauges(1.0), None, 0);
    let c = spawn(&mut w, [0.0, 0.0, -2.0], 0.0);
    run(&mut w, 1.0);
    let positions = |out: &[(ClientId, ServerMessage)]| -> Vec<String> {
        out.iter()
            .filter(|(_, m)| matches!(m, ServerMessage::Sen(s) if matches!(s.data, SenData::Position { .. })))
            .map(|(_, m)| m.to_string().split("{Type").nth(1).unwrap_or_default().to_string())
            .collect()
    };
    command(&mut w, c, "DRIVE {LinearVelocity 1}");
    command(&mut w, c, "FAULT {Sensor Position} {Mode Freeze}");
    let frozen = positions(&run(&mut w, 1.0));
    assert!(
        frozen.len() >= 9 && frozen.windows(2).all(|p| p[0] == p[1]),
        "{frozen:?}"
    );
    command(&mut w, c, "FAULT {Sensor Position} {Mode Silent}");
    assert!(positions(&run(&mut w, 1.0)).is_empty());
    command(&mut w, c, "FAULT {Sensor Position} {Mode Ok}");
    let live = positions(&run(&mut w, 1.0));
    assert!(live.len() >= 9 && live[0] != live[live.len() - 1]);
    // The battery loses half its charge at once.
    let before = last_value(&run(&mut w, 0.1), "Battery", "Charge")[0];
    command(&mut w, c, "FAULT {Battery 0.5}");
    let after = last_value(&run(&mut w, 0.1), "Battery", "Charge")[0];
    assert!((after / before - 0.5).abs() < 0.001, "{before} → {after}");
}

fn faulty_flight(seed: u64) -> String {
    let wind = WindConfig {
        velocity: [1.0, 0.0, 0.0],
        gusts: 1.0,
        gust_length: 15.0,
    };
    let mut w = world_with(RobotCatalog::embedded(), Some(wind), seed);
    let a = spawn(&mut w, [-5.0, -5.0, -2.0], 0.0);
    let mut out = run(&mut w, 1.0);
    command(&mut w, a, "DRIVE {LinearVelocity 1}");
    command(&mut w, a, "FAULT {Motor 2} {Thrust 0.7}");
    command(&mut w, a, "FAULT {Sensor Sonar0} {Mode Freeze}");
    out.extend(run(&mut w, 3.0));
    printed(&out)
}

#[test]
fn faulty_flights_repeat_bit_for_bit() {
    let a = faulty_flight(9);
    assert_eq!(a, faulty_flight(9));
    assert_ne!(a, faulty_flight(10));
}

#[test]
fn bad_fault_lines_say_what_is_wrong() {
    let parse = |line: &str| {
        let Command::Other(m) = Command::parse(line).unwrap().message else {
            panic!("not an unknown command")
        };
        dynamics::parse_fault(&m)
    };
    assert!(parse("FAULT {Motor 5}").unwrap_err().contains("1 to 4"));
    assert!(
        parse("FAULT {Motor 1} {Thrust 2}")
            .unwrap_err()
            .contains("[0, 1]")
    );
    assert!(parse("FAULT {Battery x}").unwrap_err().contains("finite"));
    assert!(
        parse("FAULT {Sensor IMU} {Mode melt}")
            .unwrap_err()
            .contains("Freeze")
    );
    assert!(parse("FAULT {Foo 1}").unwrap_err().contains("Motor"));
    assert!(
        parse("FAULT {Sensor IMU} {Mode Drift}")
            .unwrap_err()
            .contains("{Rate")
    );
    assert!(
        parse("FAULT {Sensor IMU} {Mode Noise} {Std -1}")
            .unwrap_err()
            .contains(">= 0")
    );
    assert!(
        parse("FAULT {Sensor IMU} {Mode Silent} {Duration 0}")
            .unwrap_err()
            .contains("Duration")
    );
    assert!(
        parse("FAULT {Radio dim}")
            .unwrap_err()
            .contains("Off or On")
    );
    assert!(
        parse("FAULT {Sensor IMU} {Mode Noise} {Std 1e308}")
            .unwrap_err()
            .contains("1e6")
    );
    assert_eq!(
        parse("FAULT {Radio off} {Duration 2}"),
        Ok(dynamics::Fault::Radio {
            on: false,
            duration: Some(2.0)
        })
    );
    assert_eq!(
        parse("FAULT {Motor 2} {Thrust 0.5}"),
        Ok(dynamics::Fault::Motor {
            rotor: 1,
            thrust: 0.5
        })
    );
}

/// A world over a 1 km floor with the faults of `plan`.
fn faulty_world(plan: faults::FaultPlan) -> World {
    World::new(
        floor_map(1000.0),
        RobotCatalog::embedded(),
        SimConfig {
            faults: plan,
            ..SimConfig::default()
        },
    )
}

#[test]
fn a_faults_file_fails_a_motor_at_its_time() {
    let plan = faults::FaultPlan::from_toml(
        "[[fault]]\ntime = 2.0\nrobot = 1\nline = \"FAULT {Motor 1} {Thrust 0}\"\n",
    )
    .expect("plan");
    let run_with = |plan: faults::FaultPlan| {
        let mut w = faulty_world(plan);
        let c = spawn(&mut w, [0.0, 0.0, -30.0], 0.0);
        let before = printed(&run(&mut w, 1.99));
        run(&mut w, 2.0);
        (before, state(&w, c))
    };
    let (quiet, healthy) = run_with(faults::FaultPlan::default());
    let (before, failed) = run_with(plan);
    assert_eq!(quiet, before, "nothing changes before the fault's time");
    assert!(
        (healthy.0[2] + 30.0).abs() < 0.05,
        "hovers: {:?}",
        healthy.0
    );
    assert!(
        failed.0[2] > -29.0 && failed.2[2].abs() > 0.5,
        "falls spinning: {failed:?}"
    );
}

/// Time and location of Position lines.
type Positions = Vec<(f64, [f64; 3])>;

/// (time, x, y, z) of each Position line.
fn position_lines(out: &[(ClientId, ServerMessage)]) -> Positions {
    out.iter()
        .filter_map(|(_, m)| match m {
            ServerMessage::Sen(sen) => match &sen.data {
                SenData::Position { location, .. } => Some((
                    sen.time.map_or(0.0, |t| t.seconds),
                    [location.x, location.y, location.z],
                )),
                _ => None,
            },
            _ => None,
        })
        .collect()
}

/// A hover of 6 s with `line` sent after 1 s: the Position lines with and without it.
fn hover_with_fault(line: &str) -> (Positions, Positions) {
    let fly = |fault: bool| {
        let mut w = world_with(RobotCatalog::embedded(), None, 4);
        let c = spawn(&mut w, [0.0, 0.0, -2.0], 0.0);
        let mut out = run(&mut w, 1.0);
        if fault {
            command(&mut w, c, line);
        }
        out.extend(run(&mut w, 5.0));
        position_lines(&out)
    };
    (fly(false), fly(true))
}

#[test]
fn a_drift_fault_makes_the_reported_altitude_diverge_at_its_rate() {
    let (truth, drifting) = hover_with_fault("FAULT {Sensor Position} {Mode Drift} {Rate 0.1}");
    assert_eq!(truth.len(), drifting.len());
    assert!(truth.len() > 50);
    for ((t, a), (_, b)) in truth.iter().zip(&drifting) {
        let expected = if *t < 1.0 { 0.0 } else { 0.1 * (t - 1.0) };
        for i in 0..3 {
            assert!(
                (b[i] - a[i] - expected).abs() < 2e-4,
                "t {t}: axis {i}: {} vs {} + {expected}",
                b[i],
                a[i]
            );
        }
    }
    let last = truth.len() - 1;
    assert!(
        drifting[last].1[2] - truth[last].1[2] > 0.45,
        "z drifted 0.5 m in 5 s"
    );
}

#[test]
fn bias_and_noise_faults_add_their_size_to_the_readings() {
    let (truth, biased) = hover_with_fault("FAULT {Sensor Position} {Mode Bias} {Value -0.3}");
    for ((t, a), (_, b)) in truth.iter().zip(&biased) {
        let expected = if *t <= 1.0 + 1e-9 { 0.0 } else { -0.3 };
        assert!(
            (b[2] - a[2] - expected).abs() < 2e-4,
            "t {t}: {b:?} vs {a:?}"
        );
    }
    let (truth, noisy) = hover_with_fault("FAULT {Sensor Position} {Mode Noise} {Std 0.2}");
    let errors: Vec<f64> = truth
        .iter()
        .zip(&noisy)
        .filter(|((t, _), _)| *t > 1.0)
        .flat_map(|((_, a), (_, b))| (0..3).map(move |i| b[i] - a[i]))
        .collect();
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<f64>() / n;
    let std = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!(n > 100.0 && mean.abs() < 0.05, "mean {mean} of {n}");
    assert!((std / 0.2 - 1.0).abs() < 0.15, "std {std}");
}

#[test]
fn the_position_sensor_drops_out_for_its_duration() {
    let (truth, dropped) = hover_with_fault("FAULT {Sensor Position} {Mode Silent} {Duration 2}");
    let times: Vec<f64> = dropped.iter().map(|(t, _)| *t).collect();
    assert!(
        times.iter().all(|t| !(1.001..2.999).contains(t)),
        "{times:?}"
    );
    assert!(times.iter().any(|t| *t < 1.0) && times.iter().any(|t| *t > 3.0));
    // After the dropout the readings are the healthy ones again.
    let after: Vec<_> = truth.iter().filter(|(t, _)| *t >= 3.0).collect();
    let again: Vec<_> = dropped.iter().filter(|(t, _)| *t >= 3.0).collect();
    assert_eq!(after, again);
}

#[test]
fn a_radio_fault_holds_for_its_duration() {
    let mut w = world();
    let c = spawn(&mut w, [0.0, 0.0, -2.0], 0.0);
    run(&mut w, 1.0);
    let radio_off = |w: &World| w.robots_truth()[0].radio_off;
    assert!(!radio_off(&w));
    command(&mut w, c, "FAULT {Radio Off} {Duration 1.5}");
    run(&mut w, 1.0);
    assert!(radio_off(&w));
    run(&mut w, 1.0);
    assert!(!radio_off(&w), "on again after 1.5 s");
    command(&mut w, c, "FAULT {Radio Off}");
    run(&mut w, 10.0);
    assert!(radio_off(&w), "off until told otherwise");
    command(&mut w, c, "FAULT {Radio On}");
    assert!(!radio_off(&w));
}

#[test]
fn random_faults_happen_at_their_rate_and_repeat_for_a_seed() {
    let plan = |p: f64| {
        faults::FaultPlan::from_toml(&format!(
            "[[random]]\nprobability = {p}\nrobot = 1\nfrom = 2.0\nline = \"FAULT {{Motor 1}}\"\n"
        ))
        .expect("plan")
    };
    let time = |p: f64, seed: u64| plan(p).schedule(seed).first().map(|f| f.time);
    assert_eq!(time(0.1, 5), time(0.1, 5), "the same seed, the same time");
    assert_ne!(time(0.1, 5), time(0.1, 6));
    assert_eq!(time(1.0, 5), Some(2.0));
    assert_eq!(time(0.0, 5), None);
    // Within one second of `from` with probability p (over 4000 seeds).
    let within = (0..4000)
        .filter(|&s| time(0.3, s).is_some_and(|t| t < 3.0))
        .count() as f64
        / 4000.0;
    assert!((within - 0.3).abs() < 0.03, "{within}");
    let e = faults::FaultPlan::from_toml(
        "[[random]]\nprobability = 2\nrobot = 1\nline = \"FAULT {Motor 1}\"\n",
    )
    .unwrap_err();
    assert!(e.contains("random 1") && e.contains("probability"), "{e}");
}

#[test]
fn scheduled_faults_are_told_to_the_robot_and_read_back_from_a_recording() {
    let plan = faults::FaultPlan::from_toml(
        "[[random]]\nprobability = 0.5\nrobot = 1\nline = \"FAULT {Sensor Position} {Mode Drift} {Rate 0.2}\"\n\
         [[fault]]\ntime = 1.0\nrobot = 1\nline = \"FAULT {Motor 2} {Thrust 0.8}\"\n",
    )
    .expect("plan");
    let fly = |plan: faults::FaultPlan| {
        let mut w = World::new(
            Map::default_map(),
            RobotCatalog::embedded(),
            SimConfig {
                faults: plan,
                seed: 3,
                ..SimConfig::default()
            },
        );
        spawn(&mut w, [0.0, 0.0, -2.0], 0.0);
        printed(&run(&mut w, 8.0))
    };
    let first = fly(plan);
    let notices: Vec<&str> = first
        .lines()
        .filter_map(|l| l.split_once(' ').map(|s| s.1))
        .filter(|l| l.starts_with("FAULT"))
        .collect();
    assert_eq!(notices.len(), 2, "{notices:?}");
    assert!(
        notices.contains(&"FAULT {Time 1.0000} {Robot 1} {Motor 2} {Thrust 0.8}"),
        "{notices:?}"
    );
    assert!(
        notices
            .iter()
            .any(|n| n.contains("{Robot 1} {Sensor Position} {Mode Drift} {Rate 0.2}")),
        "{notices:?}"
    );
    // The notices as a recording's S lines make the same run.
    let recording: String = std::iter::once("# usar-record 1".to_string())
        .chain(notices.iter().map(|l| format!("0.0000 S {l}")))
        .collect::<Vec<_>>()
        .join("\n");
    let again = fly(faults::FaultPlan::from_recording(&recording).expect("read back"));
    assert_eq!(first, again);
}

// ---- domain randomisation ----

/// Hovers `seconds` in a world seeded `seed` with `ranges`: the draws and the mean rotor
/// speed at the end.
fn randomized_hover(ranges: &str, seed: u64) -> (randomize::Drawn, f64, String) {
    let mut w = World::new(
        floor_map(100.0),
        with_gauges(1.0),
        SimConfig {
            seed,
            randomize: Some(randomize::Randomization::from_toml(ranges).expect("ranges")),
            ..SimConfig::default()
        },
    );
    spawn(&mut w, [0.0, 0.0, -5.0], 0.0);
    let out = run(&mut w, 4.0);
    let speeds = last_value(&out, "Rotors", "Speeds");
    let drawn = w.randomized().remove(0);
    (drawn, speeds.iter().sum::<f64>() / 4.0, printed(&out))
}

#[test]
fn each_robot_draws_its_parameters_and_a_heavier_one_hovers_faster() {
    let ranges = "mass = [0.7, 1.4]\nnoise = [0.5, 2.0]\n";
    let (a, wa, out_a) = randomized_hover(ranges, 1);
    let (b, wb, _) = randomized_hover(ranges, 2);
    let (again, _, out_again) = randomized_hover(ranges, 1);
    assert_eq!(a, again, "the same seed, the same draws");
    assert_eq!(out_a, out_again, "and the same bytes");
    let (ma, mb) = (a.get("mass").unwrap(), b.get("mass").unwrap());
    assert_ne!(ma, mb, "two episodes draw different masses");
    // Hover: 4·kf·ω² = m·g, so ω ∝ √m.
    let expected = (ma / mb).sqrt();
    assert!(
        ((wa / wb) / expected - 1.0).abs() < 0.01,
        "ω {wa:.1} / {wb:.1} against √(m ratio) {expected:.4}"
    );
    let q = quadrotor::QuadrotorConfig::default();
    let hover = (ma * q.mass * GRAVITY / (4.0 * q.thrust_coefficient)).sqrt();
    assert!((wa / hover - 1.0).abs() < 0.01, "{wa} vs {hover}");
    // The robot's connection is told, before its first STA.
    assert!(
        out_a.contains(&format!(
            "RANDOMIZED {{Time 0.0000}} {{Robot 1}} {{mass {ma:.4}}}"
        )),
        "{}",
        &out_a[..300]
    );
}

#[test]
fn randomised_noise_scales_every_sensor_error_and_wind_drifts() {
    let gyro_std = |ranges: Option<&str>| {
        let mut w = World::new(
            floor_map(100.0),
            RobotCatalog::embedded(),
            SimConfig {
                seed: 3,
                randomize: ranges.map(|r| randomize::Randomization::from_toml(r).unwrap()),
                ..SimConfig::default()
            },
        );
        let c = spawn(&mut w, [0.0, 0.0, -5.0], 0.0);
        let out = run(&mut w, 20.0);
        let z: Vec<f64> = imu_lines(&out).iter().map(|(_, w)| w.z).collect();
        let mean = z.iter().sum::<f64>() / z.len() as f64;
        let std = (z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / z.len() as f64).sqrt();
        (std, state(&w, c).0)
    };
    let (plain, _) = gyro_std(None);
    let (tripled, _) = gyro_std(Some("noise = [3.0, 3.0]\n"));
    assert!(
        (tripled / plain / 3.0 - 1.0).abs() < 0.25,
        "gyro σ {plain:.2e} → {tripled:.2e}"
    );
    // A drawn wind of 2 m/s carries an uncommanded vehicle away.
    let (_, p) = gyro_std(Some("wind = [2.0, 2.0]\n"));
    assert!(p[0].hypot(p[1]) > 1.0, "drifted: {p:?}");
}

/// Issue #54: the horizontal acceleration was limited to g·tan(max_tilt), but a descent
/// lightens the vertical thrust, so the same horizontal force tilted the body to 41° at a 25°
/// limit. The limit now holds on the thrust vector itself: within the attitude loop's half
/// degree of overshoot.
#[test]
fn the_tilt_limit_holds_while_descending_and_reversing() {
    let mut rig = rig(
        quadrotor::QuadrotorConfig::default(),
        [0.0, 0.0, -40.0],
        [0.0; 3],
    );
    let limit = 0.44f64; // the rig's max_tilt
    rig.run(1.0);
    let mut tilt = 0.0f64;
    for linear in [2.0, -2.0] {
        dynamics::Dynamics::drive(
            &mut rig.quad,
            &dynamics::SetPoints {
                linear,
                altitude: -2.0,
                ..dynamics::SetPoints::default()
            },
        );
        for _ in 0..(3.0 / DT) as u64 {
            rig.step();
            tilt = tilt.max((rig.r[0].cos() * rig.r[1].cos()).acos());
        }
    }
    assert!(
        tilt > limit - 0.02 && tilt < limit + 1f64.to_radians(),
        "tilted up to {:.1}° at a limit of {:.1}°",
        tilt.to_degrees(),
        limit.to_degrees()
    );
}

/// Issue #54: faults were keyed by spawn number, so in a loop (a new spawn each iteration)
/// only the first iteration got its fault. `robot = "each"` gives every robot spawned the
/// fault, its time counted from the spawn.
#[test]
fn a_fault_for_each_robot_comes_at_its_time_after_every_spawn() {
    let plan = faults::FaultPlan::from_toml(
        "[[fault]]\ntime = 1.0\nrobot = \"each\"\nline = \"FAULT {Motor 1} {Thrust 0}\"\n",
    )
    .expect("plan");
    let mut w = faulty_world(plan);
    let falls = |w: &mut World, c: ClientId| {
        run(w, 0.95);
        let hovering = state(w, c).0[2];
        run(w, 1.5);
        let after = state(w, c).0[2];
        (hovering, after)
    };
    // The first iteration at t = 0, the second at t = 2.45 s (after the first one's fault).
    let first = spawn(&mut w, [0.0, 0.0, -30.0], 0.0);
    let (hovering, after) = falls(&mut w, first);
    assert!(
        (hovering + 30.0).abs() < 0.05 && after > -29.0,
        "first: {hovering} then {after}"
    );
    w.disconnect(first);
    let second = spawn(&mut w, [5.0, 0.0, -30.0], 0.0);
    let (hovering, after) = falls(&mut w, second);
    assert!(
        (hovering + 30.0).abs() < 0.05 && after > -29.0,
        "the second spawn gets its fault too, 1 s after it: {hovering} then {after}"
    );
    let bad = faults::FaultPlan::from_toml(
        "[[fault]]\ntime = 1.0\nrobot = \"every\"\nline = \"FAULT {Motor 1}\"\n",
    )
    .unwrap_err();
    assert!(bad.contains("\"each\"") && bad.contains("every"), "{bad}");
}
