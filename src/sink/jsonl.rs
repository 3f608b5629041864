//! JSON lines (`--json PATH|-`): one object per line, four kinds, in this order per report:
//!
//! ```text
//! {"type":"window","t":…,"measured_w":…,"features":{"wind_speed":…,…}}
//! {"type":"estimate","t":…,"measured_w":…,"models":{"<name>":watts,…},["bands":{"<name>":[lo,hi]},]"energy_used_wh":…,"remaining_wh":…,"time_to_empty_s":…,"home_margin_wh":…,
//!  ["adapted":{"<name>":watts,…},]"capacity_wh":…,"capacity_source":"config"|"vehicle parameter BATT_CAPACITY"|"default"|…,"cell_count":…,"cell_count_source":…}
//! {"type":"alert","t":…,"rule":…,"severity":…,"state":"raised"|"cleared","message":…}   (one per alert event)
//! ```
//!
//! and last, once the run is over (end of a replay, Ctrl-C, a source error):
//!
//! ```text
//! {"type":"summary","frames_ok":…,"frames_bad":…,"unknown":…,"gaps":…,"windows":…,
//!  "junk_bytes":…,"clock_jumps":…,"silences":…,"reports":…,"missed_reports":…}
//! ```
//!
//! `null` stands for unknown, and for any NaN or infinity (JSON has neither). Feature
//! names are [`crate::telemetry::FEATURE_NAMES`]; `t` is the source's `t_s`. The writer runs
//! on its own thread so a slow disk or pipe never stalls the runtime.

use std::io::Write;
use std::sync::Arc;

use anyhow::Context;
use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;
use tokio::sync::broadcast;
use tokio::task::JoinHandle;

use super::JsonTarget;
use crate::energy::Report;
use crate::source::{IngestStats, StatsSnapshot};
use crate::telemetry::FEATURE_NAMES;

/// Open the target now (so a bad path fails before the run) and write on a blocking thread.
pub fn spawn(
    target: JsonTarget,
    mut rx: broadcast::Receiver<Arc<Report>>,
    stats: Arc<IngestStats>,
) -> anyhow::Result<JoinHandle<anyhow::Result<()>>> {
    let (out, name): (Box<dyn Write + Send>, String) = match &target {
        JsonTarget::Stdout => (Box::new(std::io::stdout()), "standard output".into()),
        JsonTarget::File(p) => (
            Box::new(std::fs::File::create(p).with_context(|| format!("{}: cannot create the JSON file", p.display()))?),
            p.display().to_string(),
        ),
    };
    Ok(tokio::task::spawn_blocking(move || {
        let mut w = std::io::BufWriter::new(out);
        let mut missed = 0;
        let mut reports = 0u64;
        let run = (|| -> std::io::Result<()> {
            while let Some(r) = super::next_report_blocking(&mut rx, &mut missed) {
                reports += 1;
                write_report(&mut w, &r)?;
                if rx.is_empty() {
                    w.flush()?; // live: each report shows up as it happens
                }
            }
            write_line(&mut w, &Summary::new(stats.snapshot(), reports, missed))?;
            w.flush()
        })();
        run.with_context(|| format!("{name}: cannot write JSON lines"))
    }))
}

/// Write the lines for one report.
pub fn write_report(w: &mut impl Write, r: &Report) -> std::io::Result<()> {
    let e = &r.estimate;
    let s = &e.sample;
    write_line(w, &WindowLine { kind: "window", t: e.t_s, measured_w: s.measured_w, features: Features(&s.features) })?;
    write_line(
        w,
        &EstimateLine {
            kind: "estimate",
            t: e.t_s,
            measured_w: s.measured_w,
            models: Models(&e.models),
            bands: Bands(&e.models),
            energy_used_wh: r.energy.energy_used_wh,
            remaining_wh: r.energy.remaining_wh,
            time_to_empty_s: r.energy.time_to_empty_s,
            home_margin_wh: r.energy.home_margin_wh,
            adapted: Adapted(&e.models),
            capacity_wh: r.energy.capacity_wh,
            capacity_source: &r.energy.capacity_source,
            cell_count: r.energy.cell_count,
            cell_count_source: &r.energy.cell_count_source,
        },
    )?;
    for a in &r.alerts {
        write_line(
            w,
            &AlertLine { kind: "alert", t: a.t, rule: &a.rule, severity: &a.severity, state: a.state, message: &a.message },
        )?;
    }
    Ok(())
}

