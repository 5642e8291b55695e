//! The calibrated readout in the regimes a drone or a car lives in, one rendered scene each
//! (`host-sim synth --regime R`; objects: two), and on the real recording of a static camera
//! with a moving object. Each scene prints its figures (`--nocapture`): correlation with the
//! ground-truth yaw rate and RMSE over its peak, both of the output as it is (as `host-sim
//! eval` computes them: a "no evidence" sample is 0), the share of samples flagged "no
//! evidence" while the camera turns at 0.05 rad/s or more, and for a camera that does not
//! turn, the RMS output with the samples flagged "no evidence" as 0 (what a consumer that drops
//! them sees).
//!
//! The spike readout runs on the same scenes: its RMSE stays within a bound of the calibrated
//! readout's (today's ratio with a margin: car 1.19, drone 1.31, 1.20 before the aperture gate,
//! hover 1.08, rotation 0.95; README: "Three readouts"), and on the static scenes its RMS
//! output within the same 0.03 rad/s.
//!
//! The bounds are what the readout reaches today with a margin (README: "Flight regimes"; on
//! these scenes it reaches correlation 0.994 / 0.988 / 0.975 / 0.996, RMSE 5.7 / 9.3 / 13.5
//! / 6.2 % of peak for car / drone / hover / rotation (drone 10.6 % before the aperture gate), "no evidence" while turning 2.2-4.4 %,
//! and RMS output 0.000 and 0.000 rad/s for the static scenes; before a column band's upper
//! half decided where its halves disagree 5.5 / 11.7 / 13.5 / 6.2 %; before an answer after "no
//! evidence" waited for a second reading 5.9 / 11.9 / 13.9 / 6.6 %; before the majority-sign
//! region medians 6.0 / 13.4 / 13.6 / 6.5 %; before the near units 0.978 / 0.946 / 0.930 /
//! 0.989 and 10.6 / 19.1 / 23.5 / 10.2 %); the targets are tighter elsewhere and not
//! all met: see the README for where it falls short.

use host_sim::eval::metrics::{pearson, resample, rmse, Resample};
use host_sim::eval::Series;
use host_sim::formats::{self, Recording};
use host_sim::pipeline::{run_pipeline, ReadoutKind, RunOptions};
use host_sim::synth::regime::{preset, Regime};
use host_sim::synth::truth::GtRow;
use host_sim::synth::{generate, MotionKind, Preset};
use host_sim::testdata::shared_data;

/// Flag of a sample without rotation evidence.
const NO_EVIDENCE: u8 = core_nostd::flags::NO_EVIDENCE;

/// What one scene gave.
struct Figures {
    corr: f64,
    rmse_rel: f64,
    rmse: f64,
    /// Share of samples without evidence while |yaw rate| >= 0.05 rad/s.
    no_evidence: f64,
    /// Share of samples answered (not "no evidence") with the other sign than the truth while
    /// |yaw rate| >= 0.05 rad/s.
    wrong_way: f64,
    /// The largest output (rad/s) answered with the other sign than the truth while |yaw rate|
    /// >= 0.05 rad/s.
    largest_wrong_way: f64,
    /// RMS of the output, samples flagged "no evidence" as 0 (rad/s).
    rms_out: f64,
}

/// Renders `regime` (seed, duration in s) and runs the product's pipeline on it: the
/// calibrated readout's figures, and the spike readout's.
fn scene(regime: Regime, seed: u64, duration_s: f64) -> (Figures, Figures) {
    scene_with(regime, seed, duration_s, |_| {})
}

/// [`scene`] with the rendering's settings changed by `adjust` first.
fn scene_with(
    regime: Regime,
    seed: u64,
    duration_s: f64,
    adjust: impl FnOnce(&mut host_sim::synth::SynthConfig),
) -> (Figures, Figures) {
    let (rec, gt) = render(regime, seed, duration_s, adjust);
    let spikes = RunOptions {
        readout: ReadoutKind::Spikes,
        ..RunOptions::default()
    };
    let run = |opts: &RunOptions| figures(&run_pipeline(opts, &rec).expect("run").samples, &gt);
    (run(&RunOptions::default()), run(&spikes))
}

/// Renders `regime` (seed, duration in s, settings changed by `adjust`): the recording as
/// `host-sim run` reads it, and the ground truth.
fn render(
    regime: Regime,
    seed: u64,
    duration_s: f64,
    adjust: impl FnOnce(&mut host_sim::synth::SynthConfig),
) -> (Recording, Vec<GtRow>) {
    let mut cfg = preset(regime, seed, duration_s, Preset::Davis346);
    adjust(&mut cfg);
    let mut seq = generate(&cfg).expect("render");
    let gt = std::mem::take(&mut seq.gt);
    (seq.into_recording(), gt)
}

