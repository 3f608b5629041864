//! How much of a corrupted tlog survives: `replay/demo.tlog` (a simulated flight, committed)
//! with bytes flipped at random (seeded) at rates 1e-3 and 1e-2, decoded by the tlog reader.
//! Every record the flips left whole must still be decoded, every byte must be accounted
//! for, and nothing may be invented. The kept/total figures are printed for the README:
//! `cargo test --test it source_tlog_corruption:: -- --nocapture`.

use dronewatt::report::status::IngestStats;
use dronewatt::source::frame::good_frame_len;
use dronewatt::source::frame::timed::TimedReader;

/// Byte ranges of the records of a clean tlog (stamp + frame).
fn records(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut pos = 0;
    while pos + 8 < bytes.len() {
        let len = good_frame_len(&bytes[pos + 8..]).expect("the demo tlog is clean");
        out.push((pos, pos + 8 + len));
        pos += 8 + len;
    }
    assert_eq!(pos, bytes.len(), "the demo tlog ends on a record boundary");
    out
}

/// Flip one random bit pattern in about `rate` of the bytes (xorshift, fixed seed).
fn corrupt(bytes: &[u8], rate: f64, seed: u64) -> (Vec<u8>, Vec<bool>) {
    let mut x = seed;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut out = bytes.to_vec();
    let mut hit = vec![false; bytes.len()];
    for (i, b) in out.iter_mut().enumerate() {
        if (next() as f64 / u64::MAX as f64) < rate {
            *b ^= 1 + (next() % 255) as u8; // never a no-op
            hit[i] = true;
        }
    }
    (out, hit)
}

#[test]
fn corrupted_tlog_keeps_every_record_the_flips_left_whole() {
    let clean = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/replay/demo.tlog"))
        .expect("replay/demo.tlog");
    let recs = records(&clean);
    for rate in [1e-3, 1e-2] {
        let (bytes, hit) = corrupt(&clean, rate, 0x5EED_0000 ^ (rate * 1e6) as u64);
        let untouched = recs
            .iter()
            .filter(|(a, b)| !hit[*a..*b].iter().any(|&h| h))
            .count();
        let stats = IngestStats::default();
        let mut r = TimedReader::tlog();
        r.push(&bytes);
        r.finish();
        let mut kept = 0usize;
        while r.next_message(&stats).is_some() {
            kept += 1;
        }
        let s = stats.snapshot();
        let t = r.byte_tally();
        println!(
            "rate {rate:e}: {} bytes flipped; {kept} of {} frames kept ({untouched} records untouched); {} bad, {} unknown, {} junk bytes",
            hit.iter().filter(|&&h| h).count(),
            recs.len(),
            s.frames_bad,
            s.unknown,
            s.junk_bytes
        );
        assert!(
            kept >= untouched,
            "rate {rate}: {kept} frames kept but {untouched} records were untouched"
        );
        assert!(
            kept <= recs.len(),
            "rate {rate}: {kept} frames from {} records",
            recs.len()
        );
        assert_eq!(
            t.ok + t.bad + t.unknown + s.junk_bytes,
            bytes.len() as u64,
            "rate {rate}: {s:?} {t:?}"
        );
    }
}
