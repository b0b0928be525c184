//! Decodes a capture of server lines (a file of real USARSim output, or a `--record`
//! recording's lines without their stamps) with the typed model, and counts what it read.
//!
//! ```text
//! cargo run -p usar-proto --example decode_capture -- capture.txt
//! ```
//!
//! Without a file it decodes a few lines of real UDK output.

use std::collections::BTreeMap;

use usar_proto::{SenData, ServerMessage};

/// Lines of real UDK-USARSim output (the RoboCupRescuePackage's command sample).
const SAMPLE: &str = "\
NFO {Gametype BotDeathMatch} {Level DM-RoboCup2009_Compact} {TimeLimit 0}
STA {Type GroundVehicle} {Time 477.7743} {FrontSteer 0.0000} {RearSteer 0.0000} {LightToggle False} {LightIntensity 0} {Battery 3599}
SEN {Time 477.7743} {Type Camera} 
SEN {Time 477.7743} {Type GroundTruth} {Name GroundTruth} {Location 0.52,-1.91,1.85} {Orientation 0.00,0.00,4.71}
";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let text = match std::env::args_os().nth(1) {
        Some(path) => std::fs::read_to_string(path)?,
        None => SAMPLE.to_owned(),
    };
    let mut kinds: BTreeMap<String, usize> = BTreeMap::new();
    let mut generic = 0;
    for (number, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let parsed = match ServerMessage::parse(line) {
            Ok(parsed) => parsed,
            Err(e) => {
                println!("line {}: not a server message: {e}", number + 1);
                continue;
            }
        };
        let kind = match &parsed.message {
            ServerMessage::Sen(sen) => {
                if let SenData::GroundTruth { location, .. } = &sen.data {
                    println!("line {}: ground truth at {location:?}", number + 1);
                }
                format!("SEN {}", sen.data.kind())
            }
            ServerMessage::Other(_) => {
                generic += 1;
                "other (kept generic)".to_owned()
            }
            message => message
                .to_string()
                .split(' ')
                .next()
                .unwrap_or("")
                .to_owned(),
        };
        *kinds.entry(kind).or_default() += 1;
    }
    for (kind, count) in &kinds {
        println!("{count:6}  {kind}");
    }
    println!("{generic} line(s) without a typed model");
    Ok(())
}
