//! The live terminal view: one status line a second on stderr, alert events the moment
//! they come, and a closing line with the run's counters. Colour when stderr is a terminal.
//!
//! The status line is the pilot's ([`super::pilot::line`], at most 120 characters): power,
//! the state of charge and its source, the time to the first of empty and low voltage, the
//! voltage and its forecast minimum, the mission margin, the worst alert standing.
//!
//! ```text
//! 242 W  31 % 32.3 Wh (resting voltage)  12 min to low V  22.8 V min 21.4 V  mission +4.2 Wh  CRITICAL below_reserve
//! ```
//!
//! With `--detail`, the engineer's line instead (every model's raw~adapted estimate, the
//! energy's bookkeeping, the pack model, link health, stale features), and which message
//! feeds each signal whenever that changes:
//!
//! ```text
//! t 312.4 s  multirotor  measured 241.7 W  dandrea 236.0  lstm 244.1~241.0  used 12.80 Wh  left 88.1 Wh 68 % [capacity 130.0 Wh: …; resting voltage] (21 min on lstm~)  home +31.2 Wh  link 52 msg/s ok 16211 bad 2 unk 0 gaps 3  stale: wind_speed
//! ```
//!
//! With more than one vehicle on the link, the status line becomes a fleet view: one row
//! per vehicle (the newest report's power, remaining energy, time to empty, home margin
//! and the most severe alert standing), under the link's line. Alert lines name the vehicle.
//!
//! ```text
//! fleet: 2 vehicles  link 104 msg/s ok 9120 bad 0 unk 0 gaps 0
//!  vehicle   power W  left Wh  to empty  home Wh  worst alert
//!        1     241.7     88.1    21 min    +31.2  —
//!        2     198.0     60.3    18 min     -2.1  home_margin (critical)
//! ```

use std::collections::BTreeMap;
use std::io::{IsTerminal, Write};
use std::sync::atomic::Ordering::Relaxed;
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::ReportRx;
use crate::report::status::{ChainStatus, IngestStats, SignalHealth};
use crate::report::{AlertEvent, AlertState, Report, Severity};
use crossterm::style::Stylize;

/// Run the view until the report channel closes; `detail`: the engineer's line
/// ([`detail_line`]) instead of the pilot's.
pub async fn run(mut rx: ReportRx, status: ChainStatus, detail: bool) -> anyhow::Result<()> {
    let ChainStatus {
        stats,
        health,
        latency,
        ..
    } = status;
    let colour = std::io::stderr().is_terminal();
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    tick.tick().await; // the first tick is immediate: nothing to show yet
                       // The newest report and the alerts standing, per vehicle.
    let mut fleet: BTreeMap<crate::report::VehicleId, (Arc<Report>, BTreeMap<String, Severity>)> =
        BTreeMap::new();
    let mut last = (Instant::now(), 0u64);
    let mut feeds_shown = String::new();
    loop {
        tokio::select! {
            r = rx.next() => match r {
                Some(r) => {
                    let many = fleet.len() > 1 || fleet.keys().any(|&id| id != r.vehicle);
                    for a in &r.alerts {
                        let line = alert_line(a, colour);
                        if many { eprintln!("vehicle {}: {line}", r.vehicle) } else { eprintln!("{line}") }
                    }
                    if r.alerts.iter().any(|a| a.rule == "vehicle_dropped" && a.state == AlertState::Raised) {
                        fleet.remove(&r.vehicle);
                        continue;
                    }
                    let entry = fleet.entry(r.vehicle).or_insert_with(|| (r.clone(), BTreeMap::new()));
                    for a in &r.alerts {
                        match a.state {
                            AlertState::Raised => entry.1.insert(a.rule.clone(), a.severity),
                            AlertState::Cleared => entry.1.remove(&a.rule),
                        };
                    }
                    entry.0 = r;
                }
                None => break,
            },
            _ = tick.tick() => {
                let ok = stats.frames_ok.load(Relaxed);
                let rate = ok.saturating_sub(last.1) as f64 / last.0.elapsed().as_secs_f64().max(1e-3);
                last = (Instant::now(), ok);
                let mut e = std::io::stderr().lock();
                if fleet.len() > 1 {
                    let _ = writeln!(e, "{}", fleet_view(&fleet, &stats, rate, colour));
                    continue;
                }
                let one = fleet.values().next();
                let line = status_line(one.map(|(r, a)| (&**r, a)), &stats, rate, colour, detail);
                // Which message feeds each signal (with --detail): said once, and again
                // whenever it changes (a better source appeared, or one went quiet and a
                // fallback took over).
                let feeds = health.lock().map(|h| feeds_line(&h)).unwrap_or_default();
                if detail && !feeds.is_empty() && feeds != feeds_shown {
                    let _ = writeln!(e, "{feeds}");
                    feeds_shown = feeds;
                }
                let _ = writeln!(e, "{line}");
            }
        }
    }
    print_summary(&stats, rx.missed(), "the terminal view", &latency);
    for (id, (r, _)) in &fleet {
        eprintln!(
            "      vehicle {id}: {}",
            r.estimate.sample.vehicle.describe()
        );
    }
    Ok(())
}