/// The figures of a run's `(t_s, value, flags)` samples against the ground truth.
fn figures(samples: &[(f64, f64, u8)], gt: &[GtRow]) -> Figures {
    // RMSE and correlation take the output as it is, flagged or not (as `host-sim eval` does).
    let est = Series::from_pairs(&samples.iter().map(|s| (s.0, s.1)).collect::<Vec<_>>());
    let flags = Series::from_pairs(
        &samples
            .iter()
            .map(|s| (s.0, f64::from(s.2)))
            .collect::<Vec<_>>(),
    );
    let t: Vec<f64> = gt.iter().map(|g| g.t_s).collect();
    let at = resample(&est, &t, Resample::Hold);
    let fl = resample(&flags, &t, Resample::Hold);
    let (mut e, mut g, mut moving, mut silent) = (Vec::new(), Vec::new(), 0usize, 0usize);
    let mut wrong = 0usize;
    let mut largest_wrong = 0.0f64;
    let mut answered_sq = 0.0;
    for ((v, f), row) in at.iter().zip(&fl).zip(gt) {
        if let (Some(v), Some(f)) = (v, f) {
            let no_evidence = (*f as u8) & NO_EVIDENCE != 0;
            e.push(*v);
            g.push(row.w[1]);
            if !no_evidence {
                answered_sq += v * v;
            }
            if row.w[1].abs() >= 0.05 {
                moving += 1;
                if no_evidence {
                    silent += 1;
                } else if v * row.w[1] < 0.0 {
                    wrong += 1;
                    largest_wrong = largest_wrong.max(v.abs());
                }
            }
        }
    }
    let peak = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let err = rmse(&e, &g);
    Figures {
        corr: if peak > 0.0 {
            pearson(&e, &g)
        } else {
            f64::NAN
        },
        rmse_rel: if peak > 0.0 { err / peak } else { f64::NAN },
        rmse: err,
        no_evidence: silent as f64 / moving.max(1) as f64,
        wrong_way: wrong as f64 / moving.max(1) as f64,
        largest_wrong_way: largest_wrong,
        rms_out: (answered_sq / e.len().max(1) as f64).sqrt(),
    }
}

fn report(name: &str, f: &Figures) {
    eprintln!(
        "{name}: correlation {:.3}, RMSE {:.1} % of peak ({:.3} rad/s), no evidence while turning {:.1} %, the other way while turning {:.1} % (at most {:.3} rad/s), RMS output {:.3} rad/s",
        f.corr,
        f.rmse_rel * 100.0,
        f.rmse,
        f.no_evidence * 100.0,
        f.wrong_way * 100.0,
        f.largest_wrong_way,
        f.rms_out
    );
}

/// A scene where the camera turns, both readouts: reports them, bounds the calibrated
/// readout's correlation, RMSE over peak and share of "no evidence" while turning, and the
/// spike readout's RMSE to `ratio` times the calibrated one's ([`check_spikes`]).
fn check_turning(
    name: &str,
    f: &Figures,
    s: &Figures,
    (corr, rmse_rel, no_evidence): (f64, f64, f64),
    ratio: f64,
) {
    report(name, f);
    assert!(f.corr >= corr, "correlation {:.3}", f.corr);
    assert!(f.rmse_rel <= rmse_rel, "RMSE {:.1} %", f.rmse_rel * 100.0);
    assert!(
        f.no_evidence <= no_evidence,
        "no evidence {:.1} %",
        f.no_evidence * 100.0
    );
    check_spikes(name, f, s, ratio);
}

/// The spike readout's figures `s` against the calibrated readout's `f` on the same scene: its
/// RMSE at most `ratio` times theirs.
fn check_spikes(name: &str, f: &Figures, s: &Figures, ratio: f64) {
    report(&format!("{name}, spike readout"), s);
    let r = s.rmse / f.rmse;
    eprintln!("{name}: spike / calibrated RMSE {r:.2}");
    assert!(r <= ratio, "{name}: spike / calibrated RMSE {r:.2}");
}

/// The spike readout's own RMSE / peak at most `rmse_rel`, where its ratio to the calibrated
/// readout's is held looser than the target's 1.25.
fn check_spike_rmse(s: &Figures, rmse_rel: f64) {
    assert!(
        s.rmse_rel <= rmse_rel,
        "spike readout: RMSE {:.1} %",
        s.rmse_rel * 100.0
    );
}

