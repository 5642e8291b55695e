//! MVSEC HDF5 reader on files written here with the HDF5 library, with the structure varied:
//! datasets present, missing or misnamed; stored as f64, f32, integers or strings; of the right
//! shape, with no rows, wrong column counts or another rank; contiguous, compact, chunked,
//! compressed or never written; holding good values, NaN, infinities, negative or huge numbers.
//! Reading never panics; well-formed content reads back exactly (time rounded to the µs); every
//! failure is an error on one line that names the file (and says what is wrong). Each case
//! writes a file, so the case counts stay low.

use std::path::Path;

use host_sim::formats::{self, Event64, Format, GyroSample};
use proptest::prelude::*;

const EVENTS: &str = "davis/left/events";
const IMU: &str = "davis/left/imu";
const IMU_TS: &str = "davis/left/imu_ts";
const POSE: &str = "davis/left/pose";
const POSE_TS: &str = "davis/left/pose_ts";

/// How a dataset is stored.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Layout {
    Contiguous,
    Compact,
    Chunked,
    Deflate,
    /// Chunked and never written: it reads as its fill value, 0.
    Unwritten,
}

/// The element type a dataset is stored as.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Dtype {
    F64,
    F32,
    I32,
    U8,
    /// Fixed-length ASCII text: no conversion to f64 exists.
    Str,
}

impl Dtype {
    /// `v` as this type stores it, read back as f64 (`None` for text).
    fn stored(self, v: f64) -> Option<f64> {
        match self {
            Self::F64 => Some(v),
            Self::F32 => Some(f64::from(v as f32)),
            Self::I32 => Some(f64::from(v as i32)),
            Self::U8 => Some(f64::from(v as u8)),
            Self::Str => None,
        }
    }
}

/// One dataset to write.
#[derive(Clone, Debug)]
struct Ds {
    name: &'static str,
    dtype: Dtype,
    shape: Vec<usize>,
    layout: Layout,
    /// Row-major values, as many as the shape holds.
    values: Vec<f64>,
}

impl Ds {
    fn f64(name: &'static str, shape: &[usize], values: Vec<f64>) -> Self {
        Self {
            name,
            dtype: Dtype::F64,
            shape: shape.to_vec(),
            layout: Layout::Contiguous,
            values,
        }
    }

    /// The values a reader gets (`None` for text).
    fn read_back(&self) -> Option<Vec<f64>> {
        // Text never converts, even with no rows.
        self.dtype.stored(0.0)?;
        if self.layout == Layout::Unwritten && !self.shape.is_empty() {
            return self.dtype.stored(0.0).map(|_| vec![0.0; self.values.len()]);
        }
        self.values.iter().map(|&v| self.dtype.stored(v)).collect()
    }
}

fn write_as<T: hdf5::H5Type>(file: &hdf5::File, ds: &Ds, data: &[T]) -> hdf5::Result<()> {
    let chunk: Vec<usize> = ds.shape.iter().map(|&d| d.clamp(1, 1024)).collect();
    let mut b = file.new_dataset::<T>();
    // A scalar cannot be chunked.
    let layout = if ds.shape.is_empty() {
        Layout::Contiguous
    } else {
        ds.layout
    };
    match layout {
        Layout::Contiguous => {}
        Layout::Compact => b = b.layout(hdf5::dataset::Layout::Compact),
        Layout::Chunked | Layout::Unwritten => b = b.chunk(chunk),
        Layout::Deflate => b = b.chunk(chunk).deflate(4),
    }
    let d = match layout {
        Layout::Chunked | Layout::Deflate | Layout::Unwritten => b
            .shape(hdf5::SimpleExtents::resizable(&ds.shape))
            .create(ds.name)?,
        _ => b.shape(&ds.shape).create(ds.name)?,
    };
    if layout != Layout::Unwritten && !data.is_empty() {
        d.write_raw(data)?;
    }
    Ok(())
}

