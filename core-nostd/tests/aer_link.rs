//! The SPI link receiver against a simulated STM32 SPI slave with injected faults: spurious and
//! lost SCK edges (bit slips), NSS glitches, mode faults and overruns. After each fault the
//! next whole frame must be received, nothing false may come out, and each fault is counted.

use core_nostd::aer::frame::{encode_frame, FrameDecoder, FrameStats, Kind, MAX_FRAME};
use core_nostd::aer::link::{LinkEvent, LinkReceiver, LinkStats};

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// What the master sends: transactions of whole frames.
struct Sent {
    /// Bytes of each transaction.
    transactions: Vec<Vec<u8>>,
    /// Per frame: (transaction, first bit, end bit, seq, payload).
    frames: Vec<(usize, usize, usize, u16, Vec<u8>)>,
}

/// Each transaction ends with `filler` bytes 0x00 after its last frame (the sender's option;
/// one lets the last frame of a transaction whose bits slipped be completed).
fn master(n_transactions: usize, max_frames_per_tx: u64, filler: usize, rng: &mut Rng) -> Sent {
    let mut transactions = Vec::new();
    let mut frames = Vec::new();
    let mut seq = 0u16;
    for t in 0..n_transactions {
        let mut bytes = Vec::new();
        for _ in 0..1 + rng.below(max_frames_per_tx) {
            let len = 4 + 4 * (10 + rng.below(50) as usize);
            let payload: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
            let mut buf = [0u8; MAX_FRAME];
            let n = encode_frame(Kind::Events, 0, seq, &payload, &mut buf).unwrap();
            frames.push((t, bytes.len() * 8, (bytes.len() + n) * 8, seq, payload));
            bytes.extend_from_slice(&buf[..n]);
            seq = seq.wrapping_add(1);
        }
        bytes.resize(bytes.len() + filler, 0);
        transactions.push(bytes);
    }
    Sent {
        transactions,
        frames,
    }
}

/// A fault at a bit of a transaction (bit index in the master's stream).
#[derive(Clone, Copy, Debug)]
enum Fault {
    /// A spurious SCK edge before this bit: the slave shifts in one bit too many.
    ExtraEdge(bool),
    /// This bit's SCK edge is lost.
    LostEdge,
    /// NSS rises for a moment: the board sees an NSS edge, re-arms the peripheral and misses
    /// this many bits meanwhile.
    NssGlitch(usize),
    /// MODF: the peripheral disables itself; the board re-arms it after this many bits.
    Modf(usize),
    /// The DMA is late: the next `lost` bytes are lost (OVR); the board's error interrupt
    /// reports it after `delay` more bytes have reached the ring.
    Overrun { lost: usize, delay: usize },
}

impl Fault {
    /// Bits of the master's stream this fault can damage, from its bit on.
    fn reach(self) -> usize {
        match self {
            Self::ExtraEdge(_) | Self::LostEdge => 1,
            Self::NssGlitch(n) | Self::Modf(n) => n + 8,
            Self::Overrun { lost, .. } => 8 * (lost + 2),
        }
    }
}

/// What the board hands the receiver: bytes off the DMA ring and the peripheral's events.
#[derive(Clone, Copy, Debug)]
enum Item {
    Byte(u8),
    Event(LinkEvent),
}

/// The SPI slave as the F405/H743 board drives it (MSB first, mode 0): a shift register whose
/// bit counter only the board's re-arm (on NSS rising, on MODF) resets, DMA into a ring.
#[derive(Default)]
struct Slave {
    out: Vec<Item>,
    sr: u8,
    count: u32,
    /// Bytes still to lose to an overrun.
    ovr_lost: usize,
    /// Bytes until the board reports the overrun.
    ovr_report: Option<usize>,
}

impl Slave {
    fn clock(&mut self, bit: bool) {
        self.sr = (self.sr << 1) | u8::from(bit);
        self.count += 1;
        if self.count < 8 {
            return;
        }
        self.count = 0;
        if self.ovr_lost > 0 {
            self.ovr_lost -= 1;
            return;
        }
        self.out.push(Item::Byte(self.sr));
        match self.ovr_report {
            Some(0) => {
                self.out.push(Item::Event(LinkEvent::Overrun));
                self.ovr_report = None;
            }
            Some(d) => self.ovr_report = Some(d - 1),
            None => {}
        }
    }
}

