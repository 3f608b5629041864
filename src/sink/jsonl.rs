//! JSON lines (`--json PATH|-`): one object per line, four kinds, in this order per report:
//!
//! ```text
//! {"type":"window","system_id":…,"t":…,"measured_w":…,"features":{"wind_speed":…,…}}
//! {"type":"estimate","system_id":…,"t":…,"vehicle_class":"multirotor"|"fixed_wing"|"vtol"|"other",["mav_type":…,]["vtol_state":"mc"|"fw"|…,]
//!  "measured_w":…,"models":{"<name>":watts,…},["bands":{"<name>":[lo,hi]},]["adapted":{"<name>":watts,…},]
//!  "energy_used_wh":…,"remaining_wh":…,"remaining_pct":…,"remaining_source":"resting voltage"|"battery"|"assumed full","time_to_empty_s":…,"home_margin_wh":…,["mission_energy_wh":…,"mission_margin_wh":…,]"forecast_adapted":…,"forecast_model":…,"forecast_why":…,
//!  ["hover_calibration":{"t_s":…,"hover_w":…,"hover_s":…,"eta_h":…,"prior_eta_h":…,"avionics_w":…,"applied":…},]
//!  "capacity_wh":…|null,"capacity_source":"config"|"vehicle parameter BATT_CAPACITY"|"--pack …"|"not known: …"|…,"cell_count":…,"cell_count_source":…,
//!  "chemistry":"lipo"|"lihv"|"liion"|"lifepo4","chemistry_source":…,"battery_v":…,"battery_v_model":…,"battery_ocv_v":…,"battery_rest_v":…,
//!  "soc_pct":…,"soc_band_pct":…,"pack_start":"resting voltage"|"load-compensated …"|null,"internal_r_ohm":…,"v_min_forecast_v":…,"v_min_forecast_at_s":…,
//!  "time_to_low_v_s":…,"low_threshold_v":…,"pack_withheld":null|"<why the voltage figures are null>",["battery_pct_disagreement":…,]
//!  ["low_voltage_v":…,"low_voltage_source":…,]["critical_voltage_v":…,"critical_voltage_source":…]}
//! {"type":"alert","system_id":…,"t":…,"rule":…,"severity":…,"state":"raised"|"cleared","message":…}   (one per alert event)
//! ```
//!
//! `system_id` is the MAVLink system id of the vehicle the line is about (a link may carry
//! a fleet; see [`crate::pipeline::Demux`]). Where the links are separate networks
//! (`[[links]] network`), `"network":N` follows it (networks numbered from 1; absent on the
//! only network, so such a run's lines are as they always were).
//!
//! and last, once the run is over (end of a replay, Ctrl-C, a source error):
//!
//! ```text
//! {"type":"summary","frames_ok":…,"frames_bad":…,"unknown":…,"gaps":…,"windows":…,
//!  "junk_bytes":…,"clock_jumps":…,"silences":…,"reports":…,"missed_reports":…,
//!  "signed_ok":…,"signature_bad":…,"signature_replay":…,"unsigned_refused":…,
//!  "queue_peak":…,"queue_peak_at_s":…,"latency":{"count":…,"p50_ms":…,"p99_ms":…,"max_ms":…}|null,
//!  "vehicle_kinds":["multirotor"|"fixed_wing"|"vtol (mc)"|"vtol (fw)"|"other: SUBMARINE (12)"|…]}
//! ```
//!
//! `latency` is the message → estimate latency over the run's reports: from the arrival of
//! the newest message behind an estimate (read off a live link; a paced replay's message
//! at its due time) to its report going to the sinks ([`crate::report::status::LatencyHistogram`]:
//! quantiles at most 12.5 % high, the maximum exact). A flat-out replay's is its queueing.
//! The windows the end of the input flushes (no message arrived to make them) are not counted.
//!
//! The MQTT sink ([`super::mqtt`]) publishes the same `estimate` and `alert` objects, and
//! its retained per-vehicle state as one more kind, never written to the file:
//!
//! ```text
//! {"type":"state","t":…,"vehicle_class":…,"energy_used_wh":…,"power_source":…,"remaining_wh":…,"remaining_pct":…,
//!  "remaining_source":…,"forecast_w":…,"forecast_model":…,"time_to_empty_s":…,"home_energy_wh":…,
//!  "home_margin_wh":…,"cell_voltage_v":…,"active_alerts":["<rule>",…]}
//! ```
//!
//! (the fields of [`crate::report::EnergyState`], and the rules raised and not yet cleared).
//!
//! `null` stands for unknown, and for any NaN or infinity (JSON has neither). Feature
//! names are [`crate::features::FEATURE_NAMES`]; `t` is the source's `t_s`. The writer runs
//! on its own thread so a slow disk or pipe never stalls the runtime.

