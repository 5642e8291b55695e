//! A recording through the emulated firmware (`cargo xtask qemu`, the QEMU system tests).
//!
//! Steps of [`Qemu::run`]: turn the input into the AER stream with the hidden `host-sim
//! aer-stream` command, which takes the flags of `host-sim run` and prints the settings they
//! give (`settings=HEX`, the configuration payload of `docs/wire-formats.md`); or, for an input
//! that already is an AER stream, take it as it is with the settings `host-sim settings`
//! prints for the flags. Then run `qemu-system-arm -M mps2-an386 -icount shift=N` with the
//! stream in an emulated SPI flash (or, over 16 MiB, a semihosting file) and the firmware
//! started with `--settings HEX`; decode the firmware's yaw frames with `host-sim yaw-decode`.
//! The firmware's counters are in [`Report::summary`].
//!
//! The QEMU firmware must be built (`cargo xtask firmware --board qemu`); `cargo xtask qemu`
//! and `cargo xtask test` build it first.

use std::fmt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use core_nostd::settings::{ReadoutChoice, Settings};

use crate::{field, firmware_elf, host_sim, output, root, run};

/// The SPI flash QEMU emulates (n25q128): the drive file must be exactly this large.
const FLASH_BYTES: u64 = 16 * 1024 * 1024;
/// Longest a QEMU run may take (wall clock) before it is stopped.
const QEMU_TIMEOUT: Duration = Duration::from_secs(1200);
/// Link rate of a paced run, Mbit/s: a fast SPI link (4 MB/s, 1 M AER events/s).
pub const DEFAULT_LINK_MBIT: f64 = 32.0;

/// `cargo xtask qemu`'s command line.
pub const USAGE: &str = "usage: cargo xtask qemu INPUT --out yaw.csv [--via spi|file] [--live] \
[--paced] [--link-mbit 32] [--icount-shift 0..3] [--work DIR] [--send-config] [host-sim run \
flags: --layout, --window X0:Y0:W:H, --stride, --rate-hz, --tau-a-ms, --readout, --unit-pool, --focal-px, \
--cx, --cy, --width W --height H, --format] [--profile FILE: instructions per function and the hottest blocks, from QEMU's block trace]";

/// How the stream reaches the firmware.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Via {
    /// The emulated SPI NOR flash on the PL022 (the byte path of a real SPI link; up to 16 MiB).
    Spi,
    /// A host file through semihosting (any size, much faster).
    File,
}

/// One run of the emulated firmware: `cargo xtask qemu`'s options.
#[derive(Clone, Debug)]
pub struct Qemu {
    /// A recording (any format `host-sim run` reads) or an AER stream (`.aer`, or starting
    /// with the frame sync).
    pub input: PathBuf,
    /// The yaw CSV, as `host-sim run --out` writes it.
    pub out: PathBuf,
    /// Working folder (the stream, the flash image, `yaw.bin`, `summary.txt`, the defmt log).
    pub work: PathBuf,
    /// Flags of `host-sim run`, passed as they are to `host-sim aer-stream` (or, for an AER
    /// stream, to `host-sim settings`).
    pub run_flags: Vec<String>,
    /// `None`: the SPI flash when the stream fits, else a file.
    pub via: Option<Via>,
    /// Drop frames when the processing falls behind; the clock drives stale output.
    pub live: bool,
    /// Frames become readable at their events' times (needs a recording).
    pub paced: bool,
    /// Link rate of a paced run, Mbit/s (0 = unlimited).
    pub link_mbit: f64,
    /// QEMU `-icount shift` (0..=3; `None`: 0 for replays, 3 with `live`).
    pub icount_shift: Option<u8>,
    /// Put the settings at the start of the stream as a configuration frame.
    pub send_config: bool,
    /// For an AER stream: the settings (hex) the firmware starts with, instead of those
    /// `host-sim settings` gives for [`Qemu::run_flags`].
    pub start_settings: Option<String>,
    /// Write the instructions executed per function and the hottest blocks here
    /// ([`crate::profile`]; the run is many times slower).
    pub profile: Option<PathBuf>,
}

