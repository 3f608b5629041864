//! What a pack's facts give before it has flown: its OCV curve and circuit, a prior
//! resistance, its charge and the low threshold.

use super::*;

/// A prior series resistance for a pack, Ω: the TB48D's fitted R0 + R1 a cell at its
/// 5.7 Ah, times the cells, over the pack's charge in Ah (cells in parallel lower it); a
/// 5.7 Ah cell where the charge is not known.
pub fn prior_r_ohm(cells: u32, ah: Option<f64>) -> f64 {
    let base = CircuitParams::default();
    let per_cell = (base.r0 + base.r1) / f64::from(base.n_cells);
    let ah = ah.filter(|a| a.is_finite() && *a > 0.05).unwrap_or(5.7);
    (per_cell * 5.7 / ah).min(MAX_R_CELL_OHM) * f64::from(cells.max(1))
}

/// The low-voltage threshold, V: the vehicle's (`BATT_LOW_VOLT`, the config), else
/// [`DEFAULT_LOW_V_CELL`] a cell.
pub(super) fn low_v(facts: &BatteryFacts) -> f64 {
    facts
        .low_voltage_v
        .as_ref()
        .map(|s| s.value)
        .unwrap_or(DEFAULT_LOW_V_CELL * f64::from(facts.cell_count.value))
}

/// The pack's charge, Ah, from its facts (capacity ÷ cells ÷ nominal), when known.
pub(super) fn pack_ah(facts: &BatteryFacts, chem: Chemistry) -> Option<f64> {
    facts
        .capacity()
        .map(|wh| wh / (f64::from(facts.cell_count.value.max(1)) * chem.nominal_v()))
}

/// The current over which this pack counts as loaded, A: take-off (flown), the sag check's
/// seconds under load (the load-compensated start's 10 s hold on the voltage forecast), the
/// "assumed full" warning. The resistance fit's threshold ([`crate::battery::trend::loaded_a`]):
/// [`LOAD_CURRENT_A`] on the M100's pack, less on a smaller one in proportion to its charge (a
/// 3S1P 2.5 Ah pack hovering at 2 A is loaded), never under [`rest_current_a`] (a current the
/// rest rule calls rest is not a take-off). With the capacity not known: [`LOAD_CURRENT_A`]
/// (a rule from the currents seen would let a busy ground idle count as a take-off).
pub fn load_current_a(facts: &BatteryFacts) -> f64 {
    currents(facts).1
}

/// The current under which this pack counts as resting, A: [`REST_CURRENT_A`], and on a pack
/// whose loaded current ([`crate::battery::trend::loaded_a`]) is under twice that (under
/// about 3 Ah), half its loaded current, so that a small pack's hover is never read as a rest
/// (a 1 Ah pack hovering at 0.8 A had its loaded voltage read as a resting one, and never
/// took off); never under [`REST_FLOOR_A`]. With the capacity not known: [`REST_CURRENT_A`].
pub fn rest_current_a(facts: &BatteryFacts) -> f64 {
    currents(facts).0
}

/// ([`rest_current_a`], [`load_current_a`]) of these facts, the chemistry read once.
pub fn currents(facts: &BatteryFacts) -> (f64, f64) {
    let chem = Chemistry::from_name(&facts.chemistry.value).unwrap_or(Chemistry::LiPo);
    currents_of(pack_ah(facts, chem))
}

/// ([`rest_current_a`], [`load_current_a`]) of a pack of this charge (Ah; `None`: not known).
pub(super) fn currents_of(ah: Option<f64>) -> (f64, f64) {
    let loaded = crate::battery::trend::loaded_a(ah);
    let rest = (0.5 * loaded).clamp(REST_FLOOR_A, REST_CURRENT_A);
    (rest, loaded.max(rest))
}

/// The OCV curve and circuit for these battery facts: the TB48D's own fit for the M100's
/// 6S LiHV pack, else the chemistry's default shape scaled to the capacity, with the
/// TB48D's resistances scaled by cells and capacity.
pub fn pack_model(facts: &BatteryFacts) -> Option<(OcvCurve, CircuitParams)> {
    let chem = Chemistry::from_name(&facts.chemistry.value)?;
    let cells = facts.cell_count.value;
    // No capacity, no circuit (its energy is in Wh); no pack of 0 or more than 24 cells.
    let cap = facts.capacity().filter(|c| c.is_finite() && *c > 0.0)?;
    if !(1..=24).contains(&cells) {
        return None;
    }
    let tb48d = chem == Chemistry::LiHv
        && cells == crate::report::M100_CELL_COUNT
        && (cap - crate::report::M100_CAPACITY_WH).abs() < 0.5;
    let base = CircuitParams::default();
    if tb48d {
        return Some((OcvCurve::tb48d(), base));
    }
    let curve = chem.default_curve().scaled(cap)?;
    // Resistance grows with cells in series and falls with capacity (cells in parallel).
    let ah = cap / (f64::from(cells) * chem.nominal_v());
    let k = f64::from(cells) / f64::from(base.n_cells) * (5.7 / ah);
    Some((
        curve,
        CircuitParams {
            n_cells: cells,
            r0: base.r0 * k,
            r1: base.r1 * k,
            bias_v: 0.0,
            deep_a: crate::battery::deep::PRIOR_A,
            // chosen on ProgPy's 18650 packs: Li-ion's; a LiPo's curve keeps one resistance
            deep_slope: if chem.is_li_ion() {
                crate::battery::deep::PRIOR_SLOPE
            } else {
                0.0
            },
            // Li-ion's curve is a resting-voltage table (∫OCV dq): the heat in the cells'
            // resistance leaves the pack too (docs/src/pack.md, "Energy at landing").
            ocv_count: ocv_table(chem),
            ..base
        },
    ))
}

/// Whether the chemistry's default curve is a resting-voltage table whose energies are
/// ∫OCV dq (Li-ion's of either cathode, [`Chemistry::default_curve`]): its packs count energy at the
/// open-circuit voltage and read their resting voltage corrected for the ground idle's I·R
/// ([`rest_ocv`]). The TB48D's (and the LiHV shape from it) was fitted on terminal energy
/// between voltages read at ground idle; LiPo and LiFePO4 are not yet measured on a peer.
pub fn ocv_table(chem: Chemistry) -> bool {
    chem.is_li_ion()
}

/// The open-circuit voltage a reading at a small discharge current stands for, V: `v + i·r`,
/// `r` the pack's resistance (Ω) where it is known. A current of 0 or under (a sensor's offset
/// at rest; charging is not a rest) and a resistance not known (`None`, not finite, under 0)
/// leave the reading as it is.
pub fn rest_ocv(v: f64, i: f64, r_ohm: Option<f64>) -> f64 {
    match r_ohm.filter(|r| r.is_finite() && *r >= 0.0) {
        Some(r) if i.is_finite() && i > 0.0 => v + i * r,
        _ => v,
    }
}
