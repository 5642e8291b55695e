//! Hostile inputs (issue 13): each one ends with one `error: ...` line and exit code 2, or with
//! correct output; never a panic, an abort, a hang, a partial file or a silently wrong answer.
//! Every file is crafted here, in a temporary folder.

use std::ffi::OsStr;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_host-sim");

/// Longest any command here may take: a hang is a failure, not a stuck test run.
const TIMEOUT: Duration = Duration::from_secs(60);

/// Runs `host-sim ARGS` (through `sh -c 'ulimit -v KB; exec ...'` when `vmem_kb` is given), killed
/// after [`TIMEOUT`].
fn run_limited(args: &[&OsStr], vmem_kb: Option<u64>) -> Output {
    let mut cmd = match vmem_kb {
        Some(kb) => {
            let mut c = Command::new("sh");
            c.arg("-c")
                .arg(format!("ulimit -v {kb}; exec \"$0\" \"$@\""))
                .arg(BIN);
            c
        }
        None => Command::new(BIN),
    };
    let mut child = cmd
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start host-sim");
    let start = Instant::now();
    loop {
        if child.try_wait().expect("wait").is_some() {
            return child.wait_with_output().expect("output");
        }
        if start.elapsed() > TIMEOUT {
            let _ = child.kill();
            panic!("host-sim {args:?} did not finish within {TIMEOUT:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn run(args: &[&OsStr]) -> Output {
    run_limited(args, None)
}

/// Checks a failure: exit code 2, exactly one stderr line, starting `error: `, containing every
/// needle.
fn assert_fails(o: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "expected exit 2, stderr: {err}");
    assert_eq!(err.lines().count(), 1, "expected one line: {err}");
    assert!(err.starts_with("error: "), "{err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` not in: {err}");
    }
}

fn assert_ok(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "failed: {err}");
    err
}

/// Files in `dir` whose names mark them as partial outputs.
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".partial-") || n.starts_with(".spill-"))
        .collect()
}

macro_rules! args {
    ($($a:expr),* $(,)?) => { &[$(AsRef::<OsStr>::as_ref(&$a)),*] };
}

/// A small CSV recording: an edge sweeping right to left over a 64 x 32 sensor for 0.3 s.
fn edge_csv(path: &Path) {
    let mut s = String::from("t_us,x,y,p\n");
    for k in 0..3000u64 {
        let t = 1000 + k * 100;
        let x = 63 - (k / 50) % 60;
        for y in 0..32 {
            s.push_str(&format!("{t},{x},{y},1\n"));
        }
    }
    std::fs::write(path, s).unwrap();
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

fn geometry<'a>() -> [&'a str; 6] {
    ["--width", "64", "--height", "32", "--focal-px", "60"]
}

#[test]
fn number_options_out_of_range_are_one_error() {
    let d = tmp();
    let input = d.path().join("rec.csv");
    edge_csv(&input);
    let out = d.path().join("yaw.csv");
    let aer = d.path().join("rec.aer");
    for (flag, value, needle) in [
        ("--cx", "nan", "--cx must be a pixel coordinate"),
        ("--cx", "-5", "--cx must be a pixel coordinate"),
        ("--cx", "inf", "--cx must be a pixel coordinate"),
        ("--cy", "nan", "--cy must be a pixel coordinate"),
        ("--focal-px", "inf", "--focal-px must be a focal length"),
        ("--focal-px", "1e9", "--focal-px must be a focal length"),
        ("--focal-px", "1e-300", "--focal-px must be a focal length"),
        ("--focal-px", "nan", "--focal-px must be a focal length"),
        ("--tau-a-ms", "nan", "--tau-a-ms"),
    ] {
        let given = format!("{flag}={value}");
        let mut common: Vec<&OsStr> =
            args![input, "--width", "64", "--height", "32", given].to_vec();
        if flag != "--focal-px" {
            common.extend_from_slice(args!["--focal-px", "60"]);
        }
        for model in ["fixed", "float"] {
            let mut a: Vec<&OsStr> = args!["run", "--out", out, "--model", model].to_vec();
            a.extend_from_slice(&common);
            assert_fails(&run(&a), &[needle]);
            assert!(!out.exists());
        }
        if flag == "--cx" || flag == "--focal-px" {
            let mut a: Vec<&OsStr> = args!["aer-stream", "--out", aer].to_vec();
            a.extend_from_slice(&common);
            assert_fails(&run(&a), &[needle]);
            assert!(!aer.exists(), "aer-stream left its output");
        }
    }
    assert!(leftovers(d.path()).is_empty());
}

#[test]
fn a_recording_without_a_focal_length_says_what_to_pass() {
    let d = tmp();
    let input = d.path().join("rec.csv");
    edge_csv(&input);
    let out = d.path().join("yaw.csv");
    for readout in ["calibrated", "spikes", "normalized"] {
        let o = run(args![
            "run",
            input,
            "--out",
            out,
            "--width",
            "64",
            "--height",
            "32",
            "--readout",
            readout
        ]);
        if readout == "normalized" {
            // The paper's readout needs none.
            assert_ok(&o);
            continue;
        }
        let needles = [
            "focal length unknown",
            "64x32",
            "--focal-px",
            "(31.5, 15.5)",
        ];
        assert_fails(&o, &needles);
        assert!(!out.exists());
    }
}

