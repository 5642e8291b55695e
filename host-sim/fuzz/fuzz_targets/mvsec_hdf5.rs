//! The MVSEC HDF5 readers on structurally varied, well-formed HDF5 files. The input chooses
//! which datasets exist and under which names (mostly the ones MVSEC uses, sometimes a near
//! miss, a group or a link in their place), their element types (floats, integers, bool,
//! strings, arrays), shapes (no rows, wrong column counts, 1-D, 3-D, scalars), storage layouts
//! (contiguous, compact, chunked, compressed, declared but never written) and values (NaN,
//! infinities, negative or huge numbers, time going backwards, pixels out of range, odd
//! polarities). The file is written with the HDF5 library into a per-process scratch folder and
//! read back as events (`formats::read` with `Format::MvsecHdf5`), as ground truth and as gyro.
//! Every call must return: a result, or an error on one line that names the file.
//!
//! The bytes of the file itself are always what the HDF5 library writes: this target checks
//! host-sim's handling of what a valid HDF5 file can contain, not the C library's parser.
#![no_main]

use std::path::{Path, PathBuf};

use hdf5::types::FixedAscii;
use hdf5::H5Type;
use host_sim::formats::{self, Format};
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;

/// The datasets the readers look for and the shape each has after its row count.
const ROLES: [(&str, &[usize]); 5] = [
    ("davis/left/events", &[4]),
    ("davis/left/imu", &[6]),
    ("davis/left/imu_ts", &[]),
    ("davis/left/pose", &[4, 4]),
    ("davis/left/pose_ts", &[]),
];

/// Names close to the right ones (case, spelling, side, depth).
const NEAR_MISSES: [&str; 9] = [
    "davis/left/event",
    "davis/right/events",
    "Davis/left/imu",
    "davis/left/imu_ts_",
    "davis/left/pose/ts",
    "davis/left/events/x",
    "left/pose",
    "events",
    "davis/left",
];

/// Values a reader has to reject or survive.
const ODD: [f64; 16] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    -0.0,
    -1.0,
    0.5,
    -2.0,
    2.0,
    65_535.0,
    65_536.0,
    1e300,
    -1e300,
    f64::MAX,
    f64::MIN_POSITIVE,
    1.8e13,
    -1e-7,
];

/// How a dataset's elements are stored.
#[derive(Clone, Copy, Debug)]
enum Elem {
    F64,
    F32,
    I32,
    U8,
    I64,
    U16,
    I8,
    U64,
    Bool,
    Str,
    /// Each element an array of 4 f64 (so `[N]` of `[f64; 4]` instead of `[N, 4]`).
    F64x4,
}

const ELEMS: [Elem; 11] = [
    Elem::F64,
    Elem::F64,
    Elem::F32,
    Elem::I32,
    Elem::U8,
    Elem::I64,
    Elem::U16,
    Elem::I8,
    Elem::U64,
    Elem::Bool,
    Elem::Str,
];

/// Storage layout of a dataset.
#[derive(Clone, Copy, Debug)]
enum Layout {
    Contiguous,
    Compact,
    Chunked,
    Deflate,
    /// Created (chunked) but never written: every read gives the fill value.
    Unwritten,
}

/// One object of the file.
#[derive(Debug)]
enum Node {
    Dataset {
        name: &'static str,
        elem: Elem,
        shape: Vec<usize>,
        layout: Layout,
        values: Vec<f64>,
    },
    Group(&'static str),
    /// A soft link `name -> target` (the target may not exist).
    Link {
        name: &'static str,
        target: &'static str,
    },
}

fn name_for(u: &mut Unstructured, role: usize) -> Result<&'static str> {
    Ok(if !u.ratio(7, 8)? {
        *u.choose(&NEAR_MISSES)?
    } else {
        ROLES[role].0
    })
}

/// A value that makes sense in column `col` of row `row` of a dataset of `role`.
fn plausible(
    u: &mut Unstructured,
    role: usize,
    row: usize,
    col: usize,
    plan: &Plan,
) -> Result<f64> {
    let t = plan.t0 + row as f64 * 1e-3;
    Ok(match (role, col) {
        (0, 0) => f64::from(u.int_in_range(0u16..=345)?),
        (0, 1) => f64::from(u.int_in_range(0u16..=259)?),
        (0, 2) => t,
        (0, _) => *u.choose(&[1.0, -1.0, 0.0])?,
        (1, _) => f64::from(u.int_in_range(-400i16..=400)?) / 100.0,
        (2 | 4, _) => t,
        // A rotation about y by an angle growing with the row, then a translation.
        _ => {
            let a = row as f64 * plan.yaw_step;
            let (s, c) = a.sin_cos();
            [
                c, 0.0, s, 0.1, 0.0, 1.0, 0.0, 0.2, -s, 0.0, c, 0.3, 0.0, 0.0, 0.0, 1.0,
            ][col % 16]
        }
    })
}

