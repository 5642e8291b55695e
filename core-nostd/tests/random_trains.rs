//! Random event trains: the fixed-point core against the f64 oracle, on one unit (the Newton
//! engine of `Tde`) and on small pixel grids (the network's burst engine, with its tables and
//! with Newton's method for parameters the tables were not built for); and the u32 clock wrap.

use core_nostd::event::Event;
use core_nostd::layout::Dir;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{
    active_words, Cell, InputFilter, NetSink, NetState, NetStats, Network, Spike, UnitPair,
};
use core_nostd::oracle::{OracleNetwork, OracleParams, OracleTde, GRAZE_MARGIN};
use core_nostd::params::TdeParams;
use core_nostd::readout::spikes::BurstDecoder;
use core_nostd::unit::{Kernel, Tde};
use proptest::prelude::*;

/// Allowed distance (µs) between a fixed-core spike and the nearest oracle spike of its unit.
const SPIKE_TOL_US: f64 = 100.0;

/// Within a burst, allowed spike offset as a fraction of the time since the burst's first
/// spike (when that exceeds [`SPIKE_TOL_US`]).
const BURST_REL_TOL: f64 = 0.01;

/// A pause (µs) between two spikes of a unit that ends a burst (longer than any interval
/// within one: those stay below ~15 ms with the default time constants).
const BURST_GAP_US: f64 = 30_000.0;

/// How far from its peak a grazing spike may fall: the crossing of a peak that overshoots the
/// threshold by the relative margin `m` lies `tau · sqrt(2 m)` before the peak.
fn graze_tol_us() -> f64 {
    let p = OracleParams::default();
    p.tau_mem * (2.0 * GRAZE_MARGIN).sqrt()
}

/// One unit's spikes: the fixed core's count lies within the oracle's, widened by its grazes
/// (either way) and by max(1, 1 %); every fixed spike is within [`SPIKE_TOL_US`] of an oracle
/// spike, or belongs to an ill-conditioned burst: one with a spike within `graze_tol_us()` of
/// an oracle graze, or with an order flip (an input event, `inputs` µs, came within
/// [`SPIKE_TOL_US`] after the oracle's spike but before the fixed core's, so it met the unit
/// before its spike in one model and after it in the other).
fn compare(
    fixed: &[f64],
    oracle: &[f64],
    grazes: &[f64],
    inputs: &[f64],
    what: &str,
) -> Result<(), TestCaseError> {
    let (nf, no, ng) = (fixed.len(), oracle.len(), grazes.len());
    let allowed = (no as f64 * 0.01).ceil().max(1.0) as usize + ng;
    prop_assert!(
        nf.abs_diff(no) <= allowed,
        "{what}: {nf} fixed vs {no} oracle spikes ({ng} grazes)"
    );
    let nearest = |set: &[f64], t: f64| {
        set.iter()
            .map(|o| (o - t).abs())
            .fold(f64::INFINITY, f64::min)
    };
    let order_flip = |t: f64| {
        oracle.iter().rev().find(|&&o| o < t).is_some_and(|&o| {
            inputs
                .iter()
                .any(|&e| e >= o && e <= t && e - o <= SPIKE_TOL_US)
        })
    };
    // A burst that starts ill-conditioned (at a graze, or after an order flip) carries the
    // offset to all its later spikes, growing as the drive decays: its last spikes are
    // near-tangent crossings. Such a burst is exempt until a gap of BURST_GAP_US ends it.
    let mut ill = false;
    let mut prev: Option<f64> = None;
    let mut burst_start = 0.0;
    for &t in fixed {
        if prev.is_none_or(|p| t - p > BURST_GAP_US) {
            ill = false;
            burst_start = t;
        }
        // A graze shortly before a spike may have left the membrane reset in one model and not
        // in the other: the rest of that burst runs from different states.
        ill = ill || grazes.iter().any(|&g| g <= t && t - g <= BURST_GAP_US);
        prev = Some(t);
        // Within a long burst each spike restarts from the previous one, so offsets add up and
        // grow as the crossings flatten: allow 1 % of the time since the burst's first spike.
        let tol = SPIKE_TOL_US.max(BURST_REL_TOL * (t - burst_start));
        let d = nearest(oracle, t);
        ill = ill || nearest(grazes, t) <= graze_tol_us() || (d > tol && order_flip(t));
        prop_assert!(
            d <= tol || ill,
            "{what}: fixed spike at {t} µs is {d} µs from any oracle spike and not at a graze"
        );
    }
    Ok(())
}

