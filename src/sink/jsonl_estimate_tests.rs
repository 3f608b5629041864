//! The hand-written `estimate` line against the derived struct it replaced (below, as it
//! was in `sink/jsonl.rs`): byte for byte the same over reports with every optional part
//! present or absent, NaN and infinite figures, odd text, several networks and classes.

use super::*;
use crate::features::{Sample, VehicleClass, VehicleKind, VtolState, N_FEATURES};
use crate::report::hover::HoverCalibration;
use crate::report::{
    BatteryFacts, EnergyState, Estimate, ModelEstimate, PackState, Provenance, RemainingSource,
    Report, Sourced, VehicleId,
};
use proptest::prelude::*;
use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;

/// What every line about one vehicle begins with (the derived head the other lines still use).
use crate::sink::jsonl::Head;

/// The `estimate` line as serde wrote it before (the reference).
fn by_serde(w: &mut Vec<u8>, r: &Report) -> std::io::Result<()> {
    let e = &r.estimate;
    let b = &r.energy.battery;
    let s = &e.sample;
    serde_json::to_writer(
        &mut *w,
        &EstimateLine {
            head: Head::new("estimate", r.vehicle),
            t: e.t_s,
            vehicle_class: s.vehicle.class,
            mav_type: s.vehicle.mav_type,
            vtol_state: (s.vehicle.class == crate::features::VehicleClass::Vtol)
                .then(|| s.vehicle.vtol_state.as_str()),
            measured_w: s.measured_w,
            models: PerModel {
                models: &e.models,
                figure: |m| Some(m.power_w),
            },
            bands: PerModel {
                models: &e.models,
                figure: |m| m.band_w.map(|(lo, hi)| [lo, hi]),
            },
            energy_used_wh: r.energy.energy_used_wh,
            remaining_wh: r.energy.remaining_wh,
            remaining_pct: r.energy.remaining_pct,
            remaining_source: r.energy.remaining_source,
            time_to_empty_s: r.energy.time_to_empty_s,
            home_margin_wh: r.energy.home_margin_wh,
            mission_energy_wh: r.energy.mission_energy_wh,
            mission_margin_wh: r.energy.mission_margin_wh,
            adapted: PerModel {
                models: &e.models,
                figure: |m| m.adapted_w,
            },
            forecast_adapted: r.energy.forecast_adapted,
            forecast_model: r.energy.forecast_model.as_deref(),
            forecast_why: r.energy.forecast_why.as_deref(),
            hover_calibration: r.energy.hover_calibration.as_ref(),
            // Not known: null, and the source says why (never another vehicle's pack).
            capacity_wh: b.capacity(),
            capacity_source: b.capacity_source(),
            cell_count: b.cell_count.value,
            cell_count_source: &b.cell_count.source,
            chemistry: &b.chemistry.value,
            chemistry_source: &b.chemistry.source,
            pack: &r.energy.pack,
            low_voltage_v: b.low_voltage_v.as_ref().map(|v| v.value),
            low_voltage_source: b.low_voltage_v.as_ref().map(|v| &v.source),
            critical_voltage_v: b.critical_voltage_v.as_ref().map(|v| v.value),
            critical_voltage_source: b.critical_voltage_v.as_ref().map(|v| &v.source),
        },
    )?;
    w.push(b'\n');
    Ok(())
}

