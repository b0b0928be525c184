//! Arbitrary bytes, cut into arbitrary chunks, through the line and typed codecs: never a
//! panic, and the buffer never holds more than the line limit.
#![no_main]

use bytes::BytesMut;
use libfuzzer_sys::fuzz_target;
use tokio_util::codec::Decoder;
use usar_proto::codec::{CommandCodec, LineCodec, ServerCodec};

const MAX: usize = 256;

fuzz_target!(|data: &[u8]| {
    let mut lines = LineCodec::new(MAX);
    let mut commands = CommandCodec::new(MAX);
    let mut servers = ServerCodec::new(MAX);
    let (mut a, mut b, mut c) = (BytesMut::new(), BytesMut::new(), BytesMut::new());
    // The first byte of each chunk gives its length.
    let mut rest = data;
    while let Some((&n, tail)) = rest.split_first() {
        let (chunk, tail) = tail.split_at(usize::from(n).min(tail.len()));
        rest = tail;
        for buf in [&mut a, &mut b, &mut c] {
            buf.extend_from_slice(chunk);
        }
        while lines.decode(&mut a).expect("no io error").is_some() {}
        while commands.decode(&mut b).expect("no io error").is_some() {}
        while servers.decode(&mut c).expect("no io error").is_some() {}
        assert!(a.len() <= MAX);
    }
    while lines.decode_eof(&mut a).expect("no io error").is_some() {}
    while commands.decode_eof(&mut b).expect("no io error").is_some() {}
    while servers.decode_eof(&mut c).expect("no io error").is_some() {}
});
