//! MAVLink 2 message signing: verifying what a live link brings, signing what dronewatt
//! sends back. The `[link]` table configures it ([`super::LinkConfig`]).
//!
//! ## The signature (MAVLink 2 spec, "Message Signing")
//!
//! A signed frame has incompatibility flag `0x01` and 13 bytes after its CRC:
//!
//! ```text
//!  link_id (1) | timestamp (6, little-endian, 10 µs units since 2015-01-01 00:00:00 UTC) | signature (6)
//!  signature = first 6 bytes of SHA-256(secret_key (32) ‖ frame from STX through CRC ‖ link_id ‖ timestamp)
//! ```
//!
//! ## What is accepted ([`Verifier`])
//!
//! - The signature must match the key: else the frame is dropped and counted
//!   (`signature_bad`).
//! - Per *stream* (link id, system id, component id) the timestamp must increase: a frame
//!   whose timestamp is not above the stream's last one is a replay, dropped and counted
//!   (`signature_replay`).
//! - A stream not seen before is accepted only if its timestamp is no more than one minute
//!   ([`REPLAY_WINDOW_10US`]) behind the newest timestamp seen on the link (which starts at
//!   this machine's clock): an old capture replayed to a fresh dronewatt is refused.
//! - Unsigned frames (MAVLink 1, or 2 without the flag) pass unless `require_signing` is
//!   set; then they are dropped and counted (`unsigned_refused`).
//!
//! Frames are checked after their CRC (a frame that fails its CRC is `frames_bad`, as
//! without signing) and before anything reads them. Only live links verify; a `.tlog` or
//! raw file is read as recorded.
//!
//! ## The key file
//!
//! `signing_key_file` names a file holding the 32-byte secret key, never the key itself
//! (a TOML file gets shared, pasted and committed). The file may hold the 32 raw bytes, 64
//! hex digits, or base64 (44 characters with padding, 43 without), surrounding whitespace
//! ignored. On Unix it must not be readable or writable by group or others (`chmod 600`),
//! as ssh insists for its keys. MAVProxy's `signing setup PASSPHRASE` uses
//! SHA-256(passphrase) as the key: `printf %s PASSPHRASE | sha256sum | cut -c1-64 > key.hex`.

use std::collections::HashMap;
use std::path::Path;

use sha2::{Digest, Sha256};

use crate::source::frame::{crc16, IFLAG_SIGNED, STX_V2};

/// Bytes after the CRC of a signed frame: link id, timestamp, signature.
pub const SIGNATURE_BLOCK_LEN: usize = 13;
/// Secret key length, bytes.
pub const KEY_LEN: usize = 32;
/// How far behind the newest timestamp a new stream may start: one minute, in the
/// timestamp's 10 µs units.
pub const REPLAY_WINDOW_10US: u64 = 60 * 100_000;
/// 2015-01-01 00:00:00 UTC as a Unix time, s: the signing timestamp's epoch.
pub const EPOCH_2015_UNIX_S: u64 = 1_420_070_400;
const V2_HEADER: usize = 10;

/// A loaded signing set-up: the key and what to do with it.
#[derive(Clone)]
pub struct Signing {
    /// The shared secret.
    pub key: [u8; KEY_LEN],
    /// Refuse unsigned frames.
    pub require: bool,
    /// Link id for outgoing frames.
    pub link_id: u8,
}

impl std::fmt::Debug for Signing {
    /// Never prints the key.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Signing")
            .field("key", &"<secret>")
            .field("require", &self.require)
            .field("link_id", &self.link_id)
            .finish()
    }
}

/// Read a key file: 32 raw bytes, 64 hex digits or base64 of 32 bytes. On Unix the file
/// must be private to its owner.
pub fn read_key_file(path: &Path) -> Result<[u8; KEY_LEN], String> {
    parse_key(&crate::files::read_private(path)?)
}

