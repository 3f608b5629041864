//! Energy used, remaining energy and time, energy to get home.
//!
//! The tracker turns a stream of [`Estimate`]s into an [`EnergyState`]:
//!
//! - **energy used** `E_used = ∫ P dt`, trapezoidal, Wh. `P` is the measured electrical power
//!   V·I when the sample has it, else the predicted power of the *forecast model* (the one
//!   `[energy] model` names, else `lstm`), else of the first model that ran. Which one was
//!   integrated is in [`EnergyState::power_source`]. A step longer than `max_dt_s` (a gap,
//!   a lost link) is capped at `max_dt_s`, and a step backwards (a clock jump, a new
//!   replay) integrates nothing: one bad timestamp cannot add or remove an hour.
//! - **remaining** `E_rem = E_cap − E_used`, or `E_cap · pct / 100` when the autopilot reports
//!   a battery percentage (BATTERY_STATUS `battery_remaining`). `E_cap` is `capacity_wh` when
//!   the config (or `--pack`) sets it, else what the vehicle store learned, else the
//!   vehicle's own capacity parameter (`BATT_CAPACITY`, `BAT1_CAPACITY`: mAh × cells ×
//!   `nominal_cell_v`) ([`crate::vehicle::resolve_battery`]); [`EnergyState::battery`] says
//!   which. Else the capacity is **not known**: remaining energy and time to empty are null
//!   (`remaining_source` "capacity not known", said once), and what is known without it is
//!   still reported: the state of charge from the voltage and cells, the energy used, the
//!   pack's voltages. No vehicle ever gets another vehicle's pack (the M100's TB48D is the
//!   data set's and the M100 profile's only). The cell count likewise (config,
//!   `BAT1_N_CELLS`, the first voltage seen, else assumed and said).
//! - **forecast model**: `[energy] model` when set, else the vehicle profile's (`learn`
//!   picks it), else `lstm`, until this vehicle's measured power shows another model's
//!   adapted estimate steadily better ([`select`]: online selection with a minimum of
//!   evidence and hysteresis). [`EnergyState::forecast_model`] and
//!   [`EnergyState::forecast_why`] say which and why.
//! - **forecast power** `P_f`: an exponential moving average (time constant `smoothing_s`)
//!   of the forecast model's prediction, adapted to measured power when adaptation runs
//!   ([`crate::model::adapt`]; [`EnergyState::forecast_adapted`]); without one, of the measured power (a physics
//!   model is a worse guess of the next minutes than the power actually drawn); without
//!   either, of the first model that ran. [`EnergyState::forecast_model`] says which.
//! - **time to empty** `t_empty = 3600 · E_rem / P_f`, s.
//! - **energy to get home** `E_home = P_cruise · d / v_cruise + P_hover · (h / v_descent + t_land)`,
//!   Wh after dividing by 3600, where `d` and `h` are the horizontal distance to home and
//!   the height above it (m, from the sample's home vector), `v_cruise` is `cruise_speed_m_s`
//!   (default the mission's commanded speed, else 10 m/s), `P_cruise` the smoothed forecast
//!   power while the vehicle moved at ≥ half the cruise speed (else `P_f`), `P_hover` the
//!   smoothed forecast power while it moved slower (else `P_cruise`): descending and landing
//!   cost about what hovering does on a multirotor.
//! - **home margin** `E_rem − E_home − E_reserve`, `E_reserve = reserve_pct/100 · E_cap`.
//! - **the first hover** ([`hover`]): for a vehicle whose forecast is the momentum-theory
//!   member (a spec sheet), the measured power of its first hover sets that member's hover
//!   efficiency; from then on its power, the forecast and the mission's energy are the
//!   vehicle's ([`EnergyState::hover_calibration`] says so).
//! - **mission margin** `E_rem − E_mission − E_reserve`, `E_mission` the live mission
//!   forecast's P50 energy for the rest of the mission, the return and the landing
//!   ([`crate::mission::live`], set with [`EnergyTracker::set_mission`]).

use crate::features::idx;
use crate::report::{BatteryFacts, Estimate, ModelEstimate, Provenance, Sourced};
use crate::report::{EnergyState, PowerSource, RemainingSource};
use crate::vehicle::params::VehicleParams;

pub mod hover;
mod hover_tracker;
pub mod pack;
pub mod select;
mod state;
use state::PowerNow;
pub mod steady;

mod config;
pub use config::EnergyConfig;

use steady::Ema;

