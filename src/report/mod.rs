//! The floor the later stages stand on: the typed messages that flow from the models to
//! the sinks. [`Estimate`] is what inference hands the energy + alerts stage; [`Report`]
//! (the estimate, the [`EnergyState`] and the [`AlertEvent`]s it raised) is what that stage
//! hands every sink. They live here, not in the stages that make them, so a stage depends
//! only on what it reads, never on the stage that wrote it (no import loops), and a sink
//! never needs the energy or alert code to read a report. Imports nothing of ours but the
//! feature floor. [`status`] is the other half of the floor: what a chain says beside the
//! reports (ingest counters, signal health, the uplink, the stop signal).

pub(crate) mod battery;
pub mod hover;
pub mod status;

pub use battery::{
    BatteryFacts, Provenance, Sourced, BATTERY_PCT_AGREE, CAPACITY_UNKNOWN, DEFAULT_CELL_COUNT,
    M100_CAPACITY_WH, M100_CELL_COUNT, M100_PACK,
};

use std::fmt;

use serde::{Serialize, Serializer};

use crate::features::Sample;

/// One model's estimate, named.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelEstimate {
    /// The model's stable name (`dandrea`, `tseng_cal`, `lstm`, …).
    pub name: String,
    /// Predicted electrical power, W.
    pub power_w: f32,
    /// The model's uncertainty band (low, high), W, where it gives one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub band_w: Option<(f32, f32)>,
    /// The prediction corrected by online adaptation to measured power
    /// (`model::adapt`), W; absent when adaptation is off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adapted_w: Option<f32>,
    /// The prediction corrected by the slowly adapting reference the `deviation_above`
    /// alert compares with (`model::adapt`), W; absent when adaptation is off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_w: Option<f32>,
    /// How `adapted_w` has done on this vehicle lately (`model::adapt`): what the forecast
    /// picks its model by (`energy::select`); absent before the first scored window.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adapted_err: Option<AdaptedError>,
}

/// The adapted estimate's recent error on this vehicle, and the evidence behind it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AdaptedError {
    /// Recent mean absolute error against measured power, W (forgotten like the fit).
    pub err_w: f32,
    /// Seconds of flight with measured power that scored the model this run.
    pub evidence_s: f32,
}

impl ModelEstimate {
    /// A raw estimate (no adaptation).
    pub fn new(name: impl Into<String>, power_w: f32, band_w: Option<(f32, f32)>) -> Self {
        Self {
            name: name.into(),
            power_w,
            band_w,
            adapted_w: None,
            reference_w: None,
            adapted_err: None,
        }
    }
}

/// Every model's estimate for one window: what the inference stage sends on.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// Time of the window's newest sample, s.
    pub t_s: f64,
    /// The window's newest sample (features, measured power, home vector).
    pub sample: Sample,
    /// One entry per model that ran, in the model set's order.
    pub models: Vec<ModelEstimate>,
    /// When the newest message behind it reached dronewatt (its window's `arrived`);
    /// `None` for estimates not from a source (a silent tick, offline work).
    pub arrived: Option<std::time::Instant>,
}

impl Estimate {
    /// What is known at `t_s` when nothing has been heard since `self`: every feature
    /// stale, nothing measured, no model ran. The chain evaluates its alert rules on it
    /// while a live link is silent, so `telemetry_lost` fires on a link gone quiet.
    pub fn silent(&self, t_s: f64) -> Estimate {
        let mut sample = self.sample.clone();
        sample.t_s = t_s;
        sample.stale_mask = u32::MAX;
        sample.measured_w = None;
        Estimate {
            t_s,
            sample,
            models: Vec::new(),
            arrived: None,
        }
    }
}

/// What `energy_used_wh` integrated at one step.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum PowerSource {
    /// The measured electrical power V·I.
    Measured,
    /// The named model's prediction (nothing was measured).
    Model(String),
    /// Neither: nothing was integrated.
    #[default]
    None,
}

impl PowerSource {
    /// As JSON and the terminal say it: `measured`, the model's name, or `none`.
    pub fn as_str(&self) -> &str {
        match self {
            PowerSource::Measured => "measured",
            PowerSource::Model(name) => name,
            PowerSource::None => "none",
        }
    }
}

