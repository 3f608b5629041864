//! The `estimate` and `alert` lines [`super::jsonl`] writes, read back into a [`Report`] and an
//! [`AlertEvent`]: what a viewer that is not the worker (`dronewatt dashboard --nats`, which
//! hears the fleet's workers on NATS) feeds the same dashboard a monitor's own reports feed.
//!
//! Everything the line carries comes back as it was: writing the report read back gives the
//! same line, byte for byte (tested). What the line does not carry is not made up: the
//! feature vector (every feature marked stale), the smoothed forecast power (`forecast_w`),
//! the energy to fly home (`home_energy_wh`, the margin is there), the power source
//! integrated, the mission's status and route (its margin and energy are there) and the
//! pack's internal figures the line skips. The dashboard shows those as not known.
//!
//! Bad input (not JSON, another `type`, a field of the wrong kind) is an error naming what
//! is wrong, never a panic.

use std::collections::HashSet;
use std::sync::Mutex;

use serde::de::{Deserializer, MapAccess, Visitor};
use serde::Deserialize;

use crate::features::{Sample, VehicleClass, VehicleKind, VtolState, N_FEATURES};

use crate::report::hover::HoverCalibration;
use crate::report::{
    AlertEvent, AlertState, BatteryFacts, EnergyState, Estimate, ModelEstimate, PackState,
    Provenance, RemainingSource, Report, Severity, Sourced, VehicleId,
};

/// One line read back.
#[derive(Debug, Clone)]
pub enum Line {
    /// An `estimate` line: the report it was written from, without alerts (those are lines
    /// of their own).
    Estimate(Box<Report>),
    /// An `alert` line: the vehicle it is about and the event.
    Alert(VehicleId, AlertEvent),
}

/// Read one `estimate` or `alert` line (with or without its newline).
pub fn read(line: &[u8]) -> Result<Line, String> {
    #[derive(Deserialize)]
    struct Kind {
        #[serde(rename = "type")]
        kind: String,
    }
    let kind: Kind = serde_json::from_slice(line).map_err(|e| format!("not a JSON line: {e}"))?;
    match kind.kind.as_str() {
        "estimate" => {
            let e: EstimateIn =
                serde_json::from_slice(line).map_err(|e| format!("estimate line: {e}"))?;
            Ok(Line::Estimate(Box::new(e.report()?)))
        }
        "alert" => {
            let a: AlertIn =
                serde_json::from_slice(line).map_err(|e| format!("alert line: {e}"))?;
            let v = vehicle(a.network, a.system_id);
            Ok(Line::Alert(
                v,
                AlertEvent {
                    t: a.t.unwrap_or(f64::NAN),
                    rule: a.rule,
                    severity: a.severity,
                    state: a.state,
                    message: a.message,
                },
            ))
        }
        other => Err(format!(
            "a line of type '{other}': expected estimate or alert"
        )),
    }
}

fn vehicle(network: Option<u8>, system_id: u8) -> VehicleId {
    VehicleId {
        network: network.unwrap_or(0),
        system_id,
    }
}

#[derive(Deserialize)]
struct AlertIn {
    system_id: u8,
    network: Option<u8>,
    t: Option<f64>,
    rule: String,
    severity: Severity,
    state: AlertState,
    message: String,
}

/// Every field of the estimate line ([`super::jsonl::write_estimate`]); `null` numbers are
/// `None` (the writer's NaN and infinities among them).
#[derive(Deserialize)]
struct EstimateIn {
    system_id: u8,
    network: Option<u8>,
    t: Option<f64>,
    vehicle_class: VehicleClass,
    mav_type: Option<u8>,
    vtol_state: Option<String>,
    measured_w: Option<f32>,
    models: InOrder<Option<f32>>,
    #[serde(default)]
    bands: InOrder<Option<[f32; 2]>>,
    #[serde(default)]
    adapted: InOrder<Option<f32>>,
    energy_used_wh: Option<f64>,
    remaining_wh: Option<f64>,
    remaining_pct: Option<f64>,
    remaining_source: RemainingSource,
    time_to_empty_s: Option<f64>,
    home_margin_wh: Option<f64>,
    mission_energy_wh: Option<f64>,
    mission_margin_wh: Option<f64>,
    forecast_adapted: bool,
    forecast_model: Option<String>,
    forecast_why: Option<String>,
    hover_calibration: Option<HoverCalibration>,
    capacity_wh: Option<f64>,
    capacity_source: Provenance,
    cell_count: u32,
    cell_count_source: Provenance,
    chemistry: String,
    chemistry_source: Provenance,
    low_voltage_v: Option<f64>,
    low_voltage_source: Option<Provenance>,
    critical_voltage_v: Option<f64>,
    critical_voltage_source: Option<Provenance>,
    #[serde(flatten)]
    pack: PackIn,
}

