//! The first hover calibrates, live: the vehicle's measured electrical power over its first
//! hover (airborne, still) sets the hover efficiency of the momentum-theory member
//! (`stolaroff`: `P = T·(v_a sin α + v_i)/η_h + P_avio`), so the live estimate and the
//! remaining mission's forecast follow the vehicle instead of the priors.
//!
//! - **A hover sample**: height above home > [`AIRBORNE_M`], ground speed <
//!   [`STILL_M_S`], vertical speed within ±[`STILL_VZ_M_S`], still for [`SETTLE_S`] already
//!   (the stop after the climb is not a hover), with a measured power V·I.
//! - **Calibrated** once [`HOVER_S`] of hover samples are in (the first 30 s), or a hover of
//!   at least [`MIN_HOVER_S`] ends; the mean power `P_h` over them gives
//!   `η_h = P_ideal / (P_h − P_avio)`, `P_ideal = T^1.5/√(2ρA)` for the profile's take-off
//!   mass with the mission's payload on board ([`HoverCalibrator::set_payload_kg`]) and the
//!   rotor disk. From then on every power the member gives, and the energy of the
//!   rest of the mission, scale their non-avionics part by `k = η_prior / η_h`
//!   ([`HoverCalibration::power_w`], [`HoverCalibration::energy_wh`]): exact for the
//!   momentum-theory member, whose every term but the avionics is divided by η_h.
//! - **Or at the hover throttle**: with ArduPilot's `MOT_THST_HOVER` (the throttle it learned
//!   holds the vehicle in a hover, 0–1) and VFR_HUD's throttle, the samples airborne, under
//!   [`THROTTLE_GROUND_M_S`] across and within ±[`STILL_VZ_M_S`] vertically, whose
//!   throttle is within ±[`THROTTLE_BAND`] of it, are hover power whether still or not;
//!   [`THROTTLE_S`] of them (not necessarily in one piece) calibrate, if no still hover did
//!   first. A `MOT_THST_HOVER` of 0 or outside 5–95 % (never learned, or not ArduPilot's) is
//!   not used ([`HoverCalibrator::set_hover_throttle`] says why).
//! - **No hover**: a vehicle that is not a multirotor, or one that flies
//!   [`SEARCH_S`] airborne without a hover of [`MIN_HOVER_S`] (straight into cruise), is not
//!   calibrated, and that is said once ([`HoverCalibrator::observe`] returns it).
//!
//! Pure: no I/O; the energy tracker feeds it and says what it returns.

use crate::features::VehicleClass;
use crate::model::profile::VehicleProfile;

/// Height above home above which the vehicle is airborne, m.
pub const AIRBORNE_M: f64 = 2.0;
/// Horizontal ground speed below which it is still, m/s.
pub const STILL_M_S: f64 = 1.0;
/// Vertical speed within which it is still, m/s.
pub const STILL_VZ_M_S: f64 = 0.5;
/// How long it must have been still before a sample counts as hover, s.
pub const SETTLE_S: f64 = 3.0;
/// Hover averaged at most, s (the first 30 s).
pub const HOVER_S: f64 = 30.0;
/// The shortest hover that calibrates when it ends, s.
pub const MIN_HOVER_S: f64 = 15.0;
/// Airborne time without such a hover after which there is none, s.
pub const SEARCH_S: f64 = 180.0;
/// Throttle within this of `MOT_THST_HOVER` (as a fraction, 0–1) is the hover throttle.
pub const THROTTLE_BAND: f64 = 0.03;
/// Ground speed below which a sample at the hover throttle counts, m/s (at a walking pace
/// the thrust is the weight's and translational lift is small).
pub const THROTTLE_GROUND_M_S: f64 = 3.0;
/// Seconds at the hover throttle that calibrate.
pub const THROTTLE_S: f64 = 10.0;

