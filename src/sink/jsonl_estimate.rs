//! The JSON lines' `estimate` line ([`super::jsonl`]'s docs give its shape), written by
//! hand: byte for byte what serde_json wrote for the derived struct it replaced (kept in
//! `jsonl_estimate_tests.rs`, which compares the two), without serde_json escaping each of
//! its ~45 fixed keys at every report, nor the flattened pack's map machinery. With the
//! `window` line ([`super::jsonl_window`]) this was most of the JSON sink's CPU in a
//! flat-out 250-vehicle replay (issue 47).
//!
//! Numbers go through serde_json's own formatter (the same shortest round-trip digits), a
//! NaN or infinity as `null`; text is escaped as serde_json escapes it; the enums and
//! provenances still serialise through serde (few, short).

use std::io::{self, Write};

use serde_json::ser::{CompactFormatter, Formatter};

use super::jsonl_window::{f32_or_null, f64_or_null, head};
use crate::report::{ModelEstimate, PackState, Report};

/// Write report `r`'s `estimate` line.
pub(super) fn write_estimate(w: &mut impl Write, r: &Report) -> io::Result<()> {
    let (e, en, b) = (&r.estimate, &r.energy, &r.energy.battery);
    let kind = &e.sample.vehicle;
    w.write_all(b"{\"type\":\"estimate\",")?;
    head(w, r.vehicle)?;
    w.write_all(b",\"t\":")?;
    f64_or_null(w, e.t_s)?;
    w.write_all(b",\"vehicle_class\":")?;
    ser(w, &kind.class)?;
    if let Some(t) = kind.mav_type {
        w.write_all(b",\"mav_type\":")?;
        CompactFormatter.write_u8(w, t)?;
    }
    if kind.class == crate::features::VehicleClass::Vtol {
        w.write_all(b",\"vtol_state\":")?;
        text(w, kind.vtol_state.as_str())?;
    }
    w.write_all(b",\"measured_w\":")?;
    opt_f32(w, e.sample.measured_w)?;
    w.write_all(b",\"models\":")?;
    per_model(w, &e.models, |m| Some(m.power_w), f32_or_null)?;
    if e.models.iter().any(|m| m.band_w.is_some()) {
        w.write_all(b",\"bands\":")?;
        per_model(w, &e.models, |m| m.band_w.map(|(lo, hi)| [lo, hi]), band)?;
    }
    w.write_all(b",\"energy_used_wh\":")?;
    f64_or_null(w, en.energy_used_wh)?;
    w.write_all(b",\"remaining_wh\":")?;
    opt_f64(w, en.remaining_wh)?;
    w.write_all(b",\"remaining_pct\":")?;
    opt_f64(w, en.remaining_pct)?;
    w.write_all(b",\"remaining_source\":")?;
    ser(w, &en.remaining_source)?;
    w.write_all(b",\"time_to_empty_s\":")?;
    opt_f64(w, en.time_to_empty_s)?;
    w.write_all(b",\"home_margin_wh\":")?;
    opt_f64(w, en.home_margin_wh)?;
    if let Some(v) = en.mission_energy_wh {
        w.write_all(b",\"mission_energy_wh\":")?;
        f64_or_null(w, v)?;
    }
    if let Some(v) = en.mission_margin_wh {
        w.write_all(b",\"mission_margin_wh\":")?;
        f64_or_null(w, v)?;
    }
    if e.models.iter().any(|m| m.adapted_w.is_some()) {
        w.write_all(b",\"adapted\":")?;
        per_model(w, &e.models, |m| m.adapted_w, f32_or_null)?;
    }
    w.write_all(b",\"forecast_adapted\":")?;
    CompactFormatter.write_bool(w, en.forecast_adapted)?;
    w.write_all(b",\"forecast_model\":")?;
    opt_text(w, en.forecast_model.as_deref())?;
    w.write_all(b",\"forecast_why\":")?;
    opt_text(w, en.forecast_why.as_deref())?;
    if let Some(h) = &en.hover_calibration {
        w.write_all(b",\"hover_calibration\":")?;
        ser(w, h)?;
    }
    // Not known: null, and the source says why (never another vehicle's pack).
    w.write_all(b",\"capacity_wh\":")?;
    opt_f64(w, b.capacity())?;
    w.write_all(b",\"capacity_source\":")?;
    text(w, &b.capacity_source())?;
    w.write_all(b",\"cell_count\":")?;
    CompactFormatter.write_u32(w, b.cell_count.value)?;
    w.write_all(b",\"cell_count_source\":")?;
    ser(w, &b.cell_count.source)?;
    w.write_all(b",\"chemistry\":")?;
    text(w, &b.chemistry.value)?;
    w.write_all(b",\"chemistry_source\":")?;
    ser(w, &b.chemistry.source)?;
    pack(w, &en.pack)?;
    if let Some(v) = &b.low_voltage_v {
        w.write_all(b",\"low_voltage_v\":")?;
        f64_or_null(w, v.value)?;
        w.write_all(b",\"low_voltage_source\":")?;
        ser(w, &v.source)?;
    }
    if let Some(v) = &b.critical_voltage_v {
        w.write_all(b",\"critical_voltage_v\":")?;
        f64_or_null(w, v.value)?;
        w.write_all(b",\"critical_voltage_source\":")?;
        ser(w, &v.source)?;
    }
    w.write_all(b"}\n")
}

