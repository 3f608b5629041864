//! Resolving the battery's facts, best first, from the config, the vehicle's parameters and
//! the first voltage seen (the table in [`super`]'s docs).

use super::{params, BatteryConfig};
use crate::battery::{cell_candidates, Chemistry};
use crate::report::{BatteryFacts, Provenance, Sourced, DEFAULT_CELL_COUNT};

/// The cell count a pack voltage parameter gives when it is `cells × per_cell` within
/// ±`tol` V a cell (integer arithmetic on the rounded count: no `ceil`).
pub(crate) fn cells_from(v: f64, per_cell: f64, tol: f64) -> Option<u32> {
    let n = (v / per_cell).round();
    ((1.0..=24.0).contains(&n) && (v - n * per_cell).abs() <= tol * n).then_some(n as u32)
}

/// The battery parameters the vehicle sent, each range-checked (a skip is a note).
struct PackParams {
    cells: Option<u32>,
    capacity: Option<(&'static str, f64)>,
    low: Option<Sourced<f64>>,
    crt: Option<Sourced<f64>>,
    v_empty: Option<f64>,
    max_cells: Option<(u32, Chemistry)>,
    min_cells: Option<u32>,
}

impl PackParams {
    fn read(p: &params::VehicleParams, notes: &mut Vec<String>) -> Self {
        let mut checked = |name: &str, lo: f64, hi: f64, unit: &str| -> Option<f64> {
            let v = p.get(name)?;
            if v.is_finite() && v >= lo && v <= hi {
                Some(v)
            } else {
                notes.push(format!("vehicle parameter {name} = {v}: outside {lo}..={hi} {unit}, ignored: using the config or the default instead"));
                None
            }
        };
        let cells = checked("BAT1_N_CELLS", 1.0, 24.0, "cells").map(|v| v.round() as u32);
        let capacity = ["BATT_CAPACITY", "BAT1_CAPACITY"]
            .into_iter()
            .find_map(|n| {
                // PX4's BAT1_CAPACITY is −1 when unset: "absent", not an error.
                if p.get(n).is_some_and(|v| v == -1.0) {
                    return None;
                }
                // 1 Ah to 1,000 Ah: 0 is ArduPilot's "not set", and a number past that is a typo
                // (1,000,000 mAh), neither a pack.
                checked(n, 50.0, 999_999.0, "mAh").map(|v| (n, v))
            });
        let low = checked("BATT_LOW_VOLT", 0.1, 100.0, "V")
            .map(|v| Sourced::new(v, Provenance::Parameter("BATT_LOW_VOLT".into())));
        let crt = checked("BATT_CRT_VOLT", 0.1, 100.0, "V")
            .map(|v| Sourced::new(v, Provenance::Parameter("BATT_CRT_VOLT".into())));
        let v_empty = checked("BAT1_V_EMPTY", 2.0, 4.5, "V per cell");
        // ArduCopter's thrust-scaling voltages: 0 (the default) means off, not a pack.
        let volt_param = |name: &str| p.get(name).filter(|v| v.is_finite() && *v > 0.0);
        let max_cells = volt_param("MOT_BAT_VOLT_MAX").and_then(|v| {
            cells_from(v, 4.2, 0.03)
                .map(|n| (n, Chemistry::LiPo))
                .or_else(|| cells_from(v, 4.35, 0.03).map(|n| (n, Chemistry::LiHv)))
        });
        let min_cells = volt_param("MOT_BAT_VOLT_MIN").and_then(|v| cells_from(v, 3.3, 0.1));
        Self {
            cells,
            capacity,
            low,
            crt,
            v_empty,
            max_cells,
            min_cells,
        }
    }
}

/// A figure the config gave: from the named pack, else the config.
fn configured(cfg: &BatteryConfig) -> Provenance {
    cfg.named
        .clone()
        .map_or(Provenance::Config, Provenance::Named)
}

/// The chemistry: the config, the battery's type (Li-ion, LiFePO4), MOT_BAT_VOLT_MAX, any
/// other type, else a LiPo assumed.
fn chemistry_of(
    cfg: &BatteryConfig,
    typed: Option<Chemistry>,
    max_cells: Option<(u32, Chemistry)>,
) -> Sourced<Chemistry> {
    let by_type = |c| Sourced::new(c, Provenance::Parameter("BATTERY_STATUS type".into()));
    match (cfg.chemistry, max_cells) {
        (Some(c), _) => Sourced::new(c, configured(cfg)),
        // Li-ion and LiFePO4 by the battery's type: MOT_BAT_VOLT_MAX (× 4.2) cannot tell
        // Li-ion from LiPo; MAVLink's type has no LiHV, so a "LiPo" at 4.35 a cell is one.
        (None, _)
            if matches!(
                typed,
                Some(Chemistry::LiIon | Chemistry::LiIonNmc | Chemistry::LiFePo4)
            ) =>
        {
            by_type(typed.unwrap_or(Chemistry::LiPo))
        }
        (None, Some((_, c))) => Sourced::new(c, Provenance::Parameter("MOT_BAT_VOLT_MAX".into())),
        (None, None) if typed.is_some() => by_type(typed.unwrap_or(Chemistry::LiPo)),
        // Nothing says: a LiPo, said as assumed (the band is widened for it).
        (None, None) => Sourced::new(Chemistry::LiPo, Provenance::Default),
    }
}

/// The first voltage and the cell counts it fits; an assumed chemistry: the counts a LiPo
/// or a LiHV pack at this voltage could have (a full 6S LiHV at 26.1 V is also a 7S LiPo at
/// 3.73 V: said, not picked silently).
fn voltage_fits(
    first_voltage_v: Option<f64>,
    chemistry: &Sourced<Chemistry>,
) -> Option<(f64, Vec<u32>)> {
    first_voltage_v
        .filter(|v| v.is_finite() && *v > 1.0)
        .map(|v| {
            let mut fits = cell_candidates(chemistry.value, v);
            if chemistry.source == Provenance::Default {
                fits.extend(cell_candidates(Chemistry::LiHv, v));
                fits.sort_unstable();
                fits.dedup();
            }
            (v, fits)
        })
}

/// The cell count: the config, BAT1_N_CELLS, the cell voltages, BATTERY_INFO,
/// MOT_BAT_VOLT_MAX, MOT_BAT_VOLT_MIN, the first voltage, else the default.
fn cell_count_of(
    cfg: &BatteryConfig,
    p: &params::VehicleParams,
    pp: &PackParams,
    from_voltage: Option<u32>,
) -> Sourced<u32> {
    let info_cells = p.battery_info.and_then(|(_, n)| n);
    let monitor_cells = p
        .battery_cells
        .filter(|n| (2..=24).contains(n))
        .or(info_cells);
    let cells_param = pp.cells;
    match (
        cfg.cell_count,
        cells_param.or(monitor_cells),
        pp.max_cells,
        pp.min_cells,
        from_voltage,
    ) {
        (Some(n), ..) => Sourced::new(n, configured(cfg)),
        (None, Some(n), ..) if cells_param.is_some() => {
            Sourced::new(n, Provenance::Parameter("BAT1_N_CELLS".into()))
        }
        (None, Some(n), ..) if p.battery_cells.is_some_and(|c| c == n) => Sourced::new(
            n,
            Provenance::Parameter("BATTERY_STATUS cell voltages".into()),
        ),
        (None, Some(n), ..) => Sourced::new(n, Provenance::Parameter("BATTERY_INFO".into())),
        (None, None, Some((n, _)), ..) => {
            Sourced::new(n, Provenance::Parameter("MOT_BAT_VOLT_MAX".into()))
        }
        (None, None, None, Some(n), _) => {
            Sourced::new(n, Provenance::Parameter("MOT_BAT_VOLT_MIN".into()))
        }
        (None, None, None, None, Some(n)) => Sourced::new(n, Provenance::FirstVoltage),
        (None, None, None, None, None) => Sourced::new(DEFAULT_CELL_COUNT, Provenance::Default),
    }
}

/// What the first voltage leaves open, said where the voltage is what decides the count
/// (not beside a count the config or vehicle gave).
fn note_voltage_fits(
    voltage_fits: &Option<(f64, Vec<u32>)>,
    cell_count: &Sourced<u32>,
    chemistry: Chemistry,
    notes: &mut Vec<String>,
) {
    if let (Some((v, fits)), Provenance::FirstVoltage | Provenance::Default) =
        (voltage_fits, &cell_count.source)
    {
        let name = chemistry.name();
        if fits.len() > 1 {
            let list = fits
                .iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(" or ");
            notes.push(format!(
                "battery voltage {v:.2} V fits {list} {name} cells; taking {} (a pack flies full more often than nearly empty) — set [energy] cell_count to be sure",
                fits[0]
            ));
        } else if fits.is_empty() {
            notes.push(format!(
                "battery voltage {v:.2} V fits no {name} pack of 1-16 cells"
            ));
        }
    }
}

/// The capacity, Wh: the config, BATT_CAPACITY/BAT1_CAPACITY, BATTERY_INFO; a charge is a
/// capacity only when the cells are known, not assumed.
fn capacity_of(
    cfg: &BatteryConfig,
    p: &params::VehicleParams,
    cap_param: Option<(&'static str, f64)>,
    cell_count: &Sourced<u32>,
    nominal_cell_v: f64,
    notes: &mut Vec<String>,
) -> Option<Sourced<f64>> {
    match (cfg.capacity_wh, cap_param) {
        (Some(wh), _) => Some(Sourced::new(wh, configured(cfg))),
        // mAh × cells × nominal is only a capacity when the cells are known, not assumed.
        (None, Some((name, mah))) if cell_count.source != Provenance::Default => {
            Some(Sourced::new(
                mah / 1000.0 * f64::from(cell_count.value) * nominal_cell_v,
                Provenance::Parameter(name.into()),
            ))
        }
        (None, Some((name, _))) => {
            notes.push(format!("vehicle parameter {name} gives the charge but nothing gives the cells (no battery voltage that fits a pack yet): capacity not known"));
            None
        }
        // A smart battery's own word (BATTERY_INFO), with the cells known.
        (None, None) => p
            .battery_info
            .and_then(|(ah, _)| ah)
            .filter(|_| cell_count.source != Provenance::Default)
            .map(|ah| {
                Sourced::new(
                    ah * f64::from(cell_count.value) * nominal_cell_v,
                    Provenance::Parameter("BATTERY_INFO".into()),
                )
            }),
    }
}

/// Resolve each figure, best first (module docs), from the config, the vehicle's
/// parameters and the first battery voltage seen (V, whole pack). Out-of-range
/// parameters are skipped, and each skip is returned as a message for a warning.
pub fn resolve_battery(
    cfg: &BatteryConfig,
    p: &params::VehicleParams,
    first_voltage_v: Option<f64>,
) -> (BatteryFacts, Vec<String>) {
    let mut notes = Vec::new();
    let pp = PackParams::read(p, &mut notes);
    let chemistry = chemistry_of(cfg, p.battery_chemistry, pp.max_cells);
    let voltage_fits = voltage_fits(first_voltage_v, &chemistry);
    let from_voltage = voltage_fits
        .as_ref()
        .and_then(|(_, fits)| fits.first().copied());
    let cell_count = cell_count_of(cfg, p, &pp, from_voltage);
    note_voltage_fits(&voltage_fits, &cell_count, chemistry.value, &mut notes);
    let nominal_cell_v = cfg.nominal_cell_v.unwrap_or(chemistry.value.nominal_v());
    let capacity_wh = capacity_of(cfg, p, pp.capacity, &cell_count, nominal_cell_v, &mut notes);
    let critical_voltage_v = pp.crt.or_else(|| {
        pp.v_empty.map(|v| {
            Sourced::new(
                v * f64::from(cell_count.value),
                Provenance::Parameter("BAT1_V_EMPTY".into()),
            )
        })
    });
    let chemistry = Sourced::new(chemistry.value.name().to_string(), chemistry.source);
    (
        BatteryFacts {
            capacity_wh,
            cell_count,
            chemistry,
            low_voltage_v: pp.low,
            critical_voltage_v,
            rated_capacity_wh: None,
        },
        notes,
    )
}

/// The facts with nothing from the vehicle: config, else defaults.
pub fn battery_from_config(cfg: &BatteryConfig) -> BatteryFacts {
    resolve_battery(cfg, &params::VehicleParams::default(), None).0
}