/// What the calibration needs of the vehicle profile.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HoverReference {
    /// Momentum theory's ideal hover power for the take-off mass on the rotors' disk, W.
    pub ideal_w: f64,
    /// Avionics power, W (the member's `p_avio_w`).
    pub avionics_w: f64,
    /// The hover efficiency before the calibration (the member's `eta`).
    pub prior_eta: f64,
    /// The take-off mass `ideal_w` is for, kg (no payload); 0: unknown, `ideal_w` used at
    /// any payload (a checkpoint written before it was kept).
    #[serde(default)]
    pub mass_kg: f64,
    /// How the member's η grows with the mass flown (`[stolaroff] eta_per_ln_mass`): a
    /// hover flown loaded gives η at the loaded mass, `eta_at` the take-off mass's.
    #[serde(default)]
    pub eta_per_ln_mass: f64,
}

impl HoverReference {
    /// From a profile: its take-off mass (no payload), disk and `[stolaroff]`; an error that
    /// says why there is no hover to calibrate (not a multirotor, no disk).
    pub fn of(p: &VehicleProfile) -> Result<Self, String> {
        if p.plane.is_some()
            || p.vehicle
                .class
                .is_some_and(|c| c != VehicleClass::Multirotor)
        {
            return Err(format!(
                "{} does not hover on its rotors alone: no hover calibration",
                p.name
            ));
        }
        let area = p.disk_area_m2();
        let thrust = p.mass_kg(0.0) * p.air.g_m_s2;
        let ideal_w = thrust.powf(1.5) / (2.0 * p.air.rho_kg_m3 * area).sqrt();
        if !(ideal_w.is_finite() && ideal_w > 0.0 && p.stolaroff.eta > 0.0) {
            return Err(format!(
                "{}: no rotor disk or hover efficiency to calibrate",
                p.name
            ));
        }
        Ok(Self {
            ideal_w,
            avionics_w: p.stolaroff.p_avio_w,
            prior_eta: p.stolaroff.eta,
            mass_kg: p.mass_kg(0.0),
            eta_per_ln_mass: p.stolaroff.eta_per_ln_mass,
        })
    }

    /// Momentum theory's ideal hover power with a payload on board, W: the thrust is the
    /// take-off mass's and the payload's weight together (`ideal_w` × (m + payload)^1.5 / m^1.5).
    pub fn ideal_at(&self, payload_kg: f64) -> f64 {
        let payload = if payload_kg.is_finite() {
            payload_kg.max(0.0)
        } else {
            0.0
        };
        if self.mass_kg > 0.0 {
            self.ideal_w * ((self.mass_kg + payload) / self.mass_kg).powf(1.5)
        } else {
            self.ideal_w
        }
    }

    /// The hover efficiency a measured hover power gives, hovering without payload; None
    /// when momentum theory cannot give this mass on these rotors that power (η_h outside
    /// (0.05, 1)).
    pub fn eta_of(&self, hover_w: f64) -> Option<f64> {
        self.eta_at(hover_w, 0.0)
    }

    /// The hover efficiency a hover power measured with `payload_kg` on board gives, at the
    /// take-off mass: the ideal power is that of the loaded mass, so a hover flown with a
    /// payload does not read as a poor efficiency (which every later forecast would then pay
    /// again for the payload), and η at the loaded mass is brought to the take-off mass's by
    /// the member's growth with the mass (`eta_per_ln_mass`, 0 but for a spec sheet).
    pub fn eta_at(&self, hover_w: f64, payload_kg: f64) -> Option<f64> {
        let grown = if self.mass_kg > 0.0 && payload_kg.is_finite() && payload_kg > 0.0 {
            ((self.mass_kg + payload_kg) / self.mass_kg)
                .clamp(0.5, 2.0)
                .powf(self.eta_per_ln_mass)
        } else {
            1.0
        };
        let eta = self.ideal_at(payload_kg) / (hover_w - self.avionics_w) / grown;
        (hover_w.is_finite() && eta > 0.05 && eta < 1.0).then_some(eta)
    }
}

/// Whether the profile's forecast follows the momentum-theory member (a spec sheet's
/// does): then a first hover rescales the live and the mission forecast.
pub fn follows_momentum_theory(p: &VehicleProfile) -> bool {
    p.forecast
        .as_ref()
        .is_some_and(|f| f.model.starts_with("stolaroff"))
}

pub use crate::report::hover::HoverCalibration;
use crate::report::hover::HoverSource;

/// Where the search stands.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum HoverState {
    /// Looking for the first hover.
    Searching,
    /// Calibrated.
    Done(HoverCalibration),
    /// No calibration, and why.
    None(String),
}