/// A train of (gap µs, is_trg) for one unit.
fn unit_train() -> impl Strategy<Value = Vec<(u32, bool)>> {
    prop::collection::vec((0u32..25_000, any::<bool>()), 1..60)
}

fn run_unit_fixed(train: &[(u32, bool)], t0: u32) -> Vec<u32> {
    let k = Kernel::DEFAULT;
    let mut tde = Tde::new(t0);
    let mut spikes = Vec::new();
    let mut t = t0;
    for &(gap, trg) in train {
        t = t.wrapping_add(gap);
        if trg {
            tde.trg(&k, t, |s| spikes.push(s));
        } else {
            tde.fac(&k, t);
        }
    }
    tde.advance(&k, t.wrapping_add(1_000_000), |s| spikes.push(s));
    spikes
}

fn run_unit_oracle(train: &[(u32, bool)]) -> (Vec<f64>, Vec<f64>, f64) {
    let p = OracleParams::default();
    let mut tde = OracleTde::new(0.0);
    let mut spikes = Vec::new();
    let mut t = 0.0;
    let mut max_trace: f64 = 0.0;
    for &(gap, trg) in train {
        t += f64::from(gap);
        if trg {
            tde.trg(&p, t, &mut spikes);
        } else {
            tde.fac(&p, t);
        }
        max_trace = max_trace.max(tde.unit.i_trg).max(tde.i_fac);
    }
    tde.advance(&p, t + 1_000_000.0, &mut spikes);
    (spikes, tde.grazes, max_trace)
}

/// Times (µs) of a train's events from its gaps.
fn event_times(gaps: impl Iterator<Item = u32>) -> Vec<f64> {
    gaps.scan(0.0, |t, gap| {
        *t += f64::from(gap);
        Some(*t)
    })
    .collect()
}

/// One unit on `train`, fixed core against the oracle ([`compare`]); also the largest trace the
/// oracle reached and its grazes.
fn unit_vs_oracle(train: &[(u32, bool)]) -> (Result<(), TestCaseError>, f64, usize) {
    let (oracle, grazes, max_trace) = run_unit_oracle(train);
    let fixed: Vec<f64> = run_unit_fixed(train, 0)
        .into_iter()
        .map(f64::from)
        .collect();
    let inputs = event_times(train.iter().map(|&(gap, _)| gap));
    let result = compare(&fixed, &oracle, &grazes, &inputs, "unit");
    (result, max_trace, grazes.len())
}

/// Every unit of an 8 x 3 grid (stride 2) on `train`, fixed core against the oracle. Every
/// event's time counts as an input: one landing between the two models' spikes of a unit may
/// reach it in a different order (an order flip, exempt as in the one-unit test).
fn grid_vs_oracle(train: &[(u32, u16, u16)]) -> Result<(), TestCaseError> {
    grid_vs_oracle_with(&TdeParams::DEFAULT, Dense::new(8, 3, 2).unwrap(), train)
}