/// The closing lines on stderr: the run's counters (and the reports `view` missed), then
/// the message → estimate latency.
pub fn print_summary(
    stats: &IngestStats,
    missed: u64,
    view: &str,
    latency: &crate::report::status::LatencyHistogram,
) {
    let s = stats.snapshot();
    eprintln!(
        "done: frames ok {} bad {} unknown {} gaps {} (clock jumps {}) junk bytes {} windows {}{}",
        s.frames_ok,
        s.frames_bad,
        s.unknown,
        s.gaps,
        s.clock_jumps,
        s.junk_bytes,
        s.windows,
        if missed > 0 {
            format!(", {missed} reports missed by {view}")
        } else {
            String::new()
        }
    );
    for l in stats.links() {
        eprintln!(
            "      link {}: frames {} (copies {}), last heard {}",
            l.name,
            l.frames,
            l.duplicates,
            l.last_heard_s
                .map_or("never".to_string(), |t| format!("{} s ago", num(t, 1)))
        );
    }
    if s.duplicates > 0 {
        eprintln!(
            "      copies dropped (heard on two links): {}",
            s.duplicates
        );
    }
    if let Some(l) = latency.summary() {
        eprintln!("      {l}");
    }
}

/// Several links: each one's rate and loss this second, or SILENT (empty with one link).
fn links_line(stats: &IngestStats) -> String {
    stats
        .links()
        .iter()
        .map(|l| {
            if l.live {
                format!(
                    "  [{} {}/s loss {}%]",
                    l.name,
                    num(l.rate_hz, 0),
                    num(l.loss_pct, 0)
                )
            } else {
                format!("  [{} SILENT]", l.name)
            }
        })
        .collect()
}

/// A number, or `?` for NaN/infinity (a sensor glitch must not look like a value).
fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "?".into()
    }
}

/// The once-a-second status line: the pilot's ([`super::pilot::line`]), or with `detail`
/// the engineer's ([`detail_line`]). `r`: the newest report and the alerts standing
/// (rule → severity).
pub fn status_line(
    r: Option<(&Report, &BTreeMap<String, Severity>)>,
    stats: &IngestStats,
    rate: f64,
    colour: bool,
    detail: bool,
) -> String {
    if detail {
        return detail_line(r.map(|(r, _)| r), stats, rate, colour);
    }
    let worst = r.and_then(|(_, active)| super::pilot::worst_of(active, |_| None));
    super::pilot::line(
        r.map(|(r, _)| r),
        worst.as_ref(),
        stats.silent.load(Relaxed),
        colour,
    )
}

/// The engineer's status line (`--detail`): every model's raw~adapted estimate, the
/// energy's bookkeeping, the pack model, the link's counters, the stale features.
pub fn detail_line(r: Option<&Report>, stats: &IngestStats, rate: f64, colour: bool) -> String {
    let mut s = String::new();
    match r {
        None => s.push_str("waiting for the first window  "),
        Some(r) => {
            models_part(&mut s, &r.estimate);
            energy_part(&mut s, &r.energy);
            pack_part(&mut s, &r.energy.pack, colour);
            margins_part(&mut s, &r.energy, colour);
        }
    }
    link_part(&mut s, stats, rate, colour);
    if let Some(r) = r {
        let stale = crate::features::stale_names(r.estimate.sample.stale_mask);
        if !stale.is_empty() {
            let txt = format!("  stale: {}", stale.join(","));
            s.push_str(&if colour {
                txt.yellow().to_string()
            } else {
                txt
            });
        }
    }
    s
}

/// `txt` in red where `colour` and `red`, else as it is.
fn red_if(txt: String, colour: bool, red: bool) -> String {
    if colour && red {
        txt.red().to_string()
    } else {
        txt
    }
}

/// The time, the class, the measured power and every model's raw~adapted estimate.
fn models_part(s: &mut String, e: &crate::report::Estimate) {
    s.push_str(&format!("t {} s  ", num(e.t_s, 1)));
    // The class (which models apply): "fixed_wing", "vtol (fw)", "other: SUBMARINE (12)".
    s.push_str(&format!("{}  ", e.sample.vehicle.describe()));
    match e.sample.measured_w {
        Some(w) => s.push_str(&format!("measured {} W  ", num(w as f64, 1))),
        None => s.push_str("measured — W  "),
    }
    for m in &e.models {
        s.push_str(&format!("{} {}", m.name, num(m.power_w as f64, 1)));
        // Adapted to measured power: "lstm 312.0~348.5".
        if let Some(a) = m.adapted_w {
            s.push_str(&format!("~{}", num(a as f64, 1)));
        }
        s.push_str("  ");
    }
}