/// A camera that does not turn: both readouts' RMS output ("no evidence" as 0) at most 0.03
/// rad/s.
fn check_still(name: &str, f: &Figures, s: &Figures) {
    for (readout, figures) in readouts(f, s) {
        report(&format!("{name}, {readout}"), figures);
        assert!(
            figures.rms_out <= 0.03,
            "{name}, {readout}: RMS output {:.3} rad/s",
            figures.rms_out
        );
    }
}

/// Both readouts' figures, each with its name.
fn readouts<'a>(f: &'a Figures, s: &'a Figures) -> [(&'static str, &'a Figures); 2] {
    [("calibrated", f), ("spike readout", s)]
}

#[test]
fn car_forward_motion() {
    let (f, s) = scene(Regime::Car, 3, 3.0);
    // 1.10 since the spike readout reads lone spikes (1.35 allowed before).
    check_turning("car", &f, &s, (0.97, 0.1, 0.1), 1.25);
}

#[test]
fn drone_forward_flight() {
    let (f, s) = scene(Regime::Drone, 3, 2.5);
    // The issue asks for 1.25: 1.15 since the spike readout reads lone spikes (1.20 before the
    // aperture gate, which improves both readouts here, the calibrated one more: it reads the
    // vertical neighbours' traces, the spike readout knows their onsets only where their units
    // burst, `docs/figures-history.md`: "Pitch and roll leak"; 1.35 was allowed then).
    check_turning("drone", &f, &s, (0.95, 0.17, 0.1), 1.25);
}

/// Drone seed 304 (held out) turns at 1.8 rad/s over its last 0.8 s while it pitches and rolls
/// at up to 0.8 rad/s. The regions below the principal row read 0.1-0.3 rad/s there, from
/// decodes split nearly evenly in sign (the ground under forward flight and pitch), and by
/// their spread alone they were the most precise of their column bands: the field read half
/// the turn for 0.1 s at a time (10.6 % RMSE / peak, the spike readout 17.2 %). Regions whose
/// decodes split in sign now count less (`field::split_variance`): 7.9 / 13.4 %. At 1.8
/// rad/s the near units' fastest one-pixel crossings reach their floor and the spike readout
/// read half the turn for 20-40 ms at a time: the layout's units decode from 1.58 rad/s
/// (`stride_choice`, "Fast motion"; 5.8 / 8.6 % before, a spike / calibrated ratio of 1.48).
/// Since a new start needs most of its latest decodes above the principal row
/// (`Field::start_against`) the calibrated readout no longer answers its first reading at 0.06
/// s, where the drone pitches and barely yaws (4.3 → 4.2 %); the spike readout's 5.3 % is
/// unchanged, its ratio 1.25 → 1.27: held to 1.3, and the spike readout to 6 % of peak itself
/// (1.26 since it reads lone spikes).
#[test]
fn a_fast_turn_while_pitching_and_rolling() {
    let (f, s) = scene(Regime::Drone, 304, 4.0);
    check_turning("fast turn with wobble", &f, &s, (0.98, 0.05, 0.1), 1.3);
    check_spike_rmse(&s, 0.06);
}

#[test]
fn hover_slow_yaw() {
    let (f, s) = scene(Regime::Hover, 3, 4.0);
    report("hover", &f);
    check_spikes("hover", &f, &s, 1.2);
    assert!(f.corr >= 0.95, "correlation {:.3}", f.corr);
    assert!(f.rmse <= 0.025, "RMSE {:.3} rad/s", f.rmse);
    assert!(
        f.no_evidence <= 0.1,
        "no evidence {:.1} %",
        f.no_evidence * 100.0
    );
}