/// [`PackState`] as the line writes it (its texts owned).
#[derive(Deserialize)]
struct PackIn {
    battery_v: Option<f64>,
    battery_v_model: Option<f64>,
    battery_ocv_v: Option<f64>,
    battery_rest_v: Option<f64>,
    soc_pct: Option<f64>,
    soc_band_pct: Option<f64>,
    pack_start: Option<String>,
    pack_withheld: Option<String>,
    internal_r_ohm: Option<f64>,
    v_min_forecast_v: Option<f64>,
    v_min_forecast_at_s: Option<f64>,
    time_to_low_v_s: Option<f64>,
    low_threshold_v: Option<f64>,
    battery_pct_disagreement: Option<f64>,
    battery_end_rest_v: Option<f64>,
    pack_r_scale: Option<f64>,
    #[serde(default)]
    pack_carried_over: bool,
}

impl EstimateIn {
    fn report(self) -> Result<Report, String> {
        let t = self.t.unwrap_or(f64::NAN);
        let vtol_state = match self.vtol_state.as_deref() {
            None => VtolState::Undefined,
            Some(s) => vtol(s).ok_or_else(|| format!("estimate line: vtol_state '{s}'"))?,
        };
        let mut sample = Sample::new(t, [0.0; N_FEATURES], self.measured_w);
        // The line carries no features: every one is "not known".
        sample.stale_mask = u32::MAX;
        sample.vehicle = VehicleKind {
            class: self.vehicle_class,
            mav_type: self.mav_type,
            vtol_state,
            from_config: false,
        };
        let models = self
            .models
            .0
            .into_iter()
            .map(|(name, w)| {
                let band = self.bands.get(&name).flatten().map(|[lo, hi]| (lo, hi));
                let mut m = ModelEstimate::new(name, w.unwrap_or(f32::NAN), band);
                m.adapted_w = self.adapted.get(&m.name).flatten();
                m
            })
            .collect();
        let src = |s: Option<Provenance>| s.unwrap_or_default();
        let battery = BatteryFacts {
            capacity_wh: self
                .capacity_wh
                .map(|c| Sourced::new(c, self.capacity_source)),
            cell_count: Sourced::new(self.cell_count, self.cell_count_source),
            chemistry: Sourced::new(self.chemistry, self.chemistry_source),
            low_voltage_v: self
                .low_voltage_v
                .map(|v| Sourced::new(v, src(self.low_voltage_source))),
            critical_voltage_v: self
                .critical_voltage_v
                .map(|v| Sourced::new(v, src(self.critical_voltage_source))),
            rated_capacity_wh: None,
        };
        let p = self.pack;
        let pack = PackState {
            battery_v: p.battery_v,
            battery_v_model: p.battery_v_model,
            battery_ocv_v: p.battery_ocv_v,
            battery_rest_v: p.battery_rest_v,
            soc_pct: p.soc_pct,
            soc_band_pct: p.soc_band_pct,
            pack_start: p.pack_start.as_deref().and_then(interned),
            pack_withheld: p.pack_withheld.as_deref().and_then(interned),
            internal_r_ohm: p.internal_r_ohm,
            v_min_forecast_v: p.v_min_forecast_v,
            v_min_forecast_at_s: p.v_min_forecast_at_s,
            time_to_low_v_s: p.time_to_low_v_s,
            low_threshold_v: p.low_threshold_v,
            battery_pct_disagreement: p.battery_pct_disagreement,
            battery_end_rest_v: p.battery_end_rest_v,
            pack_r_scale: p.pack_r_scale,
            pack_carried_over: p.pack_carried_over,
            ..PackState::default()
        };
        let energy = EnergyState {
            energy_used_wh: self.energy_used_wh.unwrap_or(f64::NAN),
            remaining_wh: self.remaining_wh,
            remaining_pct: self.remaining_pct,
            remaining_source: self.remaining_source,
            forecast_model: self.forecast_model,
            forecast_why: self.forecast_why,
            time_to_empty_s: self.time_to_empty_s,
            home_margin_wh: self.home_margin_wh,
            mission_energy_wh: self.mission_energy_wh,
            mission_margin_wh: self.mission_margin_wh,
            forecast_adapted: self.forecast_adapted,
            pack,
            battery: battery.into(),
            hover_calibration: self.hover_calibration,
            ..EnergyState::default()
        };
        Ok(Report {
            estimate: Estimate {
                t_s: t,
                sample,
                models,
                arrived: None,
            },
            energy,
            alerts: Vec::new(),
            vehicle: vehicle(self.network, self.system_id),
        })
    }
}

