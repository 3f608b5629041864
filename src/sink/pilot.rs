//! What a pilot must act on, worked out once for every view: the terminal's plain line
//! ([`fn@line`], at most [`MAX_LINE`] characters), the screen's first tiles and the dashboard's
//! banner and cards ([`PilotView`]). Every model's figures stay behind `--detail` (the
//! line) and the dashboard's toggle.
//!
//! **One percentage.** The state of charge a view shows is [`EnergyState::remaining_pct`]:
//! the usable energy left (down to the low-voltage floor under load) as a share of the
//! pack, the same figure the `below_reserve` alert compares with, named with its source
//! ([`charge_source`]). The pack model's open-circuit state of charge (`soc_pct` in the
//! JSON, which counts energy below the floor too) is an engineer's figure: `--detail` and
//! the dashboard's detail show it, labelled "OCV".
//!
//! ```text
//! 241 W  31 % 32.3 Wh (resting voltage)  12 min to low V  22.8 V min 21.4 V  mission +4.2 Wh  CRITICAL below_reserve
//! ```

use crossterm::style::Stylize;
use serde::Serialize;

use crate::report::{EnergyState, RemainingSource, Report, Severity};

/// The plain line's most characters (colour codes not counted).
pub const MAX_LINE: usize = 120;

/// Where the state of charge comes from, in words: the same on every view.
/// Each at most 18 characters, so a tile of an 80-column screen holds it whole.
pub fn charge_source(e: &EnergyState) -> &'static str {
    match e.remaining_source {
        RemainingSource::AssumedFull => "assumed full",
        RemainingSource::Battery => "autopilot %",
        RemainingSource::RestingVoltage => "resting voltage",
        RemainingSource::LoadCompensated => "voltage under load",
        RemainingSource::ModelPower => "model power",
        RemainingSource::UnknownPack if e.remaining_pct.is_some() => "voltage only",
        RemainingSource::UnknownPack => "capacity not known",
    }
}

/// The figures a pilot needs, for one vehicle: what the dashboard's banner and first cards
/// and the screen's first tiles show.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PilotView {
    /// Power now, W: measured, else the forecast power.
    pub power_w: Option<f64>,
    /// Whether `power_w` was measured (else it is the forecast's).
    pub power_measured: bool,
    /// The state of charge, % ([`EnergyState::remaining_pct`]).
    pub charge_pct: Option<f64>,
    /// The usable energy left, Wh.
    pub charge_wh: Option<f64>,
    /// Where the state of charge comes from ([`charge_source`]).
    pub charge_source: &'static str,
    /// Time to the first of empty and the low voltage, s.
    pub time_left_s: Option<f64>,
    /// What `time_left_s` runs to: `low voltage` or `empty`.
    pub time_left_to: Option<&'static str>,
    /// The pack's voltage now, V.
    pub voltage_v: Option<f64>,
    /// The lowest loaded voltage forecast for the rest of the flight, V.
    pub v_min_forecast_v: Option<f64>,
    /// The low threshold the forecast is held against, V.
    pub low_threshold_v: Option<f64>,
    /// The mission margin over the reserve, Wh, while a mission is known.
    pub mission_margin_wh: Option<f64>,
    /// The home margin over the reserve, Wh, while a home is known.
    pub home_margin_wh: Option<f64>,
    /// The most severe alert standing.
    pub worst: Option<WorstAlert>,
}

/// The most severe alert standing on a vehicle.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorstAlert {
    pub rule: String,
    pub severity: Severity,
    /// The alert's sentence as it was raised (its figures those of that moment).
    pub message: String,
    /// When it was raised, s (the source's clock), where known.
    pub t: Option<f64>,
}

/// Whether a severity calls for the pilot to act now (a red banner, bold red text).
pub fn is_critical(s: Severity) -> bool {
    s <= Severity::Error
}

