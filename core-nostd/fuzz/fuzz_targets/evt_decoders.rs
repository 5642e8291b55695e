//! EVT 2.0 / 2.1 (both layouts) / 3.0 decoders on arbitrary bytes, fed in arbitrary chunks:
//! no panic, and every event is counted. (Time may step back: arbitrary bytes can lower
//! TIME_LOW under one TIME_HIGH, and the decoder reports what the stream says.)
#![no_main]

use core_nostd::evt::{Evt21Decoder, Evt2Decoder, Evt3Decoder, StreamDecoder};
use libfuzzer_sys::fuzz_target;

fn run<D: StreamDecoder>(mut d: D, data: &[u8], chunk: usize) {
    let mut n = 0u64;
    for c in data.chunks(chunk.max(1)) {
        d.push64(c, |_| n += 1);
    }
    let _ = d.finish();
    assert_eq!(d.stats().events, n);
}

fuzz_target!(|data: &[u8]| {
    let Some((&sel, rest)) = data.split_first() else {
        return;
    };
    let chunk = usize::from(sel >> 2) + 1;
    match sel & 3 {
        0 => run(Evt3Decoder::new(), rest, chunk),
        1 => run(Evt2Decoder::new(), rest, chunk),
        2 => run(Evt21Decoder::new(), rest, chunk),
        _ => run(Evt21Decoder::legacy(), rest, chunk),
    }
});