/// [`grid_vs_oracle`] with other parameters and layout.
fn grid_vs_oracle_with(
    params: &TdeParams,
    layout: Dense,
    train: &[(u32, u16, u16)],
) -> Result<(), TestCaseError> {
    let fixed = run_grid_fixed_with(&Kernel::new(*params).unwrap(), layout, train, 0);
    let mut net = OracleNetwork::new(OracleParams::from(params), layout);
    let mut oracle = Vec::new();
    let mut t = 0.0;
    for &(gap, x, y) in train {
        t += f64::from(gap);
        net.event(t, x, y, &mut oracle);
    }
    net.flush(t + 1_000_000.0, &mut oracle);
    let of = |set: &[(f64, u32)], unit: u32| -> Vec<f64> {
        set.iter().filter(|s| s.1 == unit).map(|s| s.0).collect()
    };
    let inputs = event_times(train.iter().map(|&(gap, _, _)| gap));
    for unit in 0..(2 * layout.cell_count()) as u32 {
        let f: Vec<f64> = fixed
            .iter()
            .filter(|s| s.1 == unit)
            .map(|s| f64::from(s.0))
            .collect();
        compare(
            &f,
            &of(&oracle, unit),
            &of(&net.grazes, unit),
            &inputs,
            &format!("unit {unit}"),
        )?;
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn one_unit_matches_oracle(train in unit_train()) {
        let (result, max_trace, _) = unit_vs_oracle(&train);
        // The fixed core saturates its traces at 16 (documented); stay below that here.
        prop_assume!(max_trace < 15.0);
        result?;
    }

    #[test]
    fn one_unit_is_unchanged_by_clock_wrap(train in unit_train(), offset in 0u32..200_000) {
        let plain = run_unit_fixed(&train, 0);
        let t0 = u32::MAX - offset;
        let wrapped: Vec<u32> = run_unit_fixed(&train, t0).into_iter().map(|t| t.wrapping_sub(t0)).collect();
        prop_assert_eq!(plain, wrapped);
    }
}

/// Events on a small grid: (gap µs, x, y).
fn grid_train(w: u16, h: u16) -> impl Strategy<Value = Vec<(u32, u16, u16)>> {
    prop::collection::vec((0u32..4_000, 0..w, 0..h), 1..250)
}

fn run_grid_fixed(layout: Dense, train: &[(u32, u16, u16)], t0: u32) -> Vec<(u32, u32)> {
    run_grid_fixed_with(&Kernel::DEFAULT, layout, train, t0)
}

fn run_grid_fixed_with(
    k: &Kernel,
    layout: Dense,
    train: &[(u32, u16, u16)],
    t0: u32,
) -> Vec<(u32, u32)> {
    let mut cells = vec![Cell::default(); layout.cell_count()];
    let mut units = vec![UnitPair::default(); layout.cell_count()];
    let mut active = vec![0u32; active_words(layout.cell_count())];
    let mut net = Network::new(
        k,
        layout,
        NetState::spiking(&mut cells, &mut units, &mut active),
        InputFilter::All,
    )
    .unwrap();
    let mut spikes = Vec::new();
    let mut sink = |s: Spike| spikes.push((s.t_us, s.unit_id()));
    let mut t = t0;
    for &(gap, x, y) in train {
        t = t.wrapping_add(gap);
        net.event(
            Event {
                t_us: t,
                x,
                y,
                on: true,
            },
            &mut sink,
        );
    }
    net.flush(t.wrapping_add(1_000_000), &mut sink);
    spikes
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn grid_matches_oracle(train in grid_train(8, 3)) {
        grid_vs_oracle(&train)?;
    }

    #[test]
    fn grid_is_unchanged_by_clock_wrap(train in grid_train(8, 3), offset in 0u32..100_000) {
        let layout = Dense::new(8, 3, 2).unwrap();
        let plain = run_grid_fixed(layout, &train, 0);
        let t0 = u32::MAX - offset;
        let wrapped: Vec<(u32, u32)> = run_grid_fixed(layout, &train, t0)
            .into_iter().map(|(t, u)| (t.wrapping_sub(t0), u)).collect();
        prop_assert_eq!(plain, wrapped);
    }
}

/// Many random trains together: the total spike count agrees with the oracle to 1 %.
#[test]
fn total_spikes_within_one_percent() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut runner = TestRunner::deterministic();
    let (mut nf, mut no) = (0usize, 0usize);
    for _ in 0..300 {
        let train = unit_train().new_tree(&mut runner).unwrap().current();
        let (oracle, _, max_trace) = run_unit_oracle(&train);
        if max_trace >= 15.0 {
            continue;
        }
        nf += run_unit_fixed(&train, 0).len();
        no += oracle.len();
    }
    eprintln!("total spikes: fixed {nf}, oracle {no}");
    assert!(no > 1000, "too few spikes to judge: {no}");
    assert!(
        (nf as f64 - no as f64).abs() <= 0.01 * no as f64,
        "fixed {nf} vs oracle {no}"
    );
}