/// Time to the first of empty and the low voltage, and which it is.
pub fn time_left(e: &EnergyState) -> Option<(f64, &'static str)> {
    let finite = |v: Option<f64>| v.filter(|v| v.is_finite());
    match (finite(e.pack.time_to_low_v_s), finite(e.time_to_empty_s)) {
        (Some(low), Some(empty)) if empty < low => Some((empty, "empty")),
        (Some(low), _) => Some((low, "low voltage")),
        (None, Some(empty)) => Some((empty, "empty")),
        (None, None) => None,
    }
}

impl PilotView {
    /// The view of one report, with the most severe alert standing.
    pub fn of(r: &Report, worst: Option<WorstAlert>) -> Self {
        let e = &r.energy;
        let measured = r.estimate.sample.measured_w.map(f64::from);
        let tl = time_left(e);
        Self {
            power_w: measured.or(e.forecast_w).filter(|w| w.is_finite()),
            power_measured: measured.is_some(),
            charge_pct: e.remaining_pct.filter(|p| p.is_finite()),
            charge_wh: e.remaining_wh.filter(|w| w.is_finite()),
            charge_source: charge_source(e),
            time_left_s: tl.map(|t| t.0),
            time_left_to: tl.map(|t| t.1),
            voltage_v: e.pack.battery_v,
            v_min_forecast_v: e.pack.v_min_forecast_v,
            low_threshold_v: e.pack.low_threshold_v,
            mission_margin_wh: e.mission_margin_wh,
            home_margin_wh: e.home_margin_wh,
            worst,
        }
    }
}

/// The most severe of `active` (rule → severity), with its message and the time it was
/// raised from `raised` where known.
pub fn worst_of<'a>(
    active: impl IntoIterator<Item = (&'a String, &'a Severity)>,
    raised: impl Fn(&str) -> Option<(String, f64)>,
) -> Option<WorstAlert> {
    // Severity orders most severe first.
    let (rule, &severity) = active.into_iter().min_by_key(|(_, &s)| s)?;
    let (message, t) = raised(rule).map_or((String::new(), None), |(m, t)| (m, Some(t)));
    Some(WorstAlert {
        rule: rule.clone(),
        severity,
        message,
        t,
    })
}

/// A number, or `?` for NaN/infinity.
fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "?".into()
    }
}

/// `12 min`, or `45 s` under two minutes.
pub fn short_duration(s: f64) -> String {
    if !s.is_finite() {
        return "?".into();
    }
    let s = s.max(0.0);
    if s < 120.0 {
        format!("{} s", s.round())
    } else {
        format!("{} min", (s / 60.0).round())
    }
}

fn signed(v: f64) -> String {
    format!("{}{}", if v >= 0.0 { "+" } else { "" }, num(v, 1))
}

/// How a piece of the line is coloured on a terminal.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Tone {
    Plain,
    Bad,
    Warn,
}