/// A key from a file's bytes (see [`read_key_file`]).
pub fn parse_key(bytes: &[u8]) -> Result<[u8; KEY_LEN], String> {
    if bytes.len() == KEY_LEN {
        let mut k = [0u8; KEY_LEN];
        k.copy_from_slice(bytes);
        return Ok(k);
    }
    let text = std::str::from_utf8(bytes)
        .map_err(|_| {
            format!(
                "{} bytes that are neither a raw 32-byte key nor text",
                bytes.len()
            )
        })?
        .trim();
    let decoded = if text.len() == 2 * KEY_LEN && text.bytes().all(|b| b.is_ascii_hexdigit()) {
        hex::decode(text).map_err(|e| format!("64 hex digits that do not decode: {e}"))?
    } else {
        base64_decode(text).ok_or_else(|| {
            format!("expected 32 raw bytes, 64 hex digits or base64 of 32 bytes; found {} characters of text", text.len())
        })?
    };
    <[u8; KEY_LEN]>::try_from(decoded.as_slice()).map_err(|_| {
        format!(
            "the key decodes to {} bytes; a MAVLink key is 32",
            decoded.len()
        )
    })
}

/// Standard base64 (RFC 4648, `+/`, padding optional, unused trailing bits ignored).
/// `None` on anything else.
fn base64_decode(s: &str) -> Option<Vec<u8>> {
    use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
    use base64::Engine;
    const LENIENT: GeneralPurpose = GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        GeneralPurposeConfig::new()
            .with_decode_padding_mode(DecodePaddingMode::Indifferent)
            .with_decode_allow_trailing_bits(true),
    );
    LENIENT.decode(s.trim_end_matches('=')).ok()
}

/// This machine's clock as a signing timestamp: 10 µs units since 2015-01-01 UTC.
pub fn now_10us() -> u64 {
    let unix = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    (unix.as_micros() as u64 / 10).saturating_sub(EPOCH_2015_UNIX_S * 100_000)
}

/// The 6-byte signature of `frame_through_crc` with this link id and timestamp.
fn mac(key: &[u8; KEY_LEN], frame_through_crc: &[u8], link_id: u8, ts: u64) -> [u8; 6] {
    let mut h = Sha256::new();
    h.update(key);
    h.update(frame_through_crc);
    h.update([link_id]);
    h.update(&ts.to_le_bytes()[..6]);
    let d = h.finalize();
    let mut m = [0u8; 6];
    m.copy_from_slice(&d[..6]);
    m
}

/// What the verifier decided about one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Signed with the key, fresh.
    Signed,
    /// Not signed, and unsigned frames are allowed.
    Unsigned,
    /// Signed, but not with our key (or altered).
    BadSignature,
    /// Signed with our key, but its timestamp is not newer than its stream's last one,
    /// or a new stream more than a minute behind the newest timestamp.
    Replay,
    /// Not signed, and `require_signing` is set.
    UnsignedRefused,
}

/// Checks incoming frames against the key and the timestamp rules (see the module docs).
pub struct Verifier {
    signing: Signing,
    /// Last timestamp per (link id, system, component).
    streams: HashMap<(u8, u8, u8), u64>,
    /// Newest timestamp seen (starts at this machine's clock).
    newest: u64,
}

impl Verifier {
    /// A verifier whose clock starts now.
    pub fn new(signing: Signing) -> Self {
        Self::starting_at(signing, now_10us())
    }

    /// A verifier whose newest-seen timestamp starts at `now_10us` (tests use a fixed one).
    pub fn starting_at(signing: Signing, now_10us: u64) -> Self {
        Self {
            signing,
            streams: HashMap::new(),
            newest: now_10us,
        }
    }