/// Where `remaining_wh` comes from.
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    Eq,
    Serialize,
    serde::Deserialize,
    strum::IntoStaticStr,
    strum::Display,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum RemainingSource {
    /// No start state known: the capacity minus the energy used, as if the pack had
    /// started full (said so, never silently).
    #[default]
    #[serde(rename = "assumed full")]
    #[strum(serialize = "assumed full")]
    AssumedFull,
    /// The autopilot's reported state of charge × the capacity.
    Battery,
    /// The resting voltage before take-off through the pack's OCV curve, then the
    /// equivalent circuit, down to the usable floor (the low-voltage threshold under load).
    #[serde(rename = "resting voltage")]
    #[strum(serialize = "resting voltage")]
    RestingVoltage,
    /// As `resting voltage`, the state started load-compensated instead (OCV = V + I·R with
    /// a prior resistance: no rest was read; a wider band).
    #[serde(rename = "load-compensated voltage")]
    #[strum(serialize = "load-compensated voltage")]
    LoadCompensated,
    /// No battery telemetry at all (no voltage, no current, no %): the configured pack's
    /// capacity minus the energy of the forecast model's power, the pack taken as full at
    /// the start (said once in a warning).
    #[serde(rename = "model power")]
    #[strum(serialize = "model power")]
    ModelPower,
    /// The pack's capacity is not known (no parameter, BATTERY_INFO, store, config or
    /// `--pack` gives it): remaining energy and time to empty are null, never another
    /// vehicle's pack; the state of charge from the voltage, the energy used and the pack's
    /// voltage are still reported.
    #[serde(rename = "capacity not known")]
    #[strum(serialize = "capacity not known")]
    UnknownPack,
}

impl RemainingSource {
    /// As JSON and the terminal say it.
    pub fn as_str(self) -> &'static str {
        self.into()
    }
}

/// The pack model's view at one estimate ([`crate::energy`]'s pack): each value absent
/// until known (no voltage yet, no resting voltage read, no forecast power).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct PackState {
    /// Measured pack voltage, V.
    pub battery_v: Option<f64>,
    /// Modelled loaded voltage for this sample (predicted before it was seen), V.
    pub battery_v_model: Option<f64>,
    /// Open-circuit voltage now, V.
    pub battery_ocv_v: Option<f64>,
    /// The resting voltage the pack's state started from, V.
    pub battery_rest_v: Option<f64>,
    /// State of charge, % of the OCV curve's energy (from the voltage and cells when the
    /// capacity is not known).
    pub soc_pct: Option<f64>,
    /// The state of charge's band, ± points (wider for a load-compensated start and an
    /// assumed chemistry).
    pub soc_band_pct: Option<f64>,
    /// How the pack's start state was read: `resting voltage`, or `load-compensated …`
    /// (V + I·R with a prior resistance: no rest before take-off, a noisy ground current,
    /// a monitor attached in flight).
    pub pack_start: Option<&'static str>,
    /// Why the modelled voltage, the voltage forecast and the time to the low voltage are
    /// null (a pack that does not sag; a model outside the chemistry's range), when they are.
    pub pack_withheld: Option<&'static str>,
    /// Series resistance now, Ω (estimated online).
    pub internal_r_ohm: Option<f64>,
    /// Lowest loaded voltage forecast for the rest of the flight, V, and when, s from now.
    pub v_min_forecast_v: Option<f64>,
    pub v_min_forecast_at_s: Option<f64>,
    /// Time until the forecast loaded voltage crosses the low threshold, s.
    pub time_to_low_v_s: Option<f64>,
    /// The low threshold: the autopilot's `BATT_LOW_VOLT`, else 3.5 V a cell, V.
    pub low_threshold_v: Option<f64>,
    /// The autopilot's battery % minus the resting voltage's state of charge, points, when
    /// they disagree by more than [`BATTERY_PCT_AGREE`] (ArduPilot counts from "full at
    /// boot", so a half pack reads 100 %).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub battery_pct_disagreement: Option<f64>,
    /// The resting voltage after landing, V, and its state of charge, %.
    pub battery_end_rest_v: Option<f64>,
    #[serde(skip)]
    pub end_rest_soc_pct: Option<f64>,
    /// This flight's pack resistance over the nominal circuit's (1: as fitted on the M100).
    pub pack_r_scale: Option<f64>,
    /// Whether the pack's resistance and warmth came from its previous flight.
    pub pack_carried_over: bool,
    /// The heat proxy, A²·s (for the vehicle store).
    #[serde(skip)]
    pub heat_a2s: Option<f64>,
    /// The slope of the sag's growth as the pack empties this flight showed
    /// ([`crate::battery::deep`]; for the vehicle store, the next flight on this pack).
    #[serde(skip)]
    pub deep_slope: Option<f64>,
    /// The OCV curve's whole energy, Wh (for the vehicle store's pack health).
    #[serde(skip)]
    pub curve_wh: Option<f64>,
}

