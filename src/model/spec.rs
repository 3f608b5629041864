//! A spec sheet is a vehicle: five facts (take-off mass, rotors, propeller, pack) and the
//! priors below make a [`VehicleProfile`] whose forecast is momentum theory with a hover
//! efficiency and a body drag that scale with the airframe (the `stolaroff` member: thrust ×
//! inflow / η, drag against the airspeed), its P90 carrying the priors' spread.
//!
//! ```toml
//! name = "My quad"
//! [vehicle]
//! takeoff_kg = 1.3
//! rotors = 4
//! prop_diameter_m = 0.254
//! [battery]
//! cells = 3
//! capacity_mah = 5100
//! chemistry = "lipo"
//! ```
//!
//! A file is a spec sheet when its `[vehicle]` has `takeoff_kg`. Only `takeoff_kg` is
//! required; a missing fact is filled from its prior and the load says which. Any key of a
//! full profile (`[stolaroff] eta`, `[vehicle] diagonal_m`, `[battery]
//! internal_resistance_ohm`, …) may be added and wins over the prior; a prior it replaces
//! no longer widens the P90. `[vehicle] frame` (`tri`, `quad`, `hexa`, `octo`, `y6`, `x8`)
//! is checked against `rotors`; `[priors] eta_h`, `eta_h_log_sd`, `drag_per_kg23`,
//! `eta_h_per_ln_dl`, `profile_share` replace the priors (what the leave-one-airframe-out scoring uses). The priors and their
//! sources are the book's "Spec sheets" table (`scripts/spec-priors.py` fits η_h).

use anyhow::Context;
use toml::{Table, Value};

use super::physics::stolaroff;
use super::profile::{Battery, Body, ForecastDefault, VehicleProfile};
use crate::battery::Chemistry;
use crate::features::VehicleClass;

/// Hover efficiency η_h = ideal momentum-theory power / rotor electrical power (figure of
/// merit × motors × ESCs), a line in the log of the disk loading (thrust per disk area,
/// N/m²): ln η_h = `ETA_H_LN0` + `ETA_H_PER_LN_DL` · ln(disk loading). Fitted by
/// `scripts/spec-priors.py` across the airframes of the book's table (the M100 data set
/// and published, the Mavic Pro, 3DR Solo, S900, S1000 and M600 published, the X500 and 3S
/// quad simulators, the `multirotor` package's Tarot T18 and Mavic Pro); the form (this line
/// over a constant or a line in the propeller diameter) chosen by its
/// leave-one-airframe-out error. A figure of merit grows with the disk loading (the
/// blades work at a higher lift coefficient).
pub const ETA_H_LN0: f64 = -1.9392;
/// Slope of ln η_h in ln(disk loading).
pub const ETA_H_PER_LN_DL: f64 = 0.2572;
/// The disk loadings the fit saw, N/m² (50-105): outside, the nearest bound's η_h.
pub const ETA_H_DL_RANGE: (f64, f64) = (45.0, 110.0);
/// The log-spread of ln η_h a new airframe meets about that line: the RMS of each airframe's
/// leave-one-airframe-out residual (0.288: the error of a fit that never saw it, not the
/// fit's own residual), × the t distribution's 90th percentile over the normal's for nine
/// airframes and two parameters (1.415 / 1.2816): 0.318 (`scripts/spec-priors.py`'s
/// `shipped`). The P90's `exp(1.2816 · sd)` is then the t's 90th percentile.
#[allow(clippy::approx_constant)] // a fitted spread, not 1/π
pub const ETA_H_LOG_SD: f64 = 0.318;

