//! The configuration frame: every field survives the wire, other versions and bad values are
//! refused, a corrupted frame never reaches the parser, and payload decoding passes it by.

use core_nostd::aer::config::{ConfigError, CONFIG_BYTES, CONFIG_BYTES_V1, CONFIG_BYTES_V2};
use core_nostd::aer::events::PayloadDecoder;
use core_nostd::aer::frame::{FrameDecoder, Kind, MAX_FRAME};
use core_nostd::fixed::types::U16F16;
use core_nostd::settings::{LayoutChoice, ReadoutChoice, Settings, SettingsError};

fn davis346(layout: LayoutChoice) -> Settings {
    Settings {
        width: 346,
        height: 260,
        focal_px: U16F16::from_num(226.5),
        cx: U16F16::from_num(172.25),
        cy: U16F16::from_num(129.75),
        layout,
        stride: 2,
        period_us: 1_000,
        readout: ReadoutChoice::Calibrated,
        tau_a_us: None,
        unit_pool: None,
    }
}

/// The payload bytes of `cfg`.
fn payload(cfg: &Settings) -> Vec<u8> {
    let (p, n) = cfg.payload();
    p[..n].to_vec()
}

fn wire(cfg: &Settings, seq: u16) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    let n = cfg.encode(0, seq, &mut buf).unwrap();
    buf[..n].to_vec()
}

#[test]
fn every_field_survives_the_wire() {
    let layouts = [
        LayoutChoice::Dense,
        LayoutChoice::PaperBoxes,
        LayoutChoice::Window {
            x0: 77,
            y0: 110,
            w: 192,
            h: 40,
        },
    ];
    for (i, layout) in layouts.into_iter().enumerate() {
        let cfg = davis346(layout);
        let bytes = wire(&cfg, i as u16);
        assert_eq!(bytes.len(), 14 + CONFIG_BYTES_V1);
        let mut dec = FrameDecoder::new();
        let mut got = Vec::new();
        dec.push(&bytes, |f| {
            assert_eq!(f.kind, Kind::Config);
            got.push(Settings::parse(f.payload));
        });
        assert_eq!(got, vec![Ok(cfg)]);
    }
    // Another camera: a DAVIS240 with its own lens and a 500 Hz output.
    let other = Settings {
        width: 240,
        height: 180,
        focal_px: U16F16::from_num(199.1),
        cx: U16F16::from_num(120),
        cy: U16F16::from_num(90),
        layout: LayoutChoice::Dense,
        stride: 3,
        period_us: 2_000,
        readout: ReadoutChoice::Calibrated,
        tau_a_us: None,
        unit_pool: None,
    };
    assert_eq!(Settings::parse(&payload(&other)), Ok(other));
    // What only version 2 says: another readout, another tau_A.
    for (readout, tau_a_us) in [
        (ReadoutChoice::Normalized, None),
        (ReadoutChoice::Calibrated, Some(25_000)),
        (ReadoutChoice::Normalized, Some(1_000_000)),
    ] {
        let v2 = Settings {
            readout,
            tau_a_us,
            ..other
        };
        let p = payload(&v2);
        assert_eq!((p[0], p.len()), (2, CONFIG_BYTES_V2));
        assert_eq!(Settings::parse(&p), Ok(v2));
    }
    // What only version 3 says: a unit pool.
    for (readout, unit_pool) in [
        (ReadoutChoice::Normalized, Some(4_096)),
        (ReadoutChoice::Spikes, Some(1)),
    ] {
        let v3 = Settings {
            readout,
            unit_pool,
            ..other
        };
        let p = payload(&v3);
        assert_eq!((p[0], p.len()), (3, CONFIG_BYTES));
        assert_eq!(Settings::parse(&p), Ok(v3));
    }
}