fn slave(sent: &Sent, faults: &[Vec<(usize, Fault)>]) -> Vec<Item> {
    let mut sl = Slave::default();
    for (t, bytes) in sent.transactions.iter().enumerate() {
        sl.count = 0;
        let mut off_until = 0usize;
        let fs = &faults[t];
        let nbits = bytes.len() * 8;
        for i in 0..nbits {
            let bit = bytes[i / 8] & (0x80 >> (i % 8)) != 0;
            let mut lost = false;
            for &(_, f) in fs.iter().filter(|(at, _)| *at == i) {
                match f {
                    Fault::ExtraEdge(b) => {
                        if i >= off_until {
                            sl.clock(b);
                        }
                    }
                    Fault::LostEdge => lost = true,
                    Fault::NssGlitch(n) | Fault::Modf(n) => {
                        let ev = if matches!(f, Fault::NssGlitch(_)) {
                            LinkEvent::EndOfTransaction
                        } else {
                            LinkEvent::ModeFault
                        };
                        sl.out.push(Item::Event(ev));
                        sl.count = 0;
                        off_until = i + n;
                    }
                    Fault::Overrun { lost, delay } => {
                        sl.ovr_lost = lost;
                        sl.ovr_report = Some(delay);
                    }
                }
            }
            if lost || i < off_until {
                continue;
            }
            sl.clock(bit);
        }
        if sl.ovr_report.take().is_some() {
            sl.out.push(Item::Event(LinkEvent::Overrun));
        }
        sl.ovr_lost = 0;
        // NSS rises: the partial byte in the shift register is dropped by the re-arm.
        sl.out.push(Item::Event(LinkEvent::EndOfTransaction));
    }
    sl.out
}

struct Received {
    frames: Vec<(u16, Vec<u8>)>,
    link: LinkStats,
    frame: FrameStats,
}

fn drain(rx: &mut LinkReceiver, got: &mut Vec<(u16, Vec<u8>)>) {
    while let Some(f) = rx.next_frame() {
        got.push((f.seq, f.payload.to_vec()));
    }
}

fn feed_all(rx: &mut LinkReceiver, bytes: &[u8], rng: &mut Rng, got: &mut Vec<(u16, Vec<u8>)>) {
    let mut rest = bytes;
    let mut stalls = 0;
    while !rest.is_empty() {
        let want = (1 + rng.below(300) as usize).min(rest.len());
        let n = rx.feed(&rest[..want]);
        stalls = if n == 0 { stalls + 1 } else { 0 };
        assert!(stalls < 3, "the receiver stopped taking bytes");
        rest = &rest[n..];
        drain(rx, got);
    }
}

/// The board's input task: bytes in chunks of any size, events at their place.
fn receive(items: &[Item], rng: &mut Rng) -> Received {
    let mut rx = LinkReceiver::new();
    let mut got = Vec::new();
    let mut bytes = Vec::new();
    for it in items {
        match *it {
            Item::Byte(b) => bytes.push(b),
            Item::Event(e) => {
                feed_all(&mut rx, &bytes, rng, &mut got);
                bytes.clear();
                rx.event(e);
                drain(&mut rx, &mut got);
            }
        }
    }
    feed_all(&mut rx, &bytes, rng, &mut got);
    rx.end_of_stream();
    drain(&mut rx, &mut got);
    Received {
        frames: got,
        link: *rx.stats(),
        frame: rx.frame_stats(),
    }
}

/// Places `n` faults made by `make` in distinct frames that are not the last of their
/// transaction, `from_start` bits into the frame.
fn place(
    sent: &Sent,
    n: usize,
    rng: &mut Rng,
    mut make: impl FnMut(&mut Rng) -> Fault,
) -> Vec<Vec<(usize, Fault)>> {
    let mut faults = vec![Vec::new(); sent.transactions.len()];
    let candidates: Vec<usize> = (0..sent.frames.len())
        .filter(|&i| {
            sent.frames
                .get(i + 1)
                .is_some_and(|f| f.0 == sent.frames[i].0)
        })
        .collect();
    assert!(candidates.len() >= 3 * n, "too few frames for {n} faults");
    let mut used = std::collections::BTreeSet::new();
    while used.len() < n {
        let i = candidates[rng.below(candidates.len() as u64) as usize];
        if used.contains(&i) || used.contains(&(i + 1)) || i > 0 && used.contains(&(i - 1)) {
            continue;
        }
        used.insert(i);
        let (t, a, b, _, _) = sent.frames[i];
        // Inside the frame, past its header, well before its end (it is >= 56 bytes).
        let at = a + 12 * 8 + rng.below((b - a - 40 * 8) as u64) as usize;
        faults[t].push((at, make(rng)));
    }
    faults
}

impl Fault {
    /// Whether the slave's bytes are bit-shifted after this fault (until the next re-arm).
    fn misaligns(self) -> bool {
        !matches!(self, Self::Overrun { .. })
    }
}