/// The hover-efficiency prior for a take-off mass, rotors and propeller diameter.
pub fn eta_h_prior(takeoff_kg: f64, rotors: u32, prop_m: f64) -> f64 {
    let disk = f64::from(rotors) * std::f64::consts::PI * prop_m * prop_m / 4.0;
    let dl = (takeoff_kg * 9.81 / disk).clamp(ETA_H_DL_RANGE.0, ETA_H_DL_RANGE.1);
    (ETA_H_LN0 + ETA_H_PER_LN_DL * dl.ln()).exp()
}
/// Drag area per kg^(2/3) of take-off mass, m²/kg^(2/3): C_D·A grows as the frontal area,
/// as mass^(2/3). The geometric mean of five airframes' C_D·A per kg^(2/3): the X500
/// profile's 0.025 m² at 2.0 kg (0.0157), the 3S quad's 0.020 at 1.0 (0.0200), the M100's
/// published-model 0.055 at 2.431 (0.0304), the Mavic Pro's 0.0197 at 0.743 (0.0240, the
/// model the `multirotor` package cites) and the peer T18's 0.20 at 10.66 (0.0413, the
/// harness's ASSUMPTION) (`scripts/spec-priors.py`'s `drag_prior`). Until 2026-11-29 it was
/// 0.033, the arithmetic mean of the first three's C_D·A themselves, not per kg^(2/3): 1.5 ×
/// what its own derivation gives.
pub const DRAG_PER_KG23: f64 = 0.0249;
/// Log-spread of that drag area: the five's leave-one-out predictive spread (their
/// leave-one-out residuals' RMS 0.42 × t₀.₉(4 df) / 1.2816), 0.50.
pub const DRAG_LOG_SD: f64 = 0.5;
/// Share of a plan's energy the drag term's error reaches at cruise (its weight in the spread).
const DRAG_SHARE: f64 = 0.25;
/// The profile share of the hover power, 1 − the figure of merit (`[stolaroff]
/// profile_share`: what translational lift does not relieve). 0.6, the bound of the grid
/// 0–0.6 (a figure of merit of 0.4) that `scripts/profile-share-fit.py` chose, leave one
/// airframe out, on every airframe: the peers' cruise and the M100's training flights.
pub const PROFILE_SHARE: f64 = 0.6;
/// Avionics (flight controller, GNSS, radios), W.
pub const AVIONICS_W: f64 = 8.0;
/// Pack specific energy, Wh/kg, by chemistry (typical published drone packs).
fn pack_wh_per_kg(c: Chemistry) -> f64 {
    match c {
        Chemistry::LiPo => 150.0,
        Chemistry::LiHv => 160.0,
        Chemistry::LiIon | Chemistry::LiIonNmc => 200.0,
        // LiFePO4 packs: heavier cells, about 100-120 Wh/kg as packs.
        Chemistry::LiFePo4 => 110.0,
    }
}
/// Pack share of take-off mass when the pack is not given (1).
const PACK_MASS_SHARE: f64 = 0.3;
/// Disk loading when the propeller is not given, N/m² (spec-priors.py's airframes: 50–105).
const DISK_LOADING_N_M2: f64 = 80.0;
/// Cell resistance × capacity, Ω·Ah (5 mΩ for a 5 Ah cell), plus 5 mΩ of leads.
const CELL_R_OHM_AH: f64 = 0.025;
const LEADS_OHM: f64 = 0.005;
/// The 90th percentile of a standard normal.
const Z90: f64 = 1.2816;

/// Whether a parsed TOML file is a spec sheet (its `[vehicle]` has `takeoff_kg`).
pub fn is_spec(t: &Table) -> bool {
    t.get("vehicle")
        .and_then(Value::as_table)
        .is_some_and(|v| v.contains_key("takeoff_kg"))
}

/// The five facts (and the chemistry); `filled` names those the file did not give.
#[derive(Debug, Clone)]
struct Facts {
    takeoff_kg: f64,
    rotors: u32,
    prop_m: f64,
    cells: u32,
    capacity_mah: f64,
    chemistry: Chemistry,
    filled: Vec<String>,
}

fn num(t: &Table, sec: &str, key: &str) -> Result<Option<f64>, String> {
    match t
        .get(sec)
        .and_then(Value::as_table)
        .and_then(|s| s.get(key))
    {
        None => Ok(None),
        Some(Value::Float(f)) => Ok(Some(*f)),
        Some(Value::Integer(i)) => Ok(Some(*i as f64)),
        Some(v) => Err(format!("{sec}.{key} = {v}: must be a number")),
    }
}