fn write_line(w: &mut impl Write, v: &impl Serialize) -> std::io::Result<()> {
    serde_json::to_writer(&mut *w, v)?;
    w.write_all(b"\n")
}

#[derive(Serialize)]
struct WindowLine<'a> {
    #[serde(rename = "type")]
    kind: &'static str,
    t: f64,
    measured_w: Option<f32>,
    features: Features<'a>,
}

/// The feature vector as a name → value object.
struct Features<'a>(&'a [f32; crate::telemetry::N_FEATURES]);

impl Serialize for Features<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(FEATURE_NAMES.len()))?;
        for (name, v) in FEATURE_NAMES.iter().zip(self.0) {
            m.serialize_entry(name, v)?;
        }
        m.end()
    }
}

#[derive(Serialize)]
struct EstimateLine<'a> {
    #[serde(rename = "type")]
    kind: &'static str,
    t: f64,
    measured_w: Option<f32>,
    models: Models<'a>,
    /// `{"<name>": [low_w, high_w]}` for the models that give an uncertainty band (the LSTM's
    /// 5 %/95 % quantiles); absent when none does.
    #[serde(skip_serializing_if = "Bands::is_empty")]
    bands: Bands<'a>,
    energy_used_wh: f64,
    remaining_wh: Option<f64>,
    time_to_empty_s: Option<f64>,
    home_margin_wh: Option<f64>,
    /// `{"<name>": watts}`: each model adapted to measured power ([`crate::model::adapt`]);
    /// absent when adaptation is off.
    #[serde(skip_serializing_if = "Adapted::is_empty")]
    adapted: Adapted<'a>,
    /// Battery capacity the energy figures use, Wh, and where it came from (`config`,
    /// `vehicle parameter BATT_CAPACITY`, `default` …).
    capacity_wh: f64,
    capacity_source: &'a str,
    /// Cells in series, and where that came from.
    cell_count: u32,
    cell_count_source: &'a str,
}

/// Adapted estimates as a name → watts object.
struct Adapted<'a>(&'a [crate::model::ModelEstimate]);

impl Adapted<'_> {
    fn is_empty(&self) -> bool {
        self.0.iter().all(|m| m.adapted_w.is_none())
    }
}

impl Serialize for Adapted<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(None)?;
        for e in self.0 {
            if let Some(w) = e.adapted_w {
                m.serialize_entry(&e.name, &w)?;
            }
        }
        m.end()
    }
}

/// Uncertainty bands as a name → [low, high] watts object.
struct Bands<'a>(&'a [crate::model::ModelEstimate]);

impl Bands<'_> {
    fn is_empty(&self) -> bool {
        self.0.iter().all(|e| e.band_w.is_none())
    }
}

impl Serialize for Bands<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(None)?;
        for e in self.0 {
            if let Some((lo, hi)) = e.band_w {
                m.serialize_entry(&e.name, &[lo, hi])?;
            }
        }
        m.end()
    }
}

/// Model estimates as a name → watts object.
struct Models<'a>(&'a [crate::model::ModelEstimate]);

impl Serialize for Models<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for e in self.0 {
            m.serialize_entry(&e.name, &e.power_w)?;
        }
        m.end()
    }
}

#[derive(Serialize)]
struct AlertLine<'a> {
    #[serde(rename = "type")]
    kind: &'static str,
    t: f64,
    rule: &'a str,
    severity: &'a str,
    state: crate::alert::AlertState,
    message: &'a str,
}

