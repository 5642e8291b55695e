//! The time-gap policy of `host-sim run` (`host_sim::timeline`): a recording longer than the
//! u32 µs clock, with a gap of hours and a backward jump, gives exactly the samples of its
//! pieces run one by one, the first sample of each later piece flagged.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_host-sim");

/// A pattern of edges 8 px apart sweeping right to left over a 64 x 32 sensor at 100 px/s (the
/// whole view moves, as under a yaw): `sweeps` sweeps of 0.5 s starting every `every_us`, from
/// `t0`; between sweeps one background event per 200 ms.
fn events(out: &mut String, t0: u64, sweeps: u64, every_us: u64) {
    for s in 0..sweeps {
        let start = t0 + s * every_us;
        for k in 0..500u64 {
            if k % 10 != 0 {
                continue;
            }
            let t = start + k * 1000;
            let shift = k / 10;
            for x in (0..64u64).filter(|x| (x + shift) % 8 == 0) {
                let on = u8::from((x + shift) % 16 == 0);
                for y in (0..32).step_by(2) {
                    let _ = writeln!(out, "{t},{x},{y},{on}");
                }
            }
        }
        let mut t = start + 600_000;
        while t + 200_000 < start + every_us && s + 1 < sweeps {
            let _ = writeln!(out, "{t},{},{},1", t % 64, t % 32);
            t += 200_000;
        }
    }
}

fn run(input: &Path, out: &Path) -> String {
    let o = Command::new(BIN)
        .arg("run")
        .arg(input)
        .args([
            "--width",
            "64",
            "--height",
            "32",
            "--focal-px",
            "60",
            "--rate-hz",
            "100",
            "--out",
        ])
        .arg(out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    err
}

fn rows(path: &Path) -> Vec<(String, String, u8)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].to_owned(), f[1].to_owned(), f[2].parse().unwrap())
        })
        .collect()
}

#[test]
fn a_long_recording_with_a_gap_and_a_jump_back_is_its_pieces_one_by_one() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // A: 2 sweeps from t = 1 s. B: 3 hours later, 76 min (longer than 2^32 µs) with a sweep
    // every 5 min. C: 50 min back from B's end (the u32 clock would take that for 21.6 min
    // forward).
    let a_start = 1_000_000u64;
    let b_start = a_start + 2 * 1_000_000 + 3 * 3600 * 1_000_000;
    let b_sweeps = 16u64;
    let b_every = 5 * 60 * 1_000_000;
    let b_end = b_start + (b_sweeps - 1) * b_every + 500_000;
    let c_start = b_end - 50 * 60 * 1_000_000;
    assert!(b_end - b_start > 1 << 32);
    let mut pieces = [String::new(), String::new(), String::new()];
    events(&mut pieces[0], a_start, 2, 1_000_000);
    events(&mut pieces[1], b_start, b_sweeps, b_every);
    events(&mut pieces[2], c_start, 3, 1_000_000);
    let header = "t_us,x,y,p\n";
    let whole = d.join("whole.csv");
    std::fs::write(
        &whole,
        format!("{header}{}{}{}", pieces[0], pieces[1], pieces[2]),
    )
    .unwrap();
    let summary = run(&whole, &d.join("whole_yaw.csv"));
    assert!(
        summary.contains("1 gaps over 10 min and 1 backward jumps over 100 ms"),
        "{summary}"
    );
    let mut expected = Vec::new();
    for (i, p) in pieces.iter().enumerate() {
        let input = d.join(format!("piece{i}.csv"));
        std::fs::write(&input, format!("{header}{p}")).unwrap();
        let out = d.join(format!("piece{i}_yaw.csv"));
        let s = run(&input, &out);
        assert!(!s.contains("time jumps"), "{s}");
        let mut r = rows(&out);
        assert!(!r.is_empty());
        if i > 0 {
            r[0].2 |= 64;
        }
        expected.extend(r);
    }
    let got = rows(&d.join("whole_yaw.csv"));
    assert_eq!(got.len(), expected.len());
    for (k, (g, e)) in got.iter().zip(&expected).enumerate() {
        assert_eq!(g, e, "sample {k}");
    }
    // B runs through its 76 minutes: one sample per 10 ms up to its last event, and the sweeps
    // late in B are decoded (the clock wrapped on the way).
    let b = rows(&d.join("piece1_yaw.csv"));
    // B's last event is 10 ms before b_end.
    let span = (b_end - 10_000 - b_start) / 10_000;
    assert_eq!(b.len() as u64, span);
    let late_nonzero = b
        .iter()
        .skip(b.len() - 100)
        .filter(|r| r.1.parse::<f64>().unwrap() != 0.0)
        .count();
    assert!(
        late_nonzero > 10,
        "{late_nonzero} non-zero samples in B's last sweep"
    );
}
