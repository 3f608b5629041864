//! Our own MAVLink frame decoder, used by every source (links, `.tlog`, raw streams).
//!
//! Why not rust-mavlink's readers: they drop frames with a bad CRC without a word, ignore
//! MAVLink 1 unless told otherwise and drop `.tlog` timestamps. Here every byte is
//! accounted for in [`IngestStats`]: a frame is *ok* (CRC checked, payload decoded), *bad*
//! (bad CRC, truncated, payload that does not decode), *unknown* (a plausible frame whose
//! message id this dialect does not know, so its CRC cannot be checked) or its bytes are
//! *junk*. Decoding itself is rust-mavlink's: `MavMessage::parse(version, id, payload)`
//! with the payload exactly as sent (MAVLink 2 trims trailing zeros; the generated
//! `deser` pads a short payload with zeros itself).
//!
//! ## Framings
//!
//! - [`Framing::Stream`] (serial, TCP, UDP datagrams, raw files): frames back to back with
//!   anything in between. The decoder scans for a start byte (`0xFE` v1, `0xFD` v2).
//! - [`Framing::Tlog`]: each frame preceded by an 8-byte big-endian µs timestamp; the
//!   timestamp comes out with the frame.
//!
//! ## Resynchronisation
//!
//! A frame whose CRC fails is counted bad once, and the decoder then looks for the next
//! frame from the byte after its start byte, not after its declared end: its length byte
//! may be the corrupted one, and skipping the declared length could swallow the next good
//! frame. Candidates that start inside a frame already counted bad are not counted again
//! (a false start byte in a corrupted payload is not a second bad frame). A frame with an
//! unknown id is counted when a frame that checks out (or another unknown one, or the end
//! of input) follows it, and its bytes are then accounted for exactly by its length; the
//! scan still steps into it, so a stray start byte in garbage that merely looks like an
//! unknown frame can never swallow a good frame behind it.
//!
//! ## Every byte accounted for
//!
//! Besides the frame counters, the decoder keeps a [`ByteTally`]: how many input bytes
//! belonged to good frames, to frames counted bad and to unknown frames (tlog stamps
//! included with their record). With `junk_bytes` these account for every byte pushed:
//! once the input is finished and drained, `ok + bad + unknown + junk == bytes pushed`.
//! A bad or unknown frame's span ends where a good frame found inside it begins (the
//! resynchronisation above), so no byte is counted twice. The fuzz targets and
//! `tests/it/fuzz_props.rs` check this on every input (`crate::fuzz_props`).
//!
//! ## Gaps
//!
//! `gaps` counts discontinuities. The decoder counts *sequence gaps*: per (system,
//! component), a frame (ok or unknown) whose sequence number is neither the previous one
//! plus one (mod 256) nor a repeat of it. One gap per discontinuity, however many frames
//! it lost; a frame counted bad therefore usually shows as one gap too. Clock jumps are
//! counted by the time bases in [`timed`].

use mavlink::{MavHeader, MavlinkVersion};

use super::links::signing::{Verdict, Verifier};

mod at;
mod crc;
mod lenient;
pub mod timed;

pub use at::good_frame_len;
use at::{decode_at, At};

use crate::report::status::IngestStats;
use crate::MavMessage;
pub use crc::crc16;
pub(crate) use crc::crc_extra;

/// A link's signature verifier, shared by every connection of the link (a replay through
/// a second TCP client is still a replay).
pub type SharedVerifier = std::sync::Arc<std::sync::Mutex<Verifier>>;

/// Start byte of a MAVLink 1 frame.
pub const STX_V1: u8 = 0xFE;
/// Start byte of a MAVLink 2 frame.
pub const STX_V2: u8 = 0xFD;
/// MAVLink 2 incompatibility flag: the frame carries a 13-byte signature after its CRC.
pub const IFLAG_SIGNED: u8 = 0x01;
const SIGNATURE_LEN: usize = 13;
/// The longest frame there is: a signed MAVLink 2 frame with a 255-byte payload.
pub const MAX_FRAME_LEN: usize = V2_HEADER + 255 + 2 + SIGNATURE_LEN;
const V1_HEADER: usize = 6; // STX len seq sys comp id
const V2_HEADER: usize = 10; // STX len incompat compat seq sys comp id(3)
/// Bytes of a tlog record's timestamp.
pub const TLOG_STAMP_LEN: usize = 8;
/// During tlog resynchronisation a frame that fails its CRC is only taken as the next
/// record if the 8 bytes before it are a timestamp within this of the last good one.
const TLOG_PLAUSIBLE_US: u64 = 600_000_000;