    /// Judge one whole frame (STX through signature) whose CRC has already checked.
    pub fn check(&mut self, frame: &[u8]) -> Verdict {
        let signed =
            frame.first() == Some(&STX_V2) && frame.get(2).is_some_and(|f| f & IFLAG_SIGNED != 0);
        if !signed {
            return if self.signing.require {
                Verdict::UnsignedRefused
            } else {
                Verdict::Unsigned
            };
        }
        if frame.len() < V2_HEADER + 2 + SIGNATURE_BLOCK_LEN {
            return Verdict::BadSignature;
        }
        let (body, block) = frame.split_at(frame.len() - SIGNATURE_BLOCK_LEN);
        let link_id = block[0];
        let mut ts_bytes = [0u8; 8];
        ts_bytes[..6].copy_from_slice(&block[1..7]);
        let ts = u64::from_le_bytes(ts_bytes);
        let expected = mac(&self.signing.key, body, link_id, ts);
        // Constant time: every byte compared whatever the first difference.
        if !bool::from(subtle::ConstantTimeEq::ct_eq(&expected[..], &block[7..13])) {
            return Verdict::BadSignature;
        }
        let stream = (link_id, frame[5], frame[6]);
        let fresh = match self.streams.get(&stream) {
            Some(&last) => ts > last,
            None => ts + REPLAY_WINDOW_10US >= self.newest,
        };
        if !fresh {
            return Verdict::Replay;
        }
        self.streams.insert(stream, ts);
        self.newest = self.newest.max(ts);
        Verdict::Signed
    }
}

/// Signs outgoing MAVLink 2 frames with a timestamp that never repeats.
pub struct Signer {
    key: [u8; KEY_LEN],
    link_id: u8,
    last_ts: u64,
}

impl Signer {
    /// A signer for this set-up.
    pub fn new(signing: &Signing) -> Self {
        Self {
            key: signing.key,
            link_id: signing.link_id,
            last_ts: 0,
        }
    }

    /// Turn one unsigned MAVLink 2 frame (as `mavlink::write_versioned_msg` writes it) into
    /// a signed one in place: set the flag, recompute the CRC (it covers the flags), append
    /// link id, timestamp and signature. A MAVLink 1 frame, an already signed one, or bytes
    /// that are not one whole frame are left as they are (false).
    pub fn sign(&mut self, frame: &mut Vec<u8>) -> bool {
        if frame.len() < V2_HEADER + 2 || frame[0] != STX_V2 || frame[2] & IFLAG_SIGNED != 0 {
            return false;
        }
        let crc_at = V2_HEADER + frame[1] as usize;
        if frame.len() != crc_at + 2 {
            return false;
        }
        let id = u32::from_le_bytes([frame[7], frame[8], frame[9], 0]);
        let Some(extra) = crate::source::frame::crc_extra(id) else {
            return false;
        };
        frame[2] |= IFLAG_SIGNED;
        let crc = crc16(&frame[1..crc_at], extra);
        frame[crc_at..crc_at + 2].copy_from_slice(&crc.to_le_bytes());
        let ts = now_10us().max(self.last_ts + 1);
        self.last_ts = ts;
        let m = mac(&self.key, frame, self.link_id, ts);
        frame.push(self.link_id);
        frame.extend_from_slice(&ts.to_le_bytes()[..6]);
        frame.extend_from_slice(&m);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signing(require: bool) -> Signing {
        Signing {
            key: core::array::from_fn(|i| i as u8),
            require,
            link_id: 7,
        }
    }

    fn heartbeat_v2(seq: u8) -> Vec<u8> {
        let msg = crate::MavMessage::HEARTBEAT(crate::dialect::HEARTBEAT_DATA::default());
        let h = mavlink::MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: seq,
        };
        let mut out = Vec::new();
        mavlink::write_versioned_msg(&mut out, mavlink::MavlinkVersion::V2, h, &msg).unwrap();
        out
    }

    #[test]
    fn keys_read_as_raw_hex_or_base64() {
        let key: [u8; 32] = core::array::from_fn(|i| (i * 7) as u8);
        let hex: String = key.iter().map(|b| format!("{b:02x}")).collect();
        // base64 of the same key, as Python's base64.b64encode writes it.
        let b64 = "AAcOFRwjKjE4P0ZNVFtiaXB3foWMk5qhqK+2vcTL0tk=";
        assert_eq!(parse_key(&key).unwrap(), key);
        assert_eq!(parse_key(format!("{hex}\n").as_bytes()).unwrap(), key);
        assert_eq!(parse_key(b64.as_bytes()).unwrap(), key);
        assert_eq!(
            parse_key(b64.trim_end_matches('=').as_bytes()).unwrap(),
            key
        );
        assert!(parse_key(b"too short").unwrap_err().contains("32"));
        assert!(parse_key(&[0xff; 33]).unwrap_err().contains("33 bytes"));
    }

