//! One run summed up for the store: the vehicle's key and the flight log built from its
//! reports in bounded memory.

use crate::report::Report;
use crate::vehicle::params::Identity;
use crate::vehicle::store::dir::MIN_PCT_DROP;

/// A vehicle's key in the store, and how strong it is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VehicleKey {
    /// `uid:…` or `sysN-autopilot-TYPE` (`…@netM` on network M of separate networks).
    pub key: String,
    /// `uid` (the board's own id) or `heartbeat` (system id, autopilot, type).
    pub kind: &'static str,
}

impl VehicleKey {
    /// The key of this vehicle (module docs).
    pub fn of(id: &Identity) -> Self {
        match id.uid {
            Some(uid) => Self {
                key: format!("uid:{uid:016x}"),
                kind: "uid",
            },
            // On a separate network (`[[links]] network`), suffixed with its number: two
            // fleets' system id 1 are two vehicles. The only network's keys are as always.
            None if id.network != 0 => Self {
                key: format!(
                    "sys{}-{}-{}@net{}",
                    id.system_id, id.autopilot, id.vehicle_type, id.network
                ),
                kind: "heartbeat",
            },
            None => Self {
                key: format!("sys{}-{}-{}", id.system_id, id.autopilot, id.vehicle_type),
                kind: "heartbeat",
            },
        }
    }
}

/// One flight, summed up from its reports ([`FlightLog`]).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct FlightSummary {
    /// Seconds with the motors turning (measured power above [`FlightLog`]'s threshold).
    pub airborne_s: f64,
    /// Energy used over the run, Wh (the energy tracker's figure).
    pub energy_wh: f64,
    /// The autopilot's battery % at the first and last report that had one.
    pub pct_start: Option<f64>,
    pub pct_end: Option<f64>,
    /// Energy used ÷ battery % drop, Wh (module docs), when the gauge fell enough.
    pub effective_capacity_wh: Option<f64>,
    /// The capacity the run assumed, Wh, and where it came from.
    pub rated_capacity_wh: f64,
    pub capacity_source: String,
    /// The pack: resting voltage before and after, V; resistance scale over the nominal
    /// circuit's and the resistance, Ω, at the end; the heat proxy at the end, A²·s.
    pub rest_v_start: Option<f64>,
    pub rest_v_end: Option<f64>,
    pub r_scale: Option<f64>,
    pub internal_r_ohm: Option<f64>,
    pub heat_a2s: Option<f64>,
    /// The slope of the sag's growth as the pack empties ([`crate::battery::deep`]), as this
    /// flight left it: the next flight on the pack starts from it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub deep_slope: Option<f64>,
    /// Pack health: the energy the pack delivered between its two resting voltages over what
    /// its OCV curve holds between them, % (flights that used at least
    /// [`MIN_SOC_DROP_PCT`] of it).
    pub pack_health_pct: Option<f64>,
    /// The flight's last report on the source's clock when that is a Unix time (a replayed
    /// log), s: the gap to the next flight on the same pack is then the logs' own.
    pub ended_log_s: Option<f64>,
    /// The pack flown, where the vehicle identified it (BATTERY_INFO's serial,
    /// [`crate::vehicle::pack_identity`]); `None`: the flight counts for the vehicle.
    pub pack_id: Option<String>,
}

/// The least state-of-charge drop, %, for a flight's pack health (smaller is noise).
pub const MIN_SOC_DROP_PCT: f64 = 10.0;

/// Sums a run's reports into a [`FlightSummary`] in bounded memory, however long the run:
/// the measured powers go into a histogram of 1 %-wide bins (at most `PowerBins::MAX` bins,
/// a few hundred on a real flight), each bin holding how many reports fell in it and the
/// seconds they cover. The airborne threshold and the seconds above it are read off the
/// histogram, so both are exact to the bin width (1 %).
#[derive(Debug, Default)]
pub struct FlightLog {
    pub(super) power: PowerBins,
    /// Time of the previous report with a measured power.
    last_t: Option<f64>,
    /// Time of the last report, and the source's time its reports count from.
    end_t: Option<f64>,
    log_origin_s: Option<f64>,
    energy_wh: f64,
    pct: Option<(f64, f64)>,
    capacity: Option<(f64, String)>,
    /// The pack as the last report had it (the start state is kept from the first).
    pack: crate::report::PackState,
    pack_start: Option<(f64, f64)>,
    pack_id: Option<String>,
    /// The first hover's calibration, when the run made one (kept as a profile:
    /// [`super::hover::remember_hover`]).
    hover: Option<crate::report::hover::HoverCalibration>,
}

/// Measured powers binned on a log scale: bin 0 below 1 W, bin k ≥ 1 for
/// [1.01^(k−1), 1.01^k) W; (reports, seconds) per bin.
#[derive(Debug, Default)]
pub(crate) struct PowerBins(pub(super) std::collections::BTreeMap<u16, (u64, f64)>);

impl PowerBins {
    /// The most bins there can be (1 W to 1 MW in 1 % steps, and one below 1 W).
    pub(crate) const MAX: u16 = 1 + 1389;

    pub(crate) fn bin(p: f32) -> u16 {
        if p < 1.0 {
            return 0;
        }
        // ln(1.01) = 0.00995033; a power above 1 MW (nonsense) lands in the last bin.
        (1.0 + (f64::from(p).ln() / 1.01f64.ln()).floor()).min(f64::from(Self::MAX - 1)) as u16
    }