fn vtol(s: &str) -> Option<VtolState> {
    [
        VtolState::Undefined,
        VtolState::Mc,
        VtolState::Fw,
        VtolState::TransitionToFw,
        VtolState::TransitionToMc,
    ]
    .into_iter()
    .find(|v| v.as_str() == s)
}

/// The most distinct pack texts kept (`pack_start`, `pack_withheld`: a handful of sentences
/// in dronewatt); past it a new one reads as absent, so a stream of made-up texts cannot
/// grow the process.
const MAX_INTERNED: usize = 64;

/// `s` as a `&'static str` ([`PackState`]'s texts are the pack model's constants): each
/// distinct text is kept once, at most [`MAX_INTERNED`].
fn interned(s: &str) -> Option<&'static str> {
    static SEEN: Mutex<Option<HashSet<&'static str>>> = Mutex::new(None);
    let mut g = SEEN.lock().ok()?;
    let set = g.get_or_insert_with(HashSet::new);
    if let Some(&k) = set.get(s) {
        return Some(k);
    }
    if set.len() >= MAX_INTERNED {
        return None;
    }
    let k: &'static str = Box::leak(s.to_string().into_boxed_str());
    set.insert(k);
    Some(k)
}

/// A JSON object's entries in the order written (the models' order is the model set's, which
/// the dashboard's colours follow).
struct InOrder<T>(Vec<(String, T)>);

impl<T> Default for InOrder<T> {
    fn default() -> Self {
        Self(Vec::new())
    }
}