/// The plain line: power; the state of charge and its source; the time to the first of
/// empty and low voltage; the voltage now and its forecast minimum; the mission margin
/// (else the home margin); the worst alert standing (or the link's silence). At most
/// [`MAX_LINE`] characters: the least needed parts shorten first, the alert last.
pub fn line(r: Option<&Report>, worst: Option<&WorstAlert>, silent: bool, colour: bool) -> String {
    let mut parts: Vec<(String, Tone)> = Vec::new();
    let alert = match (worst, silent) {
        (_, true) => Some(("SILENT: no telemetry".to_string(), Tone::Bad)),
        (Some(w), _) => Some((
            format!("{} {}", w.severity.name().to_uppercase(), w.rule),
            if is_critical(w.severity) {
                Tone::Bad
            } else {
                Tone::Warn
            },
        )),
        (None, false) => None,
    };
    let Some(r) = r else {
        parts.push(("waiting for the first window".into(), Tone::Plain));
        parts.extend(alert);
        return finish(parts, None, colour);
    };
    let v = PilotView::of(r, worst.cloned());
    parts.push(match v.power_w {
        Some(w) if v.power_measured => (format!("{} W", num(w, 0)), Tone::Plain),
        Some(w) => (format!("~{} W est", num(w, 0)), Tone::Plain),
        None => ("— W".into(), Tone::Plain),
    });
    let (charge, shorter) = match (v.charge_pct, v.charge_wh) {
        (Some(p), Some(wh)) => (
            format!("{} % {} Wh ({})", num(p, 0), num(wh, 1), v.charge_source),
            Some(format!("{} % ({})", num(p, 0), v.charge_source)),
        ),
        (Some(p), None) => (format!("{} % ({})", num(p, 0), v.charge_source), None),
        (None, Some(wh)) => (format!("{} Wh ({})", num(wh, 1), v.charge_source), None),
        (None, None) => (format!("charge — ({})", v.charge_source), None),
    };
    parts.push((charge, Tone::Plain));
    // Where the line is too long, the Wh give way first (the % and its source stay).
    let first_cut = shorter.map(|s| (parts.len() - 1, s));
    if let Some((t, to)) = time_left(&r.energy) {
        let to = if to == "low voltage" { "low V" } else { to };
        parts.push((format!("{} to {to}", short_duration(t)), Tone::Plain));
    }
    if let Some(volts) = v.voltage_v {
        let mut s = format!("{} V", num(volts, 1));
        let mut tone = Tone::Plain;
        if let Some(lo) = v.v_min_forecast_v {
            s.push_str(&format!(" min {} V", num(lo, 1)));
            if v.low_threshold_v.is_some_and(|th| lo < th) {
                tone = Tone::Bad;
            }
        }
        parts.push((s, tone));
    }
    let margin = match (v.mission_margin_wh, v.home_margin_wh) {
        (Some(m), _) => Some(("mission", m)),
        (None, Some(h)) => Some(("home", h)),
        _ => None,
    };
    if let Some((what, m)) = margin {
        let tone = if m < 0.0 { Tone::Bad } else { Tone::Plain };
        parts.push((format!("{what} {} Wh", signed(m)), tone));
    }
    parts.extend(alert);
    finish(parts, first_cut, colour)
}

/// Join the parts, shortened to [`MAX_LINE`], then coloured. `first_cut` (a part and a
/// shorter text for it) gives way first; then the longest part is cut, the alert (the last
/// part) never under 24 characters.
fn finish(
    mut parts: Vec<(String, Tone)>,
    first_cut: Option<(usize, String)>,
    colour: bool,
) -> String {
    const SEP: &str = "  ";
    let len = |p: &[(String, Tone)]| {
        p.iter().map(|(s, _)| s.chars().count()).sum::<usize>()
            + SEP.len() * p.len().saturating_sub(1)
    };
    if let Some((i, shorter)) = first_cut {
        if len(&parts) > MAX_LINE {
            parts[i].0 = shorter;
        }
    }
    while len(&parts) > MAX_LINE {
        let over = len(&parts) - MAX_LINE;
        let last = parts.len() - 1;
        // The longest part gives way (the alert only down to 24 characters).
        let Some((i, _)) = parts
            .iter()
            .enumerate()
            .filter(|(i, (s, _))| s.chars().count() > if *i == last { 24 } else { 8 })
            .max_by_key(|(_, (s, _))| s.chars().count())
        else {
            break;
        };
        let s = &mut parts[i].0;
        let keep = s
            .chars()
            .count()
            .saturating_sub(over + 1)
            .max(if i == last { 23 } else { 7 });
        *s = s.chars().take(keep).chain(std::iter::once('…')).collect();
    }
    let mut out = String::new();
    for (k, (s, tone)) in parts.into_iter().enumerate() {
        if k > 0 {
            out.push_str(SEP);
        }
        out.push_str(&match (colour, tone) {
            (true, Tone::Bad) => s.red().bold().to_string(),
            (true, Tone::Warn) => s.yellow().to_string(),
            _ => s,
        });
    }
    out
}

#[cfg(test)]
#[path = "pilot_tests.rs"]
mod tests;