#[test]
fn synth_number_options_are_checked() {
    let d = tmp();
    for (flag, value) in [
        ("--focal-px", "inf"),
        ("--focal-px", "0.001"),
        ("--cx", "nan"),
        ("--max-rate", "inf"),
        ("--width", "60000"),
    ] {
        let out = d.path().join("seq");
        let given = format!("{flag}={value}");
        let o = run(args!["synth", "--out", out, "--duration", "0.05", given]);
        assert_fails(&o, &[flag]);
        assert!(!out.exists());
    }
}

#[test]
fn output_equal_to_an_input_is_refused() {
    let d = tmp();
    let input = d.path().join("rec.csv");
    edge_csv(&input);
    let before = std::fs::read(&input).unwrap();
    let other_spelling = d.path().join(".").join("rec.csv");
    let g = geometry();
    for out in [&input, &other_spelling] {
        let o = run(args![
            "run", input, "--out", out, g[0], g[1], g[2], g[3], g[4], g[5]
        ]);
        assert_fails(&o, &["--out", "is the input"]);
        let o = run(args!["convert", input, "--to", "csv", "--out", out]);
        assert_fails(&o, &["--out", "is the input"]);
    }
    let y = d.path().join("y.csv");
    let o = run(args![
        "run", input, "--out", y, "--plot", input, g[0], g[1], g[2], g[3], g[4], g[5]
    ]);
    assert_fails(&o, &["--plot", "is the input"]);
    assert_eq!(
        std::fs::read(&input).unwrap(),
        before,
        "the input was changed"
    );
    assert!(!y.exists());
}

#[test]
fn csv_columns_are_read_by_name() {
    let d = tmp();
    let input = d.path().join("swapped.csv");
    std::fs::write(&input, "t_us,y,x,p\n10,3,7,1\n20,4,9,0\n").unwrap();
    let out = d.path().join("out.csv");
    assert_ok(&run(args!["convert", input, "--to", "csv", "--out", out]));
    assert_eq!(
        std::fs::read_to_string(&out).unwrap(),
        "t_us,x,y,p\n10,7,3,1\n20,9,4,0\n"
    );
    let input = d.path().join("reordered.csv");
    std::fs::write(&input, "p,x,timestamp,y\n1,7,10,3\n").unwrap();
    let o = run(args![
        "convert", input, "--to", "csv", "--out", out, "--format", "csv"
    ]);
    assert_ok(&o);
    assert_eq!(
        std::fs::read_to_string(&out).unwrap(),
        "t_us,x,y,p\n10,7,3,1\n"
    );
    let input = d.path().join("unknown.csv");
    std::fs::write(&input, "t_us,x,y,q\n10,3,7,1\n").unwrap();
    let o = run(args![
        "convert", input, "--to", "csv", "--out", out, "--format", "csv"
    ]);
    assert_fails(&o, &["malformed header line 1", "t_us, x, y, p"]);
}

#[test]
fn sensor_sizes_beyond_the_network_are_one_error() {
    let d = tmp();
    let out = d.path().join("y.csv");
    // From the events' extent.
    let csv = d.path().join("far.csv");
    std::fs::write(&csv, "t_us,x,y,p\n0,60000,60000,1\n").unwrap();
    let o = run_limited(
        args!["run", csv, "--focal-px", "100", "--out", out],
        Some(2_000_000),
    );
    assert_fails(&o, &["sensor size 60001x60001"]);
    // From the flags.
    let small = d.path().join("small.csv");
    std::fs::write(&small, "t_us,x,y,p\n0,1,1,1\n5,2,1,1\n").unwrap();
    let o = run_limited(
        args![
            "run",
            small,
            "--focal-px",
            "100",
            "--width",
            "65535",
            "--height",
            "65535",
            "--out",
            out
        ],
        Some(2_000_000),
    );
    assert_fails(&o, &["sensor size 65535x65535"]);
    // From a Prophesee header.
    let raw = d.path().join("big.raw");
    std::fs::write(
        &raw,
        b"% evt 3.0\n% geometry 65535x65535\n% end\n\x00\x80\x01\x00",
    )
    .unwrap();
    let o = run_limited(
        args!["run", raw, "--focal-px", "100", "--out", out],
        Some(2_000_000),
    );
    assert_fails(&o, &["sensor size 65535x65535"]);
    // From an AEDAT 4.0 stream description.
    let aedat = d.path().join("big.aedat4");
    aedat4(&aedat, 0, "65535", &[]);
    let o = run_limited(
        args!["run", aedat, "--focal-px", "100", "--out", out],
        Some(2_000_000),
    );
    assert_fails(&o, &["sensor size 65535x260"]);
    assert!(!out.exists());
}