/// Trains proptest found where a burst goes ill-conditioned: the second starts at a graze and
/// its 27th spike ends 133 µs after the oracle's; the first adds an event 3 µs after the
/// oracle's spike but before the fixed core's.
#[test]
fn ill_conditioned_bursts() {
    let base = [
        (0, false),
        (2128, false),
        (3072, false),
        (39, false),
        (10140, true),
        (15302, true),
        (12786, false),
        (14318, true),
        (7365, true),
        (23263, false),
        (2398, false),
        (19700, false),
        (11922, true),
        (19911, false),
        (11623, true),
        (995, false),
        (910, true),
        (21452, false),
        (15757, true),
        (11885, false),
        (40, true),
        (23120, true),
        (2026, false),
        (11529, true),
        (1518, false),
        (6583, true),
        (10334, true),
        (10616, false),
        (21103, true),
        (13982, true),
        (5063, true),
        (21982, true),
        (15822, false),
        (0, false),
        (6781, false),
    ];
    for last in [false, true] {
        let mut train = base.to_vec();
        train.push((23599, last));
        unit_vs_oracle(&train).0.unwrap();
    }
}

/// A train a CI run found: a graze at 367.2 ms, 1.8 ms before the TRG event that starts the next
/// burst. The burst then starts from a reset membrane in one model and not in the other, and its
/// spikes drift apart (243 µs at the first, 3.9 ms at the last): exempt as a burst after a graze.
#[test]
fn burst_after_a_graze() {
    let train: Vec<(u32, bool)> = [
        (0, false),
        (14125, false),
        (23663, true),
        (4239, false),
        (4181, true),
        (24601, false),
        (10083, true),
        (17257, false),
        (3386, false),
        (11122, true),
        (15802, false),
        (20688, false),
        (15915, false),
        (12086, true),
        (9236, false),
        (4855, true),
        (19687, false),
        (17498, false),
        (19921, true),
        (9556, false),
        (19267, true),
        (21544, true),
        (6115, true),
        (4370, true),
        (0, false),
        (15249, false),
        (21391, false),
        (6349, false),
        (16764, true),
    ]
    .to_vec();
    let (result, _, grazes) = unit_vs_oracle(&train);
    assert!(grazes > 0, "the train must graze");
    result.unwrap();
}