/// Hover seed 1 turns at 0.066 rad/s from 0.85 to 2.3 s, just below the paper's units' floor
/// across one pixel (0.08 rad/s at the principal point): the slow units time the slower half
/// of its crossings, the paper's units the rest. Counting the paper's decodes past the slow
/// units' floor (`Field::add_beyond_floor`), the readout's answers over 1.2-2.2 s read 0.85-1.15
/// of the turn on average (today 0.932, 0.905 before the paper's units stopped at a yaw step; 0.80
/// from the slow units' histograms alone).
///
/// Its turns start after pauses, at 0.05-0.07 rad/s: the slow units answer them. The spike
/// readout's slow units read the chosen stride's FAC pixel (one pixel away here, as the
/// calibrated readout's): with it at the layout's stride they timed only two-pixel crossings
/// slower than 108 ms, answered 60 ms later, and the spike readout's RMSE was 1.32 times the
/// calibrated one's (now 1.01). One rendering for both checks.
#[test]
fn a_hover_turn_straddling_the_paper_units_floor() {
    let (rec, gt) = render(Regime::Hover, 1, 4.0, |_| {});
    let samples = run_pipeline(&RunOptions::default(), &rec)
        .expect("run")
        .samples;
    let spikes = RunOptions {
        readout: ReadoutKind::Spikes,
        ..RunOptions::default()
    };
    let spike_samples = run_pipeline(&spikes, &rec).expect("run").samples;
    check_spikes(
        "hover seed 1",
        &figures(&samples, &gt),
        &figures(&spike_samples, &gt),
        1.15,
    );
    let within = |t: f64| (1.2..=2.2).contains(&t);
    let answered: Vec<f64> = samples
        .iter()
        .filter(|s| within(s.0) && s.2 & NO_EVIDENCE == 0)
        .map(|s| s.1)
        .collect();
    let truth: Vec<f64> = gt
        .iter()
        .filter(|g| within(g.t_s))
        .map(|g| g.w[1])
        .collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let gain = mean(&answered) / mean(&truth);
    eprintln!(
        "hover seed 1, 1.2-2.2 s: truth {:.4} rad/s, answers {:.4} ({} samples): {gain:.3}",
        mean(&truth),
        mean(&answered),
        answered.len()
    );
    assert!(answered.len() > 900, "{} answers", answered.len());
    assert!((0.85..=1.15).contains(&gain), "gain {gain:.3}");
}

/// A constant turn of `rate` rad/s run with `opts`: the mean of its answered samples from
/// `from_s` on, over the turn, and the share of those samples that answer.
fn constant_turn_gain(
    opts: &RunOptions,
    rec: &Recording,
    rate: f64,
    from_s: f64,
    readout: &str,
) -> (f64, f64) {
    let samples = run_pipeline(opts, rec).expect("run").samples;
    let settled: Vec<_> = samples.iter().filter(|s| s.0 >= from_s).collect();
    let answered: Vec<f64> = settled
        .iter()
        .filter(|s| s.2 & NO_EVIDENCE == 0)
        .map(|s| s.1)
        .collect();
    let gain = answered.iter().sum::<f64>() / answered.len().max(1) as f64 / rate;
    eprintln!(
        "{rate} rad/s over the skyline, {readout} readout: answers read {gain:.3} of it on average ({} of {} samples from {from_s} s)",
        answered.len(),
        settled.len()
    );
    (gain, answered.len() as f64 / settled.len().max(1) as f64)
}

/// Slow constant turns over the skyline (sharp edges; 2 s, seed 5): once settled (from 1 s
/// on), the calibrated readout's answers read 0.8-1.2 of the turn on average (today 0.97 /
/// 0.95 of 0.05 / 0.07 rad/s). The slow units time these, the near ones where onsets mark
/// edges. (Over a smooth texture the same turns read 0.77 / 0.69: README, "Slowest yaw rate
/// measured".)
#[test]
fn slow_turns_over_a_skyline() {
    for rate in [0.05, 0.07] {
        let (rec, _) = render(Regime::Rotation, 5, 2.0, |c| {
            c.motion = MotionKind::Constant;
            c.max_rate = rate;
        });
        let (gain, _) = constant_turn_gain(&RunOptions::default(), &rec, rate, 1.0, "calibrated");
        assert!((0.8..=1.2).contains(&gain), "{rate} rad/s: gain {gain:.3}");
    }
}

/// Fast constant turns over the skyline (seed 5, 4 and 6 rad/s): across one pixel such an
/// edge's crossing (under 1.1 ms) is short against the jitter of its onsets, and the near
/// units read 0.963 / 0.895 of the turn (spike readout 0.867 / 0.863). While the answer says
/// the image moves faster than a pixel per 2.8 ms the layout's units decode instead
/// (`stride_choice`, "Fast motion"): 0.987 / 0.960 (spike readout 0.982 / 0.868).
#[test]
fn fast_turns_over_a_skyline() {
    let spikes = RunOptions {
        readout: ReadoutKind::Spikes,
        ..RunOptions::default()
    };
    for (rate, calibrated, spiking) in [(4.0, 0.97, 0.93), (6.0, 0.94, 0.83)] {
        let (rec, _) = render(Regime::Rotation, 5, 1.5, |c| {
            c.motion = MotionKind::Constant;
            c.max_rate = rate;
        });
        for (opts, least, name) in [
            (RunOptions::default(), calibrated, "calibrated"),
            (spikes.clone(), spiking, "spike"),
        ] {
            let (gain, answers) = constant_turn_gain(&opts, &rec, rate, 0.5, name);
            assert!(
                (least..=1.05).contains(&gain),
                "{rate} rad/s, {name} readout: gain {gain:.3}"
            );
            assert!(
                answers >= 0.95,
                "{rate} rad/s, {name} readout: answers {answers:.2}"
            );
        }
    }
}

