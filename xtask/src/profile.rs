//! Where the emulated firmware's instructions go (`cargo xtask qemu … --profile FILE`).
//!
//! QEMU logs every translation block it translates (`-d in_asm`: the block's instructions,
//! one line each, under `IN: SYMBOL`) and, with chaining off (`-d exec,nochain`), every block it
//! executes (`Trace N: HOST [FLAGS/PC/…] SYMBOL`). A block's executions times its
//! instructions, summed per function, is the function's share of the run's instructions
//! (functions inlined into another count as that one). The log is read as QEMU writes it, through
//! a FIFO: a run's log is gigabytes (the start-up's RAM clearing alone is ~20 M block runs).

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::thread::JoinHandle;

use anyhow::{bail, Context, Result};

/// Instructions executed per function of a traced run.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Profile {
    /// `(function, instructions)`, most first (demangled, without the hash).
    pub functions: Vec<(String, u64)>,
    /// `(block start address, instructions, function)` of the [`HOT_BLOCKS`] blocks that
    /// executed the most instructions, most first: where inside a function they go (map an
    /// address to its source line with `addr2line -e ELF ADDR`).
    pub blocks: Vec<(u32, u64, String)>,
    /// `(calling block's start address, calls, caller)` of the compiler's helper routines
    /// (memory copies and fills, 64-bit divisions: `is_helper`), most first: a block that
    /// runs right before one of them and is not one of them.
    pub helper_callers: Vec<(u32, u64, String)>,
    /// All instructions executed.
    pub total: u64,
}

/// Whether `symbol` is one of the helper routines the compiler calls where the Cortex-M has
/// no instruction: copies and fills (`memcpy`, `memset`, `memmove`, `__aeabi_memclr`) and
/// 64-bit divisions (`__aeabi_uldivmod`, `__udivmoddi4`, `u64_div_rem`, ...).
fn is_helper(symbol: &str) -> bool {
    ["memcpy", "memset", "memmove", "memclr", "divmod", "div_rem"]
        .iter()
        .any(|r| symbol.contains(r))
}

/// Blocks listed in [`Profile::blocks`].
pub const HOT_BLOCKS: usize = 40;

/// Reads a QEMU `-d in_asm,exec,nochain` log.
///
/// # Errors
/// On a read error.
pub fn read_trace(log: impl BufRead) -> Result<Profile> {
    // Block start address -> its instruction count (the latest translation).
    let mut sizes: HashMap<u32, u32> = HashMap::new();
    // Block start address -> (executions, symbol).
    let mut runs: HashMap<u32, (u64, String)> = HashMap::new();
    // The block being listed: its start and instructions so far.
    let mut listing: Option<(Option<u32>, u32)> = None;
    // The block executed last (its start, whether it is a helper routine) and the calls
    // into helper routines per calling block.
    let mut last: Option<(u32, bool)> = None;
    let mut calls: HashMap<u32, u64> = HashMap::new();
    for line in log.lines() {
        let line = line.context("reading the QEMU log")?;
        if line.starts_with("IN:") {
            listing = Some((None, 0));
            continue;
        }
        if let Some((start, n)) = listing.as_mut() {
            if let Some(addr) = line.strip_prefix("0x").and_then(|l| l.split(':').next()) {
                if let Ok(a) = u32::from_str_radix(addr, 16) {
                    start.get_or_insert(a);
                    *n += 1;
                    continue;
                }
            }
            if let (Some(a), n) = (*start, *n) {
                sizes.insert(a, n);
            }
            listing = None;
        }
        if let Some(rest) = line.strip_prefix("Trace ") {
            let Some((pc, symbol)) = trace_pc(rest) else {
                continue;
            };
            let e = runs.entry(pc).or_insert_with(|| (0, symbol.to_string()));
            e.0 += 1;
            let helper = is_helper(symbol);
            if let Some((from, false)) = last.filter(|_| helper) {
                *calls.entry(from).or_default() += 1;
            }
            last = Some((pc, helper));
        }
    }
    if let Some((Some(a), n)) = listing {
        sizes.insert(a, n);
    }
    let mut per: HashMap<String, u64> = HashMap::new();
    let mut blocks = Vec::with_capacity(runs.len());
    let mut total = 0u64;
    for (&pc, (count, symbol)) in &runs {
        let instructions = *count * u64::from(sizes.get(&pc).copied().unwrap_or(1));
        total += instructions;
        let function = demangle(symbol);
        *per.entry(function.clone()).or_default() += instructions;
        blocks.push((pc, instructions, function));
    }
    let mut functions: Vec<_> = per.into_iter().collect();
    functions.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
    blocks.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
    blocks.truncate(HOT_BLOCKS);
    let mut helper_callers: Vec<_> = calls
        .into_iter()
        .map(|(pc, n)| {
            let f = runs.get(&pc).map(|r| demangle(&r.1)).unwrap_or_default();
            (pc, n, f)
        })
        .collect();
    helper_callers.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
    helper_callers.truncate(HOT_BLOCKS);
    Ok(Profile {
        functions,
        blocks,
        helper_callers,
        total,
    })
}