/// A grid train (8 x 3, stride 2) a CI run drew where, with the earlier per-spike Newton engine
/// in the network, a spike of unit 21 near 323 ms lay about 180 µs from any oracle spike, with no
/// graze or order flip to explain it: the network's TRG traces saturated at 16 there. The burst
/// engine (no saturation) follows the oracle on it.
#[test]
fn grid_train_180_us_off() {
    let train: Vec<(u32, u16, u16)> = vec![
        (0, 4, 1),
        (2993, 0, 0),
        (1949, 0, 0),
        (1713, 0, 0),
        (329, 0, 0),
        (910, 0, 0),
        (3518, 0, 0),
        (1782, 0, 0),
        (3953, 0, 0),
        (3093, 2, 1),
        (2381, 5, 0),
        (3497, 0, 0),
        (2897, 0, 0),
        (3048, 0, 0),
        (1295, 0, 0),
        (518, 0, 0),
        (3723, 0, 0),
        (840, 0, 0),
        (788, 0, 0),
        (73, 0, 0),
        (2392, 0, 0),
        (2987, 4, 1),
        (2181, 2, 1),
        (2186, 0, 0),
        (800, 0, 0),
        (1825, 0, 0),
        (1955, 4, 1),
        (916, 0, 0),
        (130, 0, 0),
        (3075, 0, 0),
        (984, 0, 0),
        (1057, 0, 0),
        (363, 0, 0),
        (1329, 0, 0),
        (274, 0, 0),
        (3416, 0, 0),
        (2984, 0, 0),
        (288, 4, 1),
        (3710, 0, 0),
        (1853, 0, 0),
        (362, 0, 0),
        (1113, 5, 0),
        (3555, 0, 0),
        (1539, 0, 0),
        (1129, 0, 0),
        (2891, 0, 0),
        (1570, 0, 0),
        (3312, 2, 1),
        (2087, 0, 0),
        (3457, 0, 0),
        (1002, 0, 0),
        (1318, 4, 1),
        (2881, 0, 0),
        (2320, 0, 0),
        (2219, 0, 0),
        (542, 0, 0),
        (3394, 0, 0),
        (3176, 0, 0),
        (1355, 0, 0),
        (2890, 0, 0),
        (170, 0, 0),
        (1548, 0, 0),
        (1775, 0, 0),
        (1410, 0, 0),
        (866, 0, 0),
        (94, 0, 0),
        (3941, 0, 0),
        (1674, 0, 0),
        (3184, 0, 0),
        (442, 0, 0),
        (1654, 0, 0),
        (3927, 0, 0),
        (861, 0, 0),
        (1798, 4, 1),
        (1914, 0, 0),
        (3583, 0, 0),
        (3753, 0, 0),
        (323, 0, 0),
        (3612, 0, 0),
        (333, 0, 0),
        (1011, 0, 0),
        (1727, 0, 0),
        (3028, 0, 0),
        (202, 2, 1),
        (1365, 0, 0),
        (3949, 0, 0),
        (3830, 2, 1),
        (1120, 2, 1),
        (79, 0, 0),
        (2888, 5, 0),
        (767, 0, 0),
        (2326, 0, 0),
        (1184, 0, 0),
        (2294, 0, 0),
        (3204, 0, 0),
        (3967, 2, 1),
        (2314, 0, 0),
        (675, 5, 0),
        (3456, 0, 0),
        (3102, 0, 0),
        (1811, 0, 0),
        (17, 0, 0),
        (3108, 0, 0),
        (1993, 4, 1),
        (1519, 0, 0),
        (1182, 0, 0),
        (953, 0, 0),
        (3620, 0, 0),
        (2929, 0, 0),
        (289, 0, 0),
        (465, 0, 0),
        (74, 0, 0),
        (1223, 0, 0),
        (1223, 0, 0),
        (2054, 0, 0),
        (1991, 0, 0),
        (250, 0, 0),
        (957, 0, 0),
        (3888, 0, 0),
        (2030, 0, 0),
        (3000, 2, 1),
        (303, 0, 0),
        (2530, 0, 0),
        (1882, 2, 1),
        (2192, 0, 0),
        (907, 0, 0),
        (3247, 0, 0),
        (1213, 0, 0),
        (3634, 0, 0),
        (1233, 5, 0),
        (1668, 5, 0),
        (2574, 5, 0),
        (2701, 0, 0),
        (3689, 0, 0),
        (1671, 0, 0),
        (1772, 0, 0),
        (1900, 0, 0),
        (3853, 0, 0),
        (2238, 0, 0),
        (1361, 0, 0),
        (1163, 0, 0),
        (1466, 0, 0),
        (784, 0, 0),
        (2244, 0, 0),
        (1243, 0, 0),
        (3990, 0, 0),
        (996, 0, 0),
        (3618, 0, 0),
        (2412, 0, 0),
        (1209, 0, 0),
        (3500, 0, 0),
        (1515, 0, 0),
        (2288, 0, 0),
        (2186, 0, 0),
        (1272, 0, 0),
        (1286, 0, 0),
        (2237, 0, 0),
        (699, 0, 0),
        (873, 0, 0),
        (1851, 0, 0),
        (1887, 0, 0),
        (2415, 0, 0),
        (289, 0, 0),
        (1769, 4, 1),
        (3951, 0, 0),
        (719, 0, 0),
        (812, 0, 0),
        (3248, 2, 1),
    ];
    grid_vs_oracle(&train).unwrap();
}