/// A steady 0.15 rad/s turn (seed 608, rendered after the readout's other rules were set)
/// whose top row band loses its texture from 1.95 s on (sky comes into view) and whose left
/// outer band reads low: the field's rules for the rows above the principal row failed on a
/// reading in five, or for tens of readings at a time, and the readout said "no evidence" on 18
/// % of the samples (43 % RMSE / peak over 4 s). Band values spread as a rotation's, the same
/// way as the answer a moment ago, in two row bands above, whose estimate continues its rate,
/// go on answering.
#[test]
fn a_steady_turn_whose_texture_leaves_the_top_row_band() {
    let (f, s) = scene_with(Regime::Rotation, 608, 2.6, |c| {
        c.motion = MotionKind::Constant;
        c.max_rate = 0.15;
    });
    report("steady turn, texture leaving the top row band", &f);
    assert!(f.rmse_rel <= 0.2, "RMSE {:.1} %", f.rmse_rel * 100.0);
    assert!(
        f.no_evidence <= 0.05,
        "no evidence {:.1} %",
        f.no_evidence * 100.0
    );
    check_spikes(
        "steady turn, texture leaving the top row band",
        &f,
        &s,
        1.25,
    );
}

/// Yaw steps (held-out seed 814, `--motion steps`: rates held 0.5-1.1 s, each change ramped
/// over 30 ms). When the turn stops or reverses at once, no edge completes a crossing for a
/// while; the paper's units' decodes stop within a few ms, but their 10 ms histograms repeated
/// the old rate for 20-30 ms. They now say nothing while their decodes over the last 3 ms
/// fall below half their histograms' rate: RMSE / peak 13.1 → 8.4 % (spike readout 10.0 %),
/// "no evidence" while turning 1.9 → 3.2 % (today 8.5 % and 3.4 %).
#[test]
fn yaw_steps() {
    let (f, s) = scene_with(Regime::Rotation, 814, 2.5, |c| {
        c.motion = MotionKind::Steps;
    });
    check_turning("yaw steps", &f, &s, (0.95, 0.11, 0.05), 1.25);
}

#[test]
fn pure_rotation() {
    let (f, s) = scene(Regime::Rotation, 3, 3.0);
    check_turning("rotation", &f, &s, (0.98, 0.08, 0.08), 1.1);
}

/// A sinusoidal turn over value noise (seed 5, held out from the rule's choice). After each zero
/// crossing the sensor fires little but background activity for ~0.1-0.2 s (every pixel's
/// brightness first moves back through the level it kept), and the slow units' 100 ms
/// histograms answered the old sign, unflagged, on 7.3 % of the turning samples (both
/// readouts); now the slow units say nothing while their latest decodes split in sign
/// (`field::SPLIT_STOP_TENTHS`): 1.6 % (spike readout 1.0 %), RMSE / peak 14.4 → 14.1 %
/// (both readouts 14.4 % before), "no evidence" while turning 1.4 → 7.1 % (spike readout 7.7 %).
#[test]
fn a_turn_through_zero_over_a_smooth_texture_is_not_read_the_old_way() {
    let (f, s) = scene_with(Regime::Rotation, 5, 4.0, |cfg| {
        cfg.texture = host_sim::synth::texture::TextureKind::Noise;
    });
    check_turning("rotation over value noise", &f, &s, (0.97, 0.16, 0.12), 1.1);
    for (name, figures) in readouts(&f, &s) {
        assert!(
            figures.wrong_way <= 0.03,
            "{name}: the other way on {:.1} % of the turning samples",
            figures.wrong_way * 100.0
        );
    }
}