/// Writes `datasets` as an HDF5 file.
fn write(path: &Path, datasets: &[Ds]) {
    let file = hdf5::File::create(path).unwrap();
    for ds in datasets {
        let v = &ds.values;
        let r = match ds.dtype {
            Dtype::F64 => write_as(&file, ds, v),
            Dtype::F32 => write_as(&file, ds, &v.iter().map(|&x| x as f32).collect::<Vec<_>>()),
            Dtype::I32 => write_as(&file, ds, &v.iter().map(|&x| x as i32).collect::<Vec<_>>()),
            Dtype::U8 => write_as(&file, ds, &v.iter().map(|&x| x as u8).collect::<Vec<_>>()),
            Dtype::Str => {
                let text: Vec<hdf5::types::FixedAscii<8>> = v
                    .iter()
                    .map(|x| {
                        let s = format!("{x}");
                        hdf5::types::FixedAscii::from_ascii(&s.as_bytes()[..s.len().min(8)])
                            .unwrap()
                    })
                    .collect();
                write_as(&file, ds, &text)
            }
        };
        r.unwrap_or_else(|e| panic!("cannot write {ds:?}: {e}"));
    }
    file.close().unwrap();
}

/// `r` must be an error of one line that names `path` and contains `needle`.
fn assert_error<T: std::fmt::Debug>(r: anyhow::Result<T>, path: &Path, needle: &str) {
    let msg = match r {
        Ok(v) => panic!("expected an error with `{needle}`, got {v:?}"),
        Err(e) => format!("{e:#}"),
    };
    assert!(!msg.contains('\n'), "error on several lines: {msg}");
    assert!(
        msg.contains(&path.display().to_string()),
        "error does not name the file: {msg}"
    );
    assert!(msg.contains(needle), "`{needle}` missing in: {msg}");
}

/// Either a value or a one-line error naming `path`.
fn ok_or_one_line<T>(r: anyhow::Result<T>, path: &Path) -> Option<T> {
    match r {
        Ok(v) => Some(v),
        Err(e) => {
            let msg = format!("{e:#}");
            assert!(!msg.contains('\n'), "error on several lines: {msg}");
            assert!(
                msg.contains(&path.display().to_string()),
                "error does not name the file: {msg}"
            );
            None
        }
    }
}

/// The event of a row `[x, y, t_s, p]` as the format defines it: pixel coordinates are whole
/// numbers in 0..65536, the time a finite non-negative number of seconds (rounded to the µs),
/// p > 0 is ON, and -1 or 0 is OFF.
fn event_of(row: &[f64]) -> Option<Event64> {
    let &[x, y, t, p] = row else { return None };
    let pixel = |v: f64| ((0.0..65536.0).contains(&v) && v.fract() == 0.0).then_some(v as u16);
    let us = (t * 1e6).round();
    let t_us = (t.is_finite() && t >= 0.0 && us < 1.8e19).then_some(us as u64)?;
    let on = if p > 0.0 {
        true
    } else if p == -1.0 || p == 0.0 {
        false
    } else {
        return None;
    };
    Some(Event64 {
        t_us,
        x: pixel(x)?,
        y: pixel(y)?,
        on,
    })
}

/// Rotation about the camera's y axis by `a` rad, as a 4 x 4 pose with a translation.
fn pose_y(a: f64) -> [f64; 16] {
    let (s, c) = a.sin_cos();
    [
        c, 0.0, s, 1.0, 0.0, 1.0, 0.0, 2.0, -s, 0.0, c, 3.0, 0.0, 0.0, 0.0, 1.0,
    ]
}

/// A cell value: mostly something an event row could hold, sometimes anything.
fn cell() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => (0u16..400).prop_map(f64::from),
        2 => 0.0..5.0f64,
        2 => Just(-1.0),
        2 => Just(1.0),
        1 => prop::sample::select(vec![
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -0.0,
            -2.0,
            0.5,
            65_535.0,
            65_536.0,
            1e300,
            1.8e13,
            -1e-7,
        ]),
        1 => any::<f64>(),
    ]
}

fn layout() -> impl Strategy<Value = Layout> {
    prop::sample::select(vec![
        Layout::Contiguous,
        Layout::Contiguous,
        Layout::Compact,
        Layout::Chunked,
        Layout::Deflate,
        Layout::Unwritten,
    ])
}