/// Bursts of events at a few pixels push FAC and TRG traces far past 16 (the old saturation):
/// the network follows the oracle there too, spike count within 0.1 %.
#[test]
fn large_traces_follow_the_oracle() {
    let layout = Dense::new(8, 3, 2).unwrap();
    let mut train = Vec::new();
    for burst in 0..6u32 {
        // 40 events 50 µs apart at the FAC pixel, then 40 at the TRG pixel of a left-to-right
        // unit, 2 ms later; then a pause.
        for i in 0..40 {
            train.push((if i == 0 && burst > 0 { 120_000 } else { 50 }, 2, 1));
        }
        for i in 0..40 {
            train.push((if i == 0 { 2_000 } else { 50 }, 4, 1));
        }
    }
    let fixed = run_grid_fixed(layout, &train, 0);
    let mut net = OracleNetwork::new(OracleParams::default(), layout);
    let mut oracle = Vec::new();
    let mut t = 0.0;
    let mut max_trg: f64 = 0.0;
    for &(gap, x, y) in &train {
        t += f64::from(gap);
        net.event(t, x, y, &mut oracle);
        max_trg = max_trg.max(oracle_trg_level(&train, t));
    }
    net.flush(t + 1_000_000.0, &mut oracle);
    let (nf, no) = (fixed.len(), oracle.len());
    eprintln!("large traces: FAC trace up to {max_trg:.1}; fixed {nf} spikes, oracle {no}");
    assert!(max_trg > 30.0, "FAC trace only reached {max_trg}");
    assert!(no > 5_000, "{no} oracle spikes: the train must drive hard");
    assert!(
        (nf as f64 - no as f64).abs() <= 0.001 * no as f64,
        "fixed {nf} vs oracle {no}"
    );
    grid_vs_oracle(&train).unwrap();
}

/// The FAC trace (f64) the train leaves at pixel (2, 1) by time `t_end`: how far past 16 it
/// goes.
fn oracle_trg_level(train: &[(u32, u16, u16)], t_end: f64) -> f64 {
    let tau = OracleParams::default().tau_fac;
    let (mut t, mut i) = (0.0, 0.0f64);
    let mut last = 0.0;
    for &(gap, x, y) in train {
        t += f64::from(gap);
        if t > t_end {
            break;
        }
        if (x, y) == (2, 1) {
            i = i * (-(t - last) / tau).exp() + 1.0;
            last = t;
        }
    }
    i
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 100, ..ProptestConfig::default() })]

    /// With a refractory period the burst tables were not built for, the network finds each
    /// spike by Newton's method on the same orbit equation: it follows the oracle as closely.
    #[test]
    fn grid_without_tables_matches_oracle(train in grid_train(8, 3)) {
        let params = TdeParams { t_ref_us: 130, ..TdeParams::DEFAULT };
        prop_assert!(!Kernel::new(params).unwrap().has_burst_tables());
        grid_vs_oracle_with(&params, Dense::new(8, 3, 2).unwrap(), &train)?;
    }
}

/// A sink that takes spikes up to 4 ms ahead of the clock and drops those taken back.
struct Ahead(Vec<(u32, u32)>);

impl NetSink for Ahead {
    const SPIKES: bool = true;
    fn spike(&mut self, s: Spike) {
        self.0.push((s.unit_id(), s.t_us));
    }
    fn ahead_us(&self) -> u32 {
        4_000
    }
    fn retract(&mut self, s: Spike) {
        let k = self
            .0
            .iter()
            .rposition(|&x| x == (s.unit_id(), s.t_us))
            .expect("a retracted spike was emitted");
        self.0.remove(k);
    }
}

/// The grid with a clock tick every millisecond, spikes sorted by unit and time.
fn run_grid_ticking<S: NetSink>(train: &[(u32, u16, u16)], sink: &mut S) -> NetStats {
    let layout = Dense::new(8, 3, 2).unwrap();
    let k = Kernel::DEFAULT;
    let mut cells = vec![Cell::default(); layout.cell_count()];
    let mut units = vec![UnitPair::default(); layout.cell_count()];
    let mut active = vec![0u32; active_words(layout.cell_count())];
    let state = NetState::spiking(&mut cells, &mut units, &mut active);
    let mut net = Network::new(&k, layout, state, InputFilter::All).unwrap();
    let (mut t, mut next) = (0u32, 1_000u32);
    for &(gap, x, y) in train {
        t += gap;
        while t > next {
            net.tick(next, sink);
            next += 1_000;
        }
        net.event(
            Event {
                t_us: t,
                x,
                y,
                on: true,
            },
            sink,
        );
    }
    net.flush(t + 300_000, sink);
    *net.stats()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// Spikes given ahead of the clock and taken back when an input changes a burst leave
    /// exactly the spikes (and counts) of emission at the clock.
    #[test]
    fn ahead_emission_gives_the_same_spikes(train in grid_train(8, 3)) {
        let mut lazy = Vec::new();
        let s_lazy = run_grid_ticking(&train, &mut |s: Spike| lazy.push((s.unit_id(), s.t_us)));
        let mut ahead = Ahead(Vec::new());
        let s_ahead = run_grid_ticking(&train, &mut ahead);
        lazy.sort_unstable();
        ahead.0.sort_unstable();
        prop_assert_eq!(&lazy, &ahead.0);
        prop_assert_eq!(s_lazy, s_ahead);
        prop_assert_eq!(lazy.len() as u64, s_ahead.spikes_lr + s_ahead.spikes_rl);
    }
}