/// The recording's own intrinsics are checked like the flags.
#[test]
fn intrinsics_from_the_folder_are_checked() {
    let d = tmp();
    let input = d.path().join("rec.csv");
    edge_csv(&input);
    let out = d.path().join("y.csv");
    std::fs::write(
        d.path().join("meta.json"),
        r#"{"camera": {"width": 64, "height": 32, "fx": 1e9, "fy": 1e9, "cx": 31.5, "cy": 15.5}}"#,
    )
    .unwrap();
    assert_fails(
        &run(args!["run", input, "--out", out]),
        &["the recording's fx"],
    );
    std::fs::write(
        d.path().join("meta.json"),
        r#"{"camera": {"width": 64, "height": 32, "fx": 60, "fy": 60, "cx": -3, "cy": 15.5}}"#,
    )
    .unwrap();
    assert_fails(
        &run(args!["run", input, "--out", out]),
        &["the recording's cx"],
    );
    assert_ok(&run(args!["run", input, "--out", out, "--cx", "31.5"]));
}

/// Malformed sidecar files stop a run only when a value is taken from them.
#[test]
fn malformed_sidecars_matter_only_when_needed() {
    let d = tmp();
    let input = d.path().join("rec.csv");
    edge_csv(&input);
    std::fs::write(d.path().join("meta.json"), "{ not json").unwrap();
    std::fs::write(d.path().join("calib.txt"), "focal? no\n").unwrap();
    std::fs::write(d.path().join("imu.txt"), "0.0 1 2\n").unwrap();
    let out = d.path().join("y.csv");
    let g = geometry();
    let o = run(args![
        "run", input, "--out", out, g[0], g[1], g[2], g[3], g[4], g[5], "--cx", "31.5", "--cy",
        "15.5"
    ]);
    assert_ok(&o);
    let lines = std::fs::read_to_string(&out).unwrap().lines().count();
    assert!(lines > 250, "{lines} lines");
    // Without --width/--height the size comes from meta.json, which is malformed.
    let o = run(args![
        "run",
        input,
        "--out",
        out,
        "--focal-px",
        "60",
        "--cx",
        "31.5"
    ]);
    assert_fails(&o, &["meta.json", "malformed JSON"]);
    // The same folder through convert, which needs nothing from the sidecars for CSV.
    let c = d.path().join("c.csv");
    assert_ok(&run(args!["convert", input, "--to", "csv", "--out", c]));
}

#[test]
fn a_plot_that_cannot_be_written_leaves_no_output() {
    let d = tmp();
    let input = d.path().join("rec.csv");
    edge_csv(&input);
    let out = d.path().join("y.csv");
    let g = geometry();
    let bad = d.path().join("no_such_dir").join("y.png");
    let o = run(args![
        "run", input, "--out", out, "--plot", bad, g[0], g[1], g[2], g[3], g[4], g[5]
    ]);
    assert_fails(&o, &["y.png"]);
    assert!(!out.exists(), "the CSV was left behind");
    // A plot path that is a folder: nothing written there, nothing left beside it.
    let folder = d.path().join("plot.png");
    std::fs::create_dir(&folder).unwrap();
    let o = run(args![
        "run", input, "--out", out, "--plot", folder, g[0], g[1], g[2], g[3], g[4], g[5]
    ]);
    assert_fails(&o, &["plot.png"]);
    assert!(!out.exists());
    assert!(leftovers(d.path()).is_empty(), "{:?}", leftovers(d.path()));
    // A good plot appears complete, through a temporary file that is gone afterwards.
    let png = d.path().join("y.png");
    let o = run(args![
        "run", input, "--out", out, "--plot", png, g[0], g[1], g[2], g[3], g[4], g[5]
    ]);
    assert_ok(&o);
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    assert!(leftovers(d.path()).is_empty(), "{:?}", leftovers(d.path()));
}

/// The edge recording `rec.csv` in `dir` and what `host-sim run` makes of it read from and
/// written to files (`file.csv`): what the other ways in and out must reproduce.
fn edge_recording_and_its_output(dir: &Path) -> (PathBuf, PathBuf) {
    let input = dir.join("rec.csv");
    edge_csv(&input);
    let g = geometry();
    let out = dir.join("file.csv");
    assert_ok(&run(args![
        "run", input, "--out", out, g[0], g[1], g[2], g[3], g[4], g[5]
    ]));
    (input, out)
}

/// A named pipe at `path`.
fn mkfifo(path: &Path) {
    assert!(Command::new("mkfifo").arg(path).status().unwrap().success());
}

#[test]
fn a_fifo_is_read_once_like_a_file() {
    let d = tmp();
    let (input, from_file) = edge_recording_and_its_output(d.path());
    let fifo = d.path().join("pipe.csv");
    mkfifo(&fifo);
    let g = geometry();
    for cmd in ["run", "convert"] {
        let feeder = {
            let (fifo, input) = (fifo.clone(), input.clone());
            std::thread::spawn(move || {
                let bytes = std::fs::read(&input).unwrap();
                let mut f = std::fs::OpenOptions::new().write(true).open(&fifo).unwrap();
                // The reader may stop early on an error; a broken pipe is fine then.
                let _ = f.write_all(&bytes);
            })
        };
        let out = d.path().join(format!("fifo_{cmd}.csv"));
        let o = if cmd == "run" {
            run(args![
                "run", fifo, "--out", out, g[0], g[1], g[2], g[3], g[4], g[5]
            ])
        } else {
            run(args!["convert", fifo, "--to", "csv", "--out", out])
        };
        feeder.join().unwrap();
        assert_ok(&o);
        let expected = if cmd == "run" {
            std::fs::read(&from_file).unwrap()
        } else {
            std::fs::read(&input).unwrap()
        };
        assert_eq!(
            std::fs::read(&out).unwrap(),
            expected,
            "{cmd} through a FIFO"
        );
    }
}