/// Integrates power into energy and forecasts what is left. Its whole state serialises
/// (a fleet worker's checkpoint).
#[derive(Clone, serde::Serialize, serde::Deserialize)]
pub struct EnergyTracker {
    cfg: EnergyConfig,
    cruise_speed_m_s: f64,
    last: Option<(f64, f64)>,
    used_wh: f64,
    forecast: Ema,
    cruise: Ema,
    hover: Ema,
    /// The measured power in flight, smoothed: what the pack's forecast flies when the
    /// forecast model's power is not this vehicle's ([`pack::pack_power`]).
    measured_avg: Ema,
    /// In flight since when ([`steady`]): the averages restart at take-off.
    airborne: steady::Airborne,
    /// Remaining energy that does not rise under load ([`steady`]).
    no_rise: steady::NoRise,
    mission: Option<crate::report::MissionStatus>,
    /// The mission's mean power over the whole plan (W), from its first status, with its
    /// item count: the pack's forecast flies on at it past the mission's end.
    plan_mean_w: Option<(u16, f64)>,
    /// Capacity and cells, with where they came from (shared with each estimate's state).
    #[serde(with = "crate::report::battery::shared")]
    battery: std::sync::Arc<BatteryFacts>,
    /// What the vehicle said about itself, when it did.
    vehicle: VehicleParams,
    /// The first battery voltage seen, V (the cell count when nothing better says).
    first_voltage_v: Option<f64>,
    /// The pack's effective capacity learned on earlier flights, Wh, and over how many.
    learned_capacity: Option<(f64, usize)>,
    /// Messages already warned about (each parameter problem once).
    warned: Vec<String>,
    /// Warned once: the vehicle's battery % disagrees with the resting voltage.
    warned_pct: bool,
    /// Warned once: flying with the pack assumed full.
    warned_full: bool,
    /// Warned once: no battery telemetry (remaining from the model's power), and no pack
    /// known for a vehicle that is not a multirotor.
    warned_model_power: bool,
    warned_no_pack: bool,
    /// Say nothing (a tracker that only keeps books beside the live one).
    quiet: bool,
    /// Which model the forecast follows ([`select`]).
    selector: select::Selector,
    /// The pack: start state from the resting voltage, equivalent circuit, voltage forecast.
    pack: pack::Pack,
    /// The first hover's calibration of the momentum-theory member ([`hover`]).
    first_hover: hover::HoverCalibrator,
}

impl EnergyTracker {
    /// The live mission forecast the next updates account with (None: no mission known).
    pub fn set_mission(&mut self, m: Option<crate::report::MissionStatus>) {
        let m = m.map(|m| self.hover_scaled(m));
        if let Some(s) = m.as_ref() {
            let fresh = self.plan_mean_w.is_none_or(|(items, _)| items != s.items);
            if fresh && s.time_left_s > 1.0 && s.energy_p50_wh > 0.0 {
                self.plan_mean_w = Some((s.items, 3600.0 * s.energy_p50_wh / s.time_left_s));
            }
        }
        self.mission = m;
    }

    /// A tracker for this configuration's battery and reserve.
    /// `mission_speed_m_s` is the mission's commanded speed (`[mission] speed_m_s`), the
    /// default cruise speed home.
    pub fn new(cfg: &EnergyConfig, mission_speed_m_s: Option<f32>) -> anyhow::Result<Self> {
        cfg.validate().map_err(anyhow::Error::msg)?;
        let cruise = cfg
            .cruise_speed_m_s
            .or(mission_speed_m_s.map(f64::from))
            .filter(|v| *v > 0.0)
            .unwrap_or(10.0);
        Ok(Self {
            cfg: cfg.clone(),
            cruise_speed_m_s: cruise,
            last: None,
            used_wh: 0.0,
            forecast: Ema::default(),
            cruise: Ema::default(),
            hover: Ema::default(),
            measured_avg: Ema::default(),
            airborne: steady::Airborne::default(),
            no_rise: steady::NoRise::default(),
            mission: None,
            plan_mean_w: None,
            battery: crate::vehicle::battery_from_config(&cfg.battery()).into(),
            vehicle: VehicleParams::default(),
            first_voltage_v: None,
            learned_capacity: None,
            warned: Vec::new(),
            warned_pct: false,
            warned_full: false,
            warned_model_power: false,
            warned_no_pack: false,
            quiet: false,
            selector: select::Selector::new(&cfg.select, cfg.model.as_deref(), None),
            pack: pack::Pack::new(cfg.reserve_pct / 100.0),
            first_hover: hover::HoverCalibrator::new(Err("no vehicle profile".into()), false),
        })
    }