/// The pack model's fields, flat in the line (`PackState`'s own serde order and skips).
fn pack(w: &mut impl Write, p: &PackState) -> io::Result<()> {
    opt_figures(
        w,
        &[
            (b",\"battery_v\":", p.battery_v),
            (b",\"battery_v_model\":", p.battery_v_model),
            (b",\"battery_ocv_v\":", p.battery_ocv_v),
            (b",\"battery_rest_v\":", p.battery_rest_v),
            (b",\"soc_pct\":", p.soc_pct),
            (b",\"soc_band_pct\":", p.soc_band_pct),
        ],
    )?;
    w.write_all(b",\"pack_start\":")?;
    opt_text(w, p.pack_start)?;
    w.write_all(b",\"pack_withheld\":")?;
    opt_text(w, p.pack_withheld)?;
    opt_figures(
        w,
        &[
            (b",\"internal_r_ohm\":", p.internal_r_ohm),
            (b",\"v_min_forecast_v\":", p.v_min_forecast_v),
            (b",\"v_min_forecast_at_s\":", p.v_min_forecast_at_s),
            (b",\"time_to_low_v_s\":", p.time_to_low_v_s),
            (b",\"low_threshold_v\":", p.low_threshold_v),
        ],
    )?;
    if let Some(v) = p.battery_pct_disagreement {
        w.write_all(b",\"battery_pct_disagreement\":")?;
        f64_or_null(w, v)?;
    }
    opt_figures(
        w,
        &[
            (b",\"battery_end_rest_v\":", p.battery_end_rest_v),
            (b",\"pack_r_scale\":", p.pack_r_scale),
        ],
    )?;
    w.write_all(b",\"pack_carried_over\":")?;
    CompactFormatter.write_bool(w, p.pack_carried_over)
}

/// One figure of each model as a name → value object, leaving out the models that lack it.
fn per_model<W: Write, T>(
    w: &mut W,
    models: &[ModelEstimate],
    figure: fn(&ModelEstimate) -> Option<T>,
    write: fn(&mut W, T) -> io::Result<()>,
) -> io::Result<()> {
    w.write_all(b"{")?;
    let mut first = true;
    for m in models {
        if let Some(v) = figure(m) {
            if !first {
                w.write_all(b",")?;
            }
            first = false;
            text(w, &m.name)?;
            w.write_all(b":")?;
            write(w, v)?;
        }
    }
    w.write_all(b"}")
}

fn band<W: Write>(w: &mut W, [lo, hi]: [f32; 2]) -> io::Result<()> {
    w.write_all(b"[")?;
    f32_or_null(w, lo)?;
    w.write_all(b",")?;
    f32_or_null(w, hi)?;
    w.write_all(b"]")
}

fn opt_f32(w: &mut impl Write, v: Option<f32>) -> io::Result<()> {
    match v {
        Some(v) => f32_or_null(w, v),
        None => w.write_all(b"null"),
    }
}

fn opt_f64(w: &mut impl Write, v: Option<f64>) -> io::Result<()> {
    match v {
        Some(v) => f64_or_null(w, v),
        None => w.write_all(b"null"),
    }
}

/// Each `(key, figure)` in turn: the key's bytes (`,"name":`), then the figure or `null`.
fn opt_figures(w: &mut impl Write, figures: &[(&[u8], Option<f64>)]) -> io::Result<()> {
    for (key, v) in figures {
        w.write_all(key)?;
        opt_f64(w, *v)?;
    }
    Ok(())
}

fn opt_text(w: &mut impl Write, s: Option<&str>) -> io::Result<()> {
    match s {
        Some(s) => text(w, s),
        None => w.write_all(b"null"),
    }
}

/// A JSON string as serde_json writes it: as is between quotes when nothing in it needs
/// escaping (no control character, quote or backslash), else through serde_json.
fn text(w: &mut impl Write, s: &str) -> io::Result<()> {
    if s.bytes().all(|c| c >= 0x20 && c != b'"' && c != b'\\') {
        w.write_all(b"\"")?;
        w.write_all(s.as_bytes())?;
        w.write_all(b"\"")
    } else {
        ser(w, s)
    }
}

fn ser(w: &mut impl Write, v: &(impl serde::Serialize + ?Sized)) -> io::Result<()> {
    serde_json::to_writer(w, v).map_err(io::Error::from)
}

#[cfg(test)]
#[path = "jsonl_estimate_tests.rs"]
mod tests;
