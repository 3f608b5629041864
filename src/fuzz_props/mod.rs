//! Properties the readers keep on *any* input whatsoever: the checks the fuzz targets in
//! `fuzz/` run on every input libFuzzer makes up, and that `tests/it/fuzz_props.rs` replays
//! on the committed corpus and regression inputs (so `cargo test` keeps a fixed crash
//! fixed, with no nightly toolchain and no sanitizer).
//!
//! Each check returns `Err(what broke)` instead of panicking, so the replay test can name
//! the file; a panic inside a reader is a failure too (the fuzzer reports it, the replay
//! test fails on it).
//!
//! A top-level module, not part of [`crate::source`]: it checks the config and builds the
//! energy and alert stages, which the sources must not import. Nothing imports it.
//!
//! | check | reader | properties |
//! |---|---|---|
//! | [`check_decoder`] | [`crate::source::frame::FrameDecoder`], stream and tlog framing | every byte accounted for (ok + bad + unknown + junk = input); the same frames and counts whatever the chunking; at most about two frames buffered; a valid v1/v2/signed frame behind garbage is found |
//! | [`check_tlog`] | [`crate::source::frame::timed::TimedReader::tlog`] | bytes accounted for; `t_s` starts at 0, finite, never decreasing; one message per good frame; clock jumps among the gaps |
//! | [`check_raw`] | [`crate::source::frame::timed::TimedReader::raw`] | the same, timed by `time_boot_ms` |
//! | [`check_csv`] | [`crate::source::logs::dataset::parse_flights`] | every non-empty line a row or a counted skip; rows finite with increasing time; small flights encode to a tlog that decodes without a bad byte |
//! | [`check_config`] | [`crate::config::Config`] (TOML + `validate`) | every validation message names a key; a config that validates builds its energy tracker, alert engine and telemetry stage |
//! | [`check_trees`] | [`crate::model::trees::Trees`] (LightGBM's text model, a card's `[trees]`) | a model that parses evaluates any row (NaN, ±0, subnormal, ±∞, huge) without a panic or an endless walk, the same estimate twice; parsing is deterministic |

use mavlink::{MavHeader, MavlinkVersion, Message};

use crate::report::status::{IngestStats, StatsSnapshot};
use crate::source::frame::timed::TimedReader;
use crate::source::frame::{self, ByteTally, FrameDecoder, Framing, MAX_FRAME_LEN, TLOG_STAMP_LEN};
use crate::MavMessage;

mod files;
pub use files::{check_config, check_csv, check_plan, check_trees};

/// Most bytes the decoder may hold undecoded between pushes: an unknown frame waiting to
/// see whether a frame follows it (itself and the next frame, plus that one's next byte),
/// or a tlog stamp before a partial frame.
pub const MAX_PENDING: usize = 2 * MAX_FRAME_LEN + TLOG_STAMP_LEN + 1;

/// A CSV input larger than this is only checked for not panicking on the row properties
/// (encoding every flight of a large input would make the fuzzer crawl).
pub(super) const CSV_ENCODE_MAX_ROWS: usize = 200;

/// What one decoding pass saw: (header, version, message id, stamp) per good frame.
type FrameKey = (MavHeader, MavlinkVersion, u32, Option<u64>);

fn version_name(v: MavlinkVersion) -> &'static str {
    match v {
        MavlinkVersion::V1 => "v1",
        MavlinkVersion::V2 => "v2",
    }
}