/// A sparse sink ([`NetSink::SPARSE`]): each spike it gets, with its unit and whether it
/// resumes after skipped spikes; it reads a burst's last spikes for `memory` µs (`None`:
/// forever).
#[derive(Default)]
struct Sparse {
    spikes: Vec<(u32, u32, bool)>,
    resumed: Vec<u32>,
    memory: Option<u32>,
}

impl NetSink for Sparse {
    const SPIKES: bool = true;
    const SPARSE: bool = true;
    fn spike(&mut self, s: Spike) {
        let id = s.unit_id();
        let resumed = match self.resumed.iter().position(|&u| u == id) {
            Some(k) => {
                self.resumed.swap_remove(k);
                true
            }
            None => false,
        };
        self.spikes.push((id, s.t_us, resumed));
    }
    fn resume(&mut self, cell: u32, dir: Dir) {
        let id = Spike { t_us: 0, cell, dir }.unit_id();
        assert!(!self.resumed.contains(&id), "two resumes without a spike");
        self.resumed.push(id);
    }
    fn tail_memory_us(&self) -> u32 {
        self.memory.unwrap_or(u32::MAX)
    }
}

/// Per unit, its spikes in time order (with the resumed flags, or `false`).
fn per_unit(spikes: &[(u32, u32, bool)]) -> std::collections::BTreeMap<u32, Vec<(u32, bool)>> {
    let mut m = std::collections::BTreeMap::<u32, Vec<(u32, bool)>>::new();
    for &(id, t, r) in spikes {
        m.entry(id).or_default().push((t, r));
    }
    m
}