/// The energy's bookkeeping: used, left (the one percentage and its source), time to empty.
fn energy_part(s: &mut String, en: &crate::report::EnergyState) {
    if en.energy_used_wh != 0.0 || en.remaining_wh.is_some() {
        s.push_str(&format!("used {} Wh  ", num(en.energy_used_wh, 2)));
    }
    if let Some(left) = en.remaining_wh {
        let b = &en.battery;
        // The one percentage (the state of charge every view shows) and its source;
        // the capacity apart, as the % is of the usable pack, not of it.
        s.push_str(&format!(
            "left {} Wh {} % [{}; capacity {} Wh: {}]",
            num(left, 1),
            en.remaining_pct.map_or("?".into(), |p| num(p, 0)),
            super::pilot::charge_source(en),
            b.capacity().map_or("?".into(), |c| num(c, 1)),
            b.capacity_source(),
        ));
        if let Some(t) = en.time_to_empty_s {
            s.push_str(&format!(" ({} min", num(t / 60.0, 0)));
            // Which model the forecast follows: "(12 min on lstm~)".
            if let Some(m) = &en.forecast_model {
                s.push_str(&format!(
                    " on {m}{}",
                    if en.forecast_adapted { "~" } else { "" }
                ));
            }
            s.push(')');
        }
        s.push_str("  ");
    } else if en.battery.capacity_wh.is_none() {
        // Never another vehicle's pack: said, with what is known without it.
        s.push_str("capacity not known  ");
    }
    if let Some(why) = en.pack.pack_withheld {
        if why.contains("does not sag") {
            s.push_str("pack does not sag: no voltage forecast  ");
        }
    }
}

/// The pack: voltage measured ~ modelled, state of charge, and the forecast's low.
fn pack_part(s: &mut String, pk: &crate::report::PackState, colour: bool) {
    let Some(v) = pk.battery_v else { return };
    s.push_str(&format!("pack {} V", num(v, 2)));
    if let Some(m) = pk.battery_v_model {
        s.push_str(&format!("~{}", num(m, 2)));
    }
    if let Some(soc) = pk.soc_pct {
        // The pack model's open-circuit figure, named apart from the state of
        // charge (it counts the energy under the low-voltage floor too).
        s.push_str(&format!(" OCV {}%", num(soc, 0)));
    }
    if let (Some(lo), Some(low)) = (pk.v_min_forecast_v, pk.low_threshold_v) {
        s.push_str(&red_if(format!(" min {} V", num(lo, 2)), colour, lo < low));
    }
    s.push_str("  ");
}

/// The margins: home, and the mission's item, progress, need and margin.
fn margins_part(s: &mut String, en: &crate::report::EnergyState, colour: bool) {
    if let Some(h) = en.home_margin_wh {
        let txt = format!("home {}{} Wh  ", if h >= 0.0 { "+" } else { "" }, num(h, 1));
        s.push_str(&red_if(txt, colour, h < 0.0));
    }
    if let (Some(m), Some(mm)) = (&en.mission, en.mission_margin_wh) {
        let txt = format!(
            "mission item {}/{} {}% needs {} Wh margin {}{} Wh  ",
            m.current_seq,
            m.items,
            num(m.progress_pct, 0),
            num(m.energy_p50_wh, 1),
            if mm >= 0.0 { "+" } else { "" },
            num(mm, 1)
        );
        s.push_str(&red_if(txt, colour, mm < 0.0));
    }
}

/// The link's counters, per-link lines, and SILENT when nothing valid came for 5 s.
fn link_part(s: &mut String, stats: &IngestStats, rate: f64, colour: bool) {
    let n = stats.snapshot();
    s.push_str(&format!(
        "link {} msg/s ok {} bad {} unk {} gaps {}",
        num(rate, 0),
        n.frames_ok,
        n.frames_bad,
        n.unknown,
        n.gaps
    ));
    s.push_str(&links_line(stats));
    if stats.silent.load(Relaxed) {
        let txt = "  SILENT (no valid frame for 5 s)";
        s.push_str(&if colour {
            txt.red().bold().to_string()
        } else {
            txt.to_string()
        });
    }
}