/// The last line of every run.
#[derive(Debug, Serialize)]
pub struct Summary {
    #[serde(rename = "type")]
    kind: &'static str,
    pub frames_ok: u64,
    pub frames_bad: u64,
    pub unknown: u64,
    pub gaps: u64,
    pub windows: u64,
    pub junk_bytes: u64,
    pub clock_jumps: u64,
    pub silences: u64,
    /// Reports this sink wrote.
    pub reports: u64,
    /// Reports this sink lost by lagging behind the broadcast.
    pub missed_reports: u64,
}

impl Summary {
    /// The summary for these counters.
    pub fn new(s: StatsSnapshot, reports: u64, missed_reports: u64) -> Self {
        Self {
            kind: "summary",
            frames_ok: s.frames_ok,
            frames_bad: s.frames_bad,
            unknown: s.unknown,
            gaps: s.gaps,
            windows: s.windows,
            junk_bytes: s.junk_bytes,
            clock_jumps: s.clock_jumps,
            silences: s.silences,
            reports,
            missed_reports,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::alert::{AlertEvent, AlertState};
    use crate::energy::EnergyState;
    use crate::model::{Estimate, ModelEstimate};
    use crate::telemetry::{Sample, N_FEATURES};

    fn report() -> Report {
        let mut features = [0.5f32; N_FEATURES];
        features[0] = f32::NAN;
        let sample =
            Sample { t_s: 12.5, features, measured_w: Some(240.0), voltage_v: Some(22.8), home: None, stale_mask: 0, battery_remaining_pct: None };
        Report {
            estimate: Estimate {
                t_s: 12.5,
                sample,
                models: vec![
                    ModelEstimate::new("dandrea", 230.0, None),
                    ModelEstimate::new("lstm", f32::INFINITY, None),
                ],
            },
            energy: EnergyState { energy_used_wh: 1.5, remaining_wh: Some(80.0), time_to_empty_s: None, home_margin_wh: None, ..Default::default() },
            alerts: vec![AlertEvent {
                t: 12.5,
                rule: "low_margin".into(),
                severity: "warning".into(),
                state: AlertState::Raised,
                message: "margin below 10 Wh".into(),
            }],
        }
    }

    #[test]
    fn lines_have_exactly_the_documented_shapes_and_nan_is_null() {
        let mut out = Vec::new();
        write_report(&mut out, &report()).unwrap();
        let lines: Vec<serde_json::Value> =
            String::from_utf8(out).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        assert_eq!(lines.len(), 3);
        let w = &lines[0];
        assert_eq!((w["type"].as_str(), w["t"].as_f64(), w["measured_w"].as_f64()), (Some("window"), Some(12.5), Some(240.0)));
        let f = w["features"].as_object().unwrap();
        assert_eq!(f.len(), N_FEATURES);
        assert!(f["wind_speed"].is_null(), "NaN is written as null");
        assert_eq!(f["altitude"], 0.5);
        let e = &lines[1];
        assert_eq!(e["type"], "estimate");
        assert_eq!(e["models"]["dandrea"], 230.0);
        assert!(e["models"]["lstm"].is_null());
        assert_eq!((e["energy_used_wh"].as_f64(), e["remaining_wh"].as_f64()), (Some(1.5), Some(80.0)));
        assert!(e["time_to_empty_s"].is_null() && e["home_margin_wh"].is_null());
        let a = &lines[2];
        assert_eq!(
            (a["type"].as_str(), a["rule"].as_str(), a["severity"].as_str(), a["state"].as_str()),
            (Some("alert"), Some("low_margin"), Some("warning"), Some("raised"))
        );
        assert_eq!(a["message"], "margin below 10 Wh");
    }

    #[test]
    fn the_summary_starts_with_the_contract_fields_in_order() {
        let s = serde_json::to_string(&Summary::new(StatsSnapshot { frames_ok: 3, ..Default::default() }, 0, 0)).unwrap();
        assert!(s.starts_with(r#"{"type":"summary","frames_ok":3,"frames_bad":0,"unknown":0,"gaps":0,"windows":0,"#), "{s}");
    }
}