    /// A bin's power: its geometric centre (0 for the bin below 1 W).
    pub(crate) fn power(bin: u16) -> f64 {
        if bin == 0 {
            0.0
        } else {
            1.01f64.powf(f64::from(bin) - 0.5)
        }
    }

    fn add(&mut self, p: f32, dt_s: f64) {
        let e = self.0.entry(Self::bin(p)).or_default();
        e.0 += 1;
        e.1 += dt_s;
    }

    fn count(&self) -> u64 {
        self.0.values().map(|e| e.0).sum()
    }

    /// The power of the report at rank `k` (0-based) in increasing order, to the bin.
    fn rank(&self, k: u64) -> f64 {
        let mut seen = 0;
        for (&bin, &(n, _)) in &self.0 {
            seen += n;
            if seen > k {
                return Self::power(bin);
            }
        }
        0.0
    }

    /// Seconds covered by reports with a power above `w`, to the bin.
    fn seconds_above(&self, w: f64) -> f64 {
        self.0
            .iter()
            .filter(|(&bin, _)| Self::power(bin) > w)
            .map(|(_, e)| e.1)
            .sum()
    }
}

impl FlightLog {
    /// The source's time at its first message, s: reports' times count from it. When it is a
    /// Unix time (a replayed log), the flight's end is kept on the log's clock.
    pub fn set_log_origin(&mut self, t_s: Option<f64>) {
        self.log_origin_s = t_s;
    }

    /// The pack flown, once the vehicle identified it.
    pub fn set_pack_id(&mut self, id: Option<String>) {
        if id.is_some() {
            self.pack_id = id;
        }
    }

    /// Take one report in.
    pub fn observe(&mut self, r: &Report) {
        let s = &r.estimate.sample;
        self.end_t = Some(r.estimate.t_s);
        if let Some(p) = s.measured_w.filter(|p| p.is_finite() && *p >= 0.0) {
            let t = r.estimate.t_s;
            // A report's seconds: since the previous one, at most 1 s (a gap is not flight).
            let dt = self.last_t.map_or(0.0, |last| (t - last).clamp(0.0, 1.0));
            self.power.add(p, dt);
            self.last_t = Some(t);
        }
        self.energy_wh = r.energy.energy_used_wh;
        if let Some(c) = r.energy.hover_calibration {
            self.hover = Some(c);
        }
        if let Some(pct) = s
            .battery_remaining_pct
            .map(f64::from)
            .filter(|p| (0.0..=100.0).contains(p))
        {
            self.pct = Some((self.pct.map_or(pct, |(a, _)| a), pct));
        }
        // The rated capacity (config, parameter or default), not one learned from this store.
        let b = &r.energy.battery;
        if let Some(c) = b.rated_capacity_wh.as_ref().or(b.capacity_wh.as_ref()) {
            self.capacity = Some((c.value, c.source.to_string()));
        }
        let pk = &r.energy.pack;
        if let (Some(v), Some(soc)) = (pk.battery_rest_v, pk.soc_pct) {
            // The start state, when it is (re)read: its voltage and state of charge then.
            if pk.battery_end_rest_v.is_none() && self.pack_start.is_none_or(|(v0, _)| v0 != v) {
                self.pack_start = Some((v, soc));
            }
        }
        self.pack = *pk;
    }

    /// The first hover's calibration, when the run made one.
    pub fn hover(&self) -> Option<&crate::report::hover::HoverCalibration> {
        self.hover.as_ref()
    }

    /// The summary, or `None` when no power was ever measured (nothing flew that we saw).
    /// Motors turning: measured power above 30 % of the run's 90th-percentile power (a
    /// multirotor's ground idle is a few % of its hover).
    pub fn summary(&self) -> Option<FlightSummary> {
        let n = self.power.count();
        if n < 2 {
            return None;
        }
        let p90 = self.power.rank((n - 1) * 9 / 10);
        let airborne_s = self.power.seconds_above(0.3 * p90);
        let (rated_capacity_wh, capacity_source) =
            self.capacity.clone().unwrap_or((0.0, "unknown".into()));
        let effective_capacity_wh = self
            .pct
            .map(|(a, b)| a - b)
            .filter(|drop| *drop >= MIN_PCT_DROP)
            .map(|drop| self.energy_wh / (drop / 100.0))
            .filter(|c| c.is_finite());
        let pk = &self.pack;
        let pack_health_pct = match (self.pack_start, pk.end_rest_soc_pct, pk.curve_wh) {
            (Some((_, soc0)), Some(soc1), Some(curve)) if soc0 - soc1 >= MIN_SOC_DROP_PCT => {
                Some(100.0 * self.energy_wh / (curve * (soc0 - soc1) / 100.0))
                    .filter(|h| h.is_finite() && *h > 0.0)
            }
            _ => None,
        };
        Some(FlightSummary {
            airborne_s,
            energy_wh: self.energy_wh,
            pct_start: self.pct.map(|p| p.0),
            pct_end: self.pct.map(|p| p.1),
            effective_capacity_wh,
            rated_capacity_wh,
            capacity_source,
            rest_v_start: self.pack_start.map(|p| p.0),
            rest_v_end: pk.battery_end_rest_v,
            r_scale: pk.pack_r_scale,
            internal_r_ohm: pk.internal_r_ohm,
            heat_a2s: pk.heat_a2s,
            deep_slope: pk.deep_slope,
            pack_health_pct,
            ended_log_s: self
                .log_origin_s
                .and_then(super::unix_clock)
                .zip(self.end_t)
                .map(|(a, b)| a + b)
                .and_then(super::unix_clock),
            pack_id: self.pack_id.clone(),
        })
    }
}