/// What a QEMU run reports.
#[derive(Clone, Debug)]
pub struct Report {
    /// The firmware's counters.
    pub summary: Summary,
    /// Time origin of the stream (µs on the recording's clock; 0 for an AER stream input).
    pub t0_us: u64,
    /// The settings the firmware started with (hex of the configuration payload).
    pub settings: String,
    /// The AER stream the firmware read.
    pub stream: PathBuf,
    /// The firmware's yaw frames.
    pub yaw_bin: PathBuf,
}

/// The firmware's `summary.txt`: a line of counters (`events=N frames_ok=N frames_bad=N
/// frames_dropped=N instructions_per_event=N`), then `detail: ...` (`key=value` fields).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Summary(String);

impl Summary {
    /// The first line (the counters).
    pub fn counters(&self) -> &str {
        self.0.lines().next().unwrap_or_default()
    }

    /// The second line (`detail: ...`).
    pub fn details(&self) -> &str {
        self.0.lines().nth(1).unwrap_or_default()
    }

    /// The counter `k` (on either line), when it is there and a whole number.
    pub fn get(&self, k: &str) -> Option<u64> {
        self.0
            .lines()
            .find_map(|l| field(l, k))
            .and_then(|v| v.parse().ok())
    }

    /// The counter `k`; an error naming the summary when it is missing.
    ///
    /// # Errors
    /// When the summary has no whole-number field `k`.
    pub fn counter(&self, k: &str) -> Result<u64> {
        self.get(k)
            .with_context(|| format!("the firmware's summary has no {k}: {self}"))
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.0.trim_end())
    }
}

/// What `host-sim aer-stream` wrote and printed.
#[derive(Clone, Debug)]
pub struct Stream {
    /// Events in the stream.
    pub events: u64,
    /// Time of the first event on the recording's clock (µs); the stream's clock starts there.
    pub t0_us: u64,
    /// The settings `host-sim run` would use with the same flags (hex configuration payload).
    pub settings: String,
}

/// `host-sim aer-stream INPUT --out OUT RUN_FLAGS.. [--schedule S] [--config]`.
///
/// # Errors
/// When host-sim fails or prints no `events`, `t0_us` or `settings`.
pub fn aer_stream<S: AsRef<std::ffi::OsStr>>(
    input: &Path,
    run_flags: &[S],
    out: &Path,
    schedule: Option<&Path>,
    config: bool,
) -> Result<Stream> {
    let mut c = host_sim();
    c.arg("aer-stream").arg(input).arg("--out").arg(out);
    if let Some(s) = schedule {
        c.arg("--schedule").arg(s);
    }
    if config {
        c.arg("--config");
    }
    c.args(run_flags);
    let line = output(&format!("host-sim aer-stream {}", input.display()), c)?;
    let get = |k: &str| {
        field(&line, k).with_context(|| format!("host-sim aer-stream printed no {k}: {line}"))
    };
    Ok(Stream {
        events: get("events")?.parse().context("events: not a number")?,
        t0_us: get("t0_us")?.parse().context("t0_us: not a number")?,
        settings: get("settings")?.to_string(),
    })
}

/// `host-sim settings RUN_FLAGS..`: the settings of the flags alone (no recording).
///
/// # Errors
/// When host-sim fails (the flags lack the sensor size or focal length, say).
pub fn settings_of_flags<S: AsRef<std::ffi::OsStr>>(run_flags: &[S]) -> Result<String> {
    let mut c = host_sim();
    c.arg("settings").args(run_flags);
    let line = output("host-sim settings", c)?;
    field(&line, "settings")
        .map(str::to_string)
        .with_context(|| format!("host-sim settings printed no settings: {line}"))
}

/// Whether `path` holds an AER stream: `.aer`, or its first bytes are a frame's sync.
fn is_aer_file(path: &Path) -> Result<bool> {
    use std::io::Read;
    if path.extension().is_some_and(|e| e == "aer") {
        return Ok(true);
    }
    let sync = core_nostd::aer::frame::SYNC;
    let mut head = [0u8; 2];
    let mut f =
        std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let n = f.read(&mut head).unwrap_or(0);
    Ok(n == sync.len() && head == sync)
}