/// Every frame received is one that was sent, unchanged; every frame no fault reached is
/// received. Returns the number of frames reached. Without filler bytes, a transaction whose
/// bits were shifted also loses its last frame (its last bit never completes a byte).
fn check(sent: &Sent, faults: &[Vec<(usize, Fault)>], got: &Received) -> usize {
    let mut by_seq = std::collections::HashMap::new();
    for f in &sent.frames {
        by_seq.insert(f.3, &f.4);
    }
    let mut seen = std::collections::HashSet::new();
    for (seq, payload) in &got.frames {
        assert_eq!(
            by_seq.get(seq).map(|p| p.as_slice()),
            Some(payload.as_slice()),
            "frame {seq} is not one that was sent"
        );
        assert!(seen.insert(*seq), "frame {seq} twice");
    }
    let mut reached = 0;
    for (t, a, b, seq, _) in &sent.frames {
        let last_bit = sent.transactions[*t].len() * 8;
        let hit = faults[*t].iter().any(|&(at, f)| {
            // An overrun or a re-arm loses the slave's byte in progress, which reaches back
            // (by up to 7 bits of an earlier frame once the bytes are shifted).
            let from = match f {
                Fault::ExtraEdge(_) | Fault::LostEdge => at,
                _ => at.saturating_sub(8),
            };
            let to = if f.misaligns() && *b == last_bit {
                last_bit
            } else {
                at + f.reach()
            };
            from < *b && to > *a
        });
        if hit {
            reached += 1;
        } else {
            assert!(seen.contains(seq), "frame {seq} (untouched by any fault, bits {a}..{b} of transaction {t} of {} bits: faults {:?}) was not received", sent.transactions[*t].len() * 8, faults[*t]);
        }
    }
    reached
}

#[test]
fn clean_stream_passes_unchanged() {
    let mut rng = Rng(0x1234_5678_9ABC);
    let sent = master(300, 8, 0, &mut rng);
    let faults = vec![Vec::new(); sent.transactions.len()];
    let got = receive(&slave(&sent, &faults), &mut rng);
    check(&sent, &faults, &got);
    assert_eq!(got.frames.len(), sent.frames.len());
    assert_eq!(got.link.bit_slips, 0);
    assert_eq!(got.link.cut_transactions, 0);
    assert_eq!(got.link.transactions, 300);
    assert_eq!(
        (got.frame.bad, got.frame.dropped, got.frame.skipped_bytes),
        (0, 0, 0)
    );
}

#[test]
fn one_long_transaction_without_nss() {
    // A master that never raises NSS: the receiver is then the plain frame decoder.
    let mut rng = Rng(77);
    let mut bytes = Vec::new();
    let mut rng2 = Rng(78);
    let many = master(2000, 1, 0, &mut rng2);
    for t in &many.transactions {
        bytes.extend_from_slice(t);
    }
    let mut rx = LinkReceiver::new();
    let mut got = Vec::new();
    feed_all(&mut rx, &bytes, &mut rng, &mut got);
    let mut reference = Vec::new();
    FrameDecoder::new().push(&bytes, |f| reference.push((f.seq, f.payload.to_vec())));
    assert_eq!(got, reference);
    assert_eq!(rx.stats().bit_slips, 0);
}

#[test]
fn bit_slips_cost_one_frame_each() {
    let mut rng = Rng(0xBEEF);
    let sent = master(200, 8, 1, &mut rng);
    let faults = place(&sent, 60, &mut rng, |r| {
        if r.below(2) == 0 {
            Fault::ExtraEdge(r.below(2) == 0)
        } else {
            Fault::LostEdge
        }
    });
    let got = receive(&slave(&sent, &faults), &mut rng);
    let reached = check(&sent, &faults, &got);
    assert_eq!(reached, 60);
    assert_eq!(got.frames.len(), sent.frames.len() - 60);
    assert_eq!(got.link.bit_slips, 60, "{:?}", got.link);
    assert_eq!(got.frame.bad, 60, "{:?}", got.frame);
    assert_eq!(got.frame.dropped, 60);
}

#[test]
fn nss_glitches_cost_one_frame_each() {
    let mut rng = Rng(0xC0FFEE);
    let sent = master(200, 8, 1, &mut rng);
    let faults = place(&sent, 50, &mut rng, |r| {
        Fault::NssGlitch(1 + r.below(100) as usize)
    });
    let got = receive(&slave(&sent, &faults), &mut rng);
    check(&sent, &faults, &got);
    assert_eq!(got.frames.len(), sent.frames.len() - 50);
    assert_eq!(got.link.transactions, 200 + 50);
    assert_eq!(got.link.cut_transactions, 50, "{:?}", got.link);
    // After the re-arm the slave counts bits from wherever it resumed: unless that was a byte
    // boundary of the master's stream, the rest of the transaction is bit-shifted.
    let misaligned = faults
        .iter()
        .flatten()
        .filter(|(at, f)| matches!(f, Fault::NssGlitch(n) if (at + n) % 8 != 0))
        .count() as u64;
    assert!(misaligned > 20);
    assert_eq!(got.link.bit_slips, misaligned, "{:?}", got.link);
}

