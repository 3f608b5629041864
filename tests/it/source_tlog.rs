//! `.tlog` and raw-stream reading: timestamps, clock jumps, corruption, and tlogs written
//! by pymavlink (the independent peer) with MAVLink 1, 2 and signed frames.

use crate::mavlink_common;

use dronewatt::report::status::{IngestStats, StatsSnapshot};
use dronewatt::source::frame::timed::TimedReader;
use dronewatt::source::logs::raw::decode_raw;
use dronewatt::source::logs::tlog::decode_tlog;
use dronewatt::source::TimedMessage;
use mavlink::MavlinkVersion::{V1, V2};
use mavlink_common::*;

fn tlog_decode(bytes: &[u8]) -> (Vec<TimedMessage>, StatsSnapshot) {
    let stats = IngestStats::default();
    let m = decode_tlog(bytes, &stats);
    (m, stats.snapshot())
}

/// Byte offset of each record in a tlog built by `tlog()`.
fn record_starts(recs: &[Rec], version: mavlink::MavlinkVersion) -> Vec<usize> {
    let mut at = 0;
    recs.iter()
        .map(|(_, h, m)| {
            let s = at;
            at += 8 + frame(*h, m, version).len();
            s
        })
        .collect()
}

#[test]
fn a_clean_tlog_gives_every_message_at_its_stamp_relative_to_the_first() {
    for version in [V1, V2] {
        let recs = flight(500);
        let (msgs, s) = tlog_decode(&tlog(&recs, version));
        assert_eq!(
            (s.frames_ok, s.frames_bad, s.unknown, s.gaps, s.junk_bytes),
            (500, 0, 0, 0, 0)
        );
        for (m, r) in msgs.iter().zip(&recs) {
            let want = (r.0 - recs[0].0) as f64 * 1e-6;
            assert!((m.t_s - want).abs() < 1e-6, "t_s {} want {want}", m.t_s);
            assert_eq!(m.header, r.1);
        }
    }
}

#[test]
fn reading_in_chunks_matches_reading_whole() {
    let recs = flight(200);
    let bytes = tlog(&recs, V2);
    let (whole, _) = tlog_decode(&bytes);
    let stats = IngestStats::default();
    let mut r = TimedReader::tlog();
    let mut chunked = Vec::new();
    for c in bytes.chunks(13) {
        r.push(c);
        while let Some(m) = r.next_message(&stats) {
            chunked.push(m);
        }
    }
    r.finish();
    while let Some(m) = r.next_message(&stats) {
        chunked.push(m);
    }
    assert_eq!(chunked.len(), whole.len());
    assert!(chunked
        .iter()
        .zip(&whole)
        .all(|(a, b)| a.t_s == b.t_s && a.msg == b.msg));
}

#[test]
fn a_zero_stamp_is_one_clock_jump_and_does_not_move_time() {
    let mut recs = flight(100);
    recs[40].0 = 0;
    let (msgs, s) = tlog_decode(&tlog(&recs, V2));
    assert_eq!(
        (s.frames_ok, s.frames_bad, s.clock_jumps, s.gaps),
        (100, 0, 1, 1)
    );
    assert_eq!(
        msgs[40].t_s, msgs[39].t_s,
        "a bad stamp keeps the last time"
    );
    assert!(
        msgs.windows(2).all(|w| w[1].t_s >= w[0].t_s),
        "t_s never goes back"
    );
    let want = (recs[99].0 - recs[0].0) as f64 * 1e-6;
    assert!(
        (msgs[99].t_s - want).abs() < 1e-6,
        "time after the bad stamp is unharmed"
    );
}

#[test]
fn an_absurd_stamp_and_a_backwards_one_are_clock_jumps() {
    let mut recs = flight(100);
    recs[10].0 = u64::MAX / 2;
    recs[60].0 -= 30_000_000; // 30 s back
    let (msgs, s) = tlog_decode(&tlog(&recs, V2));
    assert_eq!((s.frames_ok, s.clock_jumps), (100, 2));
    assert!(msgs.windows(2).all(|w| w[1].t_s >= w[0].t_s));
    assert!(
        msgs[99].t_s < 15.0,
        "no jump leaks into t_s: {}",
        msgs[99].t_s
    );
}

#[test]
fn a_flipped_crc_byte_costs_one_record() {
    let recs = flight(100);
    let mut bytes = tlog(&recs, V2);
    let starts = record_starts(&recs, V2);
    bytes[starts[51] - 2] ^= 0xFF;
    let (msgs, s) = tlog_decode(&bytes);
    assert_eq!(
        (s.frames_ok, s.frames_bad, s.unknown, s.gaps, s.junk_bytes),
        (99, 1, 0, 1, 0)
    );
    assert_eq!(msgs[50].msg, recs[51].2);
}