/// A skyline seen with texture on one side only for part of the turn (seed 61: from 2.2 to 2.6 s
/// and from 3.0 to 3.3 s the buildings fill the left half and the right half sees sky). The
/// field used to need a column band on each side, and said "no evidence" through those turns
/// at 0.3-0.45 rad/s (27 % of the turning samples, RMSE 41 % of peak); one side now answers
/// alone where its bands agree as a rotation's.
#[test]
fn rotation_with_texture_on_one_side() {
    let (f, s) = scene(Regime::Rotation, 61, 3.5);
    check_turning(
        "rotation seed 61, texture on one side",
        &f,
        &s,
        (0.95, 0.2, 0.1),
        1.2,
    );
}

/// The default skyline at half its texture contrast (`--contrast 0.5`): a third of the events
/// (201 k against 663 k), and almost no decodes in the top row band (288 of 85 k: the faint
/// upper scenery hardly fires). The field asked for
/// values there (or for all eight column band sides at one rate) and said "no evidence" on
/// 99.9 % of the samples (seed 73, 4 s); nearly the whole width moving one way above the
/// principal row now answers (64.2 → 42.7 % RMSE / peak), and so do band values all of one
/// sign within 100 ms of an answer, as when the turn reverses (43.8 → 35.1 %, "no evidence"
/// while turning 57.5 → 38.6 %); then with only the field's own answers starting the 100 ms,
/// and a value on each side spread enough within them (34.6 → 31.5 %, 38.2 → 33.8 %); then
/// with values that continue the answer a moment ago going on without the top row band (31.5
/// → 24.3 %, 33.8 → 25.1 %; the spike readout 35.9 → 29.6 %).
#[test]
fn rotation_at_half_contrast() {
    let (f, s) = scene_with(Regime::Rotation, 73, 4.0, |cfg| cfg.contrast = 0.5);
    check_turning("rotation at half contrast", &f, &s, (0.9, 0.27, 0.28), 1.25);
}

/// A calibrated lens seldom has its principal point at the centre: here 30 rows above it (100
/// of 260), so that the rows above it reach two row bands, not three. Before the field asked for
/// the topmost band the layout has there, instead of the third, this scene read "no evidence"
/// throughout, both readouts.
#[test]
fn rotation_with_the_principal_point_above_the_centre() {
    let (f, s) = scene_with(Regime::Rotation, 44, 2.0, |cfg| cfg.intrinsics.cy = 100.0);
    check_turning(
        "rotation, principal row 100",
        &f,
        &s,
        (0.97, 0.12, 0.08),
        1.2,
    );
}

/// A principal point off the centre both ways (column 140, row 110 of 346 x 260). Row bands
/// used to be mirrored about it, a third of the longer half (150 rows below) each, so the rows
/// above it ended in a 10-row sliver of a top band, which the field needs values in: "no
/// evidence" on 12.7 % of the samples while turning (14.6 % RMSE / peak). Each half is now
/// split in thirds of its own rows.
#[test]
fn rotation_with_the_principal_point_off_centre() {
    let (f, s) = scene_with(Regime::Rotation, 49, 3.0, |cfg| {
        cfg.intrinsics.cx = 140.0;
        cfg.intrinsics.cy = 110.0;
    });
    check_turning(
        "rotation, principal point (140, 110)",
        &f,
        &s,
        (0.97, 0.14, 0.08),
        1.2,
    );
}

/// A camera that stands still and only wobbles (pitch and roll of 0.05 rad at 1-6 Hz, no
/// ground, urban texture): every decode is the aperture problem (near-horizontal edges
/// moving vertically), which the aperture gate drops (`core_nostd::readout::aperture`).
/// Before it this scene read 0.375 / 0.410 rad/s RMS (calibrated / spike readout), after it
/// about 0.15 / 0.19 (seed 11: 0.339 / 0.354 before, 0.151 / 0.185 after), and 0.174 / 0.236
/// since regions whose decodes split in sign count less (`field::split_variance`: here the
/// many split regions read about 0, by chance the truth); the 0.03 for a camera that
/// does not turn is not reached (README: "Known limits").
#[test]
fn a_camera_that_only_wobbles() {
    let (f, s) = scene_with(Regime::Rotation, 7, 2.0, |c| {
        c.motion = MotionKind::Static;
        c.pitch_roll_rad = 0.05;
        c.ground = false;
    });
    report("wobble only", &f);
    report("wobble only, spike readout", &s);
    assert!(f.rms_out <= 0.2, "RMS output {:.3} rad/s", f.rms_out);
    assert!(
        s.rms_out <= 0.25,
        "spike readout: RMS output {:.3} rad/s",
        s.rms_out
    );
}