/// How frames are laid out in the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Framing {
    /// Frames back to back, possibly with garbage in between (links, raw files).
    Stream,
    /// `.tlog`: an 8-byte big-endian µs timestamp before each frame.
    Tlog,
}

/// One good frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Sender system/component and sequence.
    pub header: MavHeader,
    /// Which protocol version the frame was.
    pub version: MavlinkVersion,
    /// The decoded message.
    pub msg: MavMessage,
    /// The tlog record's timestamp, µs ([`Framing::Tlog`] only).
    pub stamp_us: Option<u64>,
}

/// Input bytes by what they turned out to be (see the module docs): with `junk_bytes`
/// they add up to every byte pushed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ByteTally {
    /// Bytes of good frames (tlog: with their 8-byte stamps).
    pub ok: u64,
    /// Bytes of frames counted bad, and of a truncated last frame or record.
    pub bad: u64,
    /// Bytes of frames counted unknown (tlog: with their stamps).
    pub unknown: u64,
}

/// The open span of a frame counted bad or unknown: from `start` to the decoder's
/// `counted_until`, or to the start of a good frame found inside it.
#[derive(Debug, Clone, Copy)]
struct Claim {
    start: usize,
    unknown: bool,
}

/// Incremental decoder: [`push`](Self::push) bytes as they come (a stream chunk, a
/// datagram, a whole file), then take frames with [`next_frame`](Self::next_frame) until
/// it says `None`. [`finish`](Self::finish) at the end of input so a truncated last frame
/// is counted. Allocation-free per frame beyond the returned message.
pub struct FrameDecoder {
    framing: Framing,
    buf: Vec<u8>,
    /// Next unread byte of `buf`.
    pos: usize,
    /// Bytes before this index belong to a frame already counted (bad, or unknown):
    /// they are not junk, and false frames inside are not counted again.
    counted_until: usize,
    /// Tlog: whether `pos` is believed to be the start of a record.
    aligned: bool,
    /// Tlog: the last good record's timestamp (resync plausibility).
    last_stamp_us: Option<u64>,
    eof: bool,
    /// Last sequence number per (system, component): `(sys, comp, seq)`. A handful of
    /// components per link, so a linear scan beats hashing.
    seqs: Vec<(u32, u8, u8)>,
    /// MAVLink 2 signature checks ([`super::signing`]), [`Framing::Stream`] only: frames
    /// it rejects are counted in their own counters and never returned.
    verifier: Option<SharedVerifier>,
    /// Bytes settled as ok, bad or unknown so far.
    tally: ByteTally,
    /// The bad or unknown frame whose span is still open (ends at `counted_until`).
    claim: Option<Claim>,
}

impl FrameDecoder {
    /// An empty decoder for this framing.
    pub fn new(framing: Framing) -> Self {
        Self {
            framing,
            buf: Vec::new(),
            pos: 0,
            counted_until: 0,
            aligned: true,
            last_stamp_us: None,
            eof: false,
            seqs: Vec::new(),
            verifier: None,
            tally: ByteTally::default(),
            claim: None,
        }
    }

    /// Check every frame's signature from now on (a live link with a signing key).
    pub fn set_verifier(&mut self, verifier: SharedVerifier) {
        self.verifier = Some(verifier);
    }

    /// Whether the signing rules let the frame `b` through, counting it either way.
    fn admitted(&self, b: &[u8], stats: &IngestStats) -> bool {
        let Some(v) = &self.verifier else { return true };
        let verdict = match v.lock() {
            Ok(mut v) => v.check(b),
            Err(_) => Verdict::BadSignature, // a verifier that panicked admits nothing
        };
        let counter = match verdict {
            Verdict::Unsigned => return true,
            Verdict::Signed => {
                IngestStats::add(&stats.signed_ok, 1);
                return true;
            }
            Verdict::BadSignature => &stats.signature_bad,
            Verdict::Replay => &stats.signature_replay,
            Verdict::UnsignedRefused => &stats.unsigned_refused,
        };
        IngestStats::add(counter, 1);
        false
    }

