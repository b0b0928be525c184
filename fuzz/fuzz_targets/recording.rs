//! Arbitrary text as a recording or capture to replay: never a panic, only finite times.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|text: &str| {
    if let Ok(lines) = usar_server::replay::parse(text, "fuzz.usarlog") {
        assert!(lines.iter().all(|l| l.time.is_none_or(f64::is_finite)));
    }
    for line in text.lines() {
        if let Ok(Some(entry)) = usar_proto::record::parse_entry(line) {
            assert!(entry.time.is_finite());
        }
    }
});