/// Energy bookkeeping at one estimate (see [`crate::energy`] for the formulas). Absent
/// values mean "not known yet" (no power seen, no home), never zero.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct EnergyState {
    /// Energy drawn so far, Wh.
    pub energy_used_wh: f64,
    /// What `energy_used_wh` integrated at this step.
    pub power_source: PowerSource,
    /// Remaining usable energy, Wh, when known.
    pub remaining_wh: Option<f64>,
    /// Remaining energy as a percentage of the capacity.
    pub remaining_pct: Option<f64>,
    /// Where `remaining_wh` comes from.
    pub remaining_source: RemainingSource,
    /// Smoothed power the forecasts assume, W.
    pub forecast_w: Option<f64>,
    /// The model whose prediction the forecast follows, when a model ran (else the
    /// forecast follows measured power).
    pub forecast_model: Option<String>,
    /// Why the forecast follows `forecast_model` (`energy::select`): the config, the
    /// default (the vehicle profile's choice, else the M100's LSTM), or its lowest recent
    /// error on this vehicle.
    pub forecast_why: Option<String>,
    /// Time to empty at the forecast power, s.
    pub time_to_empty_s: Option<f64>,
    /// Energy needed to fly home, descend and land, Wh (needs a home position).
    pub home_energy_wh: Option<f64>,
    /// Remaining minus energy to get home minus reserve, Wh.
    pub home_margin_wh: Option<f64>,
    /// Battery voltage per cell, V (voltage / cell count), when the voltage is known.
    pub cell_voltage_v: Option<f64>,
    /// Energy the rest of the planned mission, the return and the landing need (P50), Wh,
    /// while a mission is known (`crate::mission::live`).
    pub mission_energy_wh: Option<f64>,
    /// Remaining − mission energy − reserve, Wh: below 0, the mission cannot finish with
    /// the reserve left.
    pub mission_margin_wh: Option<f64>,
    /// Where the vehicle stands in its mission, while one is known.
    pub mission: Option<MissionStatus>,
    /// Whether the forecast (and the power integrated when nothing is measured) is the
    /// forecast model's prediction adapted to measured power.
    pub forecast_adapted: bool,
    /// The pack model: voltages, state of charge, resistance, the voltage forecast.
    #[serde(flatten)]
    pub pack: PackState,
    /// Capacity, cells and the autopilot's thresholds the figures above use, each with
    /// where it came from. Shared with the energy tracker until they change (a handful of
    /// times a flight): every estimate's state points at them instead of copying their
    /// strings (1.4 % of a flat-out fleet replay's CPU, issue 47).
    #[serde(serialize_with = "battery::shared::serialize")]
    pub battery: std::sync::Arc<BatteryFacts>,
    /// The first hover's calibration of the momentum-theory member, once measured (the
    /// energy tracker's first-hover search).
    pub hover_calibration: Option<hover::HoverCalibration>,
}

/// What the mission task hands the energy stage, in source-time order: from `t_s` on, this
/// status, or none (the mission was cleared, or cannot be forecast).
#[derive(Debug, Clone, PartialEq)]
pub struct MissionUpdate {
    pub t_s: f64,
    pub status: Option<MissionStatus>,
}