/// Decode `input` in chunks of the given sizes (cycled), draining after each push; checks
/// the buffering bound on the way.
fn decode_chunked(
    framing: Framing,
    input: &[u8],
    chunks: &[usize],
) -> Result<(Vec<FrameKey>, StatsSnapshot, ByteTally), String> {
    let stats = IngestStats::default();
    let mut d = FrameDecoder::new(framing);
    let mut frames = Vec::new();
    let mut at = 0;
    let mut k = 0;
    while at < input.len() {
        let n = chunks
            .get(k % chunks.len().max(1))
            .copied()
            .unwrap_or(input.len())
            .clamp(1, input.len() - at);
        k += 1;
        d.push(&input[at..at + n]);
        at += n;
        while let Some(f) = d.next_frame(&stats) {
            frames.push((f.header, f.version, f.msg.message_id(), f.stamp_us));
        }
        if d.pending_len() > MAX_PENDING {
            return Err(format!(
                "{framing:?}: {} bytes buffered after {at} of {} pushed (bound {MAX_PENDING})",
                d.pending_len(),
                input.len()
            ));
        }
    }
    d.finish();
    while let Some(f) = d.next_frame(&stats) {
        frames.push((f.header, f.version, f.msg.message_id(), f.stamp_us));
    }
    if d.pending_len() != 0 {
        return Err(format!(
            "{framing:?}: {} bytes left undecoded after finish",
            d.pending_len()
        ));
    }
    Ok((frames, stats.snapshot(), d.byte_tally()))
}

/// `ok + bad + unknown + junk == input bytes`, and the frame counters agree with the bytes.
fn check_accounting(
    what: &str,
    len: usize,
    s: &StatsSnapshot,
    t: &ByteTally,
    min_frame: u64,
) -> Result<(), String> {
    let sum = t.ok + t.bad + t.unknown + s.junk_bytes;
    if sum != len as u64 {
        return Err(format!(
            "{what}: bytes do not add up: ok {} + bad {} + unknown {} + junk {} = {sum}, input {len} ({s:?})",
            t.ok, t.bad, t.unknown, s.junk_bytes
        ));
    }
    if t.ok < s.frames_ok * min_frame || (s.frames_ok == 0) != (t.ok == 0) {
        return Err(format!(
            "{what}: {} good frames in {} good bytes",
            s.frames_ok, t.ok
        ));
    }
    // Not `unknown × min_frame`: an unknown frame's span ends where a good frame found
    // inside it begins, so it may keep fewer bytes than a whole frame.
    if (s.unknown == 0) != (t.unknown == 0) {
        return Err(format!(
            "{what}: {} unknown frames in {} unknown bytes",
            s.unknown, t.unknown
        ));
    }
    if t.bad > 0 && s.frames_bad == 0 {
        return Err(format!(
            "{what}: {} bad bytes but no bad frame counted",
            t.bad
        ));
    }
    Ok(())
}

/// One valid frame of `msg` as `version` (signed: MAVLink 2 with the signing flag and a
/// 13-byte signature, which dronewatt does not verify but must skip).
pub fn encode_frame(
    header: MavHeader,
    msg: &MavMessage,
    version: MavlinkVersion,
    signed: bool,
) -> Vec<u8> {
    let mut payload = [0u8; 255];
    let n = msg.ser(version, &mut payload);
    let id = msg.message_id();
    let mut out = match version {
        MavlinkVersion::V1 => vec![
            frame::STX_V1,
            n as u8,
            header.sequence,
            header.system_id as u8,
            header.component_id,
            id as u8,
        ],
        MavlinkVersion::V2 => {
            let [a, b, c, _] = id.to_le_bytes();
            let incompat = if signed { frame::IFLAG_SIGNED } else { 0 };
            vec![
                frame::STX_V2,
                n as u8,
                incompat,
                0,
                header.sequence,
                header.system_id as u8,
                header.component_id,
                a,
                b,
                c,
            ]
        }
    };
    out.extend_from_slice(&payload[..n]);
    let crc = frame::crc16(&out[1..], MavMessage::extra_crc(id));
    out.extend_from_slice(&crc.to_le_bytes());
    if signed && version == MavlinkVersion::V2 {
        // link id, 6-byte timestamp, 6-byte signature: arbitrary, not verified.
        out.extend_from_slice(&[7, 1, 2, 3, 4, 5, 6, 0xA1, 0xB2, 0xC3, 0xD4, 0xE5, 0xF6]);
    }
    out
}