impl<T: Clone> InOrder<T> {
    fn get(&self, name: &str) -> Option<T> {
        self.0
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.clone())
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for InOrder<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for V<T> {
            type Value = InOrder<T>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("an object of model names")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<Self::Value, A::Error> {
                let mut out = Vec::new();
                while let Some((k, v)) = m.next_entry::<String, T>()? {
                    out.push((k, v));
                }
                Ok(InOrder(out))
            }
        }
        d.deserialize_map(V(std::marker::PhantomData))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A report with every field the estimate line carries set, in a non-default way.
    fn full() -> Report {
        let mut sample = Sample::new(42.25, [0.0; N_FEATURES], Some(612.5));
        sample.vehicle = VehicleKind {
            class: VehicleClass::Vtol,
            mav_type: Some(22),
            vtol_state: VtolState::TransitionToFw,
            from_config: false,
        };
        let mut lstm = ModelEstimate::new("lstm", 600.0, Some((550.0, 650.0)));
        lstm.adapted_w = Some(605.5);
        let models = vec![
            ModelEstimate::new("tseng_cal", 580.0, None),
            lstm,
            ModelEstimate::new("dandrea", f32::NAN, None),
        ];
        let battery = BatteryFacts {
            capacity_wh: Some(Sourced::new(
                266.4,
                Provenance::Parameter("BATT_CAPACITY".into()),
            )),
            cell_count: Sourced::new(6, Provenance::FirstVoltage),
            chemistry: Sourced::new("liion".into(), Provenance::Named("--pack 6S".into())),
            low_voltage_v: Some(Sourced::new(21.0, Provenance::Config)),
            critical_voltage_v: Some(Sourced::new(19.8, Provenance::Learned { flights: 3 })),
            rated_capacity_wh: None,
        };
        let pack = PackState {
            battery_v: Some(23.9),
            battery_v_model: Some(23.8),
            battery_ocv_v: Some(24.6),
            battery_rest_v: Some(25.1),
            soc_pct: Some(71.0),
            soc_band_pct: Some(4.0),
            pack_start: Some("resting voltage"),
            pack_withheld: None,
            internal_r_ohm: Some(0.031),
            v_min_forecast_v: Some(22.1),
            v_min_forecast_at_s: Some(300.0),
            time_to_low_v_s: Some(540.0),
            low_threshold_v: Some(21.0),
            battery_pct_disagreement: Some(-12.0),
            battery_end_rest_v: None,
            pack_r_scale: Some(1.2),
            pack_carried_over: true,
            ..PackState::default()
        };
        Report {
            estimate: Estimate {
                t_s: 42.25,
                sample,
                models,
                arrived: None,
            },
            energy: EnergyState {
                energy_used_wh: 12.75,
                remaining_wh: Some(180.0),
                remaining_pct: Some(70.0),
                remaining_source: RemainingSource::RestingVoltage,
                forecast_model: Some("lstm".into()),
                forecast_why: Some("lowest recent error".into()),
                time_to_empty_s: Some(1100.0),
                home_margin_wh: Some(120.0),
                mission_energy_wh: Some(40.0),
                mission_margin_wh: Some(90.0),
                forecast_adapted: true,
                pack,
                battery: battery.into(),
                ..EnergyState::default()
            },
            alerts: Vec::new(),
            vehicle: VehicleId {
                network: 2,
                system_id: 9,
            },
        }
    }

    fn line(r: &Report) -> String {
        let mut out = Vec::new();
        super::super::jsonl::write_estimate(&mut out, r).unwrap();
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn an_estimate_line_read_back_writes_the_same_line() {
        for r in [full(), {
            let mut r = full();
            r.vehicle = VehicleId::single(1);
            r.energy.battery = BatteryFacts::default().into();
            r.energy.remaining_wh = None;
            r.estimate.sample.vehicle = VehicleKind::default();
            r
        }] {
            let written = line(&r);
            let Line::Estimate(back) = read(written.as_bytes()).unwrap() else {
                panic!("not an estimate: {written}")
            };
            assert_eq!(line(&back), written);
            assert_eq!(back.vehicle, r.vehicle);
            assert_eq!(back.estimate.models[1].band_w, Some((550.0, 650.0)));
        }
    }

    #[test]
    fn an_alert_line_reads_back_and_bad_lines_are_errors_not_panics() {
        let a = AlertEvent {
            t: 3.5,
            rule: "low_margin".into(),
            severity: Severity::Critical,
            state: AlertState::Cleared,
            message: "margin 2 Wh".into(),
        };
        let v = VehicleId {
            network: 1,
            system_id: 4,
        };
        let mut out = Vec::new();
        super::super::jsonl::write_alert(&mut out, v, &a).unwrap();
        let Line::Alert(back_v, back) = read(&out).unwrap() else {
            panic!()
        };
        assert_eq!((back_v, back), (v, a));
        for bad in [
            &b"not json"[..],
            br#"{"type":"summary"}"#,
            br#"{"type":"estimate","system_id":300}"#,
            br#"{"type":"alert","system_id":1,"t":1,"rule":"x","severity":"loud","state":"raised","message":""}"#,
        ] {
            assert!(read(bad).is_err(), "{}", String::from_utf8_lossy(bad));
        }
    }
}