#[test]
fn static_camera_moving_objects() {
    let (f, s) = scene(Regime::Objects, 3, 3.0);
    check_still("objects", &f, &s);
}

/// People walking past 2-3 m from a camera 1.2 m above the ground reach into the second row
/// band above the principal row (seed 51: a person at 2.2 m, a car at 8.8 m). Before the field
/// needed its top row band above, this scene read turns of up to 0.76 rad/s (RMS output 0.21
/// rad/s, both readouts).
#[test]
fn people_walking_past_a_camera_flying_low() {
    let (f, s) = scene(Regime::Objects, 51, 4.0);
    check_still("objects seed 51", &f, &s);
}

/// A hovering drone that turns slowly while two people walk past (seed 98: one 3 m away at
/// 1.25 m/s, crossing almost the whole width of the view during the second turn, one at 6 m).
/// Their motion fills the rows below the principal row. Each column band's fit over both halves
/// read 1.5-2 times the turn while the near person crossed, and where the far one crossed, the
/// halves' split in direction read "no evidence" (50.8 % RMSE / peak, "no evidence" on 19.2 %
/// of the samples while turning). Where its halves disagree, a band now reads the rows above
/// the principal row alone (`readout::field`, `HALVES_DISAGREE_SIGMAS`): 24.3 %. The near
/// person's decodes below the principal row are many and agree, those of the slow turn above
/// it few and spread, so the halves' difference often stayed within three standard deviations;
/// a band also reads the rows above alone where the rows below read more than twice as fast
/// (`HALVES_FASTER_BELOW`): 15.5 % (spike readout 26.3 → 15.5 %).
#[test]
fn people_walking_past_a_hovering_drone_that_turns() {
    let (f, s) = scene_with(Regime::Hover, 98, 3.0, |cfg| cfg.objects = 2);
    check_turning(
        "hover seed 98, two people walking past",
        &f,
        &s,
        (0.95, 0.2, 0.1),
        1.25,
    );
}

/// A hover whose pixels also fire at 0.5 Hz on their own (seed 616, rendered and looked at
/// once): in its pauses the noise's decodes made answers of about -0.008 rad/s, slower than
/// anything the units time; the spike readout then took the first readings of the next turn,
/// from two regions of one row band, for the other side of a reversal and answered 0.39-0.51
/// rad/s at a 0.05 rad/s turn (25.9 % RMSE / peak, 1.48 times the calibrated readout's). An
/// answer below the units' slowest rotation now makes the motion recent only where it
/// continues an answer (`readout::shared::Answers`, `slowest_rate_q16`).
#[test]
fn a_hover_with_background_activity() {
    let (f, s) = scene_with(Regime::Hover, 616, 4.0, |cfg| cfg.sensor.noise_hz = 0.5);
    check_turning(
        "hover seed 616, 0.5 Hz background activity",
        &f,
        &s,
        (0.92, 0.21, 0.05),
        1.25,
    );
}

/// Two people walk past a hovering drone (seed 631, rendered after the other rules) while it
/// turns at up to 0.2 rad/s. Where a column band's rows above the principal row had no decode
/// in a moment, its rows below alone gave its value, and the people's motion there outweighed
/// the turn (34.8 % RMSE / peak, correlation 0.907; spike readout 40.0 %); now a band needs a
/// value above the principal row (`readout::field`, `Field::column_intercept`). A new start that
/// most of the latest decodes above the principal row do not support now waits
/// (`Field::start_against`): the calibrated readout 23.9 → 22.3 %, the spike readout 29.4 →
/// 28.7 %, which still says "no evidence" through much of the turn at 2.6-3.0 s, where a person
/// walking the other way in one right column band outweighs a quarter of the field: their
/// ratio 1.23 → 1.29. A decode from spikes needed a burst's first interval, two spikes, and
/// near the paper's units' floor most of the turn's slowest decodes are one-spike bursts: the
/// spike readout now reads lone spikes too (`readout::spikes`, 28.7 → 24.6 %, ratio 1.10).
#[test]
fn people_walking_past_a_drone_that_turns_under_a_skyline() {
    let (f, s) = scene_with(Regime::Hover, 631, 4.0, |cfg| cfg.objects = 2);
    check_turning(
        "hover seed 631, two people walking past",
        &f,
        &s,
        (0.93, 0.29, 0.1),
        1.25,
    );
}