/// Drains the named pipe `fifo` on a thread; the bytes read arrive on the channel (nothing does
/// if no one ever writes into the pipe: wait with a timeout).
fn drain(fifo: &Path) -> std::sync::mpsc::Receiver<Vec<u8>> {
    let fifo = fifo.to_path_buf();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || tx.send(std::fs::read(&fifo).unwrap()));
    rx
}

/// An output that is a pipe or a device (`--out /dev/null`, `--out /dev/stdout`, a named pipe)
/// is written into, never replaced: renaming a temporary file onto it, as regular outputs are
/// put in place, would turn `/dev/null` into a regular file when run as root (found so: every
/// later `cargo` run on that machine read that file as its empty input and failed).
#[test]
fn an_output_that_is_a_pipe_stays_a_pipe() {
    use std::os::unix::fs::FileTypeExt;
    let d = tmp();
    let (input, file) = edge_recording_and_its_output(d.path());
    let g = geometry();
    let fifo = d.path().join("out.csv");
    let fifo_png = d.path().join("out.png");
    for p in [&fifo, &fifo_png] {
        mkfifo(p);
    }
    let (csv, png) = (drain(&fifo), drain(&fifo_png));
    let o = run(args![
        "run", input, "--out", fifo, "--plot", fifo_png, g[0], g[1], g[2], g[3], g[4], g[5]
    ]);
    assert_ok(&o);
    let [csv, png] = [csv, png].map(|rx| {
        rx.recv_timeout(TIMEOUT)
            .expect("nothing was written into the pipe")
    });
    assert_eq!(
        csv,
        std::fs::read(&file).unwrap(),
        "the CSV through the pipe"
    );
    assert!(png.starts_with(b"\x89PNG"), "the plot through the pipe");
    for p in [&fifo, &fifo_png] {
        let t = std::fs::symlink_metadata(p).unwrap().file_type();
        assert!(t.is_fifo(), "{} was replaced", p.display());
    }
    assert!(leftovers(d.path()).is_empty(), "{:?}", leftovers(d.path()));
    // Two outputs may share a stream (both to /dev/null), not a file.
    assert_ok(&run(args![
        "run",
        input,
        "--out",
        "/dev/null",
        "--plot",
        "/dev/null",
        g[0],
        g[1],
        g[2],
        g[3],
        g[4],
        g[5]
    ]));
    // The CSV on standard output (`/dev/stdout` or `-`): exactly the file's bytes, and nothing
    // else there.
    for stdout in ["/dev/stdout", "-"] {
        let o = run(args![
            "run", input, "--out", stdout, g[0], g[1], g[2], g[3], g[4], g[5]
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(
            o.stdout,
            std::fs::read(&file).unwrap(),
            "the CSV on {stdout}"
        );
    }
    // Standard output appending to a file (`>> log`): what the file held stays.
    let log = d.path().join("log.txt");
    std::fs::write(&log, "kept\n").unwrap();
    let o = Command::new(BIN)
        .args([
            "run".as_ref(),
            input.as_os_str(),
            "--out".as_ref(),
            "-".as_ref(),
        ])
        .args(g)
        .stdout(std::fs::OpenOptions::new().append(true).open(&log).unwrap())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut expected = b"kept\n".to_vec();
    expected.extend(std::fs::read(&file).unwrap());
    assert_eq!(
        std::fs::read(&log).unwrap(),
        expected,
        "appended to stdout's file"
    );
    // A link to an output stays a link, to the new file.
    let real = d.path().join("real.csv");
    let link = d.path().join("link.csv");
    std::fs::write(&real, "old").unwrap();
    std::os::unix::fs::symlink(&real, &link).unwrap();
    assert_ok(&run(args![
        "run", input, "--out", link, g[0], g[1], g[2], g[3], g[4], g[5]
    ]));
    assert!(std::fs::symlink_metadata(&link).unwrap().is_symlink());
    assert_eq!(std::fs::read(&real).unwrap(), std::fs::read(&file).unwrap());
    assert!(leftovers(d.path()).is_empty(), "{:?}", leftovers(d.path()));
}

/// `-` as the input is standard input: the same output as from the file (and `-` as the output
/// is standard output).
#[test]
fn a_dash_reads_standard_input() {
    let d = tmp();
    let (input, from_file) = edge_recording_and_its_output(d.path());
    let g = geometry();
    for (cmd, expected) in [("run", &from_file), ("convert", &input)] {
        let mut c = Command::new(BIN);
        c.arg(cmd).arg("-");
        if cmd == "run" {
            c.args(["--out", "-"]).args(g);
        } else {
            c.args(["--to", "csv", "--out", "-"]);
        }
        let o = c
            .stdin(std::fs::File::open(&input).unwrap())
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{cmd}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert_eq!(
            o.stdout,
            std::fs::read(expected).unwrap(),
            "{cmd} from stdin"
        );
    }
}

#[test]
fn convert_to_evt3_refuses_a_gap_of_ages() {
    let d = tmp();
    let input = d.path().join("late.csv");
    std::fs::write(&input, "t_us,x,y,p\n0,1,1,1\n18446744073709551615,2,2,0\n").unwrap();
    let out = d.path().join("x.raw");
    let o = run(args!["convert", input, "--to", "evt3", "--out", out]);
    assert_fails(&o, &["event 1", "gaps over"]);
    assert!(!out.exists());
    assert!(leftovers(d.path()).is_empty(), "{:?}", leftovers(d.path()));
    // Hours apart are fine and read back exactly.
    std::fs::write(&input, "t_us,x,y,p\n5,1,1,1\n36000000005,2,2,0\n").unwrap();
    assert_ok(&run(args!["convert", input, "--to", "evt3", "--out", out]));
    let back = d.path().join("back.csv");
    assert_ok(&run(args!["convert", out, "--to", "csv", "--out", back]));
    assert_eq!(
        std::fs::read_to_string(&back).unwrap(),
        "t_us,x,y,p\n5,1,1,1\n36000000005,2,2,0\n"
    );
}

#[test]
fn float_model_survives_clock_jumps() {
    let d = tmp();
    let g = geometry();
    let out = d.path().join("y.csv");
    // The first event later than the rest (the u64 difference would wrap), then two events
    // days apart.
    let input = d.path().join("jumps.csv");
    let mut s = String::from("t_us,x,y,p\n500000,5,5,1\n");
    for k in 0..200u64 {
        s.push_str(&format!(
            "{},{},{},1\n",
            1000 + k * 1000,
            60 - k % 50,
            k % 32
        ));
    }
    s.push_str("259200000000,3,3,1\n259200001000,4,3,1\n");
    std::fs::write(&input, s).unwrap();
    for model in ["float", "fixed"] {
        let o = run(args![
            "run", input, "--out", out, "--model", model, g[0], g[1], g[2], g[3], g[4], g[5]
        ]);
        let err = assert_ok(&o);
        assert!(
            err.contains("1 gaps over 10 min and 1 backward jumps over 100 ms"),
            "{err}"
        );
        let text = std::fs::read_to_string(&out).unwrap();
        let rows: Vec<(f64, u8)> = text
            .lines()
            .skip(1)
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                (f[0].parse().unwrap(), f[2].parse().unwrap())
            })
            .collect();
        // The piece after the backward jump: 0.2 s of samples, the first one flagged; the
        // last piece holds 1 ms: one sample, flagged too.
        let restarts: Vec<f64> = rows.iter().filter(|r| r.1 & 64 != 0).map(|r| r.0).collect();
        assert_eq!(restarts, vec![0.002, 259200.001], "{model}");
        assert!(
            rows.len() > 150 && rows.len() < 250,
            "{model}: {} rows",
            rows.len()
        );
    }
}

