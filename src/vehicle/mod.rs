//! Who the vehicle is: its identity and the autopilot parameters that size its battery
//! ([`params`]), and the battery facts the energy stage uses, each with where it came from
//! ([`BatteryFacts`], [`Provenance`]).
//!
//! dronewatt's defaults are the DJI Matrice 100's (TB48D: 6 cells, 129.96 Wh). Attached to
//! another vehicle, the vehicle itself knows better: ArduPilot's `BATT_CAPACITY` (mAh) and
//! PX4's `BAT1_CAPACITY`, `BAT1_N_CELLS`. Each battery figure is taken, best first, from
//!
//! | figure | 1. config | 2. vehicle | 3. fallback |
//! |---|---|---|---|
//! | cell count | `[energy] cell_count` | `BAT1_N_CELLS` (PX4), else `ceil(V / 4.2)` of the first battery voltage seen | 6 (TB48D) |
//! | capacity, Wh | `[energy] capacity_wh` | `BATT_CAPACITY` / `BAT1_CAPACITY` (mAh) / 1000 × cells × `[energy] nominal_cell_v` (3.7 V, LiPo) | 129.96 (TB48D) |
//! | low / critical voltage, V (pack) | — | `BATT_LOW_VOLT` / `BATT_CRT_VOLT` (ArduPilot); `BAT1_V_EMPTY` × cells as critical (PX4) | none |
//!
//! and [`Provenance`] says which, all the way to the terminal, the JSON lines and the
//! dashboard. A parameter that is absent or out of range falls back to the next column
//! with one warning, never an error: the vehicle's word is a better default, not a
//! requirement.

pub mod params;
pub mod store;

pub use crate::report::{BatteryFacts, Provenance, Sourced, DEFAULT_CAPACITY_WH, DEFAULT_CELL_COUNT};

/// A full LiPo cell, V: the first voltage seen over this, rounded up, is the cell count.
pub const FULL_CELL_V: f64 = 4.2;

/// What the configuration says about the battery (the `[energy]` keys that may be left
/// to the vehicle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatteryConfig {
    /// `[energy] capacity_wh`, when set.
    pub capacity_wh: Option<f64>,
    /// `[energy] cell_count`, when set.
    pub cell_count: Option<u32>,
    /// `[energy] nominal_cell_v`: mAh × cells × this = capacity, V.
    pub nominal_cell_v: f64,
}

/// Resolve each figure, best first (module docs), from the config, the vehicle's
/// parameters and the first battery voltage seen (V, whole pack). Out-of-range
/// parameters are skipped, and each skip is returned as a message for a warning.
pub fn resolve_battery(cfg: &BatteryConfig, p: &params::VehicleParams, first_voltage_v: Option<f64>) -> (BatteryFacts, Vec<String>) {
    let mut notes = Vec::new();
    let mut checked = |name: &str, lo: f64, hi: f64, unit: &str| -> Option<f64> {
        let v = p.get(name)?;
        if v.is_finite() && v >= lo && v <= hi {
            Some(v)
        } else {
            notes.push(format!("vehicle parameter {name} = {v}: outside {lo}..={hi} {unit}, ignored"));
            None
        }
    };
    let cells_param = checked("BAT1_N_CELLS", 1.0, 24.0, "cells").map(|v| v.round() as u32);
    let cap_param = ["BATT_CAPACITY", "BAT1_CAPACITY"].into_iter().find_map(|n| {
        // PX4's BAT1_CAPACITY is −1 when unset: "absent", not an error.
        if p.get(n).is_some_and(|v| v == -1.0) {
            return None;
        }
        checked(n, 1.0, 1_000_000.0, "mAh").map(|v| (n, v))
    });
    let low = checked("BATT_LOW_VOLT", 0.1, 100.0, "V").map(|v| Sourced::new(v, Provenance::Parameter("BATT_LOW_VOLT".into())));
    let crt = checked("BATT_CRT_VOLT", 0.1, 100.0, "V").map(|v| Sourced::new(v, Provenance::Parameter("BATT_CRT_VOLT".into())));
    let v_empty = checked("BAT1_V_EMPTY", 2.0, 4.5, "V per cell");

    let from_voltage = first_voltage_v
        .filter(|v| v.is_finite() && *v > 1.0 && *v < 24.0 * FULL_CELL_V)
        .map(|v| (v / FULL_CELL_V).ceil().max(1.0) as u32);
    let cell_count = match (cfg.cell_count, cells_param, from_voltage) {
        (Some(n), _, _) => Sourced::new(n, Provenance::Config),
        (None, Some(n), _) => Sourced::new(n, Provenance::Parameter("BAT1_N_CELLS".into())),
        (None, None, Some(n)) => Sourced::new(n, Provenance::FirstVoltage),
        (None, None, None) => Sourced::new(DEFAULT_CELL_COUNT, Provenance::Default),
    };
    let capacity_wh = match (cfg.capacity_wh, cap_param) {
        (Some(wh), _) => Sourced::new(wh, Provenance::Config),
        (None, Some((name, mah))) => {
            Sourced::new(mah / 1000.0 * f64::from(cell_count.value) * cfg.nominal_cell_v, Provenance::Parameter(name.into()))
        }
        (None, None) => Sourced::new(DEFAULT_CAPACITY_WH, Provenance::Default),
    };
    let critical_voltage_v = crt.or_else(|| {
        v_empty.map(|v| Sourced::new(v * f64::from(cell_count.value), Provenance::Parameter("BAT1_V_EMPTY".into())))
    });
    (BatteryFacts { capacity_wh, cell_count, low_voltage_v: low, critical_voltage_v, rated_capacity_wh: None }, notes)
}

