//! GPS and magnetometer (issue #54, item 3): UDK's GPS line from the map's origin, a
//! 3-axis magnetometer from the map's field, their GETCONF/GETGEO answers, and the errors of a
//! bad configuration (GPS without a map origin, bad `[geo]` values).

use std::path::Path;

use usar_proto::{Command, Init, ItemQuery, SenData, ServerMessage};
use usar_sim::part::PartConfig;
use usar_sim::{Map, RobotCatalog, SimConfig, World};

const QUAD: &str = "USARBot.stsQuadrotor";

/// An empty room at 47.5° N, 122.25° W with a 20 µT north, 5 µT east, 40 µT down field.
const MAP: &str = "level = \"GeoRoom\"\n\
[[start]]\ntag = \"Start1\"\nlocation = [3.0, -4.0, -1.0]\n\
[[box]]\ncenter = [0.0, 0.0, 0.5]\nsize = [100.0, 100.0, 1.0]\n\
[geo]\nlatitude = 47.5\nlongitude = -122.25\nmagnetic_field = [20.0, 5.0, 40.0]\n";

fn part(kind: &str, name: &str, settings: &str) -> PartConfig {
    PartConfig {
        kind: kind.into(),
        name: name.into(),
        position: [0.0; 3],
        direction: [0.0; 3],
        interval: None,
        noise: 0.0,
        settings: toml::from_str(settings).unwrap(),
    }
}

/// The embedded catalog with a GPS and a magnetometer on the quadrotor.
fn catalog() -> RobotCatalog {
    let mut catalog = RobotCatalog::embedded();
    let class = catalog.get_mut(QUAD).unwrap();
    class
        .parts
        .push(part("GPS", "GPS", "error = { latency = 0.2 }"));
    class.parts.push(part("Magnetometer", "Mag", ""));
    catalog
}

/// A world of `map` and `catalog` with a quadrotor spawned at Start1 and flown `ticks`
/// ticks: the world, the quadrotor's connection, every line printed.
fn fly(
    map: Map,
    catalog: RobotCatalog,
    ticks: usize,
) -> (
    World,
    usar_sim::ClientId,
    Vec<(usar_sim::ClientId, ServerMessage)>,
) {
    let mut world = World::new(map, catalog, SimConfig::default());
    let c = world.connect();
    world.command(
        c,
        Command::Init(Init {
            class_name: QUAD.into(),
            start: Some("Start1".into()),
            ..Init::default()
        }),
    );
    let mut out = Vec::new();
    for _ in 0..ticks {
        world.step(&mut out);
    }
    (world, c, out)
}

fn map() -> Map {
    Map::from_toml(MAP, Path::new("geo.toml")).unwrap()
}

#[test]
fn gps_and_magnetometer_lines_conf_and_geo() {
    let (map, catalog) = (map(), catalog());
    catalog.check_map(&map).unwrap();
    let (mut world, c, out) = fly(map, catalog, 200);
    let lines: Vec<String> = out.iter().map(|(_, m)| m.to_string()).collect();
    let gps: Vec<&String> = lines.iter().filter(|l| l.contains("{Type GPS}")).collect();
    // 10 Hz by default, timestamped (UDK's GPSSensor inherits the Sensor defaults).
    assert_eq!(gps.len(), 10, "{gps:?}");
    // 3 m north, 4 m west of the origin: 47°30.0000′ + 3 m = 0.00162′ (a minute of latitude
    // is 1853 m here), 122°15′ − 4 m = 0.00322′ (a minute of longitude is 1252 m).
    let last = gps.last().unwrap();
    assert!(
        last.ends_with(
            "{Type GPS} {Name GPS} {Latitude 47,30.0016,N} {Longitude 122,15.0031,W} {Fix 1} {Satellites 9}"
        ),
        "{last}"
    );
    assert!(last.starts_with("SEN {Time "), "{last}");
    // Typed on the way back in.
    let typed = out.iter().find_map(|(_, m)| match m {
        ServerMessage::Sen(s) => match &s.data {
            SenData::Magnetometer { field, .. } => Some([field.x, field.y, field.z]),
            _ => None,
        },
        _ => None,
    });
    let f = typed.expect("a magnetometer line");
    // Facing north, level (hovering): the map's field.
    assert!(
        (f[0] - 20.0).abs() < 0.5 && (f[1] - 5.0).abs() < 0.5 && (f[2] - 40.0).abs() < 0.5,
        "{f:?}"
    );
    let mag = lines
        .iter()
        .find(|l| l.contains("{Type Magnetometer}"))
        .unwrap();
    assert!(ServerMessage::parse(mag).is_ok(), "{mag}");
    for kind in ["GPS", "Magnetometer"] {
        let query = ItemQuery {
            kind: kind.into(),
            name: None,
        };
        let conf = world.command(c, Command::GetConf(query.clone()));
        let geo = world.command(c, Command::GetGeo(query));
        let (conf, geo) = (conf[0].to_string(), geo[0].to_string());
        match kind {
            "GPS" => assert_eq!(conf, "CONF {Type GPS} {Name GPS} {ScanInterval 0.1000}"),
            _ => assert_eq!(conf, "CONF {Type Magnetometer} {Name Mag}"),
        }
        assert!(
            geo.starts_with(&format!("GEO {{Type {kind}}} {{Name "))
                && geo.ends_with("{Mount stsQuadrotor}"),
            "{geo}"
        );
    }
}

