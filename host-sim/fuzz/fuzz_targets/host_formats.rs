//! host-sim's file readers on arbitrary bytes (Prophesee .raw with its header, AEDAT 4.0, ECD
//! text, CSV, ground truth, gyro): an error or a recording, never a panic. MVSEC HDF5 has its
//! own target, `mvsec_hdf5`, which varies the content of well-formed HDF5 files instead of bytes.
#![no_main]

use std::path::PathBuf;

use host_sim::formats::{self, Format};
use libfuzzer_sys::fuzz_target;

fn scratch() -> PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    dir.join(format!("tde-fuzz-{}", std::process::id()))
}

fuzz_target!(|data: &[u8]| {
    let Some((&sel, rest)) = data.split_first() else {
        return;
    };
    let path = scratch();
    if std::fs::write(&path, rest).is_err() {
        return;
    }
    let format = match sel % 8 {
        0 => None,
        1 => Some(Format::Evt3),
        2 => Some(Format::Evt2),
        3 => Some(Format::Evt21),
        4 => Some(Format::Aedat4),
        5 => Some(Format::EcdText),
        _ => Some(Format::Csv),
    };
    let _ = formats::read(&path, format);
    if sel & 8 != 0 {
        let _ = formats::read_ground_truth(&path);
        let _ = formats::read_gyro(&path);
    }
    let _ = std::fs::remove_file(&path);
});