    /// Bytes so far by what they were (the open bad/unknown span included as it stands).
    /// After [`finish`](Self::finish) and draining [`next_frame`](Self::next_frame),
    /// `ok + bad + unknown` plus the `junk_bytes` counted is every byte pushed.
    pub fn byte_tally(&self) -> ByteTally {
        let mut t = self.tally;
        if let Some(c) = self.claim {
            let n = self.counted_until.saturating_sub(c.start) as u64;
            if c.unknown {
                t.unknown += n;
            } else {
                t.bad += n;
            }
        }
        t
    }

    /// Bytes pushed but not yet decoded or counted: at most about two frames whatever the
    /// input (the decoder never buffers without bound).
    pub fn pending_len(&self) -> usize {
        self.buf.len() - self.pos
    }

    /// Close the open bad/unknown span at `at` (a good frame or a new record starts there):
    /// its bytes up to there are settled, and nothing before `at` is claimed any more.
    fn close_claim(&mut self, at: usize) {
        if let Some(c) = self.claim.take() {
            let n = self.counted_until.min(at).saturating_sub(c.start) as u64;
            if c.unknown {
                self.tally.unknown += n;
            } else {
                self.tally.bad += n;
            }
        }
        self.counted_until = self.counted_until.min(at);
    }

    /// A frame counted bad or unknown spans `[start, end)`: close the previous span at
    /// `start` and open this one.
    fn open_claim(&mut self, start: usize, end: usize, unknown: bool) {
        self.close_claim(start);
        self.claim = Some(Claim { start, unknown });
        self.counted_until = end;
    }

    /// Append input. Consumed bytes are dropped first, so the buffer holds at most one
    /// partial frame plus the new bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.pos > 0 {
            // No good frame can start before `pos` any more: settle the open span's bytes
            // up to there, so the span survives the shift.
            if let Some(c) = self.claim.as_mut() {
                let settled = self.counted_until.min(self.pos).saturating_sub(c.start) as u64;
                if c.unknown {
                    self.tally.unknown += settled;
                } else {
                    self.tally.bad += settled;
                }
                c.start = c.start.max(self.pos) - self.pos;
                if self.counted_until <= self.pos {
                    self.claim = None;
                }
            }
            self.buf.drain(..self.pos);
            self.counted_until = self.counted_until.saturating_sub(self.pos);
            self.pos = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// No more input will come: what is left is decoded as far as it goes and a
    /// truncated last frame is counted bad.
    pub fn finish(&mut self) {
        self.eof = true;
    }

    /// Forget a partial frame and sequence history (a TCP reconnect: the new stream shares
    /// nothing with the old one). Counts nothing.
    pub fn reset(&mut self) {
        self.close_claim(self.counted_until);
        self.buf.clear();
        self.pos = 0;
        self.counted_until = 0;
        self.aligned = true;
        self.eof = false;
        self.seqs.clear();
    }

    /// The next good frame, counting everything skipped on the way into `stats`. `None`
    /// when the buffered input is used up (push more, or it has ended).
    pub fn next_frame(&mut self, stats: &IngestStats) -> Option<Frame> {
        match self.framing {
            Framing::Stream => self.next_stream(stats),
            Framing::Tlog => self.next_tlog(stats),
        }
    }

    /// Count the bytes in `[from, to)` that are not part of a frame counted bad as junk.
    #[inline]
    fn junk(&self, stats: &IngestStats, from: usize, to: usize) {
        let n = to.saturating_sub(from.max(self.counted_until));
        if n > 0 {
            IngestStats::add(&stats.junk_bytes, n as u64);
        }
    }

    /// Count a sequence gap if `h` does not follow its sender's previous frame.
    #[inline]
    fn track_seq(&mut self, h: &MavHeader, stats: &IngestStats) {
        for e in self.seqs.iter_mut() {
            if e.0 == h.system_id && e.1 == h.component_id {
                if h.sequence != e.2.wrapping_add(1) && h.sequence != e.2 {
                    IngestStats::add(&stats.gaps, 1);
                }
                e.2 = h.sequence;
                return;
            }
        }
        self.seqs.push((h.system_id, h.component_id, h.sequence));
    }

