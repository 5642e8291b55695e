//! Throughput of the whole fixed-point pipeline (onset filter, dense 346x260 network with its
//! 178,880 units, calibrated readout at 1 kHz) on a generated recording of about 1.9 M events;
//! and of the spiking network with every spike (dense 346x260, stride 2, the paper's normalized
//! readout at 1 kHz, output ticks included) on `dev03` of `../shared/data/synthetic` (busy, 2.6 M
//! events, about 129 M spikes), when that folder is there.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use host_sim::formats::{self, Recording};
use host_sim::pipeline::{run_pipeline, ReadoutKind, RunOptions};
use host_sim::synth::{self, SynthConfig};
use host_sim::testdata::DATA_ENV;

fn recording() -> Recording {
    synth::generate(&SynthConfig::default())
        .expect("synthetic scene")
        .into_recording()
}

fn args(readout: ReadoutKind) -> RunOptions {
    RunOptions {
        readout,
        ..RunOptions::default()
    }
}

fn pipeline(c: &mut Criterion) {
    let rec = recording();
    let mut g = c.benchmark_group("pipeline");
    g.sample_size(10);
    g.throughput(Throughput::Elements(rec.events.len() as u64));
    let a = args(ReadoutKind::Calibrated);
    g.bench_function("dense_346x260_calibrated", |b| {
        b.iter(|| run_pipeline(&a, &rec).expect("run"))
    });
    g.finish();
}

/// `dev03` of the shared synthetic sequences, or `None` with a notice when absent.
fn dev03() -> Option<Recording> {
    let base = std::env::var_os(DATA_ENV)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
        });
    let path = base.join("synthetic/dev03_davis346_urban_car/events.raw");
    if !path.is_file() {
        eprintln!(
            "NOTICE: skipping the spiking pipeline bench: {} not found (set {DATA_ENV})",
            path.display()
        );
        return None;
    }
    Some(formats::read(&path, None).expect("read dev03"))
}

fn spiking(c: &mut Criterion) {
    let Some(rec) = dev03() else {
        return;
    };
    let mut g = c.benchmark_group("pipeline");
    g.sample_size(10);
    g.throughput(Throughput::Elements(rec.events.len() as u64));
    let a = args(ReadoutKind::Normalized);
    g.bench_function("dense_346x260_spiking_normalized_dev03", |b| {
        b.iter(|| run_pipeline(&a, &rec).expect("run"))
    });
    g.finish();
}

criterion_group!(benches, pipeline, spiking);
criterion_main!(benches);