#[test]
fn raw_reader_memory_does_not_grow_with_the_file() {
    let d = tmp();
    let raw = d.path().join("zeros.raw");
    let mut f = std::fs::File::create(&raw).unwrap();
    f.write_all(b"% evt 3.0\n% end\n").unwrap();
    // 2 GB of zeros (sparse): EVT 3.0 words of one type and never a time.
    f.set_len(2_000_000_000).unwrap();
    drop(f);
    let out = d.path().join("y.csv");
    // 1 GB of address space: a reader that reserved memory per file byte would abort.
    let o = run_limited(
        args![
            "run",
            raw,
            "--focal-px",
            "1",
            "--width",
            "8",
            "--height",
            "8",
            "--out",
            out
        ],
        Some(1_000_000),
    );
    assert_fails(&o, &["no TIME_HIGH word"]);
}

/// An AEDAT 4.0 file with one event stream of width `size_x` and the given (stream 0) packet
/// bodies, compressed with `compression` (0 none, 3 zstd).
fn aedat4(path: &Path, compression: i32, size_x: &str, packets: &[Vec<u8>]) {
    let xml = format!(
        "<dv version=\"2.0\"><node name=\"outInfo\" path=\"/mainloop/Recorder/outInfo/\"><node name=\"0\" path=\"/mainloop/Recorder/outInfo/0/\"><attr key=\"compression\" type=\"string\">NONE</attr><attr key=\"originalModuleName\" type=\"string\">capture</attr><attr key=\"originalOutputName\" type=\"string\">events</attr><attr key=\"typeDescription\" type=\"string\">Array of events (polarity ON/OFF).</attr><attr key=\"typeIdentifier\" type=\"string\">EVTS</attr><node name=\"info\" path=\"/mainloop/Recorder/outInfo/0/info/\"><attr key=\"sizeX\" type=\"int\">{size_x}</attr><attr key=\"sizeY\" type=\"int\">260</attr><attr key=\"source\" type=\"string\">DAVIS346</attr></node></node></node></dv>"
    );
    let mut b = flatbuffers::FlatBufferBuilder::new();
    let info = b.create_string(&xml);
    let start = b.start_table();
    b.push_slot_always::<i32>(4, compression);
    b.push_slot_always::<i64>(6, -1);
    b.push_slot_always(8, info);
    let root = b.end_table(start);
    b.finish_size_prefixed(root, Some("IOHE"));
    let mut out = b"#!AER-DAT4.0\r\n".to_vec();
    out.extend_from_slice(b.finished_data());
    for body in packets {
        out.extend_from_slice(&0i32.to_le_bytes());
        out.extend_from_slice(&(body.len() as i32).to_le_bytes());
        out.extend_from_slice(body);
    }
    std::fs::write(path, out).unwrap();
}