fn count(t: &Table, sec: &str, key: &str) -> Result<Option<u32>, String> {
    match num(t, sec, key)? {
        None => Ok(None),
        Some(v) if v.fract() == 0.0 && (0.0..=64.0).contains(&v) => Ok(Some(v as u32)),
        Some(v) => Err(format!(
            "{sec}.{key} = {v}: must be a whole number in [0, 64]"
        )),
    }
}

fn facts(t: &Table) -> Result<Facts, String> {
    use crate::validate::{above, in_range};
    let mut filled = Vec::new();
    let takeoff_kg = num(t, "vehicle", "takeoff_kg")?.unwrap_or(f64::NAN);
    in_range("vehicle.takeoff_kg", takeoff_kg, above(0.0), "kg")?;
    in_range("vehicle.takeoff_kg", takeoff_kg, ..=1000.0, "kg")?;
    // absent: the declared frame's count, else a quad
    let frame = t
        .get("vehicle")
        .and_then(Value::as_table)
        .and_then(|v| v.get("frame"))
        .and_then(Value::as_str)
        .and_then(frame_rotors);
    let rotors = count(t, "vehicle", "rotors")?.unwrap_or_else(|| {
        let n = frame.unwrap_or(4);
        filled.push(format!("vehicle.rotors ({n})"));
        n
    });
    in_range("vehicle.rotors", rotors, 1.., "")?;
    let chem = match t
        .get("battery")
        .and_then(Value::as_table)
        .and_then(|b| b.get("chemistry"))
    {
        None => {
            filled.push("battery.chemistry (lipo)".into());
            Chemistry::LiPo
        }
        Some(v) => v.as_str().and_then(Chemistry::from_name).ok_or_else(|| {
            format!("battery.chemistry = {v}: must be \"lipo\", \"lihv\" or \"liion\"")
        })?,
    };
    let weight = takeoff_kg * 9.81;
    let prop_m = match num(t, "vehicle", "prop_diameter_m")? {
        Some(d) => d,
        None => {
            filled.push("vehicle.prop_diameter_m (disk loading 80 N/m²)".into());
            (4.0 * weight / DISK_LOADING_N_M2 / (f64::from(rotors) * std::f64::consts::PI)).sqrt()
        }
    };
    in_range("vehicle.prop_diameter_m", prop_m, above(0.0), "m")?;
    in_range("vehicle.prop_diameter_m", prop_m, ..=3.0, "m")?;
    let cells = count(t, "battery", "cells")?.unwrap_or_else(|| {
        filled.push("battery.cells (4)".into());
        4
    });
    in_range("battery.cells", cells, 1..=24, "")?;
    let capacity_mah = match num(t, "battery", "capacity_mah")? {
        Some(c) => c,
        None => {
            filled.push("battery.capacity_mah (a pack of 30 % of the take-off mass)".into());
            let wh = PACK_MASS_SHARE * takeoff_kg * pack_wh_per_kg(chem);
            wh / (f64::from(cells) * chem.nominal_v()) * 1000.0
        }
    };
    in_range("battery.capacity_mah", capacity_mah, above(0.0), "mAh")?;
    Ok(Facts {
        takeoff_kg,
        rotors,
        prop_m,
        cells,
        capacity_mah,
        chemistry: chem,
        filled,
    })
}

/// The rotor count a declared frame has.
fn frame_rotors(frame: &str) -> Option<u32> {
    Some(match frame {
        "tri" => 3,
        "quad" => 4,
        "hexa" | "y6" => 6,
        "octo" | "x8" => 8,
        _ => return None,
    })
}