/// The frame the decoder target hides in garbage, chosen by two bytes of the input.
fn embedded_frame(sel: u8, seq: u8) -> (MavHeader, MavMessage, MavlinkVersion, bool) {
    use crate::dialect::*;
    let msg = match sel % 4 {
        0 => MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavlink_version: 3,
            ..Default::default()
        }),
        1 => MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: 1234,
            roll: 0.1,
            pitch: -0.2,
            yaw: 1.5,
            ..Default::default()
        }),
        2 => MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            lat: 473_977_420,
            lon: 85_455_940,
            alt: 12_000,
            ..Default::default()
        }),
        _ => MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            voltage_battery: 22_800,
            current_battery: 1_250,
            ..Default::default()
        }),
    };
    let (version, signed) = match (sel >> 2) % 3 {
        0 => (MavlinkVersion::V1, false),
        1 => (MavlinkVersion::V2, false),
        _ => (MavlinkVersion::V2, true),
    };
    (
        MavHeader {
            system_id: 1 + (sel >> 4) as u32,
            component_id: 1,
            sequence: seq,
        },
        msg,
        version,
        signed,
    )
}

/// The frame decoder. The first byte picks the framing (bit 0: tlog) and the chunk sizes
/// come from the next two; the rest is the input. A second pass hides a valid frame
/// (v1, v2 or signed v2, picked by the input) at a position the input picks and checks
/// that it is found, unless the garbage before it itself holds a valid frame that runs
/// over it.
pub fn check_decoder(data: &[u8]) -> Result<(), String> {
    let Some((&mode, rest)) = data.split_first() else {
        return Ok(());
    };
    let (c1, c2, input) = match rest {
        [a, b, tail @ ..] => (*a, *b, tail),
        _ => return Ok(()),
    };
    let framing = if mode & 1 == 1 {
        Framing::Tlog
    } else {
        Framing::Stream
    };
    let min_frame = if framing == Framing::Tlog { 16 } else { 8 };

    // One push of everything, then odd chunk sizes: the same frames and counters.
    let (whole, s, t) = decode_chunked(framing, input, &[input.len()])?;
    check_accounting(&format!("{framing:?}"), input.len(), &s, &t, min_frame)?;
    if s.frames_ok != whole.len() as u64 {
        return Err(format!(
            "{framing:?}: frames_ok {} but {} frames returned",
            s.frames_ok,
            whole.len()
        ));
    }
    if s.gaps > s.frames_ok + s.unknown {
        return Err(format!(
            "{framing:?}: {} gaps for {} frames",
            s.gaps,
            s.frames_ok + s.unknown
        ));
    }
    let chunks = [
        1 + c1 as usize % 64,
        1 + c2 as usize,
        1 + (c1 ^ c2) as usize % 7,
    ];
    let (parts, s2, t2) = decode_chunked(framing, input, &chunks)?;
    if parts != whole || s2 != s || t2 != t {
        return Err(format!(
            "{framing:?}: chunks {chunks:?} give {} frames {s2:?} {t2:?}, one push {} frames {s:?} {t:?}",
            parts.len(),
            whole.len()
        ));
    }

    // A valid frame behind garbage is found.
    if framing == Framing::Stream {
        let (header, msg, version, signed) = embedded_frame(mode >> 1, c1);
        let frame_bytes = encode_frame(header, &msg, version, signed);
        let split = if input.is_empty() {
            0
        } else {
            c2 as usize % (input.len() + 1)
        };
        let (prefix, suffix) = input.split_at(split);
        let mut stream = prefix.to_vec();
        stream.extend_from_slice(&frame_bytes);
        stream.extend_from_slice(suffix);
        // A good frame starting in the garbage and running into ours may hide it.
        let shadowed = (0..prefix.len())
            .any(|i| frame::good_frame_len(&stream[i..]).is_some_and(|n| i + n > prefix.len()));
        let (found, s, t) = decode_chunked(Framing::Stream, &stream, &chunks)?;
        check_accounting(
            "Stream with a frame inside",
            stream.len(),
            &s,
            &t,
            min_frame,
        )?;
        let want = (header, version, msg.message_id(), None);
        if !shadowed && !found.contains(&want) {
            return Err(format!(
                "a valid {} {}frame (id {}) after {} bytes of garbage was not found: {} frames {s:?}",
                version_name(version),
                if signed { "signed " } else { "" },
                msg.message_id(),
                prefix.len(),
                found.len()
            ));
        }
    }
    Ok(())
}

