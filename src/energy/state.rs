//! The energy state's parts that are computed from the step's facts, and the steps of
//! [`EnergyTracker::update_with_battery`]'s flow: the pack's load, the forecast and the pack
//! model's step, the power the pack model flies the rest of the flight at, the remaining
//! energy and its source, the time to empty, the energy home, and the pack's report.

use super::steady::{self, Ema};
use super::{pack, EnergyTracker, RemainingSource};
use crate::features::{idx, Sample};
use crate::report::BATTERY_PCT_AGREE;
use crate::report::{Estimate, ModelEstimate, PackState, PowerSource};

impl EnergyTracker {
    /// The power the voltage forecast flies the rest of the flight at: the rest of the
    /// mission at its mean power, then on at the plan's mean power (so that the usable floor
    /// does not leap when the mission's last, light descent ends; a mission flown to its end
    /// flies on at it too); with no mission, the forecast power throughout (until the measured
    /// average is long enough, the forecast model's power for this phase).
    pub(super) fn rest_of_flight(
        &self,
        forecast: Option<f64>,
        measured_avg: Option<f64>,
        tau: f64,
    ) -> Option<pack::Load> {
        let plan_w = self.plan_mean_w.map(|(_, w)| w);
        match self.mission.as_ref() {
            Some(m) if m.time_left_s > 1.0 && m.energy_p50_wh > 0.0 => {
                let first_w = 3600.0 * m.energy_p50_wh / m.time_left_s;
                Some(pack::Load {
                    first_w,
                    first_s: Some(m.time_left_s),
                    then_w: plan_w.unwrap_or(first_w),
                })
            }
            _ => plan_w
                .or(pack::pack_power(
                    forecast,
                    // until it is long enough, the forecast model's power for this phase
                    measured_avg
                        .filter(|_| forecast.is_none() || self.airborne.measured_long_enough(tau)),
                ))
                .map(pack::Load::constant),
        }
    }

    /// Remaining energy, where it comes from, and the pack's full energy (for the %):
    /// `reported_pct` is the vehicle's own %, when the config lets it count; `cap` the pack's
    /// capacity, Wh, when known.
    pub(super) fn remaining(
        &self,
        pk: &pack::PackNow,
        reported_pct: Option<f64>,
        cap: Option<f64>,
    ) -> (Option<f64>, RemainingSource, Option<f64>) {
        match (pk.usable_wh.or(pk.energy_wh), reported_pct, cap) {
            (Some(e), _, _) if pk.start == Some(pack::FROM_REST) => (
                Some(e),
                RemainingSource::RestingVoltage,
                pk.curve_wh.or(cap),
            ),
            // No capacity: nothing in Wh (never another vehicle's pack).
            (_, _, None) => (None, RemainingSource::UnknownPack, None),
            // The autopilot's % before a load-compensated start (the wider band).
            (_, Some(pct), Some(cap)) => {
                (Some(cap * pct / 100.0), RemainingSource::Battery, Some(cap))
            }
            // Started load-compensated some seconds in: no more than the capacity less all
            // the energy used since the monitor began (what came before the start is not
            // in the pack's own count).
            (Some(e), None, Some(c)) => (
                Some(e.min((c - self.used_wh).max(0.0))),
                RemainingSource::LoadCompensated,
                pk.curve_wh.or(cap),
            ),
            // The pack rests and its voltage is settling: not known yet (a moment), not full.
            (None, None, Some(cap)) if self.pack.pending() => {
                (None, RemainingSource::AssumedFull, Some(cap))
            }
            (None, None, Some(cap)) => (
                Some((cap - self.used_wh).max(0.0)),
                RemainingSource::AssumedFull,
                Some(cap),
            ),
        }
    }

    /// Energy to fly home and land, Wh: the cruise power over the distance at the cruise
    /// speed, then the hover power down from the height and for the landing.
    pub(super) fn home_energy_wh(&self, s: &Sample, forecast: Option<f64>) -> Option<f64> {
        s.home.and_then(|h| {
            let p_cruise = self.cruise.0.or(forecast)?;
            let p_hover = self.hover.0.unwrap_or(p_cruise);
            let d = f64::from(h.distance_m).max(0.0);
            let height = f64::from(h.height_m).max(0.0);
            let flight_s = d / self.cruise_speed_m_s;
            let down_s = height / self.cfg.descent_speed_m_s + self.cfg.landing_s;
            let wh = (p_cruise * flight_s + p_hover * down_s) / 3600.0;
            wh.is_finite().then_some(wh)
        })
    }
}