use std::io::Write;

use anyhow::Context;
use serde::Serialize;
use tokio::task::JoinHandle;

use super::{JsonTarget, ReportRx};
use crate::report::status::{ChainStatus, LatencySummary, StatsSnapshot};
use crate::report::Report;

/// Open the target now (so a bad path fails before the run) and write on a blocking thread.
pub fn spawn(
    target: JsonTarget,
    mut rx: ReportRx,
    status: ChainStatus,
) -> anyhow::Result<JoinHandle<anyhow::Result<()>>> {
    let (out, name): (Box<dyn Write + Send>, String) = match &target {
        JsonTarget::Stdout => (Box::new(std::io::stdout()), "standard output".into()),
        JsonTarget::File(p) => (
            Box::new(
                std::fs::File::create(p)
                    .with_context(|| format!("{}: cannot create the JSON file", p.display()))?,
            ),
            p.display().to_string(),
        ),
    };
    Ok(tokio::task::spawn_blocking(move || {
        let mut w = std::io::BufWriter::new(out);
        let mut reports = 0u64;
        let mut kinds: Vec<String> = Vec::new();
        // The kinds already described: a report of one of them allocates nothing.
        let mut seen: Vec<crate::features::VehicleKind> = Vec::new();
        let run = (|| -> std::io::Result<()> {
            while let Some(r) = rx.blocking_next() {
                reports += 1;
                let kind = r.estimate.sample.vehicle;
                if !seen.contains(&kind) {
                    seen.push(kind);
                    let said = kind.describe();
                    if !kinds.contains(&said) {
                        kinds.push(said);
                    }
                }
                write_report(&mut w, &r)?;
                if rx.is_empty() {
                    w.flush()?; // live: each report shows up as it happens
                }
            }
            let mut summary = Summary::new(status.stats.snapshot(), reports, rx.missed())
                .with_queues(status.stats.queues.peak());
            summary.vehicle_kinds = std::mem::take(&mut kinds);
            summary.links = status.stats.links();
            write_line(&mut w, &summary.with_latency(status.latency.summary()))?;
            w.flush()
        })();
        run.with_context(|| format!("{name}: cannot write JSON lines"))
    }))
}

/// Write the lines for one report.
pub fn write_report(w: &mut impl Write, r: &Report) -> std::io::Result<()> {
    super::jsonl_window::write_window(w, r)?;
    write_estimate(w, r)?;
    for a in &r.alerts {
        write_alert(w, r.vehicle, a)?;
    }
    Ok(())
}

/// Write a report's `estimate` line (written by hand in `sink/jsonl_estimate.rs`; the module docs' shape).
pub fn write_estimate(w: &mut impl Write, r: &Report) -> std::io::Result<()> {
    super::jsonl_estimate::write_estimate(w, r)
}

/// Write one `alert` line about `vehicle`.
pub fn write_alert(
    w: &mut impl Write,
    vehicle: crate::report::VehicleId,
    a: &crate::report::AlertEvent,
) -> std::io::Result<()> {
    write_line(
        w,
        &AlertLine {
            head: Head::new("alert", vehicle),
            t: a.t,
            rule: &a.rule,
            severity: a.severity,
            state: a.state,
            message: &a.message,
        },
    )
}