/// The guest PC and symbol of a `Trace N: HOST [FLAGS/PC/…] SYMBOL` line (after `Trace `).
fn trace_pc(rest: &str) -> Option<(u32, &str)> {
    let open = rest.find('[')?;
    let close = rest[open..].find(']')? + open;
    let pc = rest[open + 1..close].split('/').nth(1)?;
    let pc = u32::from_str_radix(pc, 16).ok()?;
    Some((pc, rest[close + 1..].trim()))
}

/// A Rust symbol demangled without its hash; others as they are.
fn demangle(symbol: &str) -> String {
    format!("{:#}", rustc_demangle::demangle(symbol))
}

impl Profile {
    /// The report: total, then `instructions  share  function`, one line each, most first;
    /// then the hottest blocks, `address  instructions  share  function`.
    pub fn report(&self) -> String {
        let mut s = format!(
            "{} instructions executed (QEMU block trace; start-up included)\n",
            self.total
        );
        for (f, n) in &self.functions {
            let share = 100.0 * *n as f64 / self.total.max(1) as f64;
            s.push_str(&format!("{n:>14} {share:>6.2} %  {f}\n"));
        }
        s.push_str(
            "\nhottest blocks (start address; `llvm-addr2line -i -e ELF ADDR` gives the source lines)\n",
        );
        for (pc, n, f) in &self.blocks {
            let share = 100.0 * *n as f64 / self.total.max(1) as f64;
            s.push_str(&format!("0x{pc:08x} {n:>14} {share:>6.2} %  {f}\n"));
        }
        s.push_str(
            "\ncalls into helper routines (copies, fills, 64-bit divisions), by calling block\n",
        );
        for (pc, n, f) in &self.helper_callers {
            s.push_str(&format!("0x{pc:08x} {n:>14}  {f}\n"));
        }
        s
    }
}

/// A reader of the QEMU log QEMU writes into a FIFO: create it, give QEMU [`Tracer::args`],
/// then [`Tracer::finish`] once QEMU has exited.
pub struct Tracer {
    fifo: PathBuf,
    reader: JoinHandle<Result<Profile>>,
}

impl Tracer {
    /// A FIFO at `fifo` (replacing any file there) and a thread that reads the log from it.
    ///
    /// # Errors
    /// When the FIFO cannot be made (`mkfifo`).
    pub fn start(fifo: &Path) -> Result<Self> {
        let _ = std::fs::remove_file(fifo);
        let ok = Command::new("mkfifo")
            .arg(fifo)
            .status()
            .context("cannot run mkfifo")?
            .success();
        if !ok {
            bail!("mkfifo {} failed", fifo.display());
        }
        let path = fifo.to_path_buf();
        let reader = std::thread::spawn(move || {
            // Blocks until QEMU opens the FIFO for writing.
            let f = File::open(&path).with_context(|| format!("cannot open {}", path.display()))?;
            read_trace(BufReader::with_capacity(1 << 20, f))
        });
        Ok(Self {
            fifo: fifo.to_path_buf(),
            reader,
        })
    }

    /// QEMU's arguments for the log.
    pub fn args(&self) -> Vec<String> {
        vec![
            "-d".into(),
            "in_asm,exec,nochain".into(),
            "-D".into(),
            self.fifo.display().to_string(),
        ]
    }