#[derive(Serialize)]
struct EstimateLine<'a> {
    #[serde(flatten)]
    head: Head,
    t: f64,
    /// The vehicle class (`features::class`): which models apply.
    vehicle_class: crate::features::VehicleClass,
    /// The HEARTBEAT's MAV_TYPE number; absent before one is heard.
    #[serde(skip_serializing_if = "Option::is_none")]
    mav_type: Option<u8>,
    /// A VTOL's state (`mc`, `fw`, `transition_to_fw`, `transition_to_mc`, `undefined`);
    /// absent for other classes.
    #[serde(skip_serializing_if = "Option::is_none")]
    vtol_state: Option<&'static str>,
    measured_w: Option<f32>,
    models: PerModel<'a, f32>,
    /// `{"<name>": [low_w, high_w]}` for the models that give an uncertainty band (the LSTM's
    /// 5 %/95 % quantiles); absent when none does.
    #[serde(skip_serializing_if = "PerModel::is_empty")]
    bands: PerModel<'a, [f32; 2]>,
    energy_used_wh: f64,
    /// Energy left to the usable floor, Wh, and where the start state came from
    /// (`resting voltage`, `battery`: the autopilot's %, `assumed full`).
    remaining_wh: Option<f64>,
    /// The state of charge every view shows (`sink::pilot`): `remaining_wh` as a share of
    /// the usable pack, %.
    remaining_pct: Option<f64>,
    remaining_source: crate::report::RemainingSource,
    time_to_empty_s: Option<f64>,
    home_margin_wh: Option<f64>,
    /// While a mission is known (`crate::mission::live`).
    #[serde(skip_serializing_if = "Option::is_none")]
    mission_energy_wh: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mission_margin_wh: Option<f64>,
    /// `{"<name>": watts}`: each model adapted to measured power (`model::adapt`); absent
    /// when adaptation is off.
    #[serde(skip_serializing_if = "PerModel::is_empty")]
    adapted: PerModel<'a, f32>,
    /// Whether the forecast follows the forecast model adapted to measured power.
    forecast_adapted: bool,
    /// The model the forecast follows (null: measured power), and why (`energy::select`).
    forecast_model: Option<&'a str>,
    forecast_why: Option<&'a str>,
    /// The first hover's measured power and the hover efficiency it set
    /// (`energy::hover`), once measured; absent before.
    #[serde(skip_serializing_if = "Option::is_none")]
    hover_calibration: Option<&'a crate::report::hover::HoverCalibration>,
    /// Battery capacity the energy figures use, Wh, and where it came from (`config`,
    /// `vehicle parameter BATT_CAPACITY`, `--pack …` …); null when it is not known, the
    /// source then saying why (`remaining_source` `capacity not known`).
    capacity_wh: Option<f64>,
    capacity_source: String,
    /// Cells in series, and where that came from.
    cell_count: u32,
    cell_count_source: &'a Provenance,
    /// Cell chemistry (`lipo`, `lihv`, `liion`), and where that came from.
    chemistry: &'a str,
    chemistry_source: &'a Provenance,
    /// The pack model: `battery_v`, `battery_v_model`, `battery_ocv_v`, `battery_rest_v`,
    /// `soc_pct`, `internal_r_ohm`, `v_min_forecast_v`, `v_min_forecast_at_s`,
    /// `time_to_low_v_s`, `low_threshold_v`, [`battery_pct_disagreement`].
    #[serde(flatten)]
    pack: &'a crate::report::PackState,
    /// The autopilot's low and critical pack voltages, V, and where they came from; absent
    /// when the vehicle did not say.
    #[serde(skip_serializing_if = "Option::is_none")]
    low_voltage_v: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    low_voltage_source: Option<&'a Provenance>,
    #[serde(skip_serializing_if = "Option::is_none")]
    critical_voltage_v: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    critical_voltage_source: Option<&'a Provenance>,
}

/// One figure of each model as a name → value object (`models`: watts; `adapted`: the
/// adapted watts; `bands`: [low, high] watts), leaving out the models that lack it.
struct PerModel<'a, T> {
    models: &'a [crate::report::ModelEstimate],
    figure: fn(&crate::report::ModelEstimate) -> Option<T>,
}

impl<T> PerModel<'_, T> {
    fn is_empty(&self) -> bool {
        self.models.iter().all(|m| (self.figure)(m).is_none())
    }
}

impl<T: Serialize> Serialize for PerModel<'_, T> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(None)?;
        for e in self.models {
            if let Some(v) = (self.figure)(e) {
                m.serialize_entry(&e.name, &v)?;
            }
        }
        m.end()
    }
}

/// Any f64: every bit pattern (NaN, infinities, subnormals), or a plain figure.
fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![any::<u64>().prop_map(f64::from_bits), -1e5f64..1e5]
}

fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![any::<u32>().prop_map(f32::from_bits), -1e4f32..1e4]
}

/// Text with what JSON escapes (quotes, backslashes, control characters) and what it
/// does not (non-ASCII).
fn odd_text() -> impl Strategy<Value = String> {
    "[a-z_ \"\\\\\n\u{1}\u{7f}é°]{0,8}"
}

const WHYS: [&str; 3] = ["resting voltage", "a \"quoted\" \\ why\n", "état"];

fn provenance(i: usize, text: &str) -> Provenance {
    match i % 6 {
        0 => Provenance::Config,
        1 => Provenance::Parameter(text.into()),
        2 => Provenance::FirstVoltage,
        3 => Provenance::Learned { flights: i },
        4 => Provenance::Default,
        _ => Provenance::Named(text.into()),
    }
}

fn figure(v: &[f64], i: usize) -> Option<f64> {
    (!i.is_multiple_of(3) || v[i].is_nan()).then_some(v[i])
}

