//! The frame decoder on streams built with rust-mavlink: exact counts for every kind of
//! damage (the tlog and pymavlink sides are in source_tlog.rs).

use crate::mavlink_common;

use dronewatt::report::status::{IngestStats, StatsSnapshot};
use dronewatt::source::frame::{FrameDecoder, Framing};
use dronewatt::MavMessage;
use mavlink::MavlinkVersion::{self, V1, V2};
use mavlink_common::*;

/// Decode `bytes` pushed in chunks of `chunk`; the messages and the counters.
fn decode(bytes: &[u8], chunk: usize) -> (Vec<MavMessage>, StatsSnapshot) {
    let stats = IngestStats::default();
    let mut d = FrameDecoder::new(Framing::Stream);
    let mut out = Vec::new();
    for c in bytes.chunks(chunk.max(1)) {
        d.push(c);
        while let Some(f) = d.next_frame(&stats) {
            out.push(f.msg);
        }
    }
    d.finish();
    while let Some(f) = d.next_frame(&stats) {
        out.push(f.msg);
    }
    (out, stats.snapshot())
}

/// What rust-mavlink's reader decodes from a clean stream.
fn rust_mavlink_reads(bytes: &[u8], version: MavlinkVersion) -> Vec<MavMessage> {
    let mut r = mavlink::MavlinkReader::new(bytes);
    let mut out = Vec::new();
    while let Ok((_, m)) = r.read_message::<MavMessage>(version) {
        out.push(m);
    }
    out
}

fn counts(ok: u64, bad: u64, unknown: u64, gaps: u64, junk: u64) -> StatsSnapshot {
    StatsSnapshot {
        frames_ok: ok,
        frames_bad: bad,
        unknown,
        gaps,
        junk_bytes: junk,
        ..Default::default()
    }
}

#[test]
fn clean_v1_and_v2_streams_decode_exactly_whatever_the_chunking() {
    let recs = flight(300);
    let want: Vec<MavMessage> = recs.iter().map(|r| r.2.clone()).collect();
    for version in [V1, V2] {
        let (bytes, _) = stream(&recs, version);
        for chunk in [1, 7, 64, 4096, bytes.len()] {
            let (got, s) = decode(&bytes, chunk);
            assert_eq!(s, counts(300, 0, 0, 0, 0), "{version:?} chunk {chunk}");
            // MAVLink 1 cannot carry extension fields: compare with what rust-mavlink's
            // own reader makes of the same bytes.
            let want = if version == V1 {
                rust_mavlink_reads(&bytes, V1)
            } else {
                want.clone()
            };
            assert!(got == want, "{version:?} chunk {chunk}: messages differ");
        }
    }
}

#[test]
fn v1_and_v2_mixed_in_one_stream() {
    let recs = flight(100);
    let mut bytes = Vec::new();
    for (i, (_, h, m)) in recs.iter().enumerate() {
        bytes.extend(frame(*h, m, if i % 2 == 0 { V1 } else { V2 }));
    }
    let (got, s) = decode(&bytes, 33);
    assert_eq!(s, counts(100, 0, 0, 0, 0));
    assert_eq!(got.len(), 100);
}

#[test]
fn a_flipped_crc_byte_is_one_bad_frame_and_one_sequence_gap() {
    for version in [V1, V2] {
        let recs = flight(50);
        let (mut bytes, starts) = stream(&recs, version);
        // The last byte of frame 20 is the CRC's high byte.
        bytes[starts[21] - 1] ^= 0x5A;
        let (got, s) = decode(&bytes, 100);
        assert_eq!(s, counts(49, 1, 0, 1, 0), "{version:?}");
        assert!(
            got[20] == rust_mavlink_reads(&frame(recs[21].1, &recs[21].2, version), version)[0],
            "the frame after the bad one is kept"
        );
    }
}

#[test]
fn a_corrupted_length_byte_does_not_swallow_the_next_frame() {
    for (delta, version) in [(40u8, V2), (200, V2), (1, V1), (90, V1)] {
        let recs = flight(30);
        let (mut bytes, starts) = stream(&recs, version);
        bytes[starts[10] + 1] = bytes[starts[10] + 1].wrapping_add(delta);
        let (got, s) = decode(&bytes, 50);
        assert_eq!(
            (s.frames_ok, s.frames_bad, s.unknown),
            (29, 1, 0),
            "len +{delta} {version:?}: {s:?}"
        );
        assert!(
            got[10] == rust_mavlink_reads(&frame(recs[11].1, &recs[11].2, version), version)[0]
        );
    }
}