    /// The profile, once QEMU has exited (if it never opened the FIFO, the reader is released
    /// with an empty log).
    ///
    /// # Errors
    /// When the reader failed.
    pub fn finish(self) -> Result<Profile> {
        if !self.reader.is_finished() {
            // Opening the write end releases a reader still waiting in `open` (and gives it
            // end-of-file); with no reader left it fails, which is fine.
            use std::os::unix::fs::OpenOptionsExt;
            let _ = std::fs::OpenOptions::new()
                .write(true)
                .custom_flags(0o4000) // O_NONBLOCK
                .open(&self.fifo)
                .map(|mut f| f.flush());
        }
        let profile = self
            .reader
            .join()
            .map_err(|_| anyhow::anyhow!("the QEMU log reader panicked"))??;
        let _ = std::fs::remove_file(&self.fifo);
        Ok(profile)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LOG: &str = "\
----------------
IN: Reset
0x00000404:  480e       ldr      r0, [pc, #0x38]
0x00000406:  490f       ldr      r1, [pc, #0x3c]

Trace 0: 0x7f5a14000100 [00800408/00000404/00000110/ff020200] Reset
----------------
IN: _ZN10core_nostd7network16Network$LT$L$GT$4tick17hd9e1b4cd10bf8fa1E
0x00001000:  b580       push     {r7, lr}
0x00001002:  466f       mov      r7, sp
0x00001004:  bd80       pop      {r7, pc}

Trace 0: 0x7f5a14000240 [00800408/00001000/00000110/ff020200] _ZN10core_nostd7network16Network$LT$L$GT$4tick17hd9e1b4cd10bf8fa1E
Trace 0: 0x7f5a14000240 [00800408/00001000/00000110/ff020200] _ZN10core_nostd7network16Network$LT$L$GT$4tick17hd9e1b4cd10bf8fa1E
Stopped execution of TB chain before 0x7f7f900008c0 [0000040a] Reset
Trace 0: 0x7f5a14000100 [00800408/00000404/00000110/ff020200] Reset
Trace 0: 0x7f5a14000240 [00800408/00001000/00000110/ff020200] _ZN10core_nostd7network16Network$LT$L$GT$4tick17hd9e1b4cd10bf8fa1E
";

    #[test]
    fn executions_times_block_sizes_per_function() {
        let p = read_trace(LOG.as_bytes()).unwrap();
        // tick: 3 runs of a 3-instruction block; Reset: 2 runs of 2.
        assert_eq!(
            p.functions,
            vec![
                ("core_nostd::network::Network<L>::tick".to_string(), 9),
                ("Reset".to_string(), 4)
            ]
        );
        assert_eq!(p.total, 13);
        assert_eq!(
            p.blocks,
            vec![
                (
                    0x1000,
                    9,
                    "core_nostd::network::Network<L>::tick".to_string()
                ),
                (0x404, 4, "Reset".to_string())
            ]
        );
        let r = p.report();
        assert!(r.starts_with("13 instructions executed"), "{r}");
        assert!(
            r.contains("9  69.23 %  core_nostd::network::Network<L>::tick"),
            "{r}"
        );
        assert!(
            r.contains("0x00001000              9  69.23 %  core_nostd"),
            "{r}"
        );
    }

    #[test]
    fn calls_into_helper_routines_are_counted_by_the_block_before_them() {
        let log = "\
IN: caller
0x00002000:  b580       push     {r7, lr}

IN: __aeabi_uldivmod
0x00003000:  b580       push     {r7, lr}
0x00003002:  bd80       pop      {r7, pc}

IN: compiler_builtins::mem::memcpy
0x00004000:  bd80       pop      {r7, pc}

Trace 0: 0x1 [00800408/00002000/00000110/ff020200] caller
Trace 0: 0x2 [00800408/00003000/00000110/ff020200] __aeabi_uldivmod
Trace 0: 0x3 [00800408/00004000/00000110/ff020200] compiler_builtins::mem::memcpy
Trace 0: 0x1 [00800408/00002000/00000110/ff020200] caller
Trace 0: 0x3 [00800408/00004000/00000110/ff020200] compiler_builtins::mem::memcpy
";
        let p = read_trace(log.as_bytes()).unwrap();
        // The division's own call into memcpy is not a caller's.
        assert_eq!(p.helper_callers, vec![(0x2000, 2, "caller".to_string())]);
        assert_eq!(p.total, 1 + 2 + 1 + 1 + 1);
        assert!(p.report().contains("0x00002000              2  caller"));
    }

    #[test]
    fn lines_it_does_not_know_are_skipped() {
        let p = read_trace("Trace 0: garbage\nIN: x\nnot an address\n".as_bytes()).unwrap();
        assert_eq!(p, Profile::default());
    }
}
