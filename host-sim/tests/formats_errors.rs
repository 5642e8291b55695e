//! Malformed and truncated inputs: `host-sim convert` prints one error line naming the file and
//! the byte offset, exits with code 2, never panics, and leaves no output file.

use std::path::{Path, PathBuf};

use host_sim::testdata::shared_data;

use crate::common::host_sim;

/// Runs `convert input --to csv` (plus `extra` arguments) and checks the failure: exit code 2,
/// one stderr line starting with `error: ` naming the file and containing every `needles`.
fn fails(input: &Path, extra: &[&str], needles: &[&str]) {
    let out = input.with_extension("out.csv");
    let o = host_sim()
        .args([
            "convert",
            input.to_str().unwrap(),
            "--to",
            "csv",
            "--out",
            out.to_str().unwrap(),
        ])
        .args(extra)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{}: {err}", input.display());
    assert_eq!(
        err.lines().count(),
        1,
        "{}: not one line: {err}",
        input.display()
    );
    let line = err.lines().next().unwrap();
    let name = input.file_name().unwrap().to_string_lossy();
    assert!(
        line.starts_with("error: ") && line.contains(name.as_ref()),
        "{line}"
    );
    for n in needles {
        assert!(line.contains(n), "`{n}` missing in: {line}");
    }
    assert!(!out.exists(), "{} left an output file", input.display());
}

/// Writes the first `len` bytes of `src` to `dir/name`.
fn truncated(src: &Path, len: usize, dir: &Path, name: &str) -> PathBuf {
    let bytes = std::fs::read(src).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, &bytes[..len]).unwrap();
    p
}

#[test]
fn truncated_real_recordings() {
    let Some(real) = shared_data("real") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // EVT 3.0: header is 72 bytes; cut inside a 2-byte word.
    let p = truncated(
        &real.join("prophesee_gen41_evt3_triggers.raw"),
        1001,
        t,
        "cut_evt3.raw",
    );
    fails(&p, &[], &["truncated EVT 3.0 stream at byte 1000"]);
    // EVT 2.0: header is 166 bytes; cut 3 bytes into a 4-byte word.
    let p = truncated(
        &real.join("prophesee_gen3_evt2.raw"),
        166 + 400 + 3,
        t,
        "cut_evt2.raw",
    );
    fails(&p, &[], &["truncated EVT 2.0 stream at byte 566"]);
    // AEDAT 4.0 cut inside a packet, and inside its header.
    let p = truncated(&real.join("davis346_imu.aedat4"), 100_000, t, "cut.aedat4");
    fails(&p, &[], &["truncated AEDAT 4.0 packet at byte"]);
    let p = truncated(
        &real.join("davis346_imu.aedat4"),
        40,
        t,
        "cut_header.aedat4",
    );
    fails(&p, &[], &["truncated AEDAT 4.0 header at byte 18"]);
    // AEDAT 4.0 cut exactly between two packets: the announced data table is missing.
    let p = truncated(
        &real.join("davis346_imu.aedat4"),
        3126,
        t,
        "cut_between.aedat4",
    );
    fails(&p, &[], &["truncated AEDAT 4.0 file at byte 3126"]);
}

#[test]
fn corrupt_aedat4_packet() {
    let Some(real) = shared_data("real") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let mut bytes = std::fs::read(real.join("davis346_imu.aedat4")).unwrap();
    // The first packet header is at byte 3126; its body starts 8 bytes later (an LZ4 frame).
    for b in &mut bytes[3134 + 4..3134 + 64] {
        *b ^= 0x5A;
    }
    let p = tmp.path().join("corrupt.aedat4");
    std::fs::write(&p, &bytes).unwrap();
    fails(&p, &[], &["corrupt LZ4 packet at byte 3126"]);
    // A packet of a stream the description does not list.
    let mut bytes = std::fs::read(real.join("davis346_imu.aedat4")).unwrap();
    bytes[3126] = 99;
    let p = tmp.path().join("bad_stream.aedat4");
    std::fs::write(&p, &bytes).unwrap();
    fails(&p, &[], &["packet at byte 3126: stream id 99"]);
}

