//! DataFlash records: the self-describing framing of ArduPilot's `.bin` log, read from
//! bytes in memory. Every record is `0xA3 0x95 TYPE` and a payload; type 128 (FMT, 89 bytes
//! in all) defines another type: its length, a 4-character name, one format character per
//! field and comma-separated labels. Only what a FMT defined is decoded, so logs of any
//! ArduPilot version read without a table of message definitions.
//!
//! Bad input never stops the reader: a FMT whose length does not match its fields (or
//! under 3 bytes) defines nothing, and bytes that are not a record of a defined type are
//! skipped to the next 0xA3 0x95 (counted in [`Reader::skipped`]). Our own code rather
//! than the `ardupilot-binlog` crate: fuzzing found that crate panicking (an integer
//! underflow on a FMT length under 3) within 2,000 inputs.

use std::collections::HashMap;
use std::sync::Arc;

use super::dataflash::{FMT_TYPE, MAGIC};

/// Bytes of a FMT record, header included.
const FMT_LEN: usize = 89;

/// A field's value.
#[derive(Debug, Clone, PartialEq)]
enum Value {
    Num(f64),
    Text(String),
    /// `a`: 32 × int16, kept out of the way (nothing dronewatt reads).
    Array,
}

/// One decoded record.
#[derive(Debug, Clone)]
pub struct Entry {
    /// The type's name from its FMT (`ATT`, `BAT`, …).
    pub name: String,
    /// Its time, µs: a first field labelled `TimeUS` (µs) or `TimeMS` (ms, before ArduPilot 3.3).
    pub timestamp_usec: Option<u64>,
    labels: Arc<[String]>,
    values: Vec<Value>,
}

impl Entry {
    /// The field labels, in order.
    pub fn labels(&self) -> &[String] {
        &self.labels
    }
    fn get(&self, label: &str) -> Option<&Value> {
        self.labels
            .iter()
            .position(|l| l == label)
            .and_then(|i| self.values.get(i))
    }
    /// A numeric field (the `c C e E` centi-units scaled to units, as ArduPilot means them).
    pub fn get_f64(&self, label: &str) -> Option<f64> {
        match self.get(label)? {
            Value::Num(v) => Some(*v),
            _ => None,
        }
    }
    /// A text field (`n N Z`), up to its first NUL.
    pub fn get_str(&self, label: &str) -> Option<&str> {
        match self.get(label)? {
            Value::Text(s) => Some(s),
            _ => None,
        }
    }
}

/// A type a FMT defined.
struct Format {
    name: String,
    /// Record length, header included.
    len: usize,
    types: Vec<u8>,
    labels: Arc<[String]>,
}

/// Bytes a field of this format character takes (`None`: not a DataFlash type).
fn field_size(c: u8) -> Option<usize> {
    Some(match c {
        b'b' | b'B' | b'M' => 1,
        b'h' | b'H' | b'c' | b'C' => 2,
        b'i' | b'I' | b'e' | b'E' | b'L' | b'f' | b'n' => 4,
        b'd' | b'q' | b'Q' => 8,
        b'N' => 16,
        b'Z' | b'a' => 64,
        _ => return None,
    })
}

fn text(b: &[u8]) -> String {
    let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
    String::from_utf8_lossy(&b[..end]).into_owned()
}

/// One field from exactly `field_size(c)` bytes.
fn value(c: u8, b: &[u8]) -> Value {
    let n = |i: usize| b[i];
    let i16_ = || f64::from(i16::from_le_bytes([n(0), n(1)]));
    let u16_ = || f64::from(u16::from_le_bytes([n(0), n(1)]));
    let i32_ = || f64::from(i32::from_le_bytes([n(0), n(1), n(2), n(3)]));
    let u32_ = || f64::from(u32::from_le_bytes([n(0), n(1), n(2), n(3)]));
    let b8 = || [n(0), n(1), n(2), n(3), n(4), n(5), n(6), n(7)];
    Value::Num(match c {
        b'b' => f64::from(n(0) as i8),
        b'B' | b'M' => f64::from(n(0)),
        b'h' => i16_(),
        b'H' => u16_(),
        b'c' => i16_() / 100.0,
        b'C' => u16_() / 100.0,
        b'i' | b'L' => i32_(),
        b'I' => u32_(),
        b'e' => i32_() / 100.0,
        b'E' => u32_() / 100.0,
        b'f' => f64::from(f32::from_le_bytes([n(0), n(1), n(2), n(3)])),
        b'd' => f64::from_le_bytes(b8()),
        b'q' => i64::from_le_bytes(b8()) as f64,
        b'Q' => u64::from_le_bytes(b8()) as f64,
        b'a' => return Value::Array,
        _ => return Value::Text(text(b)),
    })
}

/// The records of a DataFlash log in memory, in order.
pub struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    formats: HashMap<u8, Format>,
    /// Bytes skipped: not a record of a defined type, or a FMT that defined nothing.
    pub skipped: usize,
}