/// Runs `train` through the ticking grid with every spike and with a sparse sink that reads
/// a burst's last spikes for `memory` µs, and checks what the sparse sink gets: a subset of
/// each unit's spikes, told of every gap but those that end spikes older than `memory`
/// (not delivered at all), with the counts of all; decoded by the spike readout's decoder,
/// what it decodes from every spike except inputs it noticed only after the second interval
/// that followed them. Returns the spikes skipped and the resumptions that came before an
/// input (not at a burst's end).
fn check_sparse(
    train: &[(u32, u16, u16)],
    memory: Option<u32>,
) -> Result<(usize, usize), TestCaseError> {
    let mut all = Vec::new();
    let s_all = run_grid_ticking(train, &mut |s: Spike| {
        all.push((s.unit_id(), s.t_us, false))
    });
    let mut sparse = Sparse {
        memory,
        ..Sparse::default()
    };
    let s_sparse = run_grid_ticking(train, &mut sparse);
    prop_assert_eq!(s_all, s_sparse);
    prop_assert!(sparse.resumed.is_empty());
    let (all, got) = (per_unit(&all), per_unit(&sparse.spikes));
    let dec = BurstDecoder::new(&Kernel::DEFAULT);
    let (mut skipped, mut mid_burst) = (0usize, 0usize);
    for (id, full) in &all {
        let got = got.get(id).map_or(&[][..], |g| &g[..]);
        // A subsequence of the unit's spikes; `resumed` exactly where spikes were skipped.
        let mut k = 0usize;
        for (i, &(t, resumed)) in got.iter().enumerate() {
            let at = full[k..].iter().position(|&(ft, _)| ft == t);
            prop_assert!(
                at.is_some(),
                "unit {} spike {} at {} not in its train",
                id,
                i,
                t
            );
            let at = at.unwrap_or(0);
            // A gap without a resumption: spikes older than `memory` were not delivered.
            let forgotten = !resumed
                && at > 0
                && memory.is_some_and(|m| {
                    full.get(k + at - 1)
                        .is_some_and(|&(last, _)| t - last >= m.saturating_sub(1))
                });
            prop_assert!(
                resumed == (at > 0) || forgotten,
                "unit {} spike {} at {}: resumed {}, {} skipped",
                id,
                i,
                t,
                resumed,
                at
            );
            skipped += at;
            k += at + 1;
            // A resumption that does not end the burst: delivered before an input.
            if resumed && full.get(k + 1).is_some_and(|&(next, _)| next - t < 30_000) {
                mid_burst += 1;
            }
        }
        if memory.is_none() {
            prop_assert_eq!(k, full.len(), "unit {}: its last spikes are delivered", id);
        }
        let times: Vec<u32> = full.iter().map(|&(t, _)| t).collect();
        let (mut want, mut have) = (Vec::new(), Vec::new());
        dec.decode_train(&times, |d| want.push(d));
        dec.decode_sparse_train(got, |d| have.push(d));
        let mut w = want.iter();
        for d in &have {
            prop_assert!(
                w.any(|x| x == d),
                "unit {} decoded {:?} from a sparse train only",
                id,
                d
            );
        }
        for d in want.iter().filter(|d| !have.contains(d)) {
            prop_assert!(!d.from_rest, "unit {} missed {:?}", id, d);
        }
    }
    Ok((skipped, mid_burst))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// A sparse sink gets what [`check_sparse`] checks, on random grid trains.
    #[test]
    fn sparse_delivery_decodes_as_every_spike(train in grid_train(8, 3)) {
        check_sparse(&train, None)?;
    }

    /// So does one that forgets bursts as the spike readout does.
    #[test]
    fn sparse_delivery_with_the_readouts_memory_decodes_as_every_spike(
        train in grid_train(8, 3)
    ) {
        let memory = BurstDecoder::new(&Kernel::DEFAULT).tail_memory_us();
        check_sparse(&train, Some(memory))?;
    }
}

/// Long bursts, and inputs in their middle: the sparse sink skips most spikes, and resumes
/// before inputs as well as at the bursts' ends.
#[test]
fn sparse_delivery_skips_long_bursts() {
    // An edge sweeping right over row 1, pixels 2 ms apart (the units facing right burst
    // long), 5 ms after the last; every fifth sweeping left.
    let mut train = Vec::new();
    for sweep in 0..20u32 {
        let xs: Vec<u16> = if sweep % 5 == 4 {
            (0..8).rev().collect()
        } else {
            (0..8).collect()
        };
        for (k, &x) in xs.iter().enumerate() {
            let gap = if k == 0 { 5_000 } else { 2_000 };
            train.push((gap, x, 1));
        }
    }
    let memory = BurstDecoder::new(&Kernel::DEFAULT).tail_memory_us();
    for memory in [None, Some(memory)] {
        let (skipped, mid_burst) = check_sparse(&train, memory).unwrap();
        eprintln!("memory {memory:?}: skipped {skipped}, resumptions before an input {mid_burst}");
        assert!(skipped > 3_000, "{skipped} spikes skipped");
        assert!(mid_burst > 100, "{mid_burst} resumptions before an input");
    }
}

/// The check has teeth: a sparse sink that forgot bursts sooner than the readout may (an
/// eighth of its memory) would make it decode what every spike does not say.
#[test]
fn a_tail_memory_shorter_than_the_readouts_is_caught() {
    let train: Vec<(u32, u16, u16)> = (0..40u32)
        .flat_map(|sweep| {
            // One edge every 20-70 ms: bursts end, and the next input comes within the
            // readout's memory of some and beyond an eighth of it.
            let gap = 20_000 + (sweep * 7_919) % 50_000;
            (0..8u16).map(move |x| (if x == 0 { gap } else { 2_000 }, x, 1))
        })
        .collect();
    let memory = BurstDecoder::new(&Kernel::DEFAULT).tail_memory_us();
    assert!(check_sparse(&train, Some(memory)).is_ok());
    let short = format!("{:?}", check_sparse(&train, Some(memory / 8)));
    assert!(short.contains("from a sparse train only"), "{short}");
}