#[test]
fn aedat4_decompression_is_capped_by_the_declared_size() {
    let d = tmp();
    let out = d.path().join("y.csv");
    // 1.5 GB of zeros behind a FlatBuffer that declares 100 bytes.
    let mut enc = zstd::stream::Encoder::new(Vec::new(), 3).unwrap();
    enc.write_all(&100u32.to_le_bytes()).unwrap();
    let zeros = vec![0u8; 1 << 20];
    for _ in 0..1500 {
        enc.write_all(&zeros).unwrap();
    }
    let bomb = enc.finish().unwrap();
    assert!(bomb.len() < 1 << 20);
    let p = d.path().join("bomb.aedat4");
    aedat4(&p, 3, "346", &[bomb]);
    let o = run_limited(
        args!["convert", p, "--to", "csv", "--out", out],
        Some(1_000_000),
    );
    assert_fails(&o, &["malformed AEDAT 4.0 packet at byte"]);
    // A packet that declares more than the reader takes.
    let mut enc = zstd::stream::Encoder::new(Vec::new(), 3).unwrap();
    enc.write_all(&0xFFFF_FFF0u32.to_le_bytes()).unwrap();
    enc.write_all(&zeros).unwrap();
    let p = d.path().join("declares.aedat4");
    aedat4(&p, 3, "346", &[enc.finish().unwrap()]);
    let o = run_limited(
        args!["convert", p, "--to", "csv", "--out", out],
        Some(1_000_000),
    );
    assert_fails(&o, &["zstd packet at byte", "declares 4294967280 bytes"]);
    assert!(!out.exists());
}

/// Events dataset written in part: the unwritten chunks would read as zero rows.
#[test]
fn hdf5_missing_chunks_are_an_error() {
    let d = tmp();
    // HDF5 opens files without close-on-exec and locks them: a child that another test spawns
    // while this one writes inherits the descriptor and keeps the lock. The reader gets a copy
    // (a new inode) that no leaked descriptor can hold.
    let staged: PathBuf = d.path().join("staged.hdf5");
    let p: PathBuf = d.path().join("partial_data.hdf5");
    {
        let file = hdf5::File::create(&staged).unwrap();
        let ds = file
            .new_dataset::<f64>()
            .chunk([100, 4])
            .shape(hdf5::SimpleExtents::resizable([1000, 4]))
            .create("davis/left/events")
            .unwrap();
        let rows: Vec<f64> = (0..1000)
            .flat_map(|i| [f64::from(i % 300), 5.0, 1.0 + f64::from(i) * 1e-4, 1.0])
            .collect();
        ds.write_raw(&rows).unwrap();
        ds.resize([4000, 4]).unwrap();
    }
    std::fs::copy(&staged, &p).unwrap();
    let out = d.path().join("y.csv");
    let o = run(args!["convert", p, "--to", "csv", "--out", out]);
    assert_fails(&o, &["stores 10 of its 40 chunks"]);
    assert!(!out.exists());
}

/// A file another process is writing (HDF5 writers lock it): the error says what to do.
#[test]
fn hdf5_locked_by_a_writer_says_so() {
    let d = tmp();
    let p: PathBuf = d.path().join("open_data.hdf5");
    let file = hdf5::File::create(&p).unwrap();
    let ds = file
        .new_dataset::<f64>()
        .shape([10, 4])
        .create("davis/left/events")
        .unwrap();
    ds.write_raw(&[1.0f64; 40]).unwrap();
    file.flush().unwrap();
    let out = d.path().join("y.csv");
    let o = run(args!["convert", p, "--to", "csv", "--out", out]);
    drop((ds, file));
    assert_fails(&o, &["unable to lock file", "HDF5_USE_FILE_LOCKING=FALSE"]);
    assert!(!out.exists());
}

