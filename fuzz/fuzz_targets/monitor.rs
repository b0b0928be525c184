//! Robot monitor (TCP 7435) lines from arbitrary text, answered from a world with robots:
//! never a panic; `GETPOS` lists every robot with finite coordinates; `GETOBS` counts whole
//! walls (or −1); replies are one line; unknown commands get none.
#![no_main]

use libfuzzer_sys::fuzz_target;
use usar_server::net::monitor;

mod common;

fuzz_target!(|text: &str| {
    common::with(|world, _| {
        for line in text.split(['\r', '\n']).take(64) {
            let Some(reply) = monitor::reply(world, line) else {
                continue;
            };
            assert!(!reply.contains(['\r', '\n']), "{reply:?}");
            if reply.starts_with("POSITIONS") {
                common::check_numbers(&reply);
            } else if let Some(count) = reply
                .rsplit("{ObstCount ")
                .next()
                .filter(|_| reply.starts_with("NUMOBS"))
            {
                let n: f64 = count.trim_end_matches('}').parse().expect("a number");
                assert!(n == -1.0 || (n >= 0.0 && n.fract() == 0.0), "{reply:?}");
            } else {
                assert!(reply.is_empty(), "{reply:?} for {line:?}");
            }
        }
    });
});
