//! Parse and print the stream one stsAirRobot produces (protocol.md §9), in its real
//! proportions: per 0.6 s, 6 × (STA, IMU, Position, Velocity) at 10 Hz, 3 × 10 sonars at
//! 5 Hz and 2 laser scans of 228 ranges at 3.3 Hz.

use criterion::{Criterion, Throughput, criterion_group};
use std::hint::black_box;
use usar_proto::{NamedRange, Scan, Sen, SenData, ServerMessage, Sta, StaLayout, Time, Vec3};

/// A small deterministic generator of plausible readings.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn in_range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
    fn vec3(&mut self, r: f64) -> Vec3 {
        Vec3::new(
            self.in_range(-r, r),
            self.in_range(-r, r),
            self.in_range(-r, r),
        )
    }
}

fn sen(t: f64, data: SenData) -> ServerMessage {
    ServerMessage::Sen(Sen {
        time: Some(Time::udk(t)),
        data,
    })
}

/// Ten seconds of one robot's output (100 periods of 0.1 s).
fn stream() -> Vec<ServerMessage> {
    let mut g = Lcg(7);
    let mut out = Vec::new();
    for tick in 0..100u32 {
        let t = 12.0 + f64::from(tick) * 0.1 + g.in_range(0.0, 0.01);
        out.push(ServerMessage::Sta(Sta {
            time: Time::udk(t),
            battery: 1200 - i64::from(tick / 10),
            vehicle: None,
            layout: StaLayout::Udk,
        }));
        out.push(sen(
            t,
            SenData::Imu {
                name: "IMU".into(),
                acceleration: g.vec3(0.5),
                angular_vel: g.vec3(0.2),
                angular_accel: g.vec3(0.5),
                rotation: g.vec3(3.0),
            },
        ));
        out.push(sen(
            t,
            SenData::Position {
                name: "Position".into(),
                location: g.vec3(30.0),
            },
        ));
        out.push(sen(
            t,
            SenData::Velocity {
                name: "Velocity".into(),
                absolute: g.vec3(2.0),
                relative: g.vec3(2.0),
            },
        ));
        if tick % 2 == 0 {
            let names = [
                "Sonar0",
                "Sonar1",
                "Sonar2",
                "Sonar3",
                "Sonar4",
                "Sonar5",
                "Sonar6",
                "Sonar7",
                "SonarTop",
                "SonarBottom",
            ];
            for name in names {
                let reading = NamedRange {
                    name: name.into(),
                    range: g.in_range(0.1, 5.0),
                };
                out.push(sen(
                    t,
                    SenData::Sonar {
                        readings: vec![reading],
                        grouped: false,
                    },
                ));
            }
        }
        if tick % 3 == 0 {
            out.push(sen(
                t,
                SenData::RangeScanner(Scan {
                    kind: "RangeScanner".into(),
                    name: "Scanner".into(),
                    resolution: 0.0184,
                    fov: 4.1889,
                    ranges: (0..228).map(|_| g.in_range(0.1, 4.0)).collect(),
                    range_decimals: 2,
                }),
            ));
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    let messages = stream();
    let mut text = String::new();
    for m in &messages {
        m.write_line(&mut text);
    }
    let lines: Vec<&str> = text.lines().collect();
    let bytes = text.len() as u64;

    let mut group = c.benchmark_group("stsAirRobot stream");
    group.throughput(Throughput::Bytes(bytes));
    group.bench_function("parse", |b| {
        b.iter(|| {
            for line in &lines {
                black_box(ServerMessage::parse(black_box(line)).ok());
            }
        })
    });
    // Printed into bytes, as the server does (into the BytesMut of a tick).
    let mut out: Vec<u8> = Vec::with_capacity(text.len() * 2);
    group.bench_function("print", |b| {
        b.iter(|| {
            out.clear();
            for m in &messages {
                m.write_line(&mut out);
            }
            black_box(out.len())
        })
    });
    let parse_print = |out: &mut Vec<u8>| {
        out.clear();
        for line in &lines {
            if let Ok(p) = ServerMessage::parse(line) {
                p.message.write_line(out);
            }
        }
        black_box(out.len());
    };
    group.bench_function("parse+print", |b| b.iter(|| parse_print(&mut out)));
    group.throughput(Throughput::Elements(messages.len() as u64));
    group.bench_function("parse+print messages", |b| b.iter(|| parse_print(&mut out)));
    group.finish();
}

/// `USAR_PROTO_PASSES=parse:20` (or `print:20`) runs that many plain passes over the stream
/// instead of the benchmarks, for instruction counts under callgrind: run it with N and with
/// 0 passes and divide the difference by N × the stream's bytes (printed on stderr).
fn passes(spec: &str) {
    let (what, n) = spec
        .split_once(':')
        .expect("USAR_PROTO_PASSES=parse:N or print:N");
    let n: usize = n.parse().expect("a number of passes");
    let messages = stream();
    let mut text = String::new();
    for m in &messages {
        m.write_line(&mut text);
    }
    let lines: Vec<&str> = text.lines().collect();
    let mut out: Vec<u8> = Vec::with_capacity(text.len() * 2);
    for _ in 0..n {
        match what {
            "parse" => {
                for line in &lines {
                    black_box(ServerMessage::parse(black_box(line)).ok());
                }
            }
            "print" => {
                out.clear();
                for m in &messages {
                    m.write_line(&mut out);
                }
                black_box(out.len());
            }
            _ => panic!("USAR_PROTO_PASSES=parse:N or print:N"),
        }
    }
    eprintln!("{} lines, {} bytes", messages.len(), text.len());
}

criterion_group!(benches, bench);

fn main() {
    match std::env::var("USAR_PROTO_PASSES") {
        Ok(spec) => passes(&spec),
        Err(_) => {
            benches();
            Criterion::default().configure_from_args().final_summary();
        }
    }
}