#[test]
fn garbage_between_frames_is_counted_as_junk() {
    let recs = flight(40);
    let mut bytes = b"line noise!".to_vec();
    let mut junk = 11;
    for (i, (_, h, m)) in recs.iter().enumerate() {
        bytes.extend(frame(*h, m, V2));
        if i % 10 == 4 {
            let g: Vec<u8> = (0..(i as u8 + 3))
                .map(|k| k.wrapping_mul(37) % 200)
                .collect();
            junk += g.len() as u64;
            bytes.extend(g);
        }
    }
    assert!(!bytes.iter().take(11).any(|&b| b == 0xFD || b == 0xFE));
    let (got, s) = decode(&bytes, 17);
    assert_eq!(s, counts(40, 0, 0, 0, junk));
    assert_eq!(got.len(), 40);
}

#[test]
fn random_garbage_with_start_bytes_never_costs_a_good_frame() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let recs = flight(500);
    let mut bytes = Vec::new();
    for (_, h, m) in &recs {
        let n = rng.random_range(0..40);
        for _ in 0..n {
            // A third of the garbage is start bytes: the worst case for resync.
            bytes.push(match rng.random_range(0..3) {
                0 => 0xFD,
                1 => 0xFE,
                _ => rng.random(),
            });
        }
        bytes.extend(frame(*h, m, if rng.random() { V1 } else { V2 }));
    }
    let (got, s) = decode(&bytes, 1000);
    assert_eq!(s.frames_ok, 500, "{s:?}");
    assert_eq!(got.len(), 500);
}

#[test]
fn an_unknown_message_id_is_counted_and_skipped_exactly() {
    let recs = flight(20);
    let mut bytes = Vec::new();
    for (i, (_, h, m)) in recs.iter().enumerate() {
        if i == 5 || i == 19 {
            bytes.extend(unknown_v2(h.sequence.wrapping_sub(1)));
        }
        bytes.extend(frame(*h, m, V2));
    }
    bytes.extend(unknown_v2(0)); // last thing in the stream
    let (got, s) = decode(&bytes, 64);
    // The unknown frames reuse sequence numbers: a repeat is not a gap, but the trailing
    // one (seq 0 after 19) is.
    assert_eq!(s, counts(20, 0, 3, 1, 0));
    assert_eq!(got.len(), 20);
}

#[test]
fn signed_v2_frames_are_framed_past_their_signature() {
    let recs = flight(30);
    let mut bytes = Vec::new();
    for (i, (_, h, m)) in recs.iter().enumerate() {
        let f = frame(*h, m, V2);
        bytes.extend(if i % 3 == 0 { sign_v2(&f, m) } else { f });
    }
    let (got, s) = decode(&bytes, 25);
    assert_eq!(s, counts(30, 0, 0, 0, 0));
    assert!(got == recs.iter().map(|r| r.2.clone()).collect::<Vec<_>>());
}

#[test]
fn a_truncated_last_frame_is_one_bad_frame() {
    for version in [V1, V2] {
        let recs = flight(10);
        let (bytes, starts) = stream(&recs, version);
        let cut = &bytes[..starts[9] + 9];
        let (got, s) = decode(cut, 4096);
        assert_eq!(s, counts(9, 1, 0, 0, 0), "{version:?}");
        assert_eq!(got.len(), 9);
    }
}

#[test]
fn a_frame_cut_short_mid_stream_costs_only_itself() {
    let recs = flight(20);
    let (bytes, starts) = stream(&recs, V2);
    let mut cut = bytes[..starts[8] + 12].to_vec();
    cut.extend_from_slice(&bytes[starts[9]..]);
    let (got, s) = decode(&cut, 4096);
    assert_eq!(s, counts(19, 1, 0, 1, 0));
    assert!(got[8] == recs[9].2);
}

#[test]
fn nan_and_infinite_fields_decode_without_panicking() {
    use dronewatt::dialect::*;
    let msg = MavMessage::ATTITUDE(ATTITUDE_DATA {
        time_boot_ms: 5,
        roll: f32::NAN,
        pitch: f32::INFINITY,
        yaw: f32::NEG_INFINITY,
        ..Default::default()
    });
    let h = mavlink::MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    };
    for version in [V1, V2] {
        let (got, s) = decode(&frame(h, &msg, version), 8);
        assert_eq!(s.frames_ok, 1);
        let MavMessage::ATTITUDE(a) = &got[0] else {
            panic!("not ATTITUDE")
        };
        assert!(a.roll.is_nan() && a.pitch == f32::INFINITY && a.yaw == f32::NEG_INFINITY);
    }
}

#[test]
fn sequence_gaps_are_counted_per_sender() {
    let recs = flight(30);
    let mut bytes = Vec::new();
    for (i, (_, h, m)) in recs.iter().enumerate() {
        if i != 12 {
            bytes.extend(frame(*h, m, V2)); // 12 lost on the way: one gap for system 1
        }
        // A second sender interleaved, with its own clean sequence.
        let h2 = mavlink::MavHeader {
            system_id: 2,
            component_id: 1,
            sequence: i as u8,
        };
        bytes.extend(frame(h2, m, V2));
    }
    let (_, s) = decode(&bytes, 4096);
    assert_eq!(s, counts(59, 0, 0, 1, 0));
}