impl Qemu {
    /// A replay of `input` with `host-sim run`'s defaults into `out`, working in `work`.
    pub fn new(
        input: impl Into<PathBuf>,
        out: impl Into<PathBuf>,
        work: impl Into<PathBuf>,
    ) -> Self {
        Self {
            input: input.into(),
            out: out.into(),
            work: work.into(),
            run_flags: Vec::new(),
            via: None,
            live: false,
            paced: false,
            link_mbit: DEFAULT_LINK_MBIT,
            icount_shift: None,
            send_config: false,
            start_settings: None,
            profile: None,
        }
    }

    /// With these flags of `host-sim run`.
    #[must_use]
    pub fn flags(mut self, flags: &[&str]) -> Self {
        self.run_flags = flags.iter().map(|s| (*s).to_string()).collect();
        self
    }

    /// `cargo xtask qemu INPUT --out yaw.csv [options]` (see [`USAGE`]): the options of the
    /// run are taken here, every other argument is a flag of `host-sim run` (with its value).
    ///
    /// # Errors
    /// On a missing INPUT or `--out`, or a bad value of an option of the run.
    pub fn parse(args: &[String]) -> Result<Self> {
        let (input, rest) = match args.split_first() {
            Some((i, rest)) if !i.starts_with("--") => (i, rest),
            _ => bail!("no INPUT (it comes first)\n{USAGE}"),
        };
        let mut q = Self::new(input, PathBuf::new(), root().join("out/qemu"));
        let mut it = rest.iter();
        while let Some(k) = it.next() {
            let mut val = || {
                it.next()
                    .cloned()
                    .with_context(|| format!("{k} needs a value\n{USAGE}"))
            };
            match k.as_str() {
                "--out" => q.out = PathBuf::from(val()?),
                "--work" => q.work = PathBuf::from(val()?),
                "--via" => {
                    q.via = Some(match val()?.as_str() {
                        "spi" => Via::Spi,
                        "file" => Via::File,
                        v => bail!("--via must be spi or file (got {v})"),
                    })
                }
                "--live" => q.live = true,
                "--paced" => q.paced = true,
                "--send-config" => q.send_config = true,
                "--profile" => q.profile = Some(PathBuf::from(val()?)),
                "--icount-shift" => {
                    let v: u8 = val()?.parse().context("--icount-shift: not a number")?;
                    if v > 3 {
                        bail!("--icount-shift must be 0..=3 (got {v})");
                    }
                    q.icount_shift = Some(v);
                }
                "--link-mbit" => {
                    let v = val()?;
                    q.link_mbit = v
                        .parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite() && *x >= 0.0)
                        .with_context(|| format!("--link-mbit: not a rate >= 0: {v}"))?;
                }
                "--schedule" | "--config" => {
                    bail!("{k} is set by xtask (--paced, --send-config)\n{USAGE}")
                }
                _ => q.run_flags.push(k.clone()),
            }
        }
        if q.out.as_os_str().is_empty() {
            bail!("no --out\n{USAGE}");
        }
        Ok(q)
    }

    /// The `-icount shift` of the run.
    fn shift(&self) -> u8 {
        self.icount_shift.unwrap_or(if self.live { 3 } else { 0 })
    }

    /// Writes `stream` (and, for a paced run, the arrival schedule next to it); returns the
    /// time origin and the settings.
    fn prepare_stream(&self, stream: &Path) -> Result<(u64, String)> {
        if is_aer_file(&self.input)? {
            if self.paced {
                bail!("--paced needs a recording: an AER stream carries no arrival times");
            }
            if self.send_config {
                bail!("--send-config needs a recording: an AER stream is sent as it is");
            }
            std::fs::copy(&self.input, stream)
                .with_context(|| format!("cannot copy {}", self.input.display()))?;
            let settings = match &self.start_settings {
                Some(s) => s.clone(),
                None => settings_of_flags(&self.run_flags).context(
                    "an AER stream carries no sensor size or intrinsics: pass --width, --height \
                     and --focal-px",
                )?,
            };
            return Ok((0, settings));
        }
        if self.start_settings.is_some() {
            bail!("start settings are for an AER stream input; a recording's come from its flags");
        }
        let schedule = self.paced.then(|| stream.with_file_name("schedule.bin"));
        let s = aer_stream(
            &self.input,
            &self.run_flags,
            stream,
            schedule.as_deref(),
            self.send_config,
        )?;
        Ok((s.t0_us, s.settings))
    }

    /// Runs the built QEMU firmware on the input; writes [`Qemu::out`].
    ///
    /// # Errors
    /// When the stream cannot be made, QEMU cannot start, the firmware does not exit with 0
    /// (the defmt log is in the working folder), or its yaw frames cannot be decoded.
    pub fn run(&self) -> Result<Report> {
        let work = &self.work;
        std::fs::create_dir_all(work)
            .with_context(|| format!("cannot create {}", work.display()))?;
        for f in [
            "events.aer",
            "schedule.bin",
            "flash.bin",
            "yaw.bin",
            "summary.txt",
            "defmt.bin",
        ] {
            let _ = std::fs::remove_file(work.join(f));
        }
        let stream = work.join("events.aer");
        let (t0_us, settings) = self.prepare_stream(&stream)?;
        let bytes = std::fs::metadata(&stream)
            .with_context(|| format!("cannot read {}", stream.display()))?
            .len();
        let via_spi = match self.via {
            Some(Via::File) => false,
            Some(Via::Spi) if bytes > FLASH_BYTES => {
                bail!("the stream ({bytes} B) does not fit the 16 MiB SPI flash: use --via file")
            }
            Some(Via::Spi) => true,
            None => bytes <= FLASH_BYTES,
        };
        let mut fw_args: Vec<String> = vec![
            "tde-firmware".into(),
            "--settings".into(),
            settings.clone(),
            "--input".into(),
            if via_spi { "spi" } else { "file" }.into(),
            "--bytes".into(),
            bytes.to_string(),
            "--icount-shift".into(),
            self.shift().to_string(),
        ];
        if self.live {
            fw_args.push("--live".into());
        }
        if self.paced {
            let bps = (self.link_mbit * 1e6 / 8.0).round();
            fw_args.push("--paced".into());
            fw_args.push("--link-bps".into());
            fw_args.push((bps.min(f64::from(u32::MAX)) as u32).to_string());
        }
        let elf = firmware_elf("qemu");
        if !elf.exists() {
            bail!(
                "no QEMU firmware at {}: build it with `cargo xtask firmware --board qemu`",
                elf.display()
            );
        }
        let mut qemu = Command::new("qemu-system-arm");
        qemu.current_dir(work).args([
            "-M",
            "mps2-an386",
            "-nographic",
            "-monitor",
            "none",
            "-serial",
            "none",
            "-icount",
        ]);
        qemu.arg(format!("shift={},align=off,sleep=off", self.shift()));
        let mut semi = String::from("enable=on,target=native");
        for arg in &fw_args {
            if arg.contains(',') {
                bail!("firmware argument with a comma: {arg}");
            }
            semi.push_str(",arg=");
            semi.push_str(arg);
        }
        qemu.arg("-semihosting-config").arg(semi);
        if via_spi {
            let flash = work.join("flash.bin");
            std::fs::copy(&stream, &flash).context("cannot write flash.bin")?;
            let f = std::fs::OpenOptions::new()
                .write(true)
                .open(&flash)
                .context("cannot open flash.bin")?;
            f.set_len(FLASH_BYTES).context("cannot pad flash.bin")?;
            qemu.args([
                "-drive",
                "file=flash.bin,if=none,format=raw,id=fl",
                "-device",
                "n25q128,drive=fl",
            ]);
        }
        qemu.arg("-kernel").arg(&elf);
        let tracer = match &self.profile {
            Some(_) => {
                let t = crate::profile::Tracer::start(&work.join("trace.fifo"))?;
                qemu.args(t.args());
                Some(t)
            }
            None => None,
        };
        let defmt =
            std::fs::File::create(work.join("defmt.bin")).context("cannot create defmt.bin")?;
        qemu.stdout(defmt);
        eprintln!(
            "xtask: qemu-system-arm -M mps2-an386 -icount shift={} ({bytes} B of AER via {}{}{}) \
             in {}",
            self.shift(),
            if via_spi { "SPI flash" } else { "semihosting" },
            if self.live { ", live" } else { "" },
            if self.paced { ", paced" } else { "" },
            work.display()
        );
        let status = run_with_timeout(qemu, QEMU_TIMEOUT)?;
        if let (Some(t), Some(path)) = (tracer, &self.profile) {
            let p = t.finish()?;
            std::fs::write(path, p.report())
                .with_context(|| format!("cannot write {}", path.display()))?;
            eprintln!(
                "xtask: {} instructions per function in {}",
                p.total,
                path.display()
            );
        }
        let summary = std::fs::read_to_string(work.join("summary.txt")).unwrap_or_default();
        if status != Some(0) {
            bail!(
                "the firmware exited with {} (defmt log: {}; decode it with `defmt-print -e {} < \
                 defmt.bin`){}",
                status.map_or("a signal / timeout".to_string(), |c| format!("code {c}")),
                work.join("defmt.bin").display(),
                elf.display(),
                if summary.is_empty() {
                    String::new()
                } else {
                    format!("\n{summary}")
                }
            );
        }
        if summary.is_empty() {
            bail!("the firmware wrote no summary.txt");
        }
        let yaw_bin = work.join("yaw.bin");
        let mut c = host_sim();
        c.arg("yaw-decode")
            .arg(&yaw_bin)
            .arg("--t0-us")
            .arg(t0_us.to_string())
            .arg("--out")
            .arg(&self.out);
        if readout_of(&settings) == Some(ReadoutChoice::Normalized) {
            c.arg("--normalized");
        }
        run("host-sim yaw-decode", c)?;
        Ok(Report {
            summary: Summary(summary),
            t0_us,
            settings,
            stream,
            yaw_bin,
        })
    }
}

