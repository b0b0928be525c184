//! Property tests: `parse(print(m)) == m` for generated typed messages of every kind (after
//! canonicalising the generated numbers through one print/parse), and no input panics the
//! parsers or the codecs.

use bytes::BytesMut;
use proptest::prelude::*;
use tokio_util::codec::Decoder;
use usar_proto::codec::{CommandCodec, LineCodec, ServerCodec};
use usar_proto::*;

fn word() -> impl Strategy<Value = String> {
    "[A-Za-z][A-Za-z0-9_]{0,7}"
}

/// A word that is no known keyword (prefix `Zq`).
fn odd_word() -> impl Strategy<Value = String> {
    "Zq[a-z0-9]{0,5}"
}

fn token() -> impl Strategy<Value = String> {
    "[a-z0-9.,+-]{1,6}"
}

fn num() -> impl Strategy<Value = f64> {
    prop_oneof![-1.0e4..1.0e4f64, Just(0.0), Just(-0.0), -2.0..2.0f64]
}

fn v3() -> impl Strategy<Value = Vec3> {
    (num(), num(), num()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn time() -> impl Strategy<Value = Time> {
    (0.0..1.0e5f64, prop_oneof![Just(2u8), Just(4u8)])
        .prop_map(|(seconds, decimals)| Time { seconds, decimals })
}

fn int() -> impl Strategy<Value = i64> {
    -100_000..100_000i64
}

/// Groups of single-token pairs with keys that are words (one or two pairs per group).
fn groups() -> impl Strategy<Value = Vec<Group>> {
    prop::collection::vec(
        prop::collection::vec(
            (odd_word(), token()).prop_map(|(key, value)| Pair { key, value }),
            1..=2,
        )
        .prop_map(|pairs| Group { pairs }),
        0..4,
    )
}

fn link_values() -> impl Strategy<Value = Vec<LinkValue>> {
    prop::collection::vec(
        (-5..50i64, num()).prop_map(|(link, value)| LinkValue { link, value }),
        0..4,
    )
}

fn flag() -> impl Strategy<Value = Option<bool>> {
    prop::option::of(any::<bool>())
}

fn command() -> impl Strategy<Value = Command> {
    let o = || prop::option::of(num());
    let drive = (
        (o(), o(), o(), o(), o(), o(), o(), o()),
        (o(), o(), o(), o(), o(), flag(), flag()),
    )
        .prop_map(|((a, b, c, d, e, f, g, h), (i, j, k, l, m, n, p))| {
            Command::Drive(Drive {
                altitude_velocity: a,
                linear_velocity: b,
                lateral_velocity: c,
                rotational_velocity: d,
                pitch_angle: e,
                roll_angle: f,
                spin1: g,
                spin2: h,
                left: i,
                right: j,
                speed: k,
                front_steer: l,
                rear_steer: m,
                normalized: n,
                light: p,
            })
        });
    let init = (
        "USARBot\\.[A-Za-z]{1,10}",
        prop::option::of(word()),
        prop::option::of(v3()),
        prop::option::of(v3()),
        prop::option::of(word()),
    )
        .prop_map(|(class_name, name, location, rotation, start)| {
            Command::Init(Init {
                class_name,
                name,
                location,
                rotation,
                start,
            })
        });
    let query =
        || (word(), prop::option::of(word())).prop_map(|(kind, name)| ItemQuery { kind, name });
    prop_oneof![
        init,
        drive,
        Just(Command::GetStartPoses),
        query().prop_map(Command::GetConf),
        query().prop_map(Command::GetGeo),
        (
            word(),
            prop::option::of(word()),
            word(),
            prop::option::of(token())
        )
            .prop_map(|(kind, name, opcode, params)| Command::Set(Set {
                kind,
                name,
                opcode,
                params
            })),
        (
            word(),
            link_values(),
            prop::option::of(int()),
            prop::option::of(int())
        )
            .prop_map(|(name, links, gripper, sequence)| Command::Act(Act {
                name,
                links,
                gripper,
                sequence
            })),
        (word(), link_values(), prop::option::of(int()))
            .prop_map(|(name, links, order)| Command::MisPkg(MisPkg { name, links, order })),
        ("ZQ[A-Z]{0,6}", groups()).prop_map(|(kind, groups)| {
            // The UDK reading has one pair per group.
            let groups = groups
                .into_iter()
                .map(|mut g| {
                    g.pairs.truncate(1);
                    g
                })
                .collect();
            Command::Other(Message {
                kind,
                groups,
                verbatim: None,
            })
        }),
    ]
}

fn sen_data() -> impl Strategy<Value = SenData> {
    let named_ranges = prop::collection::vec(
        (word(), num()).prop_map(|(name, range)| NamedRange { name, range }),
        0..4,
    );
    let ticks = prop::collection::vec(
        (word(), int()).prop_map(|(name, tick)| NamedTick { name, tick }),
        0..4,
    );
    let list = || prop::collection::vec(num(), 0..6);
    let coordinate = || (0..180i64, 0.0..60.0f64);
    let gps_fix = (coordinate(), coordinate(), any::<bool>(), any::<bool>()).prop_map(
        |((ld, lm), (od, om), n, e)| GpsFix {
            latitude_degrees: ld,
            latitude_minutes: lm,
            latitude_hemisphere: if n { 'N' } else { 'S' },
            longitude_degrees: od,
            longitude_minutes: om,
            longitude_hemisphere: if e { 'E' } else { 'W' },
        },
    );
    prop_oneof![
        (word(), v3(), v3(), v3(), v3()).prop_map(|(name, a, b, c, d)| SenData::Imu {
            name,
            acceleration: a,
            angular_vel: b,
            angular_accel: c,
            rotation: d
        }),
        (named_ranges, any::<bool>())
            .prop_map(|(readings, grouped)| SenData::Sonar { readings, grouped }),
        (
            prop_oneof![Just("RangeScanner"), Just("IRScanner")],
            word(),
            num(),
            num(),
            list(),
            prop_oneof![Just(2u8), Just(4u8)]
        )
            .prop_map(|(kind, name, resolution, fov, ranges, range_decimals)| {
                SenData::RangeScanner(Scan {
                    kind: kind.into(),
                    name,
                    resolution,
                    fov,
                    ranges,
                    range_decimals,
                })
            }),
        (word(), v3(), v3(), prop_oneof![Just(2u8), Just(3u8)]).prop_map(
            |(name, location, orientation, decimals)| SenData::GroundTruth {
                name,
                location,
                orientation,
                decimals
            }
        ),
        (word(), v3(), v3()).prop_map(|(name, location, orientation)| SenData::Ins {
            name,
            location,
            orientation
        }),
        (word(), prop::option::of(gps_fix), 0..20i64).prop_map(|(name, fix, satellites)| {
            SenData::Gps {
                name,
                fix,
                satellites,
            }
        }),
        (word(), v3()).prop_map(|(name, pose)| SenData::Odometry { name, pose }),
        (ticks, any::<bool>()).prop_map(|(ticks, grouped)| SenData::Encoder { ticks, grouped }),
        (word(), list(), list()).prop_map(|(name, vel, pos)| SenData::Tachometer {
            name,
            vel,
            pos
        }),
        (word(), any::<bool>()).prop_map(|(name, touch)| SenData::Touch { name, touch }),
        (word(), v3()).prop_map(|(name, acceleration)| SenData::Accel { name, acceleration }),
        (word(), v3()).prop_map(|(name, proper_acceleration)| SenData::AcceleroMeter {
            name,
            proper_acceleration
        }),
        (word(), num()).prop_map(|(name, range)| SenData::Ir(NamedRange { name, range })),
        (word(), num(), num()).prop_map(|(name, relative, absolute)| {
            SenData::AltitudeSensor {
                name,
                relative,
                absolute,
            }
        }),
        (word(), num()).prop_map(|(name, angle)| SenData::MagneticCompass { name, angle }),
        (word(), int()).prop_map(|(name, minutes)| SenData::MissionTime { name, minutes }),
        Just(SenData::Camera),
        (word(), v3()).prop_map(|(name, location)| SenData::Position { name, location }),
        (word(), v3(), v3()).prop_map(|(name, absolute, relative)| SenData::Velocity {
            name,
            absolute,
            relative
        }),
        (odd_word(), groups()).prop_map(|(kind, groups)| SenData::Other { kind, groups }),
    ]
}

fn conf_item() -> impl Strategy<Value = ConfItem> {
    let joint = (int(), word(), num(), num(), num()).prop_map(
        |(link, joint_type, max_torque, min_value, max_value)| ActuatorJoint {
            link,
            joint_type,
            max_torque,
            min_value,
            max_value,
        },
    );
    prop_oneof![
        word().prop_map(|name| ConfItem::Plain { name }),
        (word(), num(), num()).prop_map(|(name, max_range, min_range)| ConfItem::Range {
            name,
            max_range,
            min_range
        }),
        (word(), (num(), num(), num(), num(), num()), int(), int()).prop_map(
            |(name, (a, b, c, d, e), t, n)| ConfItem::Sonar {
                name,
                max_range: a,
                min_range: b,
                scan_interval: c,
                beam_angle: d,
                max_angle_of_incidence: e,
                traces_per_cone: t,
                number_of_cones: n
            }
        ),
        (
            word(),
            (num(), num(), num(), num()),
            any::<(bool, bool, bool)>()
        )
            .prop_map(|(name, (a, b, c, d), (panning, tilting, paning_typo))| {
                ConfItem::Scanner {
                    name,
                    max_range: a,
                    min_range: b,
                    resolution: c,
                    fov: d,
                    panning,
                    tilting,
                    paning_typo,
                }
            }),
        (word(), num()).prop_map(|(name, scan_interval)| ConfItem::Interval {
            name,
            scan_interval
        }),
        (
            word(),
            (int(), int(), int(), int()),
            (num(), num(), num(), num())
        )
            .prop_map(|(name, (a, b, c, d), (e, f, g, h))| ConfItem::Camera {
                name,
                texture_offset_x: a,
                texture_offset_y: b,
                texture_resolution_x: c,
                texture_resolution_y: d,
                default_fov: e,
                min_fov: f,
                max_fov: g,
                fov: h
            }),
        (word(), prop::collection::vec(joint, 1..3))
            .prop_map(|(name, joints)| ConfItem::Actuator { name, joints }),
        (
            word(),
            groups().prop_filter("needs a group", |g| !g.is_empty())
        )
            .prop_map(|(name, mut groups)| {
                groups.insert(
                    0,
                    Group {
                        pairs: vec![Pair {
                            key: "Name".into(),
                            value: name,
                        }],
                    },
                );
                ConfItem::Other { groups }
            }),
    ]
}

fn server_message() -> impl Strategy<Value = ServerMessage> {
    let pose = ("P[a-z0-9_]{0,6}", v3(), v3()).prop_map(|(name, location, rotation)| StartPose {
        name,
        location,
        rotation,
    });
    let vehicle = (
        word(),
        flag(),
        prop::option::of(int()),
        prop::option::of(num()),
        prop::option::of(num()),
    )
        .prop_map(
            |(kind, light_toggle, light_intensity, front_steer, rear_steer)| VehicleStatus {
                kind,
                light_toggle,
                light_intensity,
                front_steer,
                rear_steer,
            },
        );
    let geo_item = (
        word(),
        v3(),
        v3(),
        word(),
        prop::option::of(int()),
        prop_oneof![
            Just(GeoLayout::Glued),
            Just(GeoLayout::Spaced),
            Just(GeoLayout::SpacedLink)
        ],
    )
        .prop_map(
            |(name, location, orientation, mount, mount_link, layout)| GeoItem {
                name,
                location,
                orientation,
                mount,
                // Without a MountLink, SpacedLink prints (and reads) as Spaced.
                layout: match (layout, mount_link) {
                    (GeoLayout::SpacedLink, None) => GeoLayout::Spaced,
                    (layout, _) => layout,
                },
                mount_link,
            },
        );
    prop_oneof![
        (word(), word(), int()).prop_map(|(gametype, level, time_limit)| {
            ServerMessage::Nfo(Nfo::GameInfo {
                gametype,
                level,
                time_limit,
            })
        }),
        (prop::collection::vec(pose, 0..4), any::<bool>()).prop_map(|(poses, old_layout)| {
            ServerMessage::Nfo(Nfo::StartPoses { poses, old_layout })
        }),
        (
            time(),
            int(),
            prop::option::of(vehicle),
            prop::option::of(int())
        )
            .prop_map(|(time, battery, vehicle, view)| ServerMessage::Sta(Sta {
                time,
                battery,
                vehicle,
                layout: view.map_or(StaLayout::Udk, |view| StaLayout::Ut2004 { view })
            })),
        (prop::option::of(time()), sen_data())
            .prop_map(|(time, data)| ServerMessage::Sen(Sen { time, data })),
        word().prop_map(|name| ServerMessage::Conf(Conf::Robot { name })),
        (word(), word(), (num(), num(), num()), int(), int()).prop_map(
            |(name, steering_type, (mass, max_speed, max_torque), f, r)| {
                ServerMessage::Conf(Conf::GroundVehicle {
                    name,
                    steering_type,
                    mass,
                    max_speed,
                    max_torque,
                    max_front_steer: f,
                    max_rear_steer: r,
                })
            }
        ),
        (word(), prop::collection::vec(conf_item(), 0..3))
            .prop_map(|(kind, items)| ServerMessage::Conf(Conf::Items { kind, items })),
        word().prop_map(|name| ServerMessage::Geo(Geo::Robot { name })),
        (word(), v3(), v3(), (num(), num(), num())).prop_map(
            |(name, dimensions, cog, (wheel_radius, wheel_separation, wheel_base))| {
                ServerMessage::Geo(Geo::GroundVehicle {
                    name,
                    dimensions,
                    cog,
                    wheel_radius,
                    wheel_separation,
                    wheel_base,
                })
            }
        ),
        (word(), prop::collection::vec(geo_item, 0..3))
            .prop_map(|(kind, items)| ServerMessage::Geo(Geo::Items { kind, items })),
        (time(), word(), link_values()).prop_map(|(time, name, links)| ServerMessage::Asta(Asta {
            time,
            name,
            links
        })),
        (time(), word(), word(), any::<bool>()).prop_map(|(time, kind, name, on)| {
            ServerMessage::Eff(Eff {
                time,
                kind,
                name,
                on,
            })
        }),
        (word(), word()).prop_map(|(killer, damage_type)| ServerMessage::Die(Die {
            killer,
            damage_type
        })),
        ("ZQ[A-Z]{0,6}", groups()).prop_map(|(kind, groups)| {
            ServerMessage::Other(Message {
                kind,
                groups,
                verbatim: None,
            })
        }),
    ]
}

fn reparse_server(m: &ServerMessage) -> ServerMessage {
    let line = m.to_string();
    ServerMessage::parse(&line)
        .unwrap_or_else(|e| panic!("{line}: {e}"))
        .message
}

fn reparse_command(c: &Command) -> Command {
    let line = c.to_string();
    Command::parse(&line)
        .unwrap_or_else(|e| panic!("{line}: {e}"))
        .message
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn server_messages_round_trip(m in server_message()) {
        let canonical = reparse_server(&m);
        let line = canonical.to_string();
        prop_assert_eq!(reparse_server(&canonical), canonical.clone(), "{}", line);
        prop_assert_eq!(line, m.to_string());
    }

    #[test]
    fn commands_round_trip(c in command()) {
        // Shortest round-trip numbers: no canonicalisation needed.
        prop_assert_eq!(reparse_command(&c), c);
    }

    #[test]
    fn no_text_panics_the_parsers(line in "[A-Za-z0-9 {},.+-]{0,60}|\\PC{0,60}") {
        let _ = Message::parse(&line);
        if let Ok(p) = Command::parse(&line) {
            let _ = p.message.to_string();
            for d in p.deviations {
                let _ = d.to_string();
            }
        }
        if let Ok(p) = ServerMessage::parse(&line) {
            let _ = reparse_server(&p.message);
        }
    }

    #[test]
    fn no_bytes_panic_the_codecs(
        chunks in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..40), 0..8),
        max in 1..64usize,
    ) {
        let mut lines = LineCodec::new(max);
        let mut commands = CommandCodec::new(max);
        let mut servers = ServerCodec::new(max);
        let (mut a, mut b, mut c) = (BytesMut::new(), BytesMut::new(), BytesMut::new());
        for chunk in &chunks {
            a.extend_from_slice(chunk);
            b.extend_from_slice(chunk);
            c.extend_from_slice(chunk);
            while let Some(item) = lines.decode(&mut a).unwrap() {
                if let Ok(line) = item {
                    prop_assert!(line.len() <= max * 3);
                }
            }
            while commands.decode(&mut b).unwrap().is_some() {}
            while servers.decode(&mut c).unwrap().is_some() {}
            // Memory stays bounded by the limit.
            prop_assert!(a.len() <= max);
        }
        while lines.decode_eof(&mut a).unwrap().is_some() {}
        while commands.decode_eof(&mut b).unwrap().is_some() {}
        while servers.decode_eof(&mut c).unwrap().is_some() {}
    }
}