#[test]
fn eval_refuses_truth_without_time_and_gyro_on_another_clock() {
    let d = tmp();
    let yaw = d.path().join("yaw.csv");
    let mut s = String::from("t_s,yaw_rate_rad_s,flags\n");
    for k in 1..=400 {
        s.push_str(&format!(
            "{:.3},{:.3},0\n",
            f64::from(k) * 0.01,
            (f64::from(k) * 0.05).sin()
        ));
    }
    std::fs::write(&yaw, &s).unwrap();
    let gt = d.path().join("gt.csv");
    let gt_text = |times: &dyn Fn(u32) -> f64| {
        let mut s = String::from("t_s,wx,wy,wz\n");
        for k in 0..400 {
            s.push_str(&format!(
                "{},0,{:.4},0\n",
                times(k),
                (f64::from(k) * 0.05).sin()
            ));
        }
        s
    };
    // Backwards in the middle.
    std::fs::write(
        &gt,
        gt_text(&|k| if k == 200 { 0.5 } else { f64::from(k) * 0.01 }),
    )
    .unwrap();
    assert_fails(
        &run(args!["eval", "--yaw", yaw, "--gt", gt]),
        &["time goes backwards at sample 201"],
    );
    // All at one time.
    std::fs::write(&gt, gt_text(&|_| 2.0)).unwrap();
    assert_fails(
        &run(args!["eval", "--yaw", yaw, "--gt", gt]),
        &["at one time"],
    );
    // Good truth; a gyro on the Unix epoch.
    std::fs::write(&gt, gt_text(&|k| f64::from(k) * 0.01)).unwrap();
    let imu = d.path().join("imu.txt");
    let mut s = String::new();
    for k in 0..400 {
        s.push_str(&format!(
            "{} 0 0 9.8 0 0.1 0\n",
            1.7e9 + f64::from(k) * 0.01
        ));
    }
    std::fs::write(&imu, s).unwrap();
    assert_fails(
        &run(args!["eval", "--yaw", yaw, "--gt", gt, "--imu", imu]),
        &["the gyro", "do not overlap"],
    );
    let o = run(args!["eval", "--yaw", yaw, "--gt", gt]);
    assert_ok(&o);
}

#[test]
fn eval_streams_its_inputs_and_still_refuses_faults_found_late() {
    // The ground truth and the gyro are read only as far as the estimate has come, then to
    // their end: a fault after the estimate's span is found last, and still ends the run with
    // one error line, nothing printed and no figure written.
    let d = tmp();
    let yaw = d.path().join("yaw.csv");
    let mut s = String::from("t_s,yaw_rate_rad_s\n");
    for k in 0..=1000 {
        s.push_str(&format!("{:.3},{:.4}\n", 1.0 + f64::from(k) * 1e-3, 0.1));
    }
    std::fs::write(&yaw, &s).unwrap();
    let gt = d.path().join("gt.csv");
    let gt_rows = |bad: &dyn Fn(u32) -> Option<String>| {
        let mut s = String::from("t_s,wx,wy,wz\n");
        for k in 0..30_000u32 {
            let row = bad(k).unwrap_or_else(|| format!("{:.4},0,0.1,0", f64::from(k) * 1e-3));
            s.push_str(&row);
            s.push('\n');
        }
        s
    };
    let imu = d.path().join("imu.txt");
    let imu_rows = |bad: &dyn Fn(u32) -> Option<String>| {
        let mut s = String::new();
        for k in 0..6000u32 {
            let row =
                bad(k).unwrap_or_else(|| format!("{:.3} 0 0 9.8 0 0.1 0", f64::from(k) * 5e-3));
            s.push_str(&row);
            s.push('\n');
        }
        s
    };
    let png = d.path().join("e.png");
    let cases: [(&str, String, String, &[&str]); 4] = [
        (
            "truth back at 29 s",
            gt_rows(&|k| (k == 29_000).then(|| "28.5,0,0.1,0".into())),
            imu_rows(&|_| None),
            &["gt.csv", "ground-truth time goes backwards at sample 29001"],
        ),
        (
            "truth truncated",
            gt_rows(&|_| None) + "30.5,0",
            imu_rows(&|_| None),
            &["gt.csv", "truncated line 30002"],
        ),
        (
            "gyro malformed at 25 s",
            gt_rows(&|_| None),
            imu_rows(&|k| (k == 5000).then(|| "25.0 0 0".into())),
            &["imu.txt", "malformed line 5001"],
        ),
        (
            "gyro back at 29 s",
            gt_rows(&|_| None),
            imu_rows(&|k| (k == 5800).then(|| "1.0 0 0 9.8 0 0.1 0".into())),
            &["imu.txt", "gyro time goes backwards at sample 5801"],
        ),
    ];
    for (what, gt_text, imu_text, needles) in cases {
        std::fs::write(&gt, gt_text).unwrap();
        std::fs::write(&imu, imu_text).unwrap();
        let o = run(args![
            "eval", "--yaw", yaw, "--gt", gt, "--imu", imu, "--plot", png
        ]);
        assert_fails(&o, needles);
        assert!(o.stdout.is_empty(), "{what}: printed figures");
        assert!(!png.exists(), "{what}: left the figure");
        assert!(leftovers(d.path()).is_empty(), "{what}");
        // Not prefixed by the evaluation's label: the error is the file's.
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!err.contains(" vs "), "{what}: {err}");
    }
    std::fs::write(&gt, gt_rows(&|_| None)).unwrap();
    std::fs::write(&imu, imu_rows(&|_| None)).unwrap();
    let o = run(args![
        "eval", "--yaw", yaw, "--gt", gt, "--imu", imu, "--plot", png
    ]);
    assert_ok(&o);
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
}