/// What [`HoverCalibrator::observe`] has news of.
#[derive(Debug, Clone, PartialEq)]
pub enum HoverNews {
    Calibrated(HoverCalibration),
    NoHover(String),
}

/// Finds the first hover and calibrates on it.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct HoverCalibrator {
    reference: Option<HoverReference>,
    /// Whether the forecast follows the momentum-theory member.
    applies: bool,
    state: HoverState,
    airborne_s: f64,
    still_since: Option<f64>,
    last_t: Option<f64>,
    /// Σ P·dt and Σ dt over hover samples.
    sum_wj: f64,
    sum_s: f64,
    /// `MOT_THST_HOVER` (0–1), when usable, and Σ P·dt, Σ dt at that throttle.
    hover_throttle: Option<f64>,
    thr_wj: f64,
    thr_s: f64,
    /// The mission's payload, kg ([`HoverCalibrator::set_payload_kg`]): on board in the hover.
    #[serde(default)]
    payload_kg: f64,
}

impl HoverCalibrator {
    /// For a vehicle with this reference (an error: why it has none); `applies`: the
    /// forecast follows the momentum-theory member.
    pub fn new(reference: Result<HoverReference, String>, applies: bool) -> Self {
        let (reference, state) = match reference {
            Ok(r) => (Some(r), HoverState::Searching),
            Err(why) => (None, HoverState::None(why)),
        };
        Self {
            reference,
            applies,
            state,
            airborne_s: 0.0,
            still_since: None,
            last_t: None,
            sum_wj: 0.0,
            sum_s: 0.0,
            hover_throttle: None,
            thr_wj: 0.0,
            thr_s: 0.0,
            payload_kg: 0.0,
        }
    }

    /// The mission's payload, kg (the `payload` feature): the hover is flown with it on
    /// board, so its ideal power is the loaded mass's.
    pub fn set_payload_kg(&mut self, kg: f64) {
        self.payload_kg = if kg.is_finite() { kg.max(0.0) } else { 0.0 };
    }

    /// ArduPilot's `MOT_THST_HOVER` (0–1): the samples at that throttle are hover power too.
    /// An error says why it is not used (0: never learned; outside 5–95 %).
    pub fn set_hover_throttle(&mut self, value: Option<f64>) -> Result<(), String> {
        self.hover_throttle = None;
        match value {
            None => Ok(()),
            Some(v) if v.is_finite() && v > 0.05 && v < 0.95 => {
                self.hover_throttle = Some(v);
                Ok(())
            }
            Some(v) => Err(format!(
                "MOT_THST_HOVER = {v}: not a learned hover throttle (5-95 %), so the hover must be flown"
            )),
        }
    }

    /// The hover throttle in use (`MOT_THST_HOVER`, 0–1).
    pub fn hover_throttle(&self) -> Option<f64> {
        self.hover_throttle
    }

    /// Where it stands.
    pub fn state(&self) -> &HoverState {
        &self.state
    }

    /// The calibration, once made.
    pub fn calibration(&self) -> Option<&HoverCalibration> {
        match &self.state {
            HoverState::Done(c) => Some(c),
            _ => None,
        }
    }