    /// Whether a frame (one that checks out, or an unknown one itself followed by a start
    /// byte) or the end of input begins at `end`: the test an unknown frame must pass to
    /// be skipped whole. `None`: the input does not reach far enough to tell yet.
    fn followed_by_frame(&self, end: usize) -> Option<bool> {
        if end >= self.buf.len() {
            return if self.eof { Some(true) } else { None };
        }
        match decode_at(&self.buf[end..]) {
            At::Good { .. } => Some(true),
            At::Unknown { len, .. } => match self.buf.get(end + len) {
                Some(&b) => Some(b == STX_V1 || b == STX_V2),
                None => {
                    if self.eof {
                        Some(true)
                    } else {
                        None
                    }
                }
            },
            At::NeedMore => {
                if self.eof {
                    Some(true)
                } else {
                    None
                }
            }
            At::Bad { .. } | At::NotFrame => Some(false),
        }
    }

    fn next_stream(&mut self, stats: &IngestStats) -> Option<Frame> {
        loop {
            let rest = &self.buf[self.pos..];
            let Some(off) = rest.iter().position(|&b| b == STX_V2 || b == STX_V1) else {
                self.junk(stats, self.pos, self.buf.len());
                self.pos = self.buf.len();
                return None;
            };
            let q = self.pos + off;
            self.junk(stats, self.pos, q);
            self.pos = q;
            match decode_at(&self.buf[q..]) {
                At::Good {
                    len,
                    header,
                    version,
                    msg,
                } => {
                    self.pos = q + len;
                    self.close_claim(q);
                    self.tally.ok += len as u64;
                    if !self.admitted(&self.buf[q..q + len], stats) {
                        continue; // dropped whole: counted as a signing failure, not junk
                    }
                    IngestStats::add(&stats.frames_ok, 1);
                    self.track_seq(&header, stats);
                    return Some(Frame {
                        header,
                        version,
                        msg,
                        stamp_us: None,
                    });
                }
                At::Unknown { len, header } => {
                    if q >= self.counted_until {
                        let Some(followed) = self.followed_by_frame(q + len) else {
                            return None; // cannot tell yet: wait for more input
                        };
                        if followed {
                            IngestStats::add(&stats.unknown, 1);
                            self.track_seq(&header, stats);
                            self.open_claim(q, q + len, true);
                        } else {
                            self.junk(stats, q, q + 1);
                        }
                    }
                    // Step in, not over: if this was a stray start byte, the good frame
                    // it pretends to cover is still found (and ends the claimed span).
                    self.pos = q + 1;
                }
                At::Bad { len } => {
                    if q >= self.counted_until {
                        IngestStats::add(&stats.frames_bad, 1);
                        self.open_claim(q, q + len, false);
                    }
                    self.pos = q + 1;
                }
                At::NotFrame => {
                    self.junk(stats, q, q + 1);
                    self.pos = q + 1;
                }
                At::NeedMore => {
                    if !self.eof {
                        return None;
                    }
                    // Truncated by the end of input; frames may still start inside it.
                    if q >= self.counted_until {
                        IngestStats::add(&stats.frames_bad, 1);
                        self.open_claim(q, self.buf.len(), false);
                    }
                    self.pos = q + 1;
                }
            }
        }
    }

    fn stamp_at(&self, i: usize) -> u64 {
        let mut s = [0u8; 8];
        s.copy_from_slice(&self.buf[i..i + TLOG_STAMP_LEN]);
        u64::from_be_bytes(s)
    }

    /// The good record at `rec` (a `len`-byte frame after its stamp): step past it, count
    /// it, note its stamp and sequence; the reader is aligned after it.
    #[inline]
    fn accept_tlog(
        &mut self,
        rec: usize,
        len: usize,
        header: MavHeader,
        version: MavlinkVersion,
        msg: MavMessage,
        stats: &IngestStats,
    ) -> Frame {
        let stamp = self.stamp_at(rec);
        self.pos = rec + TLOG_STAMP_LEN + len;
        self.close_claim(rec);
        self.tally.ok += (TLOG_STAMP_LEN + len) as u64;
        self.aligned = true;
        self.last_stamp_us = Some(stamp);
        IngestStats::add(&stats.frames_ok, 1);
        self.track_seq(&header, stats);
        Frame {
            header,
            version,
            msg,
            stamp_us: Some(stamp),
        }
    }