#[test]
fn a_gps_without_a_map_origin_names_the_robot_the_sensor_and_the_map() {
    let e = catalog().check_map(&Map::default_map()).unwrap_err();
    assert_eq!(
        e,
        "robot USARBot.stsQuadrotor: sensor GPS: a GPS needs the map's origin (`[geo]` latitude \
         and longitude, docs/maps.md#geo); map EmptyRoom has none"
    );
    // The embedded robots have neither part: every map works with them.
    RobotCatalog::embedded()
        .check_map(&Map::default_map())
        .unwrap();
    // Spawned anyway (a program that skips the check), it reports no fix.
    let (_, _, out) = fly(Map::default_map(), catalog(), 40);
    let gps = out
        .iter()
        .map(|(_, m)| m.to_string())
        .find(|l| l.contains("{Type GPS}"))
        .unwrap();
    assert!(gps.ends_with("{Name GPS} {Fix 0} {Satellites 0}"), "{gps}");
}

#[test]
fn bad_geo_settings_and_gps_settings_are_errors() {
    for (geo, shows) in [
        (
            "latitude = 95.0\nlongitude = 0.0",
            "latitude must be a number of degrees within ±89",
        ),
        ("latitude = 45.0", "latitude and longitude together"),
        (
            "latitude = 45.0\nlongitude = 200.0",
            "longitude must be a number of degrees within ±180",
        ),
        (
            "magnetic_field = [1.0, 2.0, 1e9]",
            "magnetic_field must be three numbers",
        ),
        ("latitude = \"north\"\nlongitude = 1.0", "invalid type"),
        ("altitude = 5.0", "unknown field `altitude`"),
    ] {
        let text = format!("level = \"X\"\n[geo]\n{geo}\n");
        let e = Map::from_toml(&text, Path::new("m.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(shows) && e.contains("m.toml"), "{geo}: {e}");
    }
    for (settings, shows) in [
        (
            "[[robot.part]]\ntype = \"GPS\"\nname = \"G\"\nsatellites = -1\n",
            "satellites must be within [0, 64]",
        ),
        (
            "[[robot.part]]\ntype = \"GPS\"\nname = \"G\"\nerror = { noise = -1.0 }\n",
            "error.noise must be within",
        ),
        (
            "[[robot.part]]\ntype = \"GPS\"\nname = \"G\"\ninterval = -0.2\n",
            "robot USARBot.T: sensor G: interval must be a positive number, got -0.2",
        ),
        (
            "[[robot.part]]\ntype = \"Magnetometer\"\nname = \"M\"\nerror = { bias = -2.0 }\n",
            "error.bias must be within",
        ),
    ] {
        let text = format!("[[robot]]\nclass = \"USARBot.T\"\n{settings}");
        let e = RobotCatalog::from_toml(&text, Path::new("r.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(shows), "{settings}: {e}");
    }
}