/// Write one `state` line (the MQTT sink's retained state): the energy at report time `t`
/// and the alert rules currently raised.
pub fn write_state(
    w: &mut impl Write,
    t: f64,
    vehicle_class: crate::features::VehicleClass,
    energy: &crate::report::EnergyState,
    active_alerts: &[String],
) -> std::io::Result<()> {
    write_line(
        w,
        &StateLine {
            kind: "state",
            t,
            vehicle_class,
            energy,
            active_alerts,
        },
    )
}

fn write_line(w: &mut impl Write, v: &impl Serialize) -> std::io::Result<()> {
    serde_json::to_writer(&mut *w, v)?;
    w.write_all(b"\n")
}

/// What every line about one vehicle begins with: its type, the vehicle's system id, and
/// its network where the links are separate networks.
#[derive(Serialize)]
pub(super) struct Head {
    #[serde(rename = "type")]
    kind: &'static str,
    system_id: u8,
    #[serde(skip_serializing_if = "Option::is_none")]
    network: Option<u8>,
}

impl Head {
    pub(super) fn new(kind: &'static str, vehicle: crate::report::VehicleId) -> Self {
        Head {
            kind,
            system_id: vehicle.system_id,
            network: vehicle.network_field(),
        }
    }
}

#[derive(Serialize)]
struct StateLine<'a> {
    #[serde(rename = "type")]
    kind: &'static str,
    t: f64,
    vehicle_class: crate::features::VehicleClass,
    #[serde(flatten)]
    energy: &'a crate::report::EnergyState,
    active_alerts: &'a [String],
}

#[derive(Serialize)]
struct AlertLine<'a> {
    #[serde(flatten)]
    head: Head,
    t: f64,
    rule: &'a str,
    severity: crate::report::Severity,
    state: crate::report::AlertState,
    message: &'a str,
}

/// The last line of every run.
#[derive(Debug, Serialize)]
pub struct Summary {
    #[serde(rename = "type")]
    kind: &'static str,
    /// The source's counters at the end of the run (with MAVLink 2 signing on a live link:
    /// `signed_ok`, and the frames dropped for a bad signature, as replays, or unsigned).
    #[serde(flatten)]
    pub ingest: StatsSnapshot,
    /// Reports this sink wrote.
    pub reports: u64,
    /// Reports this sink missed while it was stuck (see [`super::SINK_PATIENCE`]).
    pub missed_reports: u64,
    /// The deepest any queue between the stages has been (items), and when it got there
    /// (seconds after the start): see [`crate::report::status::QueueGauge`].
    pub queue_peak: u64,
    pub queue_peak_at_s: f64,
    /// Message → estimate latency over the run's reports (`null`: none made).
    pub latency: Option<LatencySummary>,
    /// The vehicle kinds the reports were made for, in the order first seen (`multirotor`,
    /// `fixed_wing`, `vtol (mc)`, `vtol (fw)`, `other: SUBMARINE (12)` …): a VTOL's phases
    /// and any change of class.
    pub vehicle_kinds: Vec<String>,
    /// Several links: each link's health at the end (absent with one link).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub links: Vec<crate::report::status::LinkHealth>,
}