#[test]
fn unknown_versions_readouts_layouts_and_bad_values_are_refused() {
    let good = payload(&davis346(LayoutChoice::Dense));
    let with = |at: usize, v: &[u8]| {
        let mut p = good.clone();
        p[at..at + v.len()].copy_from_slice(v);
        Settings::parse(&p)
    };
    assert_eq!(with(0, &[4]), Err(ConfigError::Version(4)));
    assert_eq!(with(0, &[3]), Err(ConfigError::Length(CONFIG_BYTES_V1)));
    assert_eq!(with(0, &[0]), Err(ConfigError::Version(0)));
    assert_eq!(with(0, &[2]), Err(ConfigError::Length(CONFIG_BYTES_V1)));
    assert_eq!(with(1, &[1]), Err(ConfigError::Readout(1))); // normalized needs version 2
    assert_eq!(with(1, &[2]), Err(ConfigError::Readout(2)));
    assert_eq!(with(2, &[3]), Err(ConfigError::Layout(3)));
    assert_eq!(Settings::parse(&good[..32]), Err(ConfigError::Length(32)));
    assert_eq!(Settings::parse(&[]), Err(ConfigError::Version(0)));
    let value = |e| Err(ConfigError::Value(e));
    for (at, v, e) in [
        (4, 0u16.to_le_bytes(), SettingsError::Sensor), // width 0
        (4, 2049u16.to_le_bytes(), SettingsError::Sensor), // wider than the AER format
        (6, 0u16.to_le_bytes(), SettingsError::Sensor), // height 0
        (8, 0u16.to_le_bytes(), SettingsError::Layout), // stride 0
        (8, 346u16.to_le_bytes(), SettingsError::Layout), // stride >= width
    ] {
        assert_eq!(with(at, &v), value(e), "field at {at}");
    }
    assert_eq!(with(12, &0u32.to_le_bytes()), value(SettingsError::Focal));
    assert_eq!(with(32, &0u32.to_le_bytes()), value(SettingsError::Period));
    let window = |x0: u16, y0: u16, w: u16, h: u16| {
        Settings::parse(&payload(&davis346(LayoutChoice::Window { x0, y0, w, h })))
    };
    assert!(window(0, 0, 346, 260).is_ok());
    assert_eq!(window(1, 0, 346, 260), value(SettingsError::Layout));
    assert_eq!(window(0, 200, 346, 61), value(SettingsError::Layout));
    assert_eq!(window(0, 0, 2, 10), value(SettingsError::Layout)); // not wider than the stride
    assert_eq!(window(0, 0, 100, 0), value(SettingsError::Layout));
    // Version 2: tau_A above a second.
    let long_tau = Settings {
        tau_a_us: Some(2_000_000),
        ..davis346(LayoutChoice::Dense)
    };
    assert_eq!(
        Settings::parse(&payload(&long_tau)),
        value(SettingsError::TauA)
    );
    // Version 3: a pool larger than the largest.
    let huge_pool = Settings {
        readout: ReadoutChoice::Normalized,
        unit_pool: Some(core_nostd::settings::MAX_UNIT_POOL + 1),
        ..davis346(LayoutChoice::Dense)
    };
    assert_eq!(
        Settings::parse(&payload(&huge_pool)),
        value(SettingsError::UnitPool)
    );
}

#[test]
fn a_corrupted_configuration_never_reaches_the_parser() {
    let bytes = wire(&davis346(LayoutChoice::PaperBoxes), 9);
    for i in 0..bytes.len() {
        for bit in [0x01u8, 0x80] {
            let mut b = bytes.clone();
            b[i] ^= bit;
            let mut dec = FrameDecoder::new();
            let mut n = 0;
            dec.push(&b, |_| n += 1);
            dec.finish(|_| n += 1);
            assert_eq!(n, 0, "flip at byte {i}");
        }
    }
}

#[test]
fn payload_decoding_passes_configurations_by() {
    let bytes = wire(&davis346(LayoutChoice::Dense), 0);
    let mut dec = FrameDecoder::new();
    let mut payload = PayloadDecoder::new();
    let mut events = 0;
    dec.push(&bytes, |f| {
        events += payload.frame(f, |_| {});
    });
    assert_eq!(events, 0);
    let st = payload.stats();
    assert_eq!((st.config_frames, st.event_frames, st.events), (1, 0, 0));
}

#[test]
fn the_hex_form_reads_as_the_payload() {
    let cfg = Settings {
        readout: ReadoutChoice::Spikes,
        unit_pool: Some(300),
        ..davis346(LayoutChoice::Dense)
    };
    let hex: String = payload(&cfg).iter().map(|b| format!("{b:02X}")).collect();
    assert_eq!(Settings::parse_hex(&hex), Ok(cfg));
    assert_eq!(Settings::parse_hex(&hex.to_lowercase()), Ok(cfg));
    assert_eq!(Settings::parse_hex(&hex[1..]), Err(ConfigError::Hex)); // odd count
    assert_eq!(
        Settings::parse_hex(&hex.replacen('0', "g", 1)),
        Err(ConfigError::Hex)
    );
    assert_eq!(
        Settings::parse_hex(&format!("{hex}00")),
        Err(ConfigError::Hex)
    ); // too long
    assert_eq!(Settings::parse_hex(""), Err(ConfigError::Version(0)));
}