/// The readout the settings (hex of a configuration payload) name, if they parse.
fn readout_of(hex: &str) -> Option<ReadoutChoice> {
    Settings::parse_hex(hex).ok().map(|s| s.readout)
}

/// Runs `cmd`, killing it after `limit`; returns its exit code (`None` when killed).
fn run_with_timeout(mut cmd: Command, limit: Duration) -> Result<Option<i32>> {
    let mut child = cmd
        .spawn()
        .context("cannot start qemu-system-arm (apt-get install qemu-system-arm)")?;
    let start = Instant::now();
    loop {
        if let Some(st) = child.try_wait().context("waiting for qemu")? {
            return Ok(st.code());
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Ok(None);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<String> {
        s.split_whitespace().map(str::to_string).collect()
    }

    #[test]
    fn xtask_options_are_taken_and_the_rest_goes_to_host_sim() {
        let q = Qemu::parse(&args(
            "rec/events.txt --layout paper-boxes --out y.csv --live --stride 3 --via file \
             --window 0:122:346:15 --link-mbit 8 --paced --send-config --icount-shift 2 \
             --profile p.txt",
        ))
        .unwrap();
        assert_eq!(q.input, PathBuf::from("rec/events.txt"));
        assert_eq!(q.out, PathBuf::from("y.csv"));
        assert_eq!(
            q.run_flags,
            args("--layout paper-boxes --stride 3 --window 0:122:346:15")
        );
        assert_eq!(q.via, Some(Via::File));
        assert!(q.live && q.paced && q.send_config);
        assert_eq!((q.link_mbit, q.shift()), (8.0, 2));
        assert_eq!(q.profile, Some(PathBuf::from("p.txt")));
    }

    #[test]
    fn the_command_line_needs_input_first_and_out() {
        assert!(Qemu::parse(&args("--out y.csv rec.txt")).is_err());
        assert!(Qemu::parse(&args("rec.txt --layout dense")).is_err());
        assert!(Qemu::parse(&args("rec.txt --out y.csv --config")).is_err());
        assert!(Qemu::parse(&args("rec.txt --out y.csv --icount-shift 4")).is_err());
        let q = Qemu::parse(&args("rec.txt --out y.csv --live")).unwrap();
        assert_eq!((q.shift(), q.link_mbit), (3, DEFAULT_LINK_MBIT));
    }

    #[test]
    fn summary_fields_come_from_either_line() {
        let s = Summary(
            "events=5 frames_ok=2 frames_bad=0 frames_dropped=1 instructions_per_event=700\n\
             detail: bytes=90 bit_slips=3 input_instructions_per_byte=1.50\n"
                .into(),
        );
        assert_eq!(s.get("frames_ok"), Some(2));
        assert_eq!(s.get("bit_slips"), Some(3));
        assert_eq!(s.get("input_instructions_per_byte"), None);
        assert!(s.counter("frames_gap").is_err());
        assert!(s.details().starts_with("detail:"));
    }
}