    /// The base64 a key file may hold, as lenient as the hand-written reader was: padding
    /// optional (any amount), unused trailing bits ignored; a length that cannot be base64
    /// or a character outside the standard alphabet is refused.
    #[test]
    fn base64_keys_read_leniently_and_nothing_else() {
        assert_eq!(base64_decode("QQ"), Some(b"A".to_vec()));
        assert_eq!(base64_decode("QQ=="), Some(b"A".to_vec()));
        assert_eq!(base64_decode("QQ===="), Some(b"A".to_vec()));
        assert_eq!(base64_decode("QR=="), Some(b"A".to_vec()), "trailing bits");
        assert_eq!(base64_decode("+/8"), Some(vec![0xfb, 0xff]));
        assert_eq!(base64_decode(""), Some(vec![]));
        for bad in ["Q", "QUJDR", "Q Q=", "-_8", "QQ=A"] {
            assert_eq!(base64_decode(bad), None, "{bad}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_key_file_others_can_read_is_refused() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("key");
        std::fs::write(&p, [3u8; 32]).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o644)).unwrap();
        let e = read_key_file(&p).unwrap_err();
        assert!(e.contains("chmod 600") && e.contains("644"), "{e}");
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(read_key_file(&p).unwrap(), [3u8; 32]);
    }

    #[test]
    fn what_the_signer_signs_the_verifier_accepts_once() {
        let mut signer = Signer::new(&signing(false));
        let mut v = Verifier::new(signing(true));
        let mut f = heartbeat_v2(0);
        assert!(signer.sign(&mut f));
        assert_eq!(f[2] & IFLAG_SIGNED, IFLAG_SIGNED);
        assert_eq!(f[f.len() - 13], 7, "link id");
        assert_eq!(v.check(&f), Verdict::Signed);
        assert_eq!(v.check(&f), Verdict::Replay, "the same frame again");
        let mut g = heartbeat_v2(1);
        assert!(signer.sign(&mut g));
        assert_eq!(v.check(&g), Verdict::Signed);
        // One flipped payload byte (CRC fixed up, as an attacker without the key would).
        let mut h = heartbeat_v2(2);
        signer.sign(&mut h);
        h[V2_HEADER] ^= 1;
        assert_eq!(v.check(&h), Verdict::BadSignature);
        assert_eq!(v.check(&heartbeat_v2(3)), Verdict::UnsignedRefused);
        let mut open = Verifier::new(signing(false));
        assert_eq!(open.check(&heartbeat_v2(3)), Verdict::Unsigned);
    }

    #[test]
    fn a_new_stream_more_than_a_minute_old_is_a_replay() {
        let now = 1_000_000_000;
        let mut v = Verifier::starting_at(signing(false), now);
        let key = signing(false).key;
        let frame_at = |ts: u64| {
            let mut f = heartbeat_v2(0);
            // now_10us() is far above the test's clock: sign with an explicit timestamp.
            let crc_at = f.len() - 2;
            f[2] |= IFLAG_SIGNED;
            let crc = crc16(&f[1..crc_at], crate::source::frame::crc_extra(0).unwrap());
            f[crc_at..].copy_from_slice(&crc.to_le_bytes());
            let m = mac(&key, &f, 1, ts);
            f.push(1);
            f.extend_from_slice(&ts.to_le_bytes()[..6]);
            f.extend_from_slice(&m);
            f
        };
        assert_eq!(
            v.check(&frame_at(now - REPLAY_WINDOW_10US - 1)),
            Verdict::Replay
        );
        assert_eq!(
            v.check(&frame_at(now - REPLAY_WINDOW_10US + 5)),
            Verdict::Signed
        );
        assert_eq!(
            v.check(&frame_at(now - REPLAY_WINDOW_10US + 5)),
            Verdict::Replay
        );
        assert_eq!(v.check(&frame_at(now + 10)), Verdict::Signed);
    }
}