/// Names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn sweep_demo_and_eval_leave_nothing_when_the_plot_fails() {
    let d = tmp();
    let csv = d.path().join("s.csv");
    // sweep: a plot into a folder that does not exist, a plot path that is a folder, a plot
    // path equal to the CSV's; the CSV is never left behind, nor any temporary file.
    let missing_dir = d.path().join("no_such_dir").join("s.png");
    assert_fails(
        &run(args!["sweep", "--out", csv, "--plot", missing_dir]),
        &["s.png"],
    );
    assert!(!csv.exists(), "the CSV was left behind");
    let folder = d.path().join("plot.png");
    std::fs::create_dir(&folder).unwrap();
    assert_fails(
        &run(args!["sweep", "--out", csv, "--plot", folder]),
        &["plot.png"],
    );
    assert!(!csv.exists(), "the CSV was left behind");
    assert_fails(
        &run(args!["sweep", "--out", csv, "--plot", csv]),
        &["s.csv"],
    );
    assert!(!csv.exists());
    assert_eq!(names(d.path()), ["plot.png"]);
    // Both appear when both can be written.
    let png = d.path().join("s.png");
    assert_ok(&run(args!["sweep", "--out", csv, "--plot", png]));
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    assert!(std::fs::read_to_string(&csv)
        .unwrap()
        .starts_with("dt_ms,spikes,first_spike_ms\n"));
    assert_eq!(names(d.path()), ["plot.png", "s.csv", "s.png"]);

    // demo: its figure's name taken by a folder. None of the scene files, yaw.csv or the
    // staging folder is left; the one error line is the last of stderr (after the progress
    // line).
    let out = d.path().join("demo");
    std::fs::create_dir_all(out.join("eval.png")).unwrap();
    let o = run(args!["demo", "--out", out, "--duration", "0.3"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error: ")).collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert_eq!(err.lines().last(), Some(errors[0]));
    assert!(errors[0].contains("eval.png"), "{err}");
    assert_eq!(names(&out), ["eval.png"]);
    // A demo into a new folder: every output, nothing else.
    let out = d.path().join("demo2");
    let o = run(args!["demo", "--out", out, "--duration", "0.3"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        names(&out),
        [
            "eval.png",
            "events.txt",
            "gt.csv",
            "imu.txt",
            "meta.json",
            "yaw.csv"
        ]
    );

    // eval: a figure that cannot be written prints no figures and leaves no file.
    let yaw = out.join("yaw.csv");
    let gt = out.join("gt.csv");
    let before = names(&out);
    let bad = out.join("no_such_dir").join("e.png");
    let o = run(args!["eval", "--yaw", yaw, "--gt", gt, "--plot", bad]);
    assert_fails(&o, &["e.png"]);
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert_eq!(names(&out), before);
}

#[test]
fn eval_reads_the_estimate_line_by_line() {
    let d = tmp();
    let gt = d.path().join("gt.csv");
    std::fs::write(&gt, "t_s,yaw_rate\n0,0.1\n1,0.2\n2,0.3\n").unwrap();
    let yaw = d.path().join("yaw.csv");
    // A row without a line break longer than any estimate row: refused, not read whole.
    let mut s = String::from("t_s,yaw_rate_rad_s\n0,0.1\n");
    s.push_str(&"1".repeat(3 << 20));
    std::fs::write(&yaw, &s).unwrap();
    assert_fails(
        &run(args!["eval", "--yaw", yaw, "--gt", gt]),
        &["yaw.csv", "line 3", "longer than"],
    );
    // Bytes that are not text, a time going back, a time that is not finite.
    std::fs::write(&yaw, b"t_s,yaw_rate_rad_s\n0,0.1\n1,\xff\xfe\n").unwrap();
    assert_fails(&run(args!["eval", "--yaw", yaw, "--gt", gt]), &["line 3"]);
    std::fs::write(&yaw, "t_s,yaw_rate_rad_s\n0,0.1\n2,0.1\n1,0.1\n").unwrap();
    assert_fails(
        &run(args!["eval", "--yaw", yaw, "--gt", gt]),
        &["line 4: time goes backwards"],
    );
    std::fs::write(&yaw, "t_s,yaw_rate_rad_s\n0,0.1\ninf,0.1\n").unwrap();
    assert_fails(
        &run(args!["eval", "--yaw", yaw, "--gt", gt]),
        &["line 3: time is not finite"],
    );
    // Rows without a value are skipped and counted; CRLF and blank lines are fine.
    std::fs::write(
        &yaw,
        "t_s,yaw_rate_rad_s\r\n0,0.1\r\n\r\n0.5,nan\r\n1,0.2\r\n1.5,\r\n2,0.3\r\n",
    )
    .unwrap();
    let o = run(args!["eval", "--yaw", yaw, "--gt", gt]);
    assert_ok(&o);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("2 estimate rows without a value"), "{text}");
    assert!(text.contains("RMSE                 0.0000 rad/s"), "{text}");
}
