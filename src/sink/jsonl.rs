//! JSON lines (`--json PATH|-`): one object per line, four kinds, in this order per report:
//!
//! ```text
//! {"type":"window","t":…,"measured_w":…,"features":{"wind_speed":…,…}}
//! {"type":"estimate","t":…,"measured_w":…,"models":{"<name>":watts,…},"energy_used_wh":…,"remaining_wh":…,"time_to_empty_s":…,"home_margin_wh":…}
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
            energy_used_wh: r.energy.energy_used_wh,
            remaining_wh: r.energy.remaining_wh,
            time_to_empty_s: r.energy.time_to_empty_s,
            home_margin_wh: r.energy.home_margin_wh,
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
    energy_used_wh: f64,
    remaining_wh: Option<f64>,
    time_to_empty_s: Option<f64>,
    home_margin_wh: Option<f64>,
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
