//! The JSON lines' `window` line, written by hand: byte for byte what serde_json writes for
//! the derived struct it replaced (kept in the tests, which compare the two), without
//! serde_json escaping each of its 24 fixed keys at every report. Every report writes one;
//! serialising them through serde was about a third of the JSON sink's CPU in a flat-out
//! 250-vehicle replay (issue 47).
//!
//! ```text
//! {"type":"window","system_id":…,["network":…,]"t":…,"measured_w":…,"features":{"wind_speed":…,…}}
//! ```
//!
//! Numbers go through serde_json's own formatter (the same shortest round-trip digits); a
//! NaN or infinity is `null`, as serde_json writes it.

use std::io::{self, Write};

use serde_json::ser::{CompactFormatter, Formatter};

use crate::features::{FEATURE_NAMES, N_FEATURES};
use crate::report::{Report, VehicleId};

/// Each feature's `"name":`, written once (the names are plain identifiers: nothing to
/// escape, checked by the tests).
fn keys() -> &'static [String; N_FEATURES] {
    static KEYS: std::sync::OnceLock<[String; N_FEATURES]> = std::sync::OnceLock::new();
    KEYS.get_or_init(|| FEATURE_NAMES.map(|n| format!("\"{n}\":")))
}

/// Write report `r`'s `window` line.
pub(super) fn write_window(w: &mut impl Write, r: &Report) -> io::Result<()> {
    let e = &r.estimate;
    w.write_all(b"{\"type\":\"window\",")?;
    head(w, r.vehicle)?;
    w.write_all(b",\"t\":")?;
    f64_or_null(w, e.t_s)?;
    w.write_all(b",\"measured_w\":")?;
    match e.sample.measured_w {
        Some(v) => f32_or_null(w, v)?,
        None => w.write_all(b"null")?,
    }
    w.write_all(b",\"features\":{")?;
    for (i, (key, &v)) in keys().iter().zip(&e.sample.features).enumerate() {
        if i > 0 {
            w.write_all(b",")?;
        }
        w.write_all(key.as_bytes())?;
        f32_or_null(w, v)?;
    }
    w.write_all(b"}}\n")
}

/// `"system_id":N`, and `,"network":N` where the links are separate networks.
pub(super) fn head<W: Write>(w: &mut W, vehicle: VehicleId) -> io::Result<()> {
    w.write_all(b"\"system_id\":")?;
    CompactFormatter.write_u8(w, vehicle.system_id)?;
    if let Some(n) = vehicle.network_field() {
        w.write_all(b",\"network\":")?;
        CompactFormatter.write_u8(w, n)?;
    }
    Ok(())
}

pub(super) fn f32_or_null<W: Write>(w: &mut W, v: f32) -> io::Result<()> {
    if v.is_finite() {
        CompactFormatter.write_f32(w, v)
    } else {
        w.write_all(b"null")
    }
}

pub(super) fn f64_or_null<W: Write>(w: &mut W, v: f64) -> io::Result<()> {
    if v.is_finite() {
        CompactFormatter.write_f64(w, v)
    } else {
        w.write_all(b"null")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::Sample;
    use crate::report::{Estimate, Report};
    use serde::ser::{SerializeMap, Serializer};
    use serde::Serialize;

    use crate::sink::jsonl::Head;

    /// The derived line the hand-written one replaced, as it was.
    #[derive(Serialize)]
    struct WindowLine<'a> {
        #[serde(flatten)]
        head: Head,
        t: f64,
        measured_w: Option<f32>,
        features: Features<'a>,
    }

    struct Features<'a>(&'a [f32; N_FEATURES]);

    impl Serialize for Features<'_> {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            let mut m = s.serialize_map(Some(FEATURE_NAMES.len()))?;
            for (name, v) in FEATURE_NAMES.iter().zip(self.0) {
                m.serialize_entry(name, v)?;
            }
            m.end()
        }
    }

    fn by_serde(r: &Report) -> Vec<u8> {
        let e = &r.estimate;
        let mut out = serde_json::to_vec(&WindowLine {
            head: Head::new("window", r.vehicle),
            t: e.t_s,
            measured_w: e.sample.measured_w,
            features: Features(&e.sample.features),
        })
        .unwrap();
        out.push(b'\n');
        out
    }

    fn report(
        t_s: f64,
        features: [f32; N_FEATURES],
        measured_w: Option<f32>,
        vehicle: VehicleId,
    ) -> Report {
        Report {
            estimate: Estimate {
                arrived: None,
                t_s,
                sample: Sample::new(t_s, features, measured_w),
                models: Vec::new(),
            },
            energy: Default::default(),
            alerts: Vec::new(),
            vehicle,
        }
    }

    #[test]
    fn the_feature_names_need_no_escaping() {
        for (n, key) in FEATURE_NAMES.iter().zip(keys()) {
            assert_eq!(format!("{}:", serde_json::to_string(n).unwrap()), *key);
        }
    }

    /// Any float: the bit patterns of every sign, exponent and mantissa, NaN and infinity.
    fn any_f32() -> impl proptest::strategy::Strategy<Value = f32> {
        proptest::num::u32::ANY.prop_map(f32::from_bits)
    }
    use proptest::strategy::Strategy;

    proptest::proptest! {
        #[test]
        fn the_line_is_byte_for_byte_what_serde_wrote(
            t_bits in proptest::num::u64::ANY,
            t_plain in -1e6f64..1e9,
            plain_t in proptest::bool::ANY,
            features in proptest::collection::vec(any_f32(), N_FEATURES),
            measured in proptest::option::of(any_f32()),
            system_id in 0u8..=255,
            network in 0u8..=255,
        ) {
            let t = if plain_t { t_plain } else { f64::from_bits(t_bits) };
            let features: [f32; N_FEATURES] = features.try_into().unwrap();
            let r = report(t, features, measured, VehicleId { network, system_id });
            let mut out = Vec::new();
            write_window(&mut out, &r).unwrap();
            proptest::prop_assert_eq!(String::from_utf8(out).unwrap(), String::from_utf8(by_serde(&r)).unwrap());
        }
    }
}