/// The pack's part of the report: the measured voltage, the pack model's state now and the
/// disagreement with the vehicle's own %.
pub(super) fn pack_state(
    volts: Option<f64>,
    pk: &pack::PackNow,
    disagreement: Option<f64>,
) -> PackState {
    PackState {
        battery_v: volts,
        battery_v_model: pk.v_model,
        battery_ocv_v: pk.ocv_v,
        battery_rest_v: pk.rest_v,
        soc_pct: pk.soc_pct,
        soc_band_pct: pk.soc_band_pct,
        pack_start: pk.start,
        pack_withheld: pk.withheld,
        internal_r_ohm: pk.internal_r_ohm,
        v_min_forecast_v: pk.v_min_forecast.map(|(v, _)| v),
        v_min_forecast_at_s: pk.v_min_forecast.map(|(_, t)| t),
        time_to_low_v_s: pk.time_to_low_v_s,
        low_threshold_v: pk.low_v,
        battery_pct_disagreement: disagreement,
        battery_end_rest_v: pk.end_rest_v,
        end_rest_soc_pct: pk.end_rest_soc_pct,
        pack_r_scale: pk.r_scale,
        pack_carried_over: pk.carried,
        heat_a2s: pk.heat,
        deep_slope: pk.deep_slope,
        curve_wh: pk.curve_wh,
    }
}

/// The power now and what the forecast flies on, from one estimate.
pub(super) struct PowerNow<'a> {
    /// Measured electrical power, W.
    pub measured: Option<f64>,
    /// The power integrated into energy (measured, else a model's), and its source.
    pub power: Option<f64>,
    pub power_source: PowerSource,
    /// The forecast's model (none: measured power) and its power, W.
    pub forecast_from: Option<(Option<&'a ModelEstimate>, f64)>,
    /// The forecast is the preferred (selected) model's.
    pub preferred: bool,
    /// The forecast model's prediction is adapted to measured power.
    pub forecast_adapted: bool,
}

impl EnergyTracker {
    /// The power now (measured, else the forecast model's, else the first model's) and the
    /// forecast's: the preferred model (adapted where adaptation runs), else measured power,
    /// else the first model.
    pub(super) fn power_now<'a>(&self, est: &'a Estimate) -> PowerNow<'a> {
        let s = &est.sample;
        let watts = |m: &ModelEstimate| Some(f64::from(m.power_w)).filter(|p| p.is_finite());
        // The forecast model's prediction adapted to measured power, where adaptation runs.
        let adapted = |m: &ModelEstimate| m.adapted_w.map(f64::from).filter(|p| p.is_finite());
        let preferred = self
            .forecast_model(est)
            .and_then(|m| Some((m, adapted(m).or(watts(m))?)));
        let forecast_adapted = self
            .forecast_model(est)
            .is_some_and(|m| adapted(m).is_some());
        let first = est.models.iter().find_map(|m| Some((m, watts(m)?)));
        let measured = s.measured_w.map(f64::from).filter(|p| p.is_finite());
        let (power, power_source) = match (measured, preferred.or(first)) {
            (Some(p), _) => (Some(p), PowerSource::Measured),
            (None, Some((m, p))) => (Some(p), PowerSource::Model(m.name.clone())),
            (None, None) => (None, PowerSource::None),
        };
        // Forecast from: the preferred model, else measured power, else the first model.
        let forecast_from = match (preferred, measured) {
            (Some((m, p)), _) => Some((Some(m), p)),
            (None, Some(p)) => Some((None, p)),
            (None, None) => first.map(|(m, p)| (Some(m), p)),
        };
        PowerNow {
            measured,
            power,
            power_source,
            forecast_from,
            preferred: preferred.is_some(),
            forecast_adapted,
        }
    }
}