/// The facts with nothing from the vehicle: config, else defaults.
pub fn battery_from_config(cfg: &BatteryConfig) -> BatteryFacts {
    resolve_battery(cfg, &params::VehicleParams::default(), None).0
}

#[cfg(test)]
mod tests {
    use super::params::VehicleParams;
    use super::*;

    fn cfg(capacity_wh: Option<f64>, cell_count: Option<u32>) -> BatteryConfig {
        BatteryConfig { capacity_wh, cell_count, nominal_cell_v: 3.7 }
    }

    #[test]
    fn config_beats_vehicle_beats_default() {
        let p = VehicleParams::from_pairs(&[("BATT_CAPACITY", 3300.0), ("BATT_LOW_VOLT", 10.5), ("BATT_CRT_VOLT", 9.9)]);
        // Nothing configured: 3300 mAh, 3 cells from the first voltage (12.4 V), 3.7 V a cell.
        let (f, notes) = resolve_battery(&cfg(None, None), &p, Some(12.4));
        assert!(notes.is_empty());
        assert_eq!(f.cell_count, Sourced::new(3, Provenance::FirstVoltage));
        assert!((f.capacity_wh.value - 3.3 * 3.0 * 3.7).abs() < 1e-9);
        assert_eq!(f.capacity_wh.source.to_string(), "vehicle parameter BATT_CAPACITY");
        assert_eq!(f.low_voltage_v.as_ref().map(|s| s.value), Some(10.5));
        // The config wins where it speaks.
        let (f, _) = resolve_battery(&cfg(Some(50.0), Some(4)), &p, Some(12.4));
        assert_eq!((f.capacity_wh.value, f.capacity_wh.source.clone()), (50.0, Provenance::Config));
        assert_eq!(f.cell_count.source, Provenance::Config);
        // Nothing at all: the M100's pack, said so.
        let f = battery_from_config(&cfg(None, None));
        assert_eq!((f.capacity_wh.value, f.cell_count.value), (DEFAULT_CAPACITY_WH, 6));
        assert_eq!(f.capacity_wh.source.to_string(), "default");
    }

    #[test]
    fn px4_cells_and_empty_voltage() {
        let p = VehicleParams::from_pairs(&[("BAT1_CAPACITY", 5000.0), ("BAT1_N_CELLS", 4.0), ("BAT1_V_EMPTY", 3.5)]);
        let (f, _) = resolve_battery(&cfg(None, None), &p, Some(12.0));
        assert_eq!(f.cell_count, Sourced::new(4, Provenance::Parameter("BAT1_N_CELLS".into())));
        assert!((f.capacity_wh.value - 5.0 * 4.0 * 3.7).abs() < 1e-9);
        assert_eq!(f.critical_voltage_v.map(|s| s.value), Some(14.0));
        // PX4's "unset" capacity (−1) is absent, quietly.
        let p = VehicleParams::from_pairs(&[("BAT1_CAPACITY", -1.0)]);
        let (f, notes) = resolve_battery(&cfg(None, None), &p, None);
        assert!(notes.is_empty());
        assert_eq!(f.capacity_wh.source, Provenance::Default);
    }

    #[test]
    fn wrong_parameters_degrade_with_a_message() {
        let p = VehicleParams::from_pairs(&[("BATT_CAPACITY", 0.0), ("BAT1_N_CELLS", 99.0), ("BATT_LOW_VOLT", f64::NAN)]);
        let (f, notes) = resolve_battery(&cfg(None, None), &p, Some(f64::NAN));
        assert_eq!(f.capacity_wh.source, Provenance::Default);
        assert_eq!(f.cell_count.source, Provenance::Default);
        assert!(f.low_voltage_v.is_none());
        assert_eq!(notes.len(), 3, "{notes:?}");
        assert!(notes.iter().any(|n| n.contains("BATT_CAPACITY = 0")), "{notes:?}");
    }
}
