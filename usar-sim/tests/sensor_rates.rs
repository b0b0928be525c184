//! Sensor rates per sensor (issue #54, item 2): a rate set on a part is the rate its SEN lines
//! come at, up to the physics rate; rates the physics step cannot give are errors naming the
//! robot, the sensor and the value.

use usar_proto::{Command, Init, SenData, ServerMessage};
use usar_sim::robots::{parse_sensor_rate, physics_step};
use usar_sim::{Map, RobotCatalog, SimConfig, World};

const QUAD: &str = "USARBot.stsQuadrotor";

/// The catalog with the quadrotor's IMU at `hz`.
fn imu_at(hz: f64) -> RobotCatalog {
    let mut catalog = RobotCatalog::embedded();
    catalog
        .get_mut(QUAD)
        .expect("embedded quadrotor")
        .set_sensor_rate("IMU", hz)
        .expect("a positive rate");
    catalog
}

/// The times of the IMU lines of a quadrotor over `seconds`, after one second of hover, in
/// a world stepping at `physics` Hz.
fn imu_times(catalog: RobotCatalog, physics: f64, seconds: f64) -> Vec<f64> {
    let dt = physics_step(physics).expect("a valid physics rate");
    let mut world = World::new(
        Map::default_map(),
        catalog,
        SimConfig {
            dt,
            ..SimConfig::default()
        },
    );
    let client = world.connect();
    world.command(
        client,
        Command::Init(Init {
            class_name: QUAD.into(),
            start: Some("Start1".into()),
            ..Init::default()
        }),
    );
    let mut out = Vec::new();
    for _ in 0..(1.0 / dt).round() as usize {
        world.step(&mut out);
    }
    out.clear();
    for _ in 0..(seconds / dt).round() as usize {
        world.step(&mut out);
    }
    out.iter()
        .filter_map(|(_, m)| match m {
            ServerMessage::Sen(sen) if matches!(sen.data, SenData::Imu { .. }) => {
                sen.time.map(|t| t.seconds)
            }
            _ => None,
        })
        .collect()
}

#[test]
fn an_imu_at_500_hz_gives_50_readings_per_tenth_of_a_second() {
    let catalog = imu_at(500.0);
    catalog.check_rates(physics_step(1000.0).unwrap()).unwrap();
    let times = imu_times(catalog, 1000.0, 0.1);
    assert_eq!(times.len(), 50, "{times:?}");
    for pair in times.windows(2) {
        assert!(
            (pair[1] - pair[0] - 0.002).abs() < 1e-6,
            "readings 2 ms apart, with distinct time stamps: {times:?}"
        );
    }
    // 1 kHz, one reading per 1 ms tick.
    let times = imu_times(imu_at(1000.0), 1000.0, 0.1);
    assert_eq!(times.len(), 100);
    // What the checks refuse: unchecked, a 500 Hz IMU on 200 Hz ticks reads every tick,
    // 20 readings per 0.1 s instead of 50 (the rate silently becomes the physics rate).
    assert_eq!(imu_times(imu_at(500.0), 200.0, 0.1).len(), 20);
    // The default: 10 Hz on 200 Hz ticks.
    let times = imu_times(RobotCatalog::embedded(), 200.0, 1.0);
    assert_eq!(times.len(), 10);
}

#[test]
fn rates_the_physics_step_cannot_give_name_the_robot_the_sensor_and_the_value() {
    // Above the physics rate: 500 Hz on 200 Hz ticks.
    let e = imu_at(500.0).check_rates(0.005).unwrap_err();
    assert!(
        e.contains(QUAD) && e.contains("sensor IMU") && e.contains("rate 500 Hz"),
        "{e}"
    );
    assert!(e.contains("above the physics rate of 200 Hz"), "{e}");
    // Not a whole number of ticks: 150 Hz on 200 Hz ticks would silently be 200 Hz.
    let e = imu_at(150.0).check_rates(0.005).unwrap_err();
    assert!(
        e.contains("sensor IMU") && e.contains("not a whole number") && e.contains("100 or 200"),
        "{e}"
    );
    // Negative, zero, not a number.
    let mut catalog = RobotCatalog::embedded();
    let class = catalog.get_mut(QUAD).unwrap();
    for bad in [-5.0, 0.0, f64::NAN, f64::INFINITY] {
        let e = class.set_sensor_rate("IMU", bad).unwrap_err();
        assert!(
            e.contains(QUAD) && e.contains("sensor IMU") && e.contains("positive number"),
            "{e}"
        );
    }
    let e = class.set_sensor_rate("Lidar", 10.0).unwrap_err();
    assert!(e.contains("no sensor named \"Lidar\""), "{e}");
    for (text, shows) in [
        ("IMU=abc", "sensor IMU: the rate \"abc\" is not a number"),
        (
            "IMU=-3",
            "sensor IMU: the rate must be a positive number of Hz, got -3",
        ),
        ("IMU=0", "got 0"),
        ("IMU=nan", "got nan"),
        ("IMU", "expected NAME=HZ"),
        ("=5", "the sensor name is empty"),
    ] {
        let e = parse_sensor_rate(text).unwrap_err();
        assert!(e.contains(shows), "{text}: {e}");
    }
    assert_eq!(
        parse_sensor_rate(" IMU = 500 ").unwrap(),
        ("IMU".into(), 500.0)
    );
    let e = catalog.set_sensor_rate("Nothing", 5.0).unwrap_err();
    assert!(e.contains("sensor Nothing"), "{e}");
    // The embedded catalog at its own rates is valid at 200 Hz and at 1 kHz.
    RobotCatalog::embedded().check_rates(0.005).unwrap();
    RobotCatalog::embedded().check_rates(0.001).unwrap();
    // Physics rates.
    assert!(physics_step(2000.0).unwrap_err().contains("from 1 to 1000"));
    assert!(physics_step(f64::NAN).is_err());
}

#[test]
fn a_robot_file_with_a_bad_interval_names_the_robot_and_the_sensor() {
    let text = "[[robot]]\nclass = \"USARBot.Test\"\n[[robot.part]]\ntype = \"IMU\"\nname = \"Gyro\"\ninterval = -0.002\n";
    let e = RobotCatalog::from_toml(text, std::path::Path::new("r.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(
            "robot USARBot.Test: sensor Gyro: interval must be a positive number, got -0.002"
        ),
        "{e}"
    );
}
