//! What a recording's folder adds: `meta.json` (the synthetic sequences: `camera.width`,
//! `camera.height`, `camera.fx/fy/cx/cy`), `calib.txt` (Event Camera Dataset intrinsics) and
//! `imu.txt` (gyro). Only fills what the event file itself did not give.

use std::path::Path;

use anyhow::{anyhow, Context, Result};
use serde_json::Value;

use super::{ecd, Intrinsics, RecordingInfo};

/// Sensor size and intrinsics from a `meta.json`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Meta {
    pub width: Option<u16>,
    pub height: Option<u16>,
    pub intrinsics: Option<Intrinsics>,
}

/// Reads a `meta.json`: the `camera` object, else the top level, else `config`.
pub fn read_meta(path: &Path) -> Result<Meta> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let v: Value = serde_json::from_str(&text).map_err(|e| {
        anyhow!(
            "{}: malformed JSON at line {} column {}: {e}",
            path.display(),
            e.line(),
            e.column()
        )
    })?;
    let mut meta = Meta::default();
    for obj in [v.get("camera"), Some(&v), v.get("config")]
        .into_iter()
        .flatten()
    {
        let num = |k: &str| obj.get(k).and_then(Value::as_f64);
        let size = |k: &str| {
            obj.get(k)
                .and_then(Value::as_u64)
                .and_then(|n| u16::try_from(n).ok())
        };
        if meta.width.is_none() {
            meta.width = size("width");
        }
        if meta.height.is_none() {
            meta.height = size("height");
        }
        if meta.intrinsics.is_none() {
            if let (Some(fx), Some(fy), Some(cx), Some(cy)) =
                (num("fx"), num("fy"), num("cx"), num("cy"))
            {
                meta.intrinsics = Some(Intrinsics { fx, fy, cx, cy });
            }
        }
    }
    Ok(meta)
}

/// Which sidecar values a caller needs: only the files that can supply a missing, needed value
/// are read, so that a malformed sidecar file does not stop a run that has every value from its
/// flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Needs {
    /// Sensor width and height (`meta.json`).
    pub size: bool,
    /// Intrinsics (`meta.json`, `calib.txt`).
    pub intrinsics: bool,
    /// Gyro (`imu.txt`).
    pub gyro: bool,
}

impl Needs {
    /// Everything the folder can give.
    pub const ALL: Self = Self {
        size: true,
        intrinsics: true,
        gyro: true,
    };
}

/// Fills sensor size, intrinsics and gyro of `info` from files beside `events_path`, where
/// `needs` asks for them and the event file did not give them.
pub fn complete_from_folder(
    events_path: &Path,
    info: &mut RecordingInfo,
    needs: Needs,
) -> Result<()> {
    let dir = match events_path.parent() {
        Some(d) if d.as_os_str().is_empty() => Path::new("."),
        Some(d) => d,
        None => return Ok(()),
    };
    let want_size = needs.size && (info.width.is_none() || info.height.is_none());
    let want_intrinsics = needs.intrinsics && info.intrinsics.is_none();
    let meta_path = dir.join("meta.json");
    if meta_path.is_file() && (want_size || want_intrinsics) {
        let meta = read_meta(&meta_path)?;
        if want_size {
            if let (Some(w), Some(h)) = (meta.width, meta.height) {
                info.width = Some(w);
                info.height = Some(h);
            }
        }
        if want_intrinsics {
            info.intrinsics = meta.intrinsics;
        }
    }
    let calib = dir.join("calib.txt");
    if needs.intrinsics && info.intrinsics.is_none() && calib.is_file() {
        info.intrinsics = Some(ecd::read_calib(&calib)?);
    }
    let imu = dir.join("imu.txt");
    if needs.gyro && info.gyro.is_none() && imu.is_file() && !same_file(&imu, events_path) {
        info.gyro = Some(ecd::read_imu(&imu)?);
    }
    Ok(())
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}