/// The fleet view: the link's line, then one row per vehicle (see the module docs).
pub fn fleet_view(
    fleet: &BTreeMap<crate::report::VehicleId, (Arc<Report>, BTreeMap<String, Severity>)>,
    stats: &IngestStats,
    rate: f64,
    colour: bool,
) -> String {
    let n = stats.snapshot();
    let mut s = format!(
        "fleet: {} vehicles  link {} msg/s ok {} bad {} unk {} gaps {}{}\n{:>8} {:>9} {:>8} {:>9} {:>8}  worst alert",
        fleet.len(),
        num(rate, 0),
        n.frames_ok,
        n.frames_bad,
        n.unknown,
        n.gaps,
        links_line(stats),
        "vehicle",
        "power W",
        "left Wh",
        "to empty",
        "home Wh"
    );
    let opt = |v: Option<f64>, d: usize| v.map_or("—".to_string(), |v| num(v, d));
    for (id, (r, active)) in fleet {
        let e = &r.energy;
        let power = r.estimate.sample.measured_w.map(f64::from).or(e.forecast_w);
        let tte = e
            .time_to_empty_s
            .map_or("—".to_string(), |t| format!("{} min", num(t / 60.0, 0)));
        let home = e.home_margin_wh.map_or("—".to_string(), |h| {
            format!("{}{}", if h >= 0.0 { "+" } else { "" }, num(h, 1))
        });
        // Severity orders most severe first.
        let worst = active.iter().min_by_key(|(_, &sev)| sev);
        let alert = worst.map_or("—".to_string(), |(rule, sev)| format!("{rule} ({sev})"));
        let alert = match worst {
            Some((_, sev)) if colour && *sev <= Severity::Error => alert.red().bold().to_string(),
            Some(_) if colour => alert.yellow().to_string(),
            _ => alert,
        };
        s.push_str(&format!(
            "\n{id:>8} {:>9} {:>8} {tte:>9} {home:>8}  {alert}",
            opt(power, 1),
            opt(e.remaining_wh, 1),
        ));
    }
    s
}

/// `feeds: attitude←ATTITUDE velocity←GLOBAL_POSITION_INT … (stale: wind)`: which message
/// feeds each signal, and which signals are stale.
pub fn feeds_line(health: &[SignalHealth]) -> String {
    if health.is_empty() {
        return String::new();
    }
    let feeds: Vec<String> = health
        .iter()
        .map(|h| format!("{}←{}", h.signal, h.source.unwrap_or("none")))
        .collect();
    let stale: Vec<&str> = health
        .iter()
        .filter(|h| h.stale)
        .map(|h| h.signal)
        .collect();
    let mut s = format!("feeds: {}", feeds.join(" "));
    if !stale.is_empty() {
        s.push_str(&format!(" (stale: {})", stale.join(", ")));
    }
    s
}

/// One alert event, coloured by severity (cleared alerts green).
pub fn alert_line(a: &AlertEvent, colour: bool) -> String {
    let (tag, txt) = match a.state {
        AlertState::Raised => (
            "ALERT",
            format!(
                "[{}] {} at t {} s: {}",
                a.severity,
                a.rule,
                num(a.t, 1),
                a.message
            ),
        ),
        AlertState::Cleared => (
            "clear",
            format!("{} cleared at t {} s: {}", a.rule, num(a.t, 1), a.message),
        ),
    };
    let line = format!("{tag} {txt}");
    if !colour {
        return line;
    }
    match (a.state, a.severity.name()) {
        (AlertState::Cleared, _) => line.green().to_string(),
        (_, "critical" | "emergency" | "error") => line.red().bold().to_string(),
        (_, "warning") => line.yellow().to_string(),
        _ => line.cyan().to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_status_line_shows_link_health_silence_and_survives_nan() {
        let stats = IngestStats::default();
        IngestStats::add(&stats.frames_ok, 120);
        IngestStats::add(&stats.frames_bad, 2);
        stats.silent.store(true, Relaxed);
        let line = status_line(None, &stats, f64::NAN, false, true);
        assert!(
            line.contains("ok 120 bad 2") && line.contains("SILENT") && line.contains("? msg/s"),
            "{line}"
        );
        let line = status_line(None, &stats, f64::NAN, false, false);
        assert!(
            line.contains("waiting for the first window") && line.contains("SILENT"),
            "{line}"
        );
    }
}

#[cfg(test)]
mod feeds_tests {
    use super::feeds_line;
    use crate::report::status::SignalHealth;

    #[test]
    fn feeds_name_each_source_and_the_stale_signals() {
        let h = |signal, source, stale| SignalHealth {
            signal,
            features: vec![],
            source,
            age_s: None,
            stale,
        };
        let line = feeds_line(&[
            h("attitude", Some("ATTITUDE"), false),
            h("wind", None, true),
        ]);
        assert_eq!(line, "feeds: attitude←ATTITUDE wind←none (stale: wind)");
        assert_eq!(feeds_line(&[]), "");
    }
}