#[test]
fn mode_faults_cost_one_frame_each() {
    let mut rng = Rng(0xFACE);
    let sent = master(200, 8, 1, &mut rng);
    let faults = place(&sent, 40, &mut rng, |r| {
        Fault::Modf(8 + r.below(200) as usize)
    });
    let got = receive(&slave(&sent, &faults), &mut rng);
    check(&sent, &faults, &got);
    assert_eq!(got.frames.len(), sent.frames.len() - 40);
    assert_eq!(got.link.mode_faults, 40);
    assert_eq!(got.link.transactions, 200);
}

#[test]
fn overruns_cost_one_frame_each() {
    let mut rng = Rng(0xABCD);
    let sent = master(200, 8, 0, &mut rng);
    let faults = place(&sent, 50, &mut rng, |r| Fault::Overrun {
        lost: 1 + r.below(3) as usize,
        delay: r.below(4) as usize,
    });
    let got = receive(&slave(&sent, &faults), &mut rng);
    check(&sent, &faults, &got);
    assert_eq!(got.frames.len(), sent.frames.len() - 50);
    assert_eq!(got.link.overruns, 50);
    assert_eq!(got.frame.bad, 50);
    assert_eq!(got.link.bit_slips, 0);
}

#[test]
fn mixed_faults_anywhere() {
    // Faults of every kind at random bits, several per transaction, also in headers, between
    // frames and in the last frame: nothing false comes out, every untouched frame does.
    for seed in 1..=1000u64 {
        let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let sent = master(60, 10, rng.below(2) as usize, &mut rng);
        let mut faults = vec![Vec::new(); sent.transactions.len()];
        for (t, bytes) in sent.transactions.iter().enumerate() {
            for _ in 0..rng.below(4) {
                let at = rng.below(bytes.len() as u64 * 8) as usize;
                let f = match rng.below(5) {
                    0 => Fault::ExtraEdge(rng.below(2) == 0),
                    1 => Fault::LostEdge,
                    2 => Fault::NssGlitch(rng.below(64) as usize),
                    3 => Fault::Modf(rng.below(64) as usize),
                    _ => Fault::Overrun {
                        lost: 1 + rng.below(2) as usize,
                        delay: rng.below(3) as usize,
                    },
                };
                faults[t].push((at, f));
            }
        }
        let got = receive(&slave(&sent, &faults), &mut rng);
        let reached = check(&sent, &faults, &got);
        assert!(got.frames.len() + reached >= sent.frames.len());
    }
}

#[test]
fn garbage_gives_no_frames() {
    let mut rng = Rng(5);
    let bytes: Vec<u8> = (0..1 << 20).map(|_| rng.next() as u8).collect();
    let mut rx = LinkReceiver::new();
    let mut got = Vec::new();
    feed_all(&mut rx, &bytes, &mut rng, &mut got);
    rx.event(LinkEvent::EndOfTransaction);
    drain(&mut rx, &mut got);
    assert!(got.is_empty());
    assert_eq!(rx.frame_stats().ok, 0);
}

#[test]
fn without_filler_a_slipped_transaction_also_loses_its_last_frame() {
    let mut rng = Rng(0x5EED);
    let sent = master(200, 8, 0, &mut rng);
    let faults = place(&sent, 40, &mut rng, |_| Fault::ExtraEdge(true));
    let got = receive(&slave(&sent, &faults), &mut rng);
    let reached = check(&sent, &faults, &got);
    assert!(reached > 40);
    assert_eq!(got.frames.len(), sent.frames.len() - reached);
    assert_eq!(got.link.bit_slips, 40);
}

#[test]
fn decoder_reports_what_a_frame_still_needs() {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode_frame(Kind::Events, 0, 5, &[7; 40], &mut buf).unwrap();
    let mut dec = FrameDecoder::new();
    // Before the header is complete nothing is known.
    dec.feed(&buf[..9]);
    assert_eq!(dec.next_frame(), None);
    assert_eq!(dec.need(), None);
    assert!(dec.partial_frame());
    dec.feed(&buf[9..20]);
    assert_eq!(dec.next_frame(), None);
    assert_eq!(dec.need(), Some(n - 20));
    assert_eq!(dec.room(), MAX_FRAME - 20);
    // Dropping a cut frame counts it bad and its bytes skipped.
    dec.discard();
    assert_eq!((dec.pending(), dec.need()), (0, None));
    let st = dec.stats();
    assert_eq!((st.bad, st.skipped_bytes), (1, 20));
    // Garbage is not a frame start.
    dec.feed(&[1, 2, 3]);
    assert_eq!(dec.next_frame(), None);
    assert!(!dec.partial_frame());
    dec.feed(&buf[..n]);
    assert_eq!(dec.next_frame().map(|f| f.seq), Some(5));
    assert_eq!(dec.need(), None);
}
