//! Every line of the capture and of protocol.md's examples reads to the right typed values;
//! every UDK-era server line prints back byte for byte; the parser regression chunks fed
//! through the codec give the expected messages.

use bytes::BytesMut;
use tokio_util::codec::Decoder;
use usar_proto::codec::CommandCodec;
use usar_proto::{
    Command, Conf, ConfItem, Deviation, Drive, Geo, Init, Message, Nfo, Sen, SenData,
    ServerMessage, Sta, Time, Vec3,
};

const CAPTURE: &str = include_str!("data/USARcommandSample.txt");
const EXAMPLES: &str = include_str!("data/protocol_examples.txt");
const REGRESSIONS: &str = include_str!("data/parser_regressions.txt");

fn command(line: &str) -> (Command, Vec<Deviation>) {
    let p = Command::parse(line).unwrap_or_else(|e| panic!("{line}: {e}"));
    (p.message, p.deviations)
}

fn server(line: &str) -> ServerMessage {
    ServerMessage::parse(line)
        .unwrap_or_else(|e| panic!("{line}: {e}"))
        .message
}

fn capture_lines() -> impl Iterator<Item = &'static str> {
    CAPTURE
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
}

#[test]
fn every_capture_line_reads_and_server_lines_print_back() {
    let mut servers = 0;
    for line in capture_lines() {
        if ServerMessage::is_server_word(Message::word(line)) {
            let m = server(line);
            assert!(!matches!(m, ServerMessage::Other(_)), "{line}");
            assert_eq!(m.to_string(), line);
            servers += 1;
        } else {
            let (c, _) = command(line);
            let known = !Message::word(line).eq_ignore_ascii_case("MULTIDRIVE");
            assert_eq!(!matches!(c, Command::Other(_)), known, "{line}");
        }
    }
    assert_eq!(servers, 21);
}

#[test]
fn capture_values() {
    let (c, d) = command(
        "INIT {ClassName USARBot.pioneer3at_with_sensors_b}{Name pioneer3at_with_sensors_b}{Location 1,-2,0}{Rotation 0,0,0}{Battery 3600}",
    );
    assert_eq!(
        c,
        Command::Init(Init {
            class_name: "USARBot.pioneer3at_with_sensors_b".into(),
            name: Some("pioneer3at_with_sensors_b".into()),
            location: Some(Vec3::new(1.0, -2.0, 0.0)),
            rotation: Some(Vec3::new(0.0, 0.0, 0.0)),
            start: None
        })
    );
    assert!(d.contains(&Deviation::UnknownKey("Battery".into())));
    let (c, _) =
        command("INIT {ClassName Crawler_Robot}{Name Crawler_Robot}{Start Point1}{Battery 3600}");
    let Command::Init(init) = c else { panic!() };
    assert_eq!(init.start.as_deref(), Some("Point1"));
    assert_eq!(init.location, None);

    let line = capture_lines()
        .find(|l| l.contains("{Type RangeScanner} {Name lms200} {Resolution"))
        .unwrap();
    let ServerMessage::Sen(Sen {
        time,
        data: SenData::RangeScanner(scan),
    }) = server(line)
    else {
        panic!()
    };
    assert_eq!(time, Some(Time::udk(477.855)));
    assert_eq!(scan.ranges.len(), 181);
    assert_eq!(&scan.ranges[..4], &[9.38, 9.38, 9.38, 9.39]);
    assert_eq!(
        (scan.resolution, scan.fov, scan.range_decimals),
        (0.0174, 3.1414, 2)
    );

    let line = capture_lines().find(|l| l.starts_with("STA")).unwrap();
    let ServerMessage::Sta(Sta {
        battery, vehicle, ..
    }) = server(line)
    else {
        panic!()
    };
    assert_eq!(battery, 99999);
    assert_eq!(vehicle.unwrap().light_intensity, Some(100));

    let line = capture_lines().find(|l| l.starts_with("GEO  ")).unwrap();
    let ServerMessage::Geo(Geo::GroundVehicle {
        dimensions,
        wheel_radius,
        ..
    }) = server(line)
    else {
        panic!()
    };
    assert_eq!(
        (dimensions, wheel_radius),
        (Vec3::new(0.248, 0.36, 0.0), 0.098)
    );
}

#[test]
fn every_protocol_example_reads() {
    let mut count = 0;
    for line in EXAMPLES.lines().filter(|l| !l.starts_with('#')) {
        let (tag, text) = line.split_at(2);
        match tag {
            "C " => {
                command(text);
            }
            "S " => assert_eq!(server(text).to_string(), text),
            "R " => {
                server(text);
            }
            _ => panic!("bad data line {line:?}"),
        }
        count += 1;
    }
    assert!(count > 90, "{count}");
}

