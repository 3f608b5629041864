//! Parse-speed benchmark: decode a `.tlog` of 100 000 realistic autopilot messages
//! (MAVLink 2, the mix of `tests/it/mavlink_common`: attitude, positions, IMU, servo, GPS,
//! VFR_HUD, SYS_STATUS, HEARTBEAT, BATTERY_STATUS) with [`decode_tlog`], the path every
//! replay and offline run takes.
//!
//! The file is also written to `target/bench-parse.tlog` so the pymavlink side reads the
//! identical bytes:
//!
//! ```text
//! cargo bench --bench parse
//! .venv-py/bin/python scripts/bench_pymavlink.py target/bench-parse.tlog
//! ```

#[path = "../tests/it/mavlink_common/mod.rs"]
mod mavlink_common;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use dronewatt::report::status::IngestStats;
use dronewatt::source::frame::{FrameDecoder, Framing};
use dronewatt::source::logs::tlog::decode_tlog;

const N: usize = 100_000;

fn bench(c: &mut Criterion) {
    let bytes = mavlink_common::tlog(&mavlink_common::flight(N), mavlink::MavlinkVersion::V2);
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-parse.tlog");
    if let Err(e) = std::fs::write(&path, &bytes) {
        eprintln!("cannot write {}: {e}", path.display());
    } else {
        eprintln!(
            "wrote {} ({} messages, {} bytes)",
            path.display(),
            N,
            bytes.len()
        );
    }
    let stats = IngestStats::default();
    assert_eq!(decode_tlog(&bytes, &stats).len(), N);

    let mut g = c.benchmark_group("parse_tlog");
    g.throughput(Throughput::Elements(N as u64));
    g.sample_size(30);
    g.bench_function("decode_tlog_100k", |b| {
        b.iter(|| {
            let stats = IngestStats::default();
            decode_tlog(std::hint::black_box(&bytes), &stats).len()
        })
    });
    // The decoder alone (no clock, no Vec of messages): what a live link pays per frame.
    g.bench_function("frame_decoder_100k", |b| {
        b.iter(|| {
            let stats = IngestStats::default();
            let mut d = FrameDecoder::new(Framing::Tlog);
            d.push(std::hint::black_box(&bytes));
            d.finish();
            let mut n = 0;
            while d.next_frame(&stats).is_some() {
                n += 1;
            }
            n
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