/// An events dataset of any kind: mostly at the right name and `[N, 4]`, often f64.
fn events_ds() -> impl Strategy<Value = Ds> {
    let name = prop_oneof![
        8 => Just(EVENTS),
        1 => prop::sample::select(vec!["davis/left/event", "davis/right/events", "events"]),
    ];
    let dtype = prop_oneof![
        4 => Just(Dtype::F64),
        1 => prop::sample::select(vec![Dtype::F32, Dtype::I32, Dtype::U8, Dtype::Str]),
    ];
    let shape = prop_oneof![
        6 => (0usize..12).prop_map(|n| vec![n, 4]),
        1 => prop::collection::vec(0usize..6, 0..4),
    ];
    (name, dtype, shape, layout()).prop_flat_map(|(name, dtype, shape, layout)| {
        let n = shape.iter().product::<usize>();
        prop::collection::vec(cell(), n).prop_map(move |values| Ds {
            name,
            dtype,
            shape: shape.clone(),
            layout,
            values,
        })
    })
}

/// Well-formed events `(x, y, t_us, p)`, time in order, with µs up to ROS epoch times.
fn good_events() -> impl Strategy<Value = Vec<(u16, u16, u64, i8)>> {
    (
        0u64..2_000_000_000_000_000,
        prop::collection::vec(
            (
                any::<u16>(),
                any::<u16>(),
                0u64..5_000,
                prop::sample::select(vec![-1i8, 0, 1]),
            ),
            0..60,
        ),
    )
        .prop_map(|(t0, rows)| {
            let mut t = t0;
            rows.into_iter()
                .map(|(x, y, dt, p)| {
                    t += dt;
                    (x, y, t, p)
                })
                .collect()
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Well-formed events (and IMU) read back exactly, whatever the storage layout.
    #[test]
    fn good_files_round_trip(
        events in good_events(),
        layout in layout().prop_filter("written", |l| *l != Layout::Unwritten),
        imu in prop::option::of(prop::collection::vec(
            (0.0..1e4f64, -10.0..10.0f64, -10.0..10.0f64, -10.0..10.0f64), 0..20)),
    ) {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("good_data.hdf5");
        let values: Vec<f64> = events
            .iter()
            .flat_map(|&(x, y, t, p)| [f64::from(x), f64::from(y), t as f64 / 1e6, f64::from(p)])
            .collect();
        let mut ds = vec![Ds { layout, ..Ds::f64(EVENTS, &[events.len(), 4], values) }];
        if let Some(imu) = &imu {
            let rows: Vec<f64> = imu.iter().flat_map(|&(_, wx, wy, wz)| [0.1, 9.8, 0.2, wx, wy, wz]).collect();
            ds.push(Ds { layout, ..Ds::f64(IMU, &[imu.len(), 6], rows) });
            ds.push(Ds::f64(IMU_TS, &[imu.len()], imu.iter().map(|r| r.0).collect()));
        }
        write(&path, &ds);

        let rec = formats::read(&path, None).unwrap();
        prop_assert_eq!(rec.format, Format::MvsecHdf5);
        let expect: Vec<Event64> = events
            .iter()
            .map(|&(x, y, t_us, p)| Event64 { t_us, x, y, on: p > 0 })
            .collect();
        prop_assert_eq!(&rec.events, &expect);
        let gyro: Option<Vec<GyroSample>> = imu.as_ref().map(|imu| {
            imu.iter().map(|&(t_s, wx, wy, wz)| GyroSample { t_s, wx, wy, wz }).collect()
        });
        prop_assert_eq!(&rec.gyro, &gyro);
        match gyro {
            Some(g) => prop_assert_eq!(formats::read_gyro(&path).unwrap(), g),
            None => assert_error(formats::read_gyro(&path), &path, "no dataset `davis/left/imu`"),
        }
        assert_error(formats::read_ground_truth(&path), &path, "no dataset `davis/left/pose`");
    }

    /// Any events dataset: the reader gives exactly the events the format defines, or the
    /// error for the first thing wrong (name, shape, type, then the first malformed row).
    #[test]
    fn any_events_dataset_reads_or_fails_on_one_line(ds in events_ds()) {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("any_data.hdf5");
        write(&path, std::slice::from_ref(&ds));
        let r = formats::read(&path, Some(Format::MvsecHdf5));
        let values = ds.read_back();
        if ds.name != EVENTS {
            assert_error(r, &path, "no dataset `davis/left/events`");
        } else if ds.shape.len() != 2 || ds.shape[1] != 4 {
            // The streaming reader checks the shape before it reads any row.
            assert_error(r, &path, "has shape");
        } else if values.is_none() {
            assert_error(r, &path, "cannot read `davis/left/events`");
        } else {
            let values = values.unwrap();
            let rows: Vec<Option<Event64>> = values.chunks(4).map(event_of).collect();
            match rows.iter().position(Option::is_none) {
                Some(i) => assert_error(r, &path, &format!("malformed event {i} ")),
                None => {
                    let rec = r.unwrap();
                    let expect: Vec<Event64> = rows.into_iter().flatten().collect();
                    prop_assert_eq!(rec.events, expect);
                    prop_assert_eq!(rec.gyro, None);
                }
            }
        }
        // Neither ground truth nor gyro in this file.
        assert_error(formats::read_ground_truth(&path), &path, "davis/left/pose");
        assert_error(formats::read_gyro(&path), &path, "davis/left/imu");
    }

    /// Ground truth and IMU with rows that may disagree, times that may stall or go back, odd
    /// values and other element types: a result or one line naming the file; with everything
    /// in order, one yaw rate per pose, equal to the rotation step over the time step.
    #[test]
    fn ground_truth_and_imu_read_or_fail_on_one_line(
        k in 0usize..8,
        k_ts in prop_oneof![4 => Just(None), 1 => (0usize..8).prop_map(Some)],
        dt in prop_oneof![4 => Just(0.01), 1 => prop::sample::select(vec![0.0, -0.01, f64::NAN, f64::INFINITY])],
        step in -0.05..0.05f64,
        t0 in prop::sample::select(vec![0.0, 3.5, 1.5e9]),
        odd in prop::collection::vec((0usize..128, cell()), 0..3),
        dtype in prop_oneof![4 => Just(Dtype::F64), 1 => prop::sample::select(vec![Dtype::F32, Dtype::I32, Dtype::Str])],
        n_imu in 0usize..8,
        imu_cols in prop_oneof![4 => Just(6usize), 1 => 0usize..8],
        imu_ts_rows in prop_oneof![4 => Just(None), 1 => (0usize..8).prop_map(Some)],
    ) {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("any_gt.hdf5");
        let mut pose: Vec<f64> = (0..k).flat_map(|i| pose_y(step * i as f64)).collect();
        for &(at, v) in &odd {
            if let Some(p) = pose.get_mut(at) {
                *p = v;
            }
        }
        let k_ts = k_ts.unwrap_or(k);
        let ts: Vec<f64> = (0..k_ts).map(|i| t0 + dt * i as f64).collect();
        let imu_ts_rows = imu_ts_rows.unwrap_or(n_imu);
        let ds = [
            Ds { dtype, ..Ds::f64(POSE, &[k, 4, 4], pose.clone()) },
            Ds::f64(POSE_TS, &[k_ts], ts.clone()),
            Ds::f64(IMU, &[n_imu, imu_cols], (0..n_imu * imu_cols).map(|i| i as f64 * 0.25).collect()),
            Ds::f64(IMU_TS, &[imu_ts_rows], (0..imu_ts_rows).map(|i| t0 + i as f64 * 0.005).collect()),
        ];
        write(&path, &ds);

        let gt = formats::read_ground_truth(&path);
        let in_order = dt > 0.0 && dt.is_finite();
        if dtype == Dtype::Str {
            assert_error(gt, &path, "cannot read `davis/left/pose`");
        } else if k_ts != k {
            assert_error(gt, &path, "`davis/left/pose_ts` has shape");
        } else if k < 2 {
            assert_error(gt, &path, "needs at least 2 poses");
        } else if !in_order {
            assert_error(gt, &path, "pose times must increase");
        } else {
            let gt = gt.unwrap();
            prop_assert_eq!(gt.len(), k);
            for (s, &t) in gt.iter().zip(&ts) {
                prop_assert_eq!(s.t_s, t);
            }
            if dtype == Dtype::F64 && odd.iter().all(|&(at, _)| at >= pose.len()) && t0 < 1e3 {
                for s in &gt {
                    prop_assert!((s.yaw_rate_rad_s - step / dt).abs() < 1e-6, "{:?} vs {}", s, step / dt);
                }
            }
        }

        let gyro = formats::read_gyro(&path);
        if imu_cols != 6 {
            assert_error(gyro, &path, "dataset `davis/left/imu` has shape");
        } else if imu_ts_rows != n_imu {
            assert_error(gyro, &path, "`davis/left/imu_ts` has shape");
        } else {
            let gyro = gyro.unwrap();
            prop_assert_eq!(gyro.len(), n_imu);
            for (i, g) in gyro.iter().enumerate() {
                let base = (i * 6) as f64 * 0.25;
                prop_assert_eq!((g.wx, g.wy, g.wz), (base + 0.75, base + 1.0, base + 1.25));
            }
        }
        // No events here: a clear error, not an empty recording.
        assert_error(formats::read(&path, Some(Format::MvsecHdf5)), &path, "no dataset `davis/left/events`");
        ok_or_one_line(formats::read(&path, None), &path);
    }
}

/// A few KiB of file can declare a dataset of billions of rows that was never written (it
/// would read as fill values). The reader refuses it instead of trying to allocate the memory.
#[test]
fn declared_but_unstored_rows_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let huge = |name: &'static str, shape: &[usize]| Ds {
        layout: Layout::Unwritten,
        ..Ds::f64(name, shape, Vec::new())
    };
    let cases: [(&str, Vec<Ds>); 3] = [
        ("events", vec![huge(EVENTS, &[1 << 40, 4])]),
        (
            "pose",
            vec![huge(POSE, &[1 << 36, 4, 4]), huge(POSE_TS, &[1 << 36])],
        ),
        (
            "imu",
            vec![huge(IMU, &[1 << 44, 6]), huge(IMU_TS, &[1 << 44])],
        ),
    ];
    for (what, ds) in cases {
        let path = tmp.path().join(format!("huge_{what}.hdf5"));
        write(&path, &ds);
        assert!(std::fs::metadata(&path).unwrap().len() < 64 * 1024);
        let needle = format!("`davis/left/{what}` declares shape");
        match what {
            "events" => assert_error(
                formats::read(&path, Some(Format::MvsecHdf5)),
                &path,
                &needle,
            ),
            "pose" => assert_error(formats::read_ground_truth(&path), &path, &needle),
            _ => assert_error(formats::read_gyro(&path), &path, &needle),
        }
    }
    // Small unwritten datasets still read (as their fill value), and strongly compressible
    // data stays within the limit.
    let path = tmp.path().join("small_unwritten.hdf5");
    write(&path, &[huge(EVENTS, &[10, 4])]);
    let rec = formats::read(&path, Some(Format::MvsecHdf5)).unwrap();
    assert_eq!(rec.events.len(), 10);
    assert!(rec.events.iter().all(|e| *e
        == Event64 {
            t_us: 0,
            x: 0,
            y: 0,
            on: false
        }));
    let path = tmp.path().join("constant_deflated.hdf5");
    let rows = 200_000;
    let values: Vec<f64> = (0..rows).flat_map(|_| [5.0, 6.0, 1.0, 1.0]).collect();
    write(
        &path,
        &[Ds {
            layout: Layout::Deflate,
            ..Ds::f64(EVENTS, &[rows, 4], values)
        }],
    );
    let rec = formats::read(&path, Some(Format::MvsecHdf5)).unwrap();
    assert_eq!(rec.events.len(), rows);
}