    /// One sample: its time, height above home (None: no home), horizontal ground speed,
    /// vertical speed (m/s), throttle (%, VFR_HUD) and measured power (W). News when it
    /// calibrates or gives up.
    pub fn observe(
        &mut self,
        t_s: f64,
        height_m: Option<f64>,
        ground_m_s: f64,
        vz_m_s: f64,
        throttle_pct: Option<f64>,
        measured_w: Option<f64>,
    ) -> Option<HoverNews> {
        let reference = self.reference.clone()?;
        if !matches!(self.state, HoverState::Searching) || !t_s.is_finite() {
            return None;
        }
        let dt = self.last_t.map_or(0.0, |t0| (t_s - t0).clamp(0.0, 1.0));
        self.last_t = Some(t_s);
        let airborne = height_m.is_some_and(|h| h > AIRBORNE_M);
        if !airborne {
            self.still_since = None;
            return self.hover_ended(reference.clone(), t_s);
        }
        self.airborne_s += dt;
        let at_throttle = (ground_m_s, vz_m_s, throttle_pct, measured_w);
        if let Some(news) = self.at_hover_throttle(&reference, t_s, dt, at_throttle) {
            return Some(news);
        }
        let still = ground_m_s.is_finite()
            && ground_m_s < STILL_M_S
            && vz_m_s.is_finite()
            && vz_m_s.abs() < STILL_VZ_M_S;
        if !still {
            self.still_since = None;
            if let Some(news) = self.hover_ended(reference.clone(), t_s) {
                return Some(news);
            }
        } else {
            let since = *self.still_since.get_or_insert(t_s);
            if let Some(p) = measured_w.filter(|p| p.is_finite() && *p > 0.0) {
                if t_s - since >= SETTLE_S {
                    self.sum_wj += p * dt;
                    self.sum_s += dt;
                }
            }
            if self.sum_s >= HOVER_S {
                return self.calibrate(reference.clone(), t_s);
            }
        }
        if self.airborne_s > SEARCH_S {
            let why = format!(
                "no hover of {MIN_HOVER_S:.0} s in the first {SEARCH_S:.0} s airborne (straight into cruise?): no hover calibration"
            );
            self.state = HoverState::None(why.clone());
            return Some(HoverNews::NoHover(why));
        }
        None
    }

    /// An airborne sample at `MOT_THST_HOVER`'s throttle, slow and level: its power is
    /// hover power; [`THROTTLE_S`] of them calibrate.
    fn at_hover_throttle(
        &mut self,
        r: &HoverReference,
        t_s: f64,
        dt: f64,
        (ground_m_s, vz_m_s, throttle_pct, measured_w): (f64, f64, Option<f64>, Option<f64>),
    ) -> Option<HoverNews> {
        let (u_h, u, p) = (self.hover_throttle?, throttle_pct?, measured_w?);
        let level = ground_m_s < THROTTLE_GROUND_M_S && vz_m_s.abs() < STILL_VZ_M_S;
        if !(level && p.is_finite() && p > 0.0 && (u / 100.0 - u_h).abs() <= THROTTLE_BAND) {
            return None;
        }
        self.thr_wj += p * dt;
        self.thr_s += dt;
        if self.thr_s < THROTTLE_S {
            return None;
        }
        let (w, s) = (self.thr_wj / self.thr_s, self.thr_s);
        self.calibrate_on(r.clone(), t_s, w, s, HoverSource::HoverThrottle)
    }

    /// A hover ended: calibrate when it was long enough, else start over.
    fn hover_ended(&mut self, r: HoverReference, t_s: f64) -> Option<HoverNews> {
        if self.sum_s >= MIN_HOVER_S {
            return self.calibrate(r, t_s);
        }
        self.sum_wj = 0.0;
        self.sum_s = 0.0;
        None
    }

    fn calibrate(&mut self, r: HoverReference, t_s: f64) -> Option<HoverNews> {
        let (w, s) = (self.sum_wj / self.sum_s, self.sum_s);
        self.calibrate_on(r, t_s, w, s, HoverSource::Hover)
    }

    fn calibrate_on(
        &mut self,
        r: HoverReference,
        t_s: f64,
        hover_w: f64,
        hover_s: f64,
        source: HoverSource,
    ) -> Option<HoverNews> {
        let Some(eta) = r.eta_at(hover_w, self.payload_kg) else {
            let why = format!(
                "a hover of {hover_w:.0} W is not one momentum theory gives this vehicle (at least {:.0} W ideal + {:.0} W avionics): no hover calibration",
                r.ideal_at(self.payload_kg),
                r.avionics_w
            );
            self.state = HoverState::None(why.clone());
            return Some(HoverNews::NoHover(why));
        };
        let cal = HoverCalibration {
            t_s,
            hover_w,
            hover_s,
            eta_h: eta,
            prior_eta_h: r.prior_eta,
            avionics_w: r.avionics_w,
            payload_kg: self.payload_kg,
            applied: self.applies,
            source,
        };
        self.state = HoverState::Done(cal);
        Some(HoverNews::Calibrated(cal))
    }
}

#[cfg(test)]
#[path = "hover_tests.rs"]
mod tests;