impl EnergyTracker {
    /// Integrates `power` (trapezoids) up to `t`; the step's length, s: capped on gaps,
    /// nothing on a backwards jump or the first estimate.
    pub(super) fn integrate(&mut self, t: f64, power: Option<f64>) -> f64 {
        let dt = match self.last {
            Some((t0, _)) if t.is_finite() && t > t0 => (t - t0).min(self.cfg.max_dt_s),
            _ => 0.0,
        };
        if let Some(p) = power {
            let p0 = self.last.map_or(p, |(_, p0)| p0);
            self.used_wh += 0.5 * (p0 + p) * dt / 3600.0;
            if t.is_finite() {
                self.last = Some((t, p));
            }
        } else if t.is_finite() {
            // Nothing to integrate: keep the previous power, move the clock on.
            self.last = self.last.map(|(_, p0)| (t, p0));
        }
        dt
    }

    /// The forecast power `p` into the cruise average (at half the cruise speed or more) or
    /// the hover average (above 2 m, slower).
    pub(super) fn observe_phase(&mut self, s: &Sample, p: f64, dt: f64, tau: f64) {
        let vx = f64::from(s.features[idx::VX]);
        let vy = f64::from(s.features[idx::VY]);
        let ground_speed = vx.hypot(vy);
        if ground_speed.is_finite() && ground_speed >= 0.5 * self.cruise_speed_m_s {
            self.cruise.update(p, dt, tau);
        } else if s.home.is_some_and(|h| h.height_m > 2.0) {
            self.hover.update(p, dt, tau);
        }
    }

    /// The vehicle's own % less the resting voltage's state of charge, when they disagree by
    /// more than [`BATTERY_PCT_AGREE`] points; said once.
    pub(super) fn pct_disagreement(
        &mut self,
        reported_pct: Option<f64>,
        pk: &pack::PackNow,
    ) -> Option<f64> {
        let disagreement = reported_pct
            .zip(pk.soc_pct)
            .map(|(b, soc)| b - soc)
            .filter(|d| d.abs() > BATTERY_PCT_AGREE);
        if let (Some(d), false) = (disagreement, self.warned_pct) {
            self.warned_pct = true;
            self.say(format_args!(
                "battery: the vehicle reports {:.0} %, the resting voltage {:.2} V says {:.0} %: using the resting voltage (an autopilot that counts from 'full at boot' reads a half pack as full)",
                reported_pct.unwrap_or(f64::NAN),
                pk.rest_v.unwrap_or(f64::NAN),
                reported_pct.unwrap_or(f64::NAN) - d
            ));
        }
        disagreement
    }
}

/// The pack's load this sample: its voltage and current (discharge positive, from the
/// measured power), whether it is flying (drawing more than its rest current), and the
/// current that counts as under load.
pub(super) struct PackLoad {
    pub volts: Option<f64>,
    pub amps: Option<f64>,
    pub flying: bool,
    pub load_a: f64,
}

impl EnergyTracker {
    /// The first plausible pack voltage, once: the battery is resolved from it.
    pub(super) fn note_first_voltage(&mut self, s: &Sample) {
        if self.first_voltage_v.is_none() {
            if let Some(v) = s
                .voltage_v
                .map(f64::from)
                .filter(|v| v.is_finite() && *v > 1.0)
            {
                self.first_voltage_v = Some(v);
                self.resolve_battery();
            }
        }
    }

    /// The pack's load now, and whether the vehicle is airborne (at take-off the forecast
    /// starts again).
    pub(super) fn pack_load(&mut self, s: &Sample, measured: Option<f64>, dt: f64) -> PackLoad {
        // The pack: voltage and current (discharge positive) from the measured power.
        let volts = s
            .voltage_v
            .map(f64::from)
            .filter(|v| v.is_finite() && *v > 0.5);
        let amps = volts.zip(measured).map(|(v, p)| p / v);
        let (rest_a, load_a) = pack::currents(&self.battery);
        let flying = amps.is_some_and(|i| i > rest_a);
        let aloft = flying || (amps.is_none() && s.home.is_some_and(|h| h.height_m > 2.0));
        if self.airborne.update(aloft, dt) {
            // take-off: the forecast's power from the phase now flown, not from ground idle
            self.forecast = Ema::default();
        }
        PackLoad {
            volts,
            amps,
            flying,
            load_a,
        }
    }