/// `t_s` and counters of a timed reader over `input` (one push, then finish).
fn check_timed(what: &str, mut r: TimedReader, input: &[u8], min_frame: u64) -> Result<(), String> {
    let stats = IngestStats::default();
    r.push(input);
    r.finish();
    let mut n = 0u64;
    let mut last = 0.0f64;
    while let Some(m) = r.next_message(&stats) {
        if !m.t_s.is_finite() || m.t_s < 0.0 {
            return Err(format!("{what}: message {n} has t_s = {}", m.t_s));
        }
        if n == 0 && m.t_s != 0.0 {
            return Err(format!(
                "{what}: the first message has t_s = {}, not 0",
                m.t_s
            ));
        }
        if m.t_s < last {
            return Err(format!(
                "{what}: t_s goes back from {last} to {} at message {n}",
                m.t_s
            ));
        }
        last = m.t_s;
        n += 1;
    }
    let s = stats.snapshot();
    check_accounting(what, input.len(), &s, &r.byte_tally(), min_frame)?;
    if s.frames_ok != n {
        return Err(format!(
            "{what}: frames_ok {} but {n} messages",
            s.frames_ok
        ));
    }
    if s.clock_jumps > n || s.clock_jumps > s.gaps {
        return Err(format!(
            "{what}: {} clock jumps, {} gaps, {n} messages",
            s.clock_jumps, s.gaps
        ));
    }
    Ok(())
}

/// An autopilot's own log (`decode` reads it whole, as `learn` and `replay` do): an error
/// or messages whose times are finite, from 0 up and never going back, and no more
/// messages than input bytes (every message comes from a record of several bytes: nothing
/// is made up out of a time span, so a log cannot make the reader allocate without bound).
fn check_autopilot_log<E: std::fmt::Display>(
    what: &str,
    data: &[u8],
    decode: fn(&[u8], &IngestStats) -> Result<Vec<crate::source::TimedMessage>, E>,
) -> Result<(), String> {
    let stats = IngestStats::default();
    match decode(data, &stats) {
        Err(e) if e.to_string().trim().is_empty() => {
            Err(format!("{what}: an error that says nothing"))
        }
        Err(_) => Ok(()),
        Ok(msgs) => {
            if msgs.len() > data.len() {
                return Err(format!(
                    "{what}: {} messages from {} bytes",
                    msgs.len(),
                    data.len()
                ));
            }
            let mut last = 0.0f64;
            for (n, m) in msgs.iter().enumerate() {
                if !m.t_s.is_finite() || m.t_s < last {
                    return Err(format!(
                        "{what}: message {n} has t_s = {} after {last}",
                        m.t_s
                    ));
                }
                last = m.t_s;
            }
            Ok(())
        }
    }
}

/// The ArduPilot DataFlash (`.bin`) reader.
pub fn check_dataflash(data: &[u8]) -> Result<(), String> {
    check_autopilot_log(
        "dataflash",
        data,
        crate::source::logs::dataflash::decode_dataflash,
    )
}

/// The PX4 ULog (`.ulg`) reader.
pub fn check_ulog(data: &[u8]) -> Result<(), String> {
    check_autopilot_log("ulog", data, crate::source::logs::ulog::decode_ulog)
}

/// The `.tlog` reader, timestamps included.
pub fn check_tlog(data: &[u8]) -> Result<(), String> {
    check_timed("tlog", TimedReader::tlog(), data, 16)
}

/// The raw-stream reader, timed by `time_boot_ms`.
pub fn check_raw(data: &[u8]) -> Result<(), String> {
    check_timed("raw", TimedReader::raw(), data, 8)
}