    fn next_tlog(&mut self, stats: &IngestStats) -> Option<Frame> {
        loop {
            let avail = self.buf.len() - self.pos;
            if self.aligned {
                if avail <= TLOG_STAMP_LEN {
                    if self.eof && avail > 0 {
                        IngestStats::add(&stats.frames_bad, 1); // a record cut inside its stamp
                        self.open_claim(self.pos, self.buf.len(), false);
                        self.pos = self.buf.len();
                    }
                    return None;
                }
                let rec = self.pos;
                match decode_at(&self.buf[rec + TLOG_STAMP_LEN..]) {
                    At::Good {
                        len,
                        header,
                        version,
                        msg,
                    } => return Some(self.accept_tlog(rec, len, header, version, msg, stats)),
                    At::Unknown { len, header } => {
                        IngestStats::add(&stats.unknown, 1);
                        self.track_seq(&header, stats);
                        self.close_claim(rec);
                        self.tally.unknown += (TLOG_STAMP_LEN + len) as u64;
                        self.pos = rec + TLOG_STAMP_LEN + len;
                    }
                    At::Bad { len } => {
                        IngestStats::add(&stats.frames_bad, 1);
                        self.open_claim(rec, rec + TLOG_STAMP_LEN + len, false);
                        self.aligned = false;
                        self.pos = rec + 1;
                    }
                    At::NotFrame => {
                        self.aligned = false;
                    }
                    At::NeedMore => {
                        if !self.eof {
                            return None;
                        }
                        IngestStats::add(&stats.frames_bad, 1); // truncated last record
                        self.open_claim(rec, self.buf.len(), false);
                        self.pos = self.buf.len();
                        return None;
                    }
                }
            } else {
                self.resync_tlog(stats);
                if !self.aligned {
                    return None;
                }
            }
        }
    }

    /// Look for the next record start after corruption: a start byte at `q` (with 8 bytes
    /// of stamp before it) whose frame checks out, or whose frame is bad/unknown but
    /// whose stamp is plausible. Leaves `aligned` set, at that record, when one was found
    /// (the aligned path then reads it, a good frame included: resync is rare, so its
    /// second decode costs nothing that counts); `aligned` unset when the input ran out
    /// first.
    fn resync_tlog(&mut self, stats: &IngestStats) {
        let mut q = self.pos + TLOG_STAMP_LEN;
        while q < self.buf.len() {
            let b = self.buf[q];
            if b == STX_V1 || b == STX_V2 {
                let found = match decode_at(&self.buf[q..]) {
                    At::Good { .. } => true,
                    At::Unknown { .. } | At::Bad { .. } if q >= self.counted_until => {
                        let stamp = self.stamp_at(q - TLOG_STAMP_LEN);
                        match self.last_stamp_us {
                            Some(last) => stamp.abs_diff(last) <= TLOG_PLAUSIBLE_US,
                            None => false,
                        }
                    }
                    At::NeedMore if !self.eof => {
                        // Cannot tell yet; keep the bytes before it for the stamp.
                        let rec = q - TLOG_STAMP_LEN;
                        self.junk(stats, self.pos, rec);
                        self.pos = rec;
                        return;
                    }
                    _ => false,
                };
                if found {
                    let rec = q - TLOG_STAMP_LEN;
                    self.junk(stats, self.pos, rec);
                    self.pos = rec;
                    self.aligned = true;
                    return;
                }
            }
            q += 1;
        }
        // Nothing yet: all but the last 8 bytes (a possible stamp) are junk.
        let keep_from = if self.eof {
            self.buf.len()
        } else {
            self.buf.len().saturating_sub(TLOG_STAMP_LEN)
        };
        if keep_from > self.pos {
            self.junk(stats, self.pos, keep_from);
            self.pos = keep_from;
        }
    }
}

#[cfg(test)]
mod tests;