impl Summary {
    /// The summary for these counters.
    pub fn new(s: StatsSnapshot, reports: u64, missed_reports: u64) -> Self {
        Self {
            kind: "summary",
            ingest: s,
            reports,
            missed_reports,
            queue_peak: 0,
            queue_peak_at_s: 0.0,
            latency: None,
            vehicle_kinds: Vec::new(),
            links: Vec::new(),
        }
    }
    /// With the queues' high-water mark.
    pub fn with_queues(self, (queue_peak, queue_peak_at_s): (u64, f64)) -> Self {
        Self {
            queue_peak,
            queue_peak_at_s,
            ..self
        }
    }
    /// With the message → estimate latency.
    pub fn with_latency(self, latency: Option<LatencySummary>) -> Self {
        Self { latency, ..self }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::{Sample, N_FEATURES};
    use crate::report::EnergyState;
    use crate::report::{AlertEvent, AlertState};
    use crate::report::{Estimate, ModelEstimate};

    fn report() -> Report {
        let mut features = [0.5f32; N_FEATURES];
        features[0] = f32::NAN;
        let sample = Sample {
            voltage_v: Some(22.8),
            ..Sample::new(12.5, features, Some(240.0))
        };
        Report {
            estimate: Estimate {
                arrived: None,
                t_s: 12.5,
                sample,
                models: vec![
                    ModelEstimate::new("dandrea", 230.0, None),
                    ModelEstimate::new("lstm", f32::INFINITY, None),
                ],
            },
            energy: EnergyState {
                energy_used_wh: 1.5,
                remaining_wh: Some(80.0),
                time_to_empty_s: None,
                home_margin_wh: None,
                ..Default::default()
            },
            alerts: vec![AlertEvent {
                t: 12.5,
                rule: "low_margin".into(),
                severity: crate::report::Severity::Warning,
                state: AlertState::Raised,
                message: "margin below 10 Wh".into(),
            }],
            vehicle: 7.into(),
        }
    }

    #[test]
    fn lines_have_exactly_the_documented_shapes_and_nan_is_null() {
        let mut out = Vec::new();
        write_report(&mut out, &report()).unwrap();
        let lines: Vec<serde_json::Value> = String::from_utf8(out)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), 3);
        assert!(
            lines.iter().all(|l| l["system_id"] == 7),
            "every line names its vehicle: {lines:?}"
        );
        let w = &lines[0];
        assert_eq!(
            (
                w["type"].as_str(),
                w["t"].as_f64(),
                w["measured_w"].as_f64()
            ),
            (Some("window"), Some(12.5), Some(240.0))
        );
        let f = w["features"].as_object().unwrap();
        assert_eq!(f.len(), N_FEATURES);
        assert!(f["wind_speed"].is_null(), "NaN is written as null");
        assert_eq!(f["altitude"], 0.5);
        let e = &lines[1];
        assert_eq!(e["type"], "estimate");
        assert_eq!(e["models"]["dandrea"], 230.0);
        assert!(e["models"]["lstm"].is_null());
        assert_eq!(
            (e["energy_used_wh"].as_f64(), e["remaining_wh"].as_f64()),
            (Some(1.5), Some(80.0))
        );
        assert!(e["time_to_empty_s"].is_null() && e["home_margin_wh"].is_null());
        let a = &lines[2];
        assert_eq!(
            (
                a["type"].as_str(),
                a["rule"].as_str(),
                a["severity"].as_str(),
                a["state"].as_str()
            ),
            (
                Some("alert"),
                Some("low_margin"),
                Some("warning"),
                Some("raised")
            )
        );
        assert_eq!(a["message"], "margin below 10 Wh");
    }

    #[test]
    fn the_state_line_is_the_energy_state_flat_with_the_active_alerts() {
        let r = report();
        let mut out = Vec::new();
        write_state(
            &mut out,
            12.5,
            Default::default(),
            &r.energy,
            &["low_margin".to_string()],
        )
        .unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.ends_with('\n') && text.lines().count() == 1, "{text}");
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(
            (v["type"].as_str(), v["t"].as_f64()),
            (Some("state"), Some(12.5))
        );
        assert_eq!(
            (v["energy_used_wh"].as_f64(), v["remaining_wh"].as_f64()),
            (Some(1.5), Some(80.0))
        );
        assert!(v["time_to_empty_s"].is_null() && v["home_margin_wh"].is_null());
        assert_eq!(v["active_alerts"], serde_json::json!(["low_margin"]));
        let energy_keys = serde_json::to_value(&r.energy)
            .unwrap()
            .as_object()
            .unwrap()
            .len();
        assert_eq!(
            v.as_object().unwrap().len(),
            energy_keys + 4,
            "type, t, vehicle_class, the energy fields, active_alerts: {v}"
        );
    }

    #[test]
    fn the_summary_starts_with_the_contract_fields_in_order() {
        let s = serde_json::to_string(&Summary::new(
            StatsSnapshot {
                frames_ok: 3,
                ..Default::default()
            },
            0,
            0,
        ))
        .unwrap();
        assert!(s.starts_with(r#"{"type":"summary","frames_ok":3,"frames_bad":0,"unknown":0,"gaps":0,"windows":0,"#), "{s}");
    }
}