/// The live mission forecast at one moment: what the mission task
/// (`crate::mission::live`) hands the energy stage, in source-time order.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct MissionStatus {
    /// Source time of the message it was computed on, s.
    pub t_s: f64,
    /// MISSION_CURRENT's `seq`: the item being flown to.
    pub current_seq: u16,
    /// Items in the mission as the vehicle holds it (ArduPilot's home item included).
    pub items: u16,
    /// Planned time left, s (rest of the mission, return, landing).
    pub time_left_s: f64,
    /// Energy left, P50, Wh.
    pub energy_p50_wh: f64,
    /// Energy left, P90, Wh.
    pub energy_p90_wh: f64,
    /// How far along the planned trajectory, % of its time.
    pub progress_pct: f64,
    /// The planned route, east/north of home (m), at most [`MissionStatus::ROUTE_POINTS`]
    /// points (shared: one allocation per mission flown, not per status). Not serialised
    /// with the energy (the dashboard sends it on its own).
    #[serde(skip)]
    pub route_en_m: std::sync::Arc<Vec<[f32; 2]>>,
    /// Index into `route_en_m` nearest where the vehicle is.
    #[serde(skip)]
    pub route_at: usize,
}

impl MissionStatus {
    /// Most points of [`MissionStatus::route_en_m`].
    pub const ROUTE_POINTS: usize = 400;
}

/// MAVLink's MAV_SEVERITY, the scale ground stations already colour and speak. In TOML
/// either the short lower-case name (`warning`) or the enum name (`MAV_SEVERITY_WARNING`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
#[derive(strum::IntoStaticStr, strum::VariantArray, strum::Display)]
#[strum(serialize_all = "lowercase")]
pub enum Severity {
    Emergency,
    Alert,
    Critical,
    Error,
    Warning,
    Notice,
    Info,
    Debug,
}

impl Severity {
    /// Every severity, most severe first (MAV_SEVERITY's order and values).
    pub const ALL: &'static [Severity] = <Severity as strum::VariantArray>::VARIANTS;
    /// Lower-case name (also its `Display`).
    pub fn name(self) -> &'static str {
        self.into()
    }
}

impl std::str::FromStr for Severity {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let short = s.trim().to_ascii_lowercase();
        let short = short.strip_prefix("mav_severity_").unwrap_or(&short);
        Self::ALL.iter().copied().find(|v| v.name() == short).ok_or_else(|| {
            format!("severity '{s}': expected one of emergency, alert, critical, error, warning, notice, info, debug")
        })
    }
}

impl<'de> serde::Deserialize<'de> for Severity {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d)?
            .parse()
            .map_err(serde::de::Error::custom)
    }
}

/// An alert raised or cleared.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AlertEvent {
    /// Time of the estimate that raised or cleared it, s (source clock).
    pub t: f64,
    /// The rule's name.
    pub rule: String,
    /// The rule's severity (serialised as its lower-case MAV_SEVERITY name, `warning`).
    pub severity: Severity,
    pub state: AlertState,
    /// A short human sentence with the value (a STATUSTEXT carries its first 50 bytes).
    pub message: String,
}

/// Whether an alert began or ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AlertState {
    Raised,
    Cleared,
}

/// What the energy + alerts stage sends to every sink.
#[derive(Debug, Clone)]
pub struct Report {
    pub estimate: Estimate,
    pub energy: EnergyState,
    pub alerts: Vec<AlertEvent>,
    /// The vehicle this is about: its network and the MAVLink system id the telemetry
    /// stage locked onto (system id 1 when the source has none, e.g. a data-set replay, or
    /// before one is heard).
    pub vehicle: VehicleId,
}

/// Who a vehicle is across links: its MAVLink system id, and the network it flies on where
/// the links are separate networks (two fleets may both use system id 1).
///
/// `network` is 0 when every link is one network (the usual case, and every recorded
/// source): the vehicle is then its system id alone and reads as it always did (`7`).
/// With separate networks (`[[links]] network = "…"` naming more than one), networks are
/// numbered from 1 in the order the config first names them, and a vehicle reads
/// `network:system id` (`2:1`), in the terminal, JSON (`network` beside `system_id`), MQTT
/// topics and the dashboard alike.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct VehicleId {
    /// 0: the only network; else the network's number (from 1).
    pub network: u8,
    /// The MAVLink system id.
    pub system_id: u8,
}

impl VehicleId {
    /// A vehicle on the only network.
    pub const fn single(system_id: u8) -> Self {
        Self {
            network: 0,
            system_id,
        }
    }
    /// `network` as JSON carries it: absent on the only network.
    pub fn network_field(&self) -> Option<u8> {
        (self.network != 0).then_some(self.network)
    }
}