/// Choices shared by the datasets of one file, so that most files hang together.
struct Plan {
    /// Rows of each role's dataset: imu and imu_ts agree, pose and pose_ts agree.
    rows: [usize; 5],
    /// First time stamp (s).
    t0: f64,
    /// Rotation about y from one pose to the next (rad).
    yaw_step: f64,
}

fn dataset(u: &mut Unstructured, role: usize, plan: &Plan) -> Result<Node> {
    let name = name_for(u, role)?;
    let cols = ROLES[role].1;
    let mut elem = if u.ratio(2, 3)? {
        Elem::F64
    } else {
        *u.choose(&ELEMS)?
    };
    let mut shape: Vec<usize> = if u.ratio(7, 8)? {
        let rows = if u.ratio(7, 8)? {
            plan.rows[role]
        } else {
            u.int_in_range(0..=12)?
        };
        let mut s = vec![rows];
        s.extend_from_slice(cols);
        if role == 0 && !u.ratio(15, 16)? {
            elem = Elem::F64x4;
            s.truncate(1);
        }
        s
    } else {
        let rank = u.int_in_range(0..=3)?;
        (0..rank)
            .map(|_| u.int_in_range(0..=6))
            .collect::<Result<_>>()?
    };
    let layout = *u.choose(&[
        Layout::Contiguous,
        Layout::Contiguous,
        Layout::Contiguous,
        Layout::Compact,
        Layout::Chunked,
        Layout::Deflate,
        Layout::Unwritten,
    ])?;
    if matches!(layout, Layout::Unwritten) && !shape.is_empty() && !u.ratio(3, 4)? {
        // Declared far larger than anything stored: the file stays small.
        shape[0] = 1 << *u.choose(&[16u32, 20, 28, 31, 36, 44, 60])?;
        return Ok(Node::Dataset {
            name,
            elem,
            shape,
            layout,
            values: Vec::new(),
        });
    }
    let per_elem = if matches!(elem, Elem::F64x4) { 4 } else { 1 };
    let n = shape.iter().product::<usize>() * per_elem;
    let width = match elem {
        Elem::F64x4 => 4,
        _ => cols.iter().product::<usize>().max(1),
    };
    // Half the datasets are clean; the others get an odd value every `odd_every` on average.
    let odd_every = if u.ratio(1, 2)? {
        0
    } else {
        u.int_in_range(1u8..=32)?
    };
    let backwards = !u.ratio(15, 16)?;
    let mut values = Vec::with_capacity(n);
    for i in 0..n {
        let (mut row, col) = (i / width, i % width);
        if backwards {
            row = n / width - row;
        }
        let odd = odd_every > 0 && u.int_in_range(1..=odd_every)? == odd_every;
        let v = if !odd {
            plausible(u, role, row, col, plan)?
        } else if u.ratio(3, 4)? {
            *u.choose(&ODD)?
        } else {
            f64::from_bits(u.arbitrary()?)
        };
        values.push(v);
    }
    Ok(Node::Dataset {
        name,
        elem,
        shape,
        layout,
        values,
    })
}

/// A group or a soft link where a dataset is expected, or one more dataset.
fn extra(u: &mut Unstructured, plan: &Plan) -> Result<Node> {
    let role = u.choose_index(ROLES.len())?;
    Ok(match u.int_in_range(0u8..=3)? {
        0 => Node::Group(ROLES[role].0),
        1 => {
            let target = if u.ratio(1, 2)? {
                ROLES[u.choose_index(ROLES.len())?].0
            } else {
                *u.choose(&NEAR_MISSES)?
            };
            Node::Link {
                name: ROLES[role].0,
                target,
            }
        }
        _ => dataset(u, role, plan)?,
    })
}

/// A data file (events, with or without IMU), a ground-truth file, or both in one, each dataset
/// sometimes missing, then a few extra objects anywhere in the order of creation (an object
/// created first takes the name).
fn nodes(u: &mut Unstructured) -> Result<Vec<Node>> {
    // 0 to 12 rows, 3 when the input has run out.
    let mut rows = || u.int_in_range(0..=12).map(|r| (r + 3) % 13);
    let (events, imu, pose) = (rows()?, rows()?, rows()?);
    let plan = Plan {
        rows: [events, imu, imu, pose, pose],
        t0: *u.choose(&[0.0, 12.25, 1.5e9])?,
        yaw_step: f64::from(u.int_in_range(-20i8..=20)?) * 1e-3,
    };
    let roles: &[usize] = *u.choose(&[&[0, 1, 2, 3, 4][..], &[0, 1, 2], &[0], &[3, 4]])?;
    let mut nodes = Vec::new();
    for &role in roles {
        if u.ratio(15, 16)? {
            nodes.push(dataset(u, role, &plan)?);
        }
    }
    for _ in 0..u.int_in_range(0..=3)? {
        let at = u.int_in_range(0..=nodes.len())?;
        let n = extra(u, &plan)?;
        nodes.insert(at, n);
    }
    Ok(nodes)
}

