//! Arbitrary text through the generic and typed parsers: never a panic, and every server
//! message that was read prints to a line that reads back to the same message.
#![no_main]

use libfuzzer_sys::fuzz_target;
use usar_proto::{Command, Message, ServerMessage};

fuzz_target!(|text: &str| {
    let _ = Message::parse(text);
    let _ = Message::parse_udk(text);
    if let Ok(p) = Command::parse(text) {
        let line = p.message.to_string();
        let _ = Command::parse(&line);
    }
    if let Ok(p) = ServerMessage::parse(text) {
        let line = p.message.to_string();
        if let Ok(again) = ServerMessage::parse(&line) {
            // Printing is stable once the numbers are canonical.
            let canonical = again.message.to_string();
            let third = ServerMessage::parse(&canonical).map(|m| m.message.to_string());
            assert_eq!(third.as_deref(), Ok(canonical.as_str()));
        }
    }
});