/// A declared frame (`[vehicle] frame`, or a name that says quad/hexa/octo) against the
/// rotors; a propeller against the frame it must fit on.
fn check_frame(t: &Table, f: &Facts, name: &str) -> Result<(), String> {
    let frame = t
        .get("vehicle")
        .and_then(Value::as_table)
        .and_then(|v| v.get("frame"));
    let declared = match frame {
        Some(v) => {
            let s = v.as_str().unwrap_or_default();
            let n = frame_rotors(s).ok_or_else(|| {
                format!("vehicle.frame = {v}: must be tri, quad, hexa, octo, y6 or x8")
            })?;
            Some((format!("vehicle.frame = \"{s}\""), n))
        }
        None => name
            .to_lowercase()
            .split(|c: char| !c.is_alphanumeric())
            .find_map(|w| match w {
                "quad" | "quadcopter" | "quadrotor" => Some(4),
                "hexa" | "hexacopter" | "hexarotor" => Some(6),
                "octo" | "octocopter" | "octorotor" => Some(8),
                _ => None,
            })
            .map(|n| (format!("name = \"{name}\""), n)),
    };
    if let Some((what, n)) = declared {
        if n != f.rotors {
            return Err(format!(
                "vehicle.rotors = {}: {what} has {n} rotors",
                f.rotors
            ));
        }
    }
    if let Some(diag) = num(t, "vehicle", "diagonal_m")? {
        crate::validate::in_range("vehicle.diagonal_m", diag, crate::validate::above(0.0), "m")?;
        let spacing = max_prop_m(diag, f.rotors, frame.and_then(Value::as_str));
        if f.prop_m > spacing {
            return Err(format!(
                "vehicle.prop_diameter_m = {}: larger than the frame allows ({} rotors on a {diag} m diagonal leave at most {spacing:.3} m between motors)",
                f.prop_m, f.rotors
            ));
        }
    }
    Ok(())
}

/// The largest propeller that does not overlap its neighbour: motors on a circle of the
/// diagonal (a coaxial y6/x8 has half as many arms).
fn max_prop_m(diagonal_m: f64, rotors: u32, frame: Option<&str>) -> f64 {
    let arms = if matches!(frame, Some("y6" | "x8")) {
        rotors / 2
    } else {
        rotors
    };
    if arms < 2 {
        return diagonal_m;
    }
    diagonal_m * (std::f64::consts::PI / f64::from(arms)).sin()
}

/// The keys a spec sheet has that a profile does not.
const SPEC_ONLY: [(&str, &str); 3] = [
    ("vehicle", "takeoff_kg"),
    ("vehicle", "frame"),
    ("battery", "chemistry"),
];

/// Whether the file sets `sec.key`.
fn has(t: &Table, sec: &str, key: &str) -> bool {
    t.get(sec)
        .and_then(Value::as_table)
        .is_some_and(|s| s.contains_key(key))
}

/// The profile the priors make of the facts (before the file's overrides).
fn from_priors(f: &Facts, name: String, pr: &Priors, battery_kg: f64) -> VehicleProfile {
    let m100 = VehicleProfile::m100();
    let eta_h = pr.eta_h;
    let drag = pr.drag_per_kg23 * f.takeoff_kg.powf(2.0 / 3.0);
    let diag = f.prop_m / max_prop_m(1.0, f.rotors, None) * 1.2;
    let curve = f.chemistry.default_curve().normalized();
    let ocv_cell_v = (0..=10)
        .map(|i| {
            let s = f64::from(i) / 10.0;
            [s, curve.v_cell(s)]
        })
        .collect();
    let mut p = VehicleProfile {
        name,
        calibration: None,
        forecast: None,
        lstm: None,
        does_not_transfer: Vec::new(),
        rotor: None,
        powertrain: None,
        plane: None,
        fixed_wing: None,
        fixed_wing_flight: None,
        body: Some(Body { drag_area_m2: drag }),
        battery: Some(Battery {
            cells: f.cells,
            capacity_mah: f.capacity_mah,
            internal_resistance_ohm: f64::from(f.cells) * CELL_R_OHM_AH / (f.capacity_mah / 1000.0)
                + LEADS_OHM,
            ocv_cell_v,
        }),
        stolaroff: stolaroff::Params {
            eta: eta_h,
            drag_area_m2: drag,
            p_avio_w: AVIONICS_W,
            eta_per_ln_mass: pr.eta_h_per_ln_dl,
            profile_share: pr.profile_share,
        },
        ..m100
    };
    p.vehicle.airframe_kg = f.takeoff_kg - battery_kg;
    p.vehicle.battery_kg = battery_kg;
    p.vehicle.rotors = f.rotors;
    p.vehicle.prop_diameter_m = f.prop_m;
    p.vehicle.diagonal_m = diag;
    p.vehicle.mtow_kg = 1.5 * f.takeoff_kg;
    p.vehicle.class = Some(VehicleClass::Multirotor);
    p.kirschstein.drag_area_m2 = drag;
    p.dandrea.p_avio_w = AVIONICS_W;
    p.dandrea_headwind.p_avio_w = AVIONICS_W;
    p.kirschstein.p_avio_w = AVIONICS_W;
    p
}