#[test]
fn truncated_synthetic_files() {
    let Some(syn) = shared_data("synthetic") else {
        return;
    };
    let dir = syn.join("dev01_davis346_noise_sinusoid");
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let p = truncated(
        &dir.join("dev01_davis346_noise_sinusoid_data.hdf5"),
        3_000_000,
        t,
        "cut.hdf5",
    );
    fails(&p, &[], &["truncated HDF5 file at byte 3000000"]);
    let p = truncated(&dir.join("events.txt"), 5000, t, "cut_events.txt");
    fails(&p, &[], &["truncated line 275 at byte 4991"]);
    // Cut one byte into a word: the data starts after `% end\n`.
    let raw = std::fs::read(dir.join("events.raw")).unwrap();
    let data = raw.windows(6).position(|w| w == b"% end\n").unwrap() + 6;
    let cut = data + 2 * 50_000 + 1;
    let p = truncated(&dir.join("events.raw"), cut, t, "cut_events.raw");
    fails(
        &p,
        &[],
        &[&format!("truncated EVT 3.0 stream at byte {}", cut - 1)],
    );
}

/// (file name, content, extra arguments, expected parts of the message)
type Case<'a> = (&'a str, &'a [u8], &'a [&'a str], &'a [&'a str]);

#[test]
fn malformed_files() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let cases: [Case; 9] = [
        (
            "bad.txt",
            b"0.1 1 2 1\n0.2 x 3 0\n",
            &[],
            &["malformed line 2 at byte 10"],
        ),
        (
            "bad.csv",
            b"t_us,x,y,p\n1,2,3,1\n2,3\n",
            &[],
            &["line 3 at byte 19"],
        ),
        ("bad_pol.csv", b"1,2,3,7\n", &[], &["line 1 at byte 0"]),
        (
            "noise.bin",
            &[0x00, 0xff, 0x13, 0x37, 0x99, 0x42, 0x00, 0x01],
            &[],
            &["unknown format at byte 0"],
        ),
        // EVT 3.0 words of undefined types (0x9...).
        (
            "undefined.raw",
            b"% format EVT3;width=10;height=10\n% end\n\x00\x80\x00\x90",
            &[],
            &["undefined type at byte 41"],
        ),
        // Words but no TIME_HIGH.
        (
            "no_th.raw",
            b"% format EVT3;width=10;height=10\n% end\n\x01\x00\x02\x20",
            &[],
            &["no TIME_HIGH", "byte 39"],
        ),
        (
            "noformat.raw",
            b"% Date 2020\n% end\n\x00\x80",
            &[],
            &["names no event format"],
        ),
        (
            "not.aedat4",
            b"#!AER-DAT4.0\r\n\x08\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00",
            &[],
            &["malformed AEDAT 4.0 header at byte 18"],
        ),
        (
            "not.hdf5",
            b"hello",
            &["--format", "mvsec-hdf5"],
            &["no HDF5 signature at byte 0"],
        ),
    ];
    for (name, bytes, extra, needles) in cases {
        let p = t.join(name);
        std::fs::write(&p, bytes).unwrap();
        fails(&p, extra, needles);
    }
}

#[test]
fn random_bytes_in_every_format_fail_cleanly() {
    let tmp = tempfile::tempdir().unwrap();
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let bytes: Vec<u8> = (0..5000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect();
    let p = tmp.path().join("random.bin");
    std::fs::write(&p, &bytes).unwrap();
    for f in [
        "csv",
        "ecd-text",
        "evt2",
        "evt21",
        "evt3",
        "aedat4",
        "mvsec-hdf5",
    ] {
        let out = tmp.path().join(format!("random_{f}.csv"));
        let o = host_sim()
            .args([
                "convert",
                p.to_str().unwrap(),
                "--to",
                "csv",
                "--out",
                out.to_str().unwrap(),
                "--format",
                f,
            ])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "--format {f}: {err}");
        assert_eq!(err.lines().count(), 1, "--format {f}: {err}");
        assert!(
            err.contains("random.bin") && err.contains("byte"),
            "--format {f}: {err}"
        );
        assert!(!out.exists());
    }
}
