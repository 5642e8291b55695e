//! Throughput of the whole fixed-point pipeline (onset filter, dense 346x260 network with its
//! 178,880 units, calibrated readout at 1 kHz) on a generated recording of about 1.9 M events.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use host_sim::formats::{self, Format, Recording};
use host_sim::pipeline::{run_pipeline, ReadoutKind, RunOptions};
use host_sim::synth::{self, SynthConfig};

fn recording() -> Recording {
    let seq = synth::generate(&SynthConfig::default()).expect("synthetic scene");
    let i = seq.intrinsics;
    Recording {
        events: seq.events,
        width: Some(i.width),
        height: Some(i.height),
        intrinsics: Some(formats::Intrinsics::from(i)),
        gyro: None,
        format: Format::Csv,
    }
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

criterion_group!(benches, pipeline);
criterion_main!(benches);