/// Overlay `over` onto `base`, table by table.
fn merge(base: &mut Table, over: &Table) {
    for (k, v) in over {
        match (base.get_mut(k), v) {
            (Some(Value::Table(b)), Value::Table(o)) => merge(b, o),
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
}

/// Why the other physics members are not in a spec sheet's P50.
pub const LEFT_OUT: &str = "left out of the P50: dandrea (a fixed lift-to-drag ratio and η 0.5, no disk area), \
dorling (η = 1: no losses), kirschstein (κ2, κ3 fitted on the M100), tseng (the M100's regression), \
tseng_solo (the 3DR Solo's regression)";

/// The profile a spec sheet makes; `origin` names the file in errors.
pub fn profile(mut t: Table, origin: &str) -> anyhow::Result<VehicleProfile> {
    let name = match t.get("name") {
        Some(v) => v
            .as_str()
            .map(str::to_string)
            .ok_or_else(|| anyhow::anyhow!("{origin}: name = {v}: must be a string"))?,
        None => format!("spec sheet {origin}"),
    };
    let f = facts(&t).map_err(|e| anyhow::anyhow!("{origin}: {e}"))?;
    check_frame(&t, &f, &name).map_err(|e| anyhow::anyhow!("{origin}: {e}"))?;
    let filled = f.filled.clone();
    let mut priors_used = Vec::new();
    let pr = priors(&t, &f).map_err(|e| anyhow::anyhow!("{origin}: {e}"))?;
    let (eta_h, eta_sd) = (pr.eta_h, pr.eta_h_log_sd);
    t.remove("priors");
    let battery_kg = match num(&t, "vehicle", "battery_kg").map_err(anyhow::Error::msg)? {
        Some(b) => b,
        None => {
            let kg = f.capacity_mah / 1000.0 * f64::from(f.cells) * f.chemistry.nominal_v()
                / pack_wh_per_kg(f.chemistry);
            priors_used.push(format!(
                "pack {kg:.3} kg ({} Wh/kg)",
                pack_wh_per_kg(f.chemistry)
            ));
            kg
        }
    };
    if !(battery_kg > 0.0 && battery_kg < f.takeoff_kg) {
        anyhow::bail!(
            "{origin}: vehicle.battery_kg = {battery_kg:.3}: the pack must weigh more than 0 and less than vehicle.takeoff_kg = {}",
            f.takeoff_kg
        );
    }
    let own_eta = has(&t, "stolaroff", "eta");
    let own_drag = has(&t, "stolaroff", "drag_area_m2");
    if !own_eta {
        priors_used.push(format!("η_h {eta_h:.3} (log-sd {eta_sd:.2})"));
    }
    if !own_drag {
        priors_used.push(format!(
            "C_D·A {:.3} m²",
            pr.drag_per_kg23 * f.takeoff_kg.powf(2.0 / 3.0)
        ));
    }
    if !has(&t, "stolaroff", "profile_share") {
        priors_used.push(format!("profile share {:.2}", pr.profile_share));
    }
    if !has(&t, "stolaroff", "p_avio_w") {
        priors_used.push(format!("avionics {AVIONICS_W} W"));
    }
    let sd = (if own_eta { 0.0 } else { eta_sd.powi(2) }
        + if own_drag {
            0.0
        } else {
            (DRAG_SHARE * DRAG_LOG_SD).powi(2)
        })
    .sqrt();
    let p90 = (Z90 * sd).exp().max(1.05);
    for (sec, key) in SPEC_ONLY {
        if let Some(s) = t.get_mut(sec).and_then(Value::as_table_mut) {
            s.remove(key);
        }
    }
    let mut base = from_priors(&f, name.clone(), &pr, battery_kg);
    base.forecast = Some(ForecastDefault {
        model: "stolaroff".into(),
        why: format!(
            "spec sheet, momentum theory with {}; P90 from the priors' spread; {LEFT_OUT}",
            if priors_used.is_empty() {
                "the file's own figures".to_string()
            } else {
                format!("priors {}", priors_used.join(", "))
            }
        ),
        scale: Default::default(),
        p90_ratio: Some((p90 * 1000.0).round() / 1000.0),
    });
    let mut table = Table::try_from(&base).context("spec sheet: the priors' profile")?;
    merge(&mut table, &t);
    let text = toml::to_string(&table).context("spec sheet: the merged profile")?;
    let p: VehicleProfile = toml::from_str(&text)
        .with_context(|| format!("{origin}: not a valid spec sheet (a key no profile has?)"))?;
    p.validate().map_err(|e| anyhow::anyhow!("{origin}: {e}"))?;
    if first_load(origin) {
        let why = base.forecast.as_ref().map_or("", |f| f.why.as_str());
        if filled.is_empty() {
            tracing::info!("{origin}: a spec sheet; {why}");
        } else {
            tracing::warn!(
                "{origin}: a spec sheet without {}: filled from priors",
                filled.join(", ")
            );
        }
    }
    Ok(p)
}

/// A measured hover power, W, flown with `payload_kg` on board, makes the hover efficiency
/// the vehicle's: `[stolaroff] eta` = ideal momentum-theory power at the take-off mass with
/// that payload / (hover − avionics) (as the live first hover,
/// `energy::hover::HoverReference::eta_at`: a hover flown loaded is not a poor efficiency), the forecast the momentum-theory member
/// with a P90 that keeps only the drag's spread, and its reason says so. Refused for a
/// vehicle that does not hover (a plane) and for a power momentum theory cannot give this
/// mass on these rotors (η_h outside (0.05, 1)).
pub fn calibrate_hover(
    mut p: VehicleProfile,
    hover_w: f64,
    payload_kg: f64,
) -> Result<VehicleProfile, String> {
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
    if !(payload_kg.is_finite() && payload_kg >= 0.0) {
        return Err(format!("a payload of {payload_kg} kg: must be ≥ 0"));
    }
    let thrust = p.mass_kg(payload_kg) * p.air.g_m_s2;
    let ideal = thrust.powf(1.5) / (2.0 * p.air.rho_kg_m3 * p.disk_area_m2()).sqrt();
    // η_h at the hover's mass, then at the take-off mass (`[stolaroff] eta`'s) by the
    // member's own growth with the mass (`eta_per_ln_mass`).
    let at_hover = p.stolaroff.eta_at(p.mass_kg(payload_kg), p.mass_kg(0.0)) / p.stolaroff.eta;
    let eta = ideal / (hover_w - p.stolaroff.p_avio_w) / at_hover;
    if !(hover_w.is_finite() && eta > 0.05 && eta < 1.0) {
        return Err(format!(
            "{hover_w} W is not a hover of {} ({:.2} kg on {:.3} m² of disk needs at least {:.0} W, momentum theory's ideal, plus {:.0} W avionics)",
            p.name,
            p.mass_kg(payload_kg),
            p.disk_area_m2(),
            ideal,
            p.stolaroff.p_avio_w
        ));
    }
    let was = p.stolaroff.eta;
    p.stolaroff.eta = eta;
    let p90 = calibrated_p90();
    p.forecast = Some(ForecastDefault {
        model: format!("stolaroff{}", p.name_suffix()),
        why: format!(
            "calibrated on a measured hover of {hover_w:.0} W{}: η_h {eta:.3} (was {was:.3}); P90 from the drag prior's spread alone; {LEFT_OUT}",
            if payload_kg > 0.0 {
                format!(" with {payload_kg:.2} kg of payload")
            } else {
                String::new()
            }
        ),
        scale: Default::default(),
        p90_ratio: Some((p90 * 1000.0).round() / 1000.0),
    });
    Ok(p)
}

/// P90 over P50 once the hover efficiency is the vehicle's: the drag prior's spread alone
/// (`exp(1.2816 · 0.25 · 0.5)`, 1.174).
pub fn calibrated_p90() -> f64 {
    (Z90 * DRAG_SHARE * DRAG_LOG_SD).exp()
}

/// Whether this is the process's first load of `origin` (what was filled is said once).
fn first_load(origin: &str) -> bool {
    static SEEN: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let mut seen = SEEN
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if seen.iter().any(|o| o == origin) {
        return false;
    }
    seen.push(origin.to_string());
    true
}

/// The priors a spec sheet is made with.
struct Priors {
    eta_h: f64,
    eta_h_log_sd: f64,
    drag_per_kg23: f64,
    /// d ln η_h / d ln(disk loading): how η grows with the mass flown (payload on board).
    eta_h_per_ln_dl: f64,
    /// 1 − the figure of merit: the profile share of the hover power.
    profile_share: f64,
}

/// `[priors] eta_h, eta_h_log_sd, drag_per_kg23, eta_h_per_ln_dl, profile_share`, else the shipped ones (η_h
/// from the disk loading, which also sets how η_h grows with a payload): what the leave-one-airframe-out scoring passes, each fitted without the
/// airframe scored.
fn priors(t: &Table, f: &Facts) -> Result<Priors, String> {
    use crate::validate::{above_to, in_range};
    const KEYS: [&str; 5] = [
        "eta_h",
        "eta_h_log_sd",
        "drag_per_kg23",
        "eta_h_per_ln_dl",
        "profile_share",
    ];
    if let Some(p) = t.get("priors").and_then(Value::as_table) {
        if let Some(k) = p.keys().find(|k| !KEYS.contains(&k.as_str())) {
            return Err(format!("priors.{k}: unknown ({})", KEYS.join(", ")));
        }
    }
    let eta =
        num(t, "priors", "eta_h")?.unwrap_or_else(|| eta_h_prior(f.takeoff_kg, f.rotors, f.prop_m));
    let sd = num(t, "priors", "eta_h_log_sd")?.unwrap_or(ETA_H_LOG_SD);
    let drag = num(t, "priors", "drag_per_kg23")?.unwrap_or(DRAG_PER_KG23);
    in_range("priors.eta_h", eta, above_to(0.0, 1.0), "")?;
    in_range("priors.eta_h_log_sd", sd, 0.0..=2.0, "")?;
    in_range("priors.drag_per_kg23", drag, 0.0..=1.0, "m²/kg^(2/3)")?;
    let slope = num(t, "priors", "eta_h_per_ln_dl")?.unwrap_or(ETA_H_PER_LN_DL);
    in_range("priors.eta_h_per_ln_dl", slope, 0.0..=1.0, "")?;
    let share = num(t, "priors", "profile_share")?.unwrap_or(PROFILE_SHARE);
    in_range("priors.profile_share", share, 0.0..=0.9, "")?;
    Ok(Priors {
        eta_h: eta,
        eta_h_log_sd: sd,
        drag_per_kg23: drag,
        eta_h_per_ln_dl: slope,
        profile_share: share,
    })
}

#[cfg(test)]
#[path = "spec_tests.rs"]
mod tests;