    /// The forecast model to start from when `[energy] model` is not set: the vehicle
    /// profile's (`model`), and where that came from (`from`, shown as the reason).
    pub fn set_default_model(&mut self, model: &str, from: &str) {
        self.selector = select::Selector::new(
            &self.cfg.select,
            self.cfg.model.as_deref(),
            Some((model, from)),
        );
    }

    /// Take what the vehicle said about itself ([`crate::vehicle::params`]): capacity and
    /// cells come from it where the config is silent. A parameter out of range is warned
    /// about once and left out.
    pub fn set_vehicle(&mut self, params: VehicleParams) {
        self.set_hover_throttle(params.get("MOT_THST_HOVER"));
        self.vehicle = params;
        self.resolve_battery();
    }

    /// Take the pack's effective capacity learned on earlier flights of this vehicle (Wh,
    /// over how many flights): it beats the vehicle's rated capacity, not the config.
    pub fn set_learned_capacity(&mut self, learned: Option<(f64, usize)>) {
        self.learned_capacity = learned.filter(|(wh, n)| wh.is_finite() && *wh > 0.0 && *n > 0);
        self.resolve_battery();
    }

    /// What the last flight of this vehicle left of its pack (the vehicle store): carried
    /// into this flight when it starts soon after on the same pack.
    pub fn set_pack_history(&mut self, h: Option<crate::battery::PackHistory>) {
        self.pack.history = h;
    }

    /// The energy used so far, Wh.
    pub fn used_wh(&self) -> f64 {
        self.used_wh
    }

    /// Go on from `saved`, a state a fleet worker's checkpoint kept of this vehicle (made
    /// with the same configuration: the card matched): this tracker's configuration stays
    /// (with what is no TOML key, the pack's name), and the battery facts are derived again
    /// (what their JSON does not carry, the autopilot's low voltages).
    pub fn restore(&mut self, saved: EnergyTracker) {
        let (cfg, quiet) = (self.cfg.clone(), self.quiet);
        *self = Self {
            cfg,
            quiet,
            ..saved
        };
        self.resolve_battery();
    }

    /// A tracker that warns of nothing: bookkeeping beside the live one (an offline
    /// chain's per-model energy), whose pack notes the live tracker already says.
    pub fn quiet(mut self) -> Self {
        self.quiet = true;
        self
    }

    fn say(&self, message: std::fmt::Arguments) {
        if !self.quiet {
            tracing::warn!("{message}");
        }
    }

    /// Capacity and cells as they stand, with their provenance.
    pub fn battery(&self) -> &BatteryFacts {
        &self.battery
    }

    fn resolve_battery(&mut self) {
        let (mut facts, notes) = crate::vehicle::resolve_battery(
            &self.cfg.battery(),
            &self.vehicle,
            self.first_voltage_v,
        );
        if let (Some((wh, flights)), None) = (self.learned_capacity, self.cfg.capacity_wh) {
            facts.rated_capacity_wh = facts
                .capacity_wh
                .replace(Sourced::new(wh, Provenance::Learned { flights }));
        }
        for n in notes {
            if !self.warned.contains(&n) {
                self.say(format_args!("{n}"));
                self.warned.push(n);
            }
        }
        if facts.capacity_wh != self.battery.capacity_wh
            || facts.cell_count != self.battery.cell_count
        {
            tracing::debug!(
                "battery: {:.1} Wh ({}), {} cells ({})",
                facts.capacity().unwrap_or(f64::NAN),
                facts.capacity_source(),
                facts.cell_count.value,
                facts.cell_count.source
            );
        }
        self.battery = facts.into();
    }

    /// Account for one estimate.
    pub fn update(&mut self, est: &Estimate) -> EnergyState {
        // The autopilot's own state of charge, when it reports one (used if `use_battery_pct`).
        self.update_with_battery(est, est.sample.battery_remaining_pct.map(f64::from))
    }