/// A report from the drawn figures (`v`: f64s, `g`: f32s, `on`: which parts are there).
fn report(v: &[f64], g: &[f32], on: &[bool], text: &[String], pick: &[usize]) -> Report {
    let class = [
        VehicleClass::Multirotor,
        VehicleClass::FixedWing,
        VehicleClass::Vtol,
        VehicleClass::Other,
    ][pick[0] % 4];
    let vtol_state = [VtolState::Undefined, VtolState::Mc, VtolState::Fw][pick[1] % 3];
    let mut features = [0.0f32; N_FEATURES];
    features[0] = g[0];
    let sample = Sample {
        vehicle: VehicleKind {
            class,
            mav_type: on[0].then_some(pick[2] as u8),
            vtol_state,
            from_config: on[1],
        },
        ..Sample::new(v[0], features, on[2].then_some(g[1]))
    };
    let models = (0..pick[3] % 4)
        .map(|k| ModelEstimate {
            adapted_w: on[3 + k].then_some(g[2 + k]),
            ..ModelEstimate::new(
                text[k].clone(),
                g[k + 1],
                on[4 + k].then_some((g[3 + k], g[4 + k])),
            )
        })
        .collect();
    let hover: HoverCalibration = serde_json::from_value(serde_json::json!({
        "t_s": 12.5, "hover_w": 310.25, "hover_s": 8.0, "eta_h": 0.61, "prior_eta_h": 0.55,
        "avionics_w": 12.0, "payload_kg": 0.5, "applied": on[9], "source": "hover"
    }))
    .unwrap();
    let sourced = |k: usize| Sourced::new(v[k], provenance(pick[4] + k, &text[k % 4]));
    let battery = BatteryFacts {
        capacity_wh: on[10].then(|| sourced(1)),
        cell_count: Sourced::new(pick[5] as u32, provenance(pick[4], &text[1])),
        chemistry: Sourced::new(text[2].clone(), provenance(pick[4] + 1, &text[3])),
        low_voltage_v: on[11].then(|| sourced(2)),
        critical_voltage_v: on[12].then(|| sourced(3)),
        rated_capacity_wh: None,
    };
    let pack = PackState {
        battery_v: figure(v, 4),
        battery_v_model: figure(v, 5),
        battery_ocv_v: figure(v, 6),
        battery_rest_v: figure(v, 7),
        soc_pct: figure(v, 8),
        soc_band_pct: figure(v, 9),
        pack_start: on[13].then_some(WHYS[pick[1] % 3]),
        pack_withheld: on[14].then_some(WHYS[pick[0] % 3]),
        internal_r_ohm: figure(v, 10),
        v_min_forecast_v: figure(v, 11),
        v_min_forecast_at_s: figure(v, 12),
        time_to_low_v_s: figure(v, 13),
        low_threshold_v: figure(v, 14),
        battery_pct_disagreement: figure(v, 15),
        battery_end_rest_v: figure(v, 16),
        end_rest_soc_pct: figure(v, 17),
        pack_r_scale: figure(v, 18),
        pack_carried_over: on[15],
        heat_a2s: figure(v, 19),
        deep_slope: None,
        curve_wh: None,
    };
    let energy = EnergyState {
        energy_used_wh: v[20],
        remaining_wh: figure(v, 21),
        remaining_pct: figure(v, 22),
        remaining_source: [
            RemainingSource::AssumedFull,
            RemainingSource::Battery,
            RemainingSource::default(),
        ][pick[2] % 3],
        time_to_empty_s: figure(v, 23),
        home_margin_wh: figure(v, 24),
        mission_energy_wh: figure(v, 25),
        mission_margin_wh: figure(v, 26),
        forecast_adapted: on[16],
        forecast_model: on[17].then(|| text[0].clone()),
        forecast_why: on[18].then(|| text[1].clone()),
        hover_calibration: on[19].then_some(hover),
        pack,
        battery: battery.into(),
        ..Default::default()
    };
    Report {
        estimate: Estimate {
            arrived: None,
            t_s: v[0],
            sample,
            models,
        },
        energy,
        alerts: Vec::new(),
        vehicle: VehicleId {
            network: pick[6] as u8,
            system_id: pick[2] as u8,
        },
    }
}

proptest! {
    #[test]
    fn the_estimate_line_is_byte_for_byte_what_serde_wrote(
        v in proptest::collection::vec(any_f64(), 27),
        g in proptest::collection::vec(any_f32(), 8),
        on in proptest::collection::vec(any::<bool>(), 20),
        text in proptest::collection::vec(odd_text(), 4),
        pick in proptest::collection::vec(0usize..256, 7),
    ) {
        let r = report(&v, &g, &on, &text, &pick);
        let (mut fast, mut slow) = (Vec::new(), Vec::new());
        write_estimate(&mut fast, &r).unwrap();
        by_serde(&mut slow, &r).unwrap();
        prop_assert_eq!(String::from_utf8(fast).unwrap(), String::from_utf8(slow).unwrap());
    }
}