impl<'a> Reader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        Self {
            bytes,
            pos: 0,
            formats: HashMap::new(),
            skipped: 0,
        }
    }

    /// Skip `n` bytes, then on to the next record header.
    fn skip(&mut self, n: usize) {
        let from = (self.pos + n).min(self.bytes.len());
        let next = self.bytes[from..]
            .windows(2)
            .position(|w| w == MAGIC)
            .map_or(self.bytes.len(), |i| from + i);
        self.skipped += next - self.pos;
        self.pos = next;
    }

    /// Define a type from the FMT record at `self.pos` (whole: checked by the caller).
    fn define(&mut self) -> bool {
        let p = &self.bytes[self.pos + 3..self.pos + FMT_LEN];
        let (kind, len) = (p[0], usize::from(p[1]));
        let types: Vec<u8> = p[6..22].iter().copied().take_while(|&c| c != 0).collect();
        let sizes: Option<usize> = types.iter().map(|&c| field_size(c)).sum();
        if kind == FMT_TYPE || sizes.map(|s| s + 3) != Some(len) {
            return false;
        }
        let labels: Arc<[String]> = text(&p[22..86]).split(',').map(str::to_string).collect();
        self.formats.insert(
            kind,
            Format {
                name: text(&p[2..6]),
                len,
                types,
                labels,
            },
        );
        true
    }
}

impl Iterator for Reader<'_> {
    type Item = Entry;

    fn next(&mut self) -> Option<Entry> {
        loop {
            let rest = &self.bytes[self.pos..];
            if rest.len() < 3 {
                self.skipped += rest.len();
                self.pos = self.bytes.len();
                return None;
            }
            if rest[..2] != MAGIC {
                self.skip(0);
                continue;
            }
            if rest[2] == FMT_TYPE {
                if rest.len() < FMT_LEN {
                    self.skip(rest.len());
                } else if self.define() {
                    self.pos += FMT_LEN;
                } else {
                    self.skip(FMT_LEN);
                }
                continue;
            }
            let Some(f) = self.formats.get(&rest[2]).filter(|f| f.len <= rest.len()) else {
                self.skip(1);
                continue;
            };
            let mut values = Vec::with_capacity(f.types.len());
            let mut at = 3;
            for &c in &f.types {
                let n = field_size(c).unwrap_or(0);
                values.push(value(c, &rest[at..at + n]));
                at += n;
            }
            let first = |label: &str| f.labels.first().is_some_and(|l| l == label);
            let timestamp_usec = match values.first() {
                Some(Value::Num(v)) if first("TimeUS") && *v >= 0.0 => Some(*v as u64),
                Some(Value::Num(v)) if first("TimeMS") && *v >= 0.0 => {
                    Some((*v as u64).saturating_mul(1000))
                }
                _ => None,
            };
            let entry = Entry {
                name: f.name.clone(),
                timestamp_usec,
                labels: f.labels.clone(),
                values,
            };
            self.pos += f.len;
            return Some(entry);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fmt(kind: u8, len: u8, name: &str, format: &str, labels: &str) -> Vec<u8> {
        let mut r = vec![MAGIC[0], MAGIC[1], FMT_TYPE, kind, len];
        let pad = |s: &str, n: usize| {
            let mut v = s.as_bytes().to_vec();
            v.resize(n, 0);
            v
        };
        r.extend(pad(name, 4));
        r.extend(pad(format, 16));
        r.extend(pad(labels, 64));
        r
    }

    #[test]
    fn reads_what_a_fmt_defines_and_skips_the_rest() {
        let mut log = fmt(130, 3 + 8 + 4 + 2, "BAT", "QfC", "TimeUS,Volt,Curr");
        // A FMT whose length is under 3 (the crash the crate had) defines nothing.
        log.extend(fmt(131, 2, "BAD", "", ""));
        log.extend([0xA3, 0x95, 130]);
        log.extend(1_500_000u64.to_le_bytes());
        log.extend(12.5f32.to_le_bytes());
        log.extend(1234u16.to_le_bytes());
        log.extend([0xA3, 0x95, 131, 7, 7, 7]); // a type nothing defined: skipped
        log.extend([1, 2, 3]); // junk
        let mut r = Reader::new(&log);
        let e = r.next().expect("the BAT record");
        assert_eq!(
            (e.name.as_str(), e.timestamp_usec),
            ("BAT", Some(1_500_000))
        );
        assert_eq!(
            (e.get_f64("Volt"), e.get_f64("Curr"), e.get_f64("Nope")),
            (Some(12.5), Some(12.34), None)
        );
        assert!(r.next().is_none());
        assert_eq!(
            r.skipped,
            89 + 9,
            "the bad FMT, the undefined record and the junk"
        );
    }

    #[test]
    fn time_in_ms_is_scaled_and_a_truncated_record_ends_the_log() {
        let mut log = fmt(140, 3 + 4 + 4, "PARM", "In", "TimeMS,Name");
        log.extend([0xA3, 0x95, 140]);
        log.extend(2500u32.to_le_bytes());
        log.extend(*b"BATT");
        log.extend([0xA3, 0x95, 140, 1, 2]);
        let e: Vec<Entry> = Reader::new(&log).collect();
        assert_eq!(e.len(), 1);
        assert_eq!(
            (e[0].timestamp_usec, e[0].get_str("Name")),
            (Some(2_500_000), Some("BATT"))
        );
    }
}