fn write_as<T: H5Type>(
    file: &hdf5::File,
    name: &str,
    shape: &[usize],
    layout: Layout,
    data: &[T],
) -> hdf5::Result<()> {
    let mut b = file.new_dataset::<T>();
    match layout {
        Layout::Contiguous => {}
        Layout::Compact => b = b.layout(hdf5::dataset::Layout::Compact),
        Layout::Chunked | Layout::Unwritten => {
            b = b.chunk(shape.iter().map(|&d| d.clamp(1, 3)).collect::<Vec<_>>())
        }
        Layout::Deflate => {
            b = b
                .chunk(shape.iter().map(|&d| d.clamp(1, 3)).collect::<Vec<_>>())
                .deflate(1)
        }
    }
    let ds = if shape.is_empty() {
        b.shape(()).create(name)?
    } else if matches!(
        layout,
        Layout::Chunked | Layout::Deflate | Layout::Unwritten
    ) {
        b.shape(hdf5::SimpleExtents::resizable(shape))
            .create(name)?
    } else {
        b.shape(shape).create(name)?
    };
    if !matches!(layout, Layout::Unwritten) && !data.is_empty() {
        if shape.is_empty() {
            ds.write_scalar(&data[0])?;
        } else {
            ds.write_raw(data)?;
        }
    }
    Ok(())
}

fn write_dataset(file: &hdf5::File, node: &Node) -> hdf5::Result<()> {
    let Node::Dataset {
        name,
        elem,
        shape,
        layout,
        values,
        ..
    } = node
    else {
        return Ok(());
    };
    let (name, shape, layout) = (*name, shape.as_slice(), *layout);
    // `as` saturates (NaN becomes 0): the integer files hold what such a file would hold.
    macro_rules! cast {
        ($t:ty) => {
            write_as(
                file,
                name,
                shape,
                layout,
                &values.iter().map(|&v| v as $t).collect::<Vec<$t>>(),
            )
        };
    }
    match elem {
        Elem::F64 => write_as(file, name, shape, layout, values),
        Elem::F32 => cast!(f32),
        Elem::I32 => cast!(i32),
        Elem::U8 => cast!(u8),
        Elem::I64 => cast!(i64),
        Elem::U16 => cast!(u16),
        Elem::I8 => cast!(i8),
        Elem::U64 => cast!(u64),
        Elem::Bool => {
            let data: Vec<bool> = values.iter().map(|&v| v > 0.0).collect();
            write_as(file, name, shape, layout, &data)
        }
        Elem::Str => {
            let data: Vec<FixedAscii<12>> = values
                .iter()
                .map(|v| {
                    let s = format!("{v}");
                    FixedAscii::from_ascii(&s.as_bytes()[..s.len().min(12)]).unwrap_or_default()
                })
                .collect();
            write_as(file, name, shape, layout, &data)
        }
        Elem::F64x4 => {
            let (rows, _) = values.as_chunks::<4>();
            write_as(file, name, shape, layout, rows)
        }
    }
}

/// Writes `nodes` as an HDF5 file; objects the library refuses (a name already taken, a
/// layout that does not fit) are left out, as a real writer would fail on them.
fn write_file(path: &Path, nodes: &[Node]) -> bool {
    let Ok(file) = hdf5::File::create(path) else {
        return false;
    };
    for n in nodes {
        let _ = match n {
            Node::Dataset { .. } => write_dataset(&file, n),
            Node::Group(name) => file.create_group(name).map(|_| ()),
            Node::Link { name, target } => file.link_soft(target, name),
        };
    }
    file.close().is_ok()
}

/// The scratch folder of this process (a folder of its own: the event reader also looks at
/// files beside the recording).
fn scratch() -> PathBuf {
    let base = if Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    base.join(format!("tde-fuzz-mvsec-{}", std::process::id()))
}

/// An error must be one line naming the file.
fn check<T, E: std::fmt::Display>(
    what: &str,
    path: &Path,
    r: std::result::Result<T, E>,
) -> Option<T> {
    match r {
        Ok(v) => Some(v),
        Err(e) => {
            let msg = format!("{e:#}");
            assert!(!msg.contains('\n'), "{what}: error on several lines: {msg}");
            assert!(
                msg.contains(&path.display().to_string()),
                "{what}: error does not name the file: {msg}"
            );
            None
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let mut u = Unstructured::new(data);
    let Ok(nodes) = nodes(&mut u) else {
        return;
    };
    let dir = scratch();
    if std::fs::create_dir_all(&dir).is_err() {
        return;
    }
    let path = dir.join("rec_data.hdf5");
    if write_file(&path, &nodes) {
        let rec = check("read", &path, formats::read(&path, Some(Format::MvsecHdf5)));
        if let Some(rec) = rec {
            assert_eq!(rec.format, Format::MvsecHdf5);
        }
        check(
            "read_ground_truth",
            &path,
            formats::read_ground_truth(&path),
        );
        check("read_gyro", &path, formats::read_gyro(&path));
    }
    let _ = std::fs::remove_dir_all(&dir);
});