    /// The forecast power (smoothed from `forecast_input`) and the pack model's step, which
    /// flies the rest of the flight on it; the pack's notes said.
    pub(super) fn forecast_and_pack(
        &mut self,
        est: &Estimate,
        dt: f64,
        forecast_input: Option<f64>,
        measured: Option<f64>,
        load: &PackLoad,
    ) -> (Option<f64>, pack::PackNow) {
        let s = &est.sample;
        let tau = self.cfg.smoothing_s;
        let forecast = forecast_input.map(|p| self.forecast.update(p, dt, tau));
        if let Some(p) = forecast_input {
            self.observe_phase(s, p, dt, tau);
        }

        let measured_avg = match measured.filter(|_| load.flying) {
            Some(p) => Some(self.measured_avg.update(p, dt, tau)),
            None => self.measured_avg.0,
        };
        let rest_of_flight = self.rest_of_flight(forecast, measured_avg, tau);
        let pk = self.pack.update(
            est.t_s,
            load.volts,
            load.amps,
            rest_of_flight,
            &self.battery,
        );
        for n in std::mem::take(&mut self.pack.notes) {
            self.say(format_args!("{n}"));
        }
        (forecast, pk)
    }

    /// Remaining energy, its source and the pack's full energy ([`Self::remaining`], where
    /// the pack is known), never up under load without a stated reason (steady); the
    /// assumption of a full pack said once.
    pub(super) fn remaining_now(
        &mut self,
        est: &Estimate,
        pk: &pack::PackNow,
        power_source: &PowerSource,
        reported_pct: Option<f64>,
        load: &PackLoad,
        cap: Option<f64>,
    ) -> (Option<f64>, RemainingSource, Option<f64>) {
        let s = &est.sample;
        let (remaining, remaining_source, full_wh) =
            self.remaining(pk, reported_pct.filter(|_| self.cfg.use_battery_pct), cap);
        let (remaining, remaining_source) =
            self.pack_known(s, power_source, reported_pct, remaining, remaining_source);
        // never up under load without a stated reason (steady)
        // held once the flight's first seconds have shown the pack under load
        let held = load.flying && self.airborne.measured_long_enough(self.cfg.smoothing_s);
        let (remaining, revised) =
            self.no_rise
                .update(est.t_s, remaining, remaining_source, self.used_wh, held);
        if let Some(up) = revised {
            self.say(format_args!("battery: remaining energy revised up by {up:.1} Wh in flight: the pack's sag as learned over the last {:.0} s", steady::REVISE_AFTER_S));
        }
        if remaining_source == RemainingSource::AssumedFull
            && load.amps.is_some_and(|i| i >= load.load_a)
            && !self.warned_full
        {
            self.warned_full = true;
            self.say(format_args!("battery: no resting voltage was read before take-off and the vehicle sends no battery %: remaining energy assumes the pack started full"));
        }
        (remaining, remaining_source, full_wh)
    }
}

/// Time to empty, s: to the voltage failsafe when the pack model forecasts one
/// (`time_to_low_v_s`); else to the floor at the forecast power.
pub(super) fn time_to_empty(
    remaining_source: RemainingSource,
    time_to_low_v_s: Option<f64>,
    remaining: Option<f64>,
    forecast: Option<f64>,
) -> Option<f64> {
    match (remaining_source, time_to_low_v_s) {
        (RemainingSource::RestingVoltage | RemainingSource::LoadCompensated, Some(t_low)) => {
            Some(t_low)
        }
        _ => remaining
            .zip(forecast.filter(|p| *p > 1.0))
            .map(|(e, p)| 3600.0 * e / p),
    }
}

/// The share of the pack left, %: of its full energy; without a capacity, the state of
/// charge the voltage says, else the vehicle's own %.
pub(super) fn remaining_pct(
    remaining: Option<f64>,
    full_wh: Option<f64>,
    cap: Option<f64>,
    pk: &pack::PackNow,
    reported_pct: Option<f64>,
) -> Option<f64> {
    match (remaining, full_wh) {
        (Some(r), Some(f)) if f > 0.0 => Some((100.0 * r / f).clamp(0.0, 100.0)),
        _ if cap.is_none() => pk.soc_pct.or(reported_pct),
        _ => None,
    }
}