/// A hovering drone (seed 501, rendered after the other rules) that stops turning at 1.6 s while three people walk
/// on past it, one way on both sides of the view. When every answer the field gave right after
/// an answer restarted the 100 ms in which band values of one sign need not reach the top row
/// band, the people kept the readout answering in turns with "no evidence" at about -0.2 rad/s
/// for 0.6 s after the stop (36.4 % RMSE / peak, correlation 0.894); now only the field's own
/// answers restart them, and a reading the same way as the last answer counts for 24 ms only.
/// Its turn that starts at 2.2 s began the wrong way in both readouts (-0.18 / -0.15 rad/s
/// against +0.08), until a new start needed most of the latest decodes above the principal row
/// on its side (`readout::field`, `Field::start_against`).
#[test]
fn people_walking_on_past_a_drone_that_stops_turning() {
    let (f, s) = scene_with(Regime::Hover, 501, 4.0, |cfg| cfg.objects = 3);
    check_turning(
        "hover seed 501, three people walking past",
        &f,
        &s,
        (0.95, 0.22, 0.06),
        1.25,
    );
    assert_starts_the_right_way("hover seed 501", &f, &s);
}

/// Asserts that neither readout answered the other way than a turn by 0.05 rad/s or more.
fn assert_starts_the_right_way(name: &str, f: &Figures, s: &Figures) {
    for (readout, figures) in readouts(f, s) {
        assert!(
            figures.largest_wrong_way < 0.05,
            "{name}, {readout}: {:.3} rad/s the other way",
            figures.largest_wrong_way
        );
    }
}

/// A hovering drone (seed 41) that starts turning left at 3.25 s after a pause. Each pixel's
/// first onset comes a random part of an edge's crossing late, and the paper's units' first
/// decodes took either sign about evenly (43 / 38 over 20 ms): the spike readout answered
/// +0.35 rad/s for 4 ms, then +0.16, of a turn at -0.11 rad/s. A new start now needs 6 in 10
/// of the latest decodes above the principal row on its side (`Field::start_against`).
#[test]
fn a_turn_after_a_pause_does_not_start_the_wrong_way() {
    let (f, s) = scene(Regime::Hover, 41, 4.0);
    check_turning("hover seed 41", &f, &s, (0.95, 0.15, 0.06), 1.25);
    assert_starts_the_right_way("hover seed 41", &f, &s);
}

/// The same people with the principal point 30 rows above the centre (row 100 of 260): with
/// row bands mirrored from the 160 rows below, the top band above started 53 rows (0.24 f)
/// above the principal row, within the person's reach, and the scene read as turns (RMS output
/// 0.29 rad/s); split in thirds of the 100 rows above, it starts at 67 rows (0.30 f).
#[test]
fn people_walking_past_with_the_principal_point_above_the_centre() {
    let (f, s) = scene_with(Regime::Objects, 51, 4.0, |cfg| cfg.intrinsics.cy = 100.0);
    check_still("objects seed 51, principal row 100", &f, &s);
}

/// Moving objects in front of a still camera whose pixels fire at 1 Hz on their own
/// (background activity): the noise's decodes give the top row band values of either sign, and
/// the first reading after "no evidence" that answered used to pass them on (RMS output 0.048
/// rad/s calibrated, 0.043 spikes). An answer after "no evidence" now waits for a second
/// reading of its sign (`readout::shared::OutputGate`).
#[test]
fn moving_objects_in_front_of_a_noisy_sensor() {
    let (f, s) = scene_with(Regime::Objects, 81, 3.0, |cfg| cfg.sensor.noise_hz = 1.0);
    check_still("objects seed 81, 1 Hz background activity", &f, &s);
}

/// The real DAVIS346 recording: a static camera (gyro below 0.02 rad/s) and an object crossing
/// the view. No rotation may be reported.
#[test]
fn real_static_camera_with_a_moving_object() {
    let Some(dir) = shared_data("real") else {
        return;
    };
    let input = dir.join("davis346_imu.aedat4");
    let rec = formats::read(&input, None).expect("read");
    let args = RunOptions {
        focal_px: Some(226.0),
        ..RunOptions::default()
    };
    let out = run_pipeline(&args, &rec).expect("run");
    let n = out.samples.len().max(1) as f64;
    let rms = (out
        .samples
        .iter()
        .map(|s| {
            if s.2 & NO_EVIDENCE != 0 {
                0.0
            } else {
                s.1 * s.1
            }
        })
        .sum::<f64>()
        / n)
        .sqrt();
    eprintln!(
        "real static camera: RMS output {rms:.4} rad/s over {} samples",
        out.samples.len()
    );
    assert!(rms <= 0.03, "RMS output {rms:.4} rad/s");
}