#[test]
fn dialect_values() {
    let drive = |line| match command(line) {
        (Command::Drive(d), dev) => (d, dev),
        other => panic!("{other:?}"),
    };
    let (d, dev) = drive("DRIVE {Left 1,00} {Right 1,00}");
    assert_eq!((d.left, d.right), (Some(1.0), Some(1.0)));
    assert_eq!(dev[0].to_string(), "decimal comma in {Left 1,00}");
    let (d, dev) = drive("DRIVE {LinearVelocity +1,00}");
    assert_eq!(d.linear_velocity, Some(1.0));
    assert_eq!(dev.len(), 2);
    let (d, dev) = drive("DRIVE {AltitudeVelocity 50} {Normalized True}");
    assert_eq!(
        d,
        Drive {
            altitude_velocity: Some(50.0),
            normalized: Some(false),
            ..Drive::default()
        }
    );
    assert_eq!(
        dev,
        vec![Deviation::BoolCase {
            key: "Normalized".into(),
            value: "True".into()
        }]
    );
    let location = |line| match command(line) {
        (Command::Init(i), dev) => (i.location.unwrap(), dev),
        other => panic!("{other:?}"),
    };
    assert_eq!(
        location("INIT {ClassName USARBot.AirRobot} {Location 0.000000 0.000000 1.000000}").0,
        Vec3::new(0.0, 0.0, 1.0)
    );
    assert_eq!(
        location("INIT {ClassName USARBot.AirRobot} {Location .4, .4, 1.8}"),
        (Vec3::new(0.4, 0.4, 1.8), vec![])
    );
    let (v, dev) = location("INIT {ClassName USARBot.AirRobot} {Location 0,0000, 0,0000, 0,0000}");
    assert_eq!(v, Vec3::new(0.0, 0.0, 0.0));
    assert!(
        matches!(&dev[0], Deviation::AmbiguousVector { udk_reads, .. } if udk_reads == "0,0,0")
    );

    let ServerMessage::Sen(Sen {
        data: SenData::Sonar { readings, grouped },
        ..
    }) = server("SEN {Time 45.14} {Type Sonar} {Name F1 Range 4.4690} {Name F2 Range 1.9387}")
    else {
        panic!()
    };
    assert!(grouped);
    assert_eq!(
        (readings[1].name.as_str(), readings[1].range),
        ("F2", 1.9387)
    );
    let ServerMessage::Nfo(Nfo::StartPoses { poses, .. }) = server(
        "NFO {StartPoses 2} {Point1 1.0000,2.0000,-0.5000 0.0000,0.0000,1.5708 Point2 -3.0000,4.0000,-0.5000 0.0000,0.0000,-3.4361}",
    ) else {
        panic!()
    };
    assert_eq!(poses[1].rotation, Vec3::new(0.0, 0.0, -3.4361));
    let ServerMessage::Conf(Conf::Items { items, .. }) = server(
        "CONF {Type Sonar} {Name S1} {MaxRange 5.0000} {MinRange 0.1000} {ScanInterval 0.2000} {beamAngle 0.3489} {maxAngleOfIncidence 0.1745} {tracesPerCone 16} {numberOfCones 10}",
    ) else {
        panic!()
    };
    assert!(
        matches!(items[0], ConfItem::Sonar { beam_angle, traces_per_cone: 16, .. } if beam_angle == 0.3489)
    );
}

/// Unescapes `\r` and `\n` in a CHUNK line.
fn unescape(s: &str) -> String {
    s.replace("\\r", "\r").replace("\\n", "\n")
}

#[test]
fn parser_regression_chunks_through_the_codec() {
    let mut codec = CommandCodec::default();
    let mut buf = BytesMut::new();
    let mut got = Vec::new();
    for line in REGRESSIONS.lines() {
        if let Some(chunk) = line.strip_prefix("CHUNK ") {
            buf.extend_from_slice(unescape(chunk).as_bytes());
            while let Some(item) = codec.decode(&mut buf).unwrap() {
                let Command::Other(m) = item.unwrap().message else {
                    panic!()
                };
                let pairs: Vec<String> = m
                    .groups
                    .iter()
                    .flat_map(|g| &g.pairs)
                    .map(|p| format!("{}={}", p.key, p.value))
                    .collect();
                got.push(format!("{} {}", m.kind, pairs.join(" ")));
            }
        }
    }
    let expected: Vec<&str> = REGRESSIONS
        .lines()
        .filter_map(|l| l.strip_prefix("EXPECT "))
        .collect();
    assert_eq!(got, expected);
    assert!(codec.decode_eof(&mut buf).unwrap().is_none());
}