#[test]
fn corrupt_stamps_and_start_bytes_are_resynchronised() {
    let recs = flight(100);
    let mut bytes = tlog(&recs, V2);
    let starts = record_starts(&recs, V2);
    bytes[starts[20] + 8] = 0x00; // start byte of record 20 destroyed
    let (msgs, s) = tlog_decode(&bytes);
    assert_eq!(s.frames_ok, 99, "{s:?}");
    assert_eq!(msgs[20].msg, recs[21].2);
    assert_eq!(s.gaps, 1, "the lost record is a sequence gap: {s:?}");
    assert_eq!(s.junk_bytes as usize, starts[21] - starts[20], "{s:?}");
}

#[test]
fn garbage_between_records_is_junk() {
    let recs = flight(50);
    let mut bytes = Vec::new();
    let mut junk = 0;
    for (i, r) in recs.iter().enumerate() {
        bytes.extend(tlog(std::slice::from_ref(r), V2));
        if i % 7 == 3 {
            let g = vec![0x55u8; 5 + i];
            junk += g.len() as u64;
            bytes.extend(g);
        }
    }
    let (msgs, s) = tlog_decode(&bytes);
    assert_eq!(
        (s.frames_ok, s.frames_bad, s.junk_bytes, s.gaps),
        (50, 0, junk, 0)
    );
    assert_eq!(msgs.len(), 50);
}

#[test]
fn a_truncated_last_record_is_counted_bad() {
    let recs = flight(30);
    let bytes = tlog(&recs, V2);
    let starts = record_starts(&recs, V2);
    for cut in [
        starts[29] + 3,
        starts[29] + 8,
        starts[29] + 14,
        bytes.len() - 1,
    ] {
        let (msgs, s) = tlog_decode(&bytes[..cut]);
        assert_eq!(
            (s.frames_ok, s.frames_bad, s.junk_bytes),
            (29, 1, 0),
            "cut at {cut}"
        );
        assert_eq!(msgs.len(), 29);
    }
}

#[test]
fn an_unknown_message_id_record_is_skipped_exactly() {
    let recs = flight(20);
    let mut bytes = tlog(&recs[..10], V2);
    bytes.extend((T0_US + 999_000).to_be_bytes());
    bytes.extend(unknown_v2(recs[9].1.sequence)); // repeats a sequence number: no gap
    bytes.extend(tlog(&recs[10..], V2));
    let (msgs, s) = tlog_decode(&bytes);
    assert_eq!(
        (s.frames_ok, s.frames_bad, s.unknown, s.junk_bytes, s.gaps),
        (20, 0, 1, 0, 0)
    );
    assert_eq!(msgs.len(), 20);
}

#[test]
fn a_pymavlink_tlog_with_v1_v2_and_signed_frames_decodes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("peer.tlog");
    let made = run_peer(&["tlog", path.to_str().unwrap(), "90"]);
    assert_eq!(made["signed"], 30);
    let bytes = std::fs::read(&path).unwrap();
    let (msgs, s) = tlog_decode(&bytes);
    assert_eq!(
        (s.frames_ok, s.frames_bad, s.unknown, s.gaps, s.junk_bytes),
        (90, 0, 0, 0, 0),
        "{s:?}"
    );
    for (i, m) in msgs.iter().enumerate() {
        assert!((m.t_s - i as f64 * 0.1).abs() < 1e-6);
    }
    let dronewatt::MavMessage::SYS_STATUS(st) = &msgs[1].msg else {
        panic!("record 1 is SYS_STATUS")
    };
    assert_eq!((st.voltage_battery, st.current_battery), (22799, 1050));
}

#[test]
fn a_raw_stream_is_timed_by_time_boot_ms_and_a_reboot_is_one_jump() {
    let mut recs = flight(300);
    // Reboot after message 150: the autopilot's clock was at 20 s, then starts again
    // near zero.
    for r in &mut recs[..150] {
        set_boot_ms(&mut r.2, |ms| ms + 20_000);
    }
    let (bytes, _) = stream(&recs, V2);
    let stats = IngestStats::default();
    let msgs = decode_raw(&bytes, &stats);
    let s = stats.snapshot();
    assert_eq!((s.frames_ok, s.clock_jumps), (300, 1), "{s:?}");
    assert_eq!(msgs[0].t_s, 0.0);
    assert!(msgs.windows(2).all(|w| w[1].t_s >= w[0].t_s));
    // Time runs on from where it stood, at the right rate.
    let last = &msgs[299];
    let span_s = (recs[299].0 - recs[0].0) as f64 * 1e-6;
    assert!(
        (last.t_s - span_s).abs() < 0.25,
        "t_s {} want about {span_s}",
        last.t_s
    );
}

fn set_boot_ms(m: &mut dronewatt::MavMessage, f: impl Fn(u32) -> u32) {
    use dronewatt::MavMessage as M;
    match m {
        M::ATTITUDE(d) => d.time_boot_ms = f(d.time_boot_ms),
        M::GLOBAL_POSITION_INT(d) => d.time_boot_ms = f(d.time_boot_ms),
        M::LOCAL_POSITION_NED(d) => d.time_boot_ms = f(d.time_boot_ms),
        M::SCALED_IMU(d) => d.time_boot_ms = f(d.time_boot_ms),
        _ => {}
    }
}
