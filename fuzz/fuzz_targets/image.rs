//! The image server's requests and frames (usar_proto::image, sans I/O), from arbitrary
//! bytes: never a panic; the requests read do not depend on how the bytes are split, print
//! back to bytes that read the same, and every rectangle of the frame crops, encodes and
//! decodes to the same pixels; frames read by a client from arbitrary bytes never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use usar_proto::image::{
    FrameParser, ImageRequest, RAW, RequestParser, crop, decode_raw, frame_header, raw_payload,
};

fuzz_target!(|data: &[u8]| {
    let Some((&dims, bytes)) = data.split_first() else {
        return;
    };
    // A frame of 1..=16 × 1..=16 pixels.
    let (fw, fh) = (u16::from(dims & 15) + 1, u16::from(dims >> 4) + 1);
    let rgb: Vec<u8> = (0..3 * usize::from(fw) * usize::from(fh))
        .map(|i| (i * 7) as u8)
        .collect();

    // All at once, then cut at places the input's length picks.
    let mut whole = RequestParser::default();
    let mut requests = Vec::new();
    whole.push(bytes, &mut requests);
    let mut cut = RequestParser::default();
    let mut again = Vec::new();
    let mut start = 0;
    for end in 1..=bytes.len() {
        if end == bytes.len() || (end * 7919 + bytes.len()) % 13 == 0 {
            cut.push(&bytes[start..end], &mut again);
            start = end;
        }
    }
    assert_eq!(requests, again);
    assert_eq!(whole.skipped, cut.skipped);
    assert_eq!(whole.is_partial(), cut.is_partial());

    // Printed back: the same requests, nothing skipped.
    let printed: Vec<u8> = requests.iter().flat_map(ImageRequest::to_bytes).collect();
    let mut reread = RequestParser::default();
    let mut third = Vec::new();
    reread.push(&printed, &mut third);
    assert_eq!(requests, third);
    assert_eq!(reread.skipped, 0);

    for request in requests.iter().take(64) {
        let ImageRequest::Rect {
            x,
            y,
            width,
            height,
        } = *request
        else {
            continue;
        };
        let Some((w, h, pixels)) = crop(fw, fh, &rgb, x, y, width, height) else {
            assert!(
                x >= u32::from(fw) || y >= u32::from(fh) || width == 0 || height == 0,
                "{request:?} of a {fw}x{fh} frame"
            );
            continue;
        };
        assert!(w >= 1 && h >= 1 && w <= fw && h <= fh);
        assert_eq!(pixels.len(), 3 * usize::from(w) * usize::from(h));
        for bgr in [true, false] {
            let mut payload = Vec::new();
            raw_payload(w, h, &pixels, bgr, &mut payload);
            let mut frames = FrameParser::new(1 << 16);
            frames.push(&frame_header(RAW, payload.len() as u32));
            frames.push(&payload);
            let frame = frames.next_frame().expect("a valid frame").expect("whole");
            assert_eq!(frame.kind, RAW);
            assert_eq!(
                decode_raw(&frame.payload, bgr).expect("a valid raw payload"),
                (w, h, pixels.clone())
            );
        }
    }

    // The same bytes as a server's frames, as a client reads them.
    let mut frames = FrameParser::new(4096);
    frames.push(bytes);
    while let Ok(Some(frame)) = frames.next_frame() {
        if let Ok((w, h, pixels)) = decode_raw(&frame.payload, bgr_of(frame.kind)) {
            assert_eq!(pixels.len(), 3 * usize::from(w) * usize::from(h));
        }
    }
});

fn bgr_of(kind: u8) -> bool {
    kind % 2 == 0
}