impl Serialize for VehicleId {
    /// The system id as a number on the only network (as JSON always carried it), else the
    /// string `"2:7"`.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.network {
            0 => s.serialize_u8(self.system_id),
            _ => s.collect_str(self),
        }
    }
}

impl std::str::FromStr for VehicleId {
    type Err = String;
    /// `7` or `2:7`, as [`VehicleId`] displays.
    fn from_str(s: &str) -> Result<Self, String> {
        let num = |p: &str| {
            p.trim()
                .parse::<u8>()
                .map_err(|_| format!("vehicle {s:?}: expected SYSID or NETWORK:SYSID (0-255 each)"))
        };
        match s.split_once(':') {
            Some((n, id)) => Ok(Self {
                network: num(n)?,
                system_id: num(id)?,
            }),
            None => Ok(Self::single(num(s)?)),
        }
    }
}

impl From<u8> for VehicleId {
    fn from(system_id: u8) -> Self {
        Self::single(system_id)
    }
}

impl fmt::Display for VehicleId {
    /// `7` on the only network, `2:7` on network 2.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Padded as a string is, so a table's `{:>8}` lines it up.
        match self.network {
            0 => f.pad(&self.system_id.to_string()),
            n => f.pad(&format!("{n}:{}", self.system_id)),
        }
    }
}

// The enums read as the strings JSON has always carried, in code and in tests.
impl Serialize for PowerSource {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}
impl fmt::Display for PowerSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}
impl PartialEq<&str> for PowerSource {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}
impl PartialEq<&str> for RemainingSource {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}
impl PartialEq<&str> for Severity {
    fn eq(&self, other: &&str) -> bool {
        self.name() == *other
    }
}

#[cfg(test)]
mod vehicle_id_tests {
    use super::*;

    #[test]
    fn the_only_network_reads_as_the_system_id_and_others_as_network_colon_id() {
        let one = VehicleId::single(7);
        let two = VehicleId {
            network: 2,
            system_id: 7,
        };
        assert_eq!(
            (one.to_string(), two.to_string()),
            ("7".into(), "2:7".into())
        );
        assert_eq!(format!("{two:>5}|"), "  2:7|");
        assert_eq!(serde_json::to_value(one).unwrap(), serde_json::json!(7));
        assert_eq!(serde_json::to_value(two).unwrap(), serde_json::json!("2:7"));
        assert_eq!("7".parse::<VehicleId>(), Ok(one));
        assert_eq!("2:7".parse::<VehicleId>(), Ok(two));
        assert!("2:x"
            .parse::<VehicleId>()
            .unwrap_err()
            .contains("NETWORK:SYSID"));
        assert_eq!((one.network_field(), two.network_field()), (None, Some(2)));
    }
}

#[cfg(test)]
mod name_tests {
    use super::*;

    /// The names JSON, the terminal and the config use (strum's derives, as the
    /// hand-written ones were).
    #[test]
    fn enum_names_are_as_written_before() {
        let names: Vec<&str> = Severity::ALL.iter().map(|s| s.name()).collect();
        assert_eq!(
            names,
            [
                "emergency",
                "alert",
                "critical",
                "error",
                "warning",
                "notice",
                "info",
                "debug"
            ]
        );
        for (i, s) in Severity::ALL.iter().enumerate() {
            assert_eq!(*s as usize, i, "MAV_SEVERITY's value");
            assert_eq!(s.to_string(), s.name());
            assert_eq!(s.name().parse::<Severity>(), Ok(*s));
        }
        assert_eq!(" MAV_SEVERITY_Warning".parse(), Ok(Severity::Warning));
        assert!("warn"
            .parse::<Severity>()
            .unwrap_err()
            .contains("expected one of"));
        for (r, name) in [
            (RemainingSource::AssumedFull, "assumed full"),
            (RemainingSource::Battery, "battery"),
            (RemainingSource::RestingVoltage, "resting voltage"),
        ] {
            assert_eq!((r.as_str(), r.to_string()), (name, name.to_string()));
            assert_eq!(serde_json::to_value(r).unwrap(), name);
        }
    }
}