/// Lines real servers print that do not fit our typed layouts: fields missing, glued groups,
/// odd spacing. Each must read (typed or generic) and print back exactly.
const SHORT_LINES: &[&str] = &[
    "SEN {Time 12.5000} {Type IMU}",
    "SEN {Time 12.5000} {Type Sonar} ",
    "SEN {Time 12.5000} {Type RangeScanner} {Name Scanner}",
    "SEN {Type INS} {Name InsTest} {Location 0.00,0.00,-0.20}",
    "GEO {Type GroundVehicle} {Name P3AT} {Orientation 0.00,0.00,0.00}{Mount P3AT}",
    "GEO  {Name P3AT} {Type GroundVehicle} {Dimensions 0.2480,0.3600,0.0000}",
    "CONF {Type Sonar} {Name F1} {MaxRange 5.0000}",
    "STA {Time 477.7582}",
    "ASTA {Time 1.0000} {Link 1} {Value 0.5000}",
    "NFO {Gametype BotDeathMatch}",
    "SEN {Time 1.0} {Type Sonar} {Name S} {Range 1,2}",
];

#[test]
fn every_valid_server_line_reads_and_prints_back_exactly() {
    for line in SHORT_LINES {
        let m = server(line);
        assert_eq!(m.to_string(), *line, "{m:?}");
    }
    // What did not fit is the generic form, with what the line holds.
    let ServerMessage::Other(m) = server("SEN {Time 12.5000} {Type IMU}") else {
        panic!()
    };
    assert_eq!((m.kind.as_str(), m.get("Type")), ("SEN", Some("IMU")));
    // Strict reading still says what did not fit.
    let e = ServerMessage::parse_strict("SEN {Time 12.5000} {Type IMU}").unwrap_err();
    assert!(e.to_string().contains("Name"), "{e}");
}

/// Real UDK GEO lines with a space before `{Mount ..}` (issue #55: the GEO lines of the
/// capture as other UDK builds print them), and one with both spacings.
/// A line and what it must read as: name, location, mount, mount link.
type GeoCase = (
    &'static str,
    &'static str,
    [f64; 3],
    &'static str,
    Option<i64>,
);

const SPACED_GEO: &[GeoCase] = &[
    (
        "GEO {Type RangeScanner} {Name lms200} {Location 0.21,-0.00,-0.20} {Orientation 0.00,-0.00,-0.00} {Mount P3AT}",
        "lms200",
        [0.21, 0.0, -0.2],
        "P3AT",
        None,
    ),
    (
        "GEO {Type INS} {Name InsTest} {Location -0.00,-0.00,-0.20} {Orientation 0.00,-0.00,-0.00} {Mount P3AT}",
        "InsTest",
        [0.0, 0.0, -0.2],
        "P3AT",
        None,
    ),
    (
        "GEO {Type Camera} {Name Camera} {Location 0.10,-0.00,-0.42} {Orientation 0.00,-0.00,-0.00} {Mount P3AT}",
        "Camera",
        [0.1, 0.0, -0.42],
        "P3AT",
        None,
    ),
    (
        "GEO {Type GroundTruth} {Name GndTruth} {Location 0.00,0.00,-0.00} {Orientation 0.00,-0.00,-0.00} {Mount P3AT}",
        "GndTruth",
        [0.0, 0.0, 0.0],
        "P3AT",
        None,
    ),
    (
        "GEO {Type Camera} {Name cams} {Location 0.10,-0.00,0.05} {Orientation 0.00,-0.79,0.00} {Mount cam}{MountLink 1}",
        "cams",
        [0.1, 0.0, 0.05],
        "cam",
        Some(1),
    ),
    (
        "GEO {Type Camera} {Name cams} {Location 0.10,-0.00,0.05} {Orientation 0.00,-0.79,0.00} {Mount cam} {MountLink 1}",
        "cams",
        [0.1, 0.0, 0.05],
        "cam",
        Some(1),
    ),
];

#[test]
fn geo_lines_with_a_space_before_mount_read_typed_and_print_back_exactly() {
    for &(line, name, location, mount, mount_link) in SPACED_GEO {
        let m = server(line);
        let ServerMessage::Geo(Geo::Items { items, .. }) = &m else {
            panic!("{line}: {m:?}")
        };
        let it = &items[0];
        assert_eq!(
            (
                it.name.as_str(),
                it.location,
                it.mount.as_str(),
                it.mount_link
            ),
            (
                name,
                Vec3::new(location[0], location[1], location[2]),
                mount,
                mount_link
            ),
            "{line}"
        );
        assert_eq!(m.to_string(), line);
        // Strict reading agrees: nothing is missing.
        assert!(ServerMessage::parse_strict(line).is_ok(), "{line}");
    }
    // The layout is per item: one glued, one spaced, in one line.
    let line = "GEO {Type Sonar} {Name F1} {Location 0.19,-0.12,0.00} {Orientation 0.00,0.00,-0.87}{Mount P3AT} {Name F2} {Location 0.19,0.12,0.00} {Orientation 0.00,0.00,0.87} {Mount P3AT}";
    let m = server(line);
    assert!(matches!(&m, ServerMessage::Geo(Geo::Items { items, .. }) if items.len() == 2));
    assert_eq!(m.to_string(), line);
    // Our own (glued) lines still print back exactly.
    for line in capture_lines().filter(|l| l.starts_with("GEO")) {
        assert_eq!(server(line).to_string(), line);
    }
}
