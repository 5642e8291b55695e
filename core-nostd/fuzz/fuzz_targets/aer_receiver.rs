//! The AER-over-SPI receiver on arbitrary bytes in arbitrary chunks: no panic, and the frame
//! counters stay consistent.
#![no_main]

use core_nostd::aer::events::Receiver;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&sel, rest)) = data.split_first() else {
        return;
    };
    let mut rx = Receiver::new();
    let mut n = 0u64;
    for c in rest.chunks(usize::from(sel) + 1) {
        rx.push(c, |_| n += 1);
    }
    let s = rx.frame_stats();
    assert!(s.ok <= rest.len() as u64);
});
