//! USARTruth (TCP 3989) queries from arbitrary text, answered from a world with robots and
//! victims: never a panic; every answer is the matching actors' lines then `{End}`, with
//! finite numbers and no line end inside a line.
#![no_main]

use libfuzzer_sys::fuzz_target;
use usar_server::net::truth;

mod common;

fuzz_target!(|text: &str| {
    common::with(|world, actors| {
        // Lines end at CR, LF or CR LF, as the server reads them.
        for line in text.split(['\r', '\n']).take(64) {
            let answer = truth::reply(world, line);
            let body = answer
                .strip_suffix("{End}\r\n")
                .unwrap_or_else(|| panic!("no {{End}}: {answer:?}"));
            let lines: Vec<&str> = body.split_terminator("\r\n").collect();
            assert!(lines.len() <= actors, "{answer:?}");
            for l in lines {
                assert!(l.starts_with("{Name ") && l.ends_with('}'), "{l:?}");
                assert!(!l.contains(['\r', '\n']), "{l:?}");
                common::check_numbers(l);
            }
        }
    });
});