    /// Account for one estimate, with the autopilot's reported remaining charge (%,
    /// BATTERY_STATUS `battery_remaining`) when it sends one.
    pub fn update_with_battery(&mut self, est: &Estimate, battery_pct: Option<f64>) -> EnergyState {
        let s = &est.sample;
        self.selector.update(est.t_s, &est.models);
        self.note_first_voltage(s);
        // the first hover's search ([`hover`]; [`EnergyTracker::calibrated`] applies it)
        self.observe_hover(s, s.measured_w.map(f64::from).filter(|p| p.is_finite()));
        let PowerNow {
            measured,
            power,
            power_source,
            forecast_from,
            preferred,
            forecast_adapted,
        } = self.power_now(est);

        let t = est.t_s;
        let dt = self.integrate(t, power);
        let load = self.pack_load(s, measured, dt);
        let forecast_input = forecast_from.map(|(_, p)| p);
        let (forecast, pk) = self.forecast_and_pack(est, dt, forecast_input, measured, &load);
        let reported_pct = battery_pct.filter(|p| (0.0..=100.0).contains(p));
        let disagreement = self.pct_disagreement(reported_pct, &pk);
        let cap = self.battery.capacity();
        let (remaining, remaining_source, full_wh) =
            self.remaining_now(est, &pk, &power_source, reported_pct, &load, cap);
        let time_to_empty_s =
            state::time_to_empty(remaining_source, pk.time_to_low_v_s, remaining, forecast);
        let home_energy_wh = self.home_energy_wh(s, forecast);
        let reserve = full_wh.map(|f| f * self.cfg.reserve_pct / 100.0);
        let remaining_pct = state::remaining_pct(remaining, full_wh, cap, &pk, reported_pct);
        EnergyState {
            energy_used_wh: self.used_wh,
            power_source,
            remaining_wh: remaining,
            remaining_pct,
            remaining_source,
            forecast_w: forecast,
            forecast_model: forecast_from.and_then(|(m, _)| m).map(|m| m.name.clone()),
            forecast_why: preferred.then(|| self.selector.current().why.to_string()),
            time_to_empty_s,
            home_energy_wh,
            home_margin_wh: remaining
                .zip(home_energy_wh)
                .zip(reserve)
                .map(|((r, e), res)| r - e - res),
            cell_voltage_v: s
                .voltage_v
                .map(f64::from)
                .filter(|v| v.is_finite() && *v > 0.0)
                .map(|v| v / f64::from(self.battery.cell_count.value)),
            mission_energy_wh: self.mission.as_ref().map(|m| m.energy_p50_wh),
            mission_margin_wh: remaining
                .zip(self.mission.as_ref())
                .zip(reserve)
                .map(|((r, m), res)| r - m.energy_p50_wh - res),
            mission: self.mission.clone(),
            forecast_adapted: forecast_adapted && forecast_from.is_some_and(|(m, _)| m.is_some()),
            pack: state::pack_state(load.volts, &pk, disagreement),
            battery: self.battery.clone(),
            hover_calibration: self.first_hover.calibration().copied(),
        }
    }

    /// Remaining energy where the pack or the battery telemetry is missing: nothing in Wh
    /// while the capacity is not known (any vehicle: no other vehicle's pack is assumed),
    /// and the model's power against the configured pack when the vehicle sends no battery
    /// telemetry at all. Each said once in a warning.
    fn pack_known(
        &mut self,
        s: &crate::features::Sample,
        power_source: &PowerSource,
        reported_pct: Option<f64>,
        remaining: Option<f64>,
        source: RemainingSource,
    ) -> (Option<f64>, RemainingSource) {
        let Some(cap) = self.battery.capacity_wh.clone() else {
            if !self.warned_no_pack {
                self.warned_no_pack = true;
                self.say(format_args!("battery: capacity {} ({} vehicle): remaining energy and time to empty are not reported; the state of charge from the voltage and cells, the energy used and the pack's voltages are", crate::report::CAPACITY_UNKNOWN, s.vehicle.class));
            }
            return (None, RemainingSource::UnknownPack);
        };
        let silent = s.measured_w.is_none() && s.voltage_v.is_none() && reported_pct.is_none();
        match (source, power_source) {
            (RemainingSource::AssumedFull, PowerSource::Model(model)) if silent => {
                if !self.warned_model_power {
                    self.warned_model_power = true;
                    self.say(format_args!(
                        "battery: the vehicle sends no battery telemetry: remaining energy is the pack's {:.1} Wh ({}) minus the energy of the {model} model's power, the pack taken as full at the start",
                        cap.value,
                        cap.source
                    ));
                }
                (remaining, RemainingSource::ModelPower)
            }
            _ => (remaining, source),
        }
    }

    /// The model whose prediction is the forecast ([`select`]), when it ran.
    fn forecast_model<'a>(&self, est: &'a Estimate) -> Option<&'a ModelEstimate> {
        let name = &self.selector.current().model;
        est.models
            .iter()
            .find(|m| m.name == *name)
            // On a wing (a plane, a VTOL in forward flight) only the fixed-wing model runs.
            .or_else(|| est.models.iter().find(|m| m.name == "fixed_wing"))
    }
}

#[cfg(test)]
mod props;
#[cfg(test)]
mod tests;
