//! AEDAT 4.0 with every compression: the real LZ4 recording is rewritten here, packet by packet,
//! uncompressed and with zstd (and with no file data table); all versions give the same events
//! and IMU samples.

use std::io::Read;
use std::path::Path;

use host_sim::formats;
use host_sim::testdata::shared_data;

const MAGIC: &[u8] = b"#!AER-DAT4.0\r\n";

/// The size-prefixed `IOHeader` FlatBuffer: compression, no data table (-1), description.
fn io_header(compression: i32, xml: &str) -> Vec<u8> {
    let mut b = flatbuffers::FlatBufferBuilder::new();
    let info = b.create_string(xml);
    let start = b.start_table();
    b.push_slot_always::<i32>(4, compression);
    b.push_slot_always::<i64>(6, -1);
    b.push_slot_always(8, info);
    let root = b.end_table(start);
    b.finish_size_prefixed(root, Some("IOHE"));
    b.finished_data().to_vec()
}

/// Rewrites an LZ4 AEDAT4 file with `compression` (0 none, 3 zstd).
fn recompress(src: &Path, dst: &Path, compression: i32) {
    let bytes = std::fs::read(src).unwrap();
    let header_len = u32::from_le_bytes(bytes[14..18].try_into().unwrap()) as usize;
    let header = &bytes[18..18 + header_len];
    let start = header.windows(3).position(|w| w == b"<dv").unwrap();
    let end = header.windows(5).position(|w| w == b"</dv>").unwrap() + 5;
    let xml = std::str::from_utf8(&header[start..end]).unwrap();
    let mut out = MAGIC.to_vec();
    out.extend_from_slice(&io_header(compression, xml));
    let mut pos = 18 + header_len;
    let mut packets = 0;
    while pos + 8 <= bytes.len() {
        let stream = &bytes[pos..pos + 4];
        let size = u32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize;
        let Some(body) = bytes.get(pos + 8..pos + 8 + size) else {
            break;
        };
        let mut plain = Vec::new();
        // The file data table at the end is not a packet: stop there.
        if lz4_flex::frame::FrameDecoder::new(body)
            .read_to_end(&mut plain)
            .is_err()
            || !["EVTS", "IMUS", "FRME", "TRIG"]
                .iter()
                .any(|id| flatbuffers::buffer_has_identifier(&plain, id, true))
        {
            break;
        }
        let new_body = if compression == 3 {
            zstd::encode_all(&plain[..], 3).unwrap()
        } else {
            plain
        };
        out.extend_from_slice(stream);
        out.extend_from_slice(&(new_body.len() as i32).to_le_bytes());
        out.extend_from_slice(&new_body);
        pos += 8 + size;
        packets += 1;
    }
    assert!(packets > 10);
    std::fs::write(dst, out).unwrap();
}

#[test]
fn aedat4_uncompressed_lz4_and_zstd_agree() {
    let Some(real) = shared_data("real") else {
        return;
    };
    let src = real.join("davis346_imu.aedat4");
    let lz4 = formats::read(&src, None).unwrap();
    assert_eq!(lz4.events.len(), 78_830);
    let tmp = tempfile::tempdir().unwrap();
    for (name, compression) in [("none.aedat4", 0), ("zstd.aedat4", 3)] {
        let p = tmp.path().join(name);
        recompress(&src, &p, compression);
        let rec = formats::read(&p, None).unwrap();
        assert!(rec.events == lz4.events, "{name}: events differ");
        assert_eq!((rec.width, rec.height), (Some(346), Some(260)));
        assert_eq!(rec.gyro, lz4.gyro, "{name}: IMU differs");
        assert_eq!(formats::read_gyro(&p).unwrap().len(), 2363);
    }
}
