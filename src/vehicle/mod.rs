//! Who the vehicle is: its identity and the autopilot parameters that size its battery
//! ([`params`]), and the battery facts the energy stage uses, each with where it came from
//! ([`crate::report::BatteryFacts`], [`crate::report::Provenance`]).
//!
//! No vehicle gets another vehicle's pack: the DJI Matrice 100's TB48D (6 cells, 129.96 Wh)
//! is the pack of the M100 data set and of the M100's vehicle profile only. Elsewhere the
//! vehicle knows: ArduPilot's `BATT_CAPACITY` (mAh) and PX4's `BAT1_CAPACITY`,
//! `BAT1_N_CELLS`. Until something says, the capacity is *not known* (null, with
//! [`crate::report::CAPACITY_UNKNOWN`] as its source). Each battery figure is taken, best first, from
//!
//! | figure | 1. config | 2. vehicle | 3. fallback |
//! |---|---|---|---|
//! | chemistry | `[energy] chemistry` (or `--pack`) | LiHV when `MOT_BAT_VOLT_MAX` is cells × 4.35 | LiPo, said as assumed |
//! | cell count | `[energy] cell_count` (or `--pack`) | `BAT1_N_CELLS` (PX4); the cells BATTERY_STATUS reports one by one; `MOT_BAT_VOLT_MAX` = cells × 4.2 or 4.35, `MOT_BAT_VOLT_MIN` = cells × 3.3 (ArduCopter); else the first battery voltage seen, checked against the chemistry's resting window ([`crate::battery::cell_candidates`]) | 6 (TB48D) |
//! | capacity, Wh | `[energy] capacity_wh` (or `--pack`) | `BATT_CAPACITY` / `BAT1_CAPACITY` (mAh) / 1000 × cells × nominal cell voltage (`[energy] nominal_cell_v`, else the chemistry's: LiPo 3.7, LiHV 3.8, Li-ion 3.6, LiFePO4 3.2 V) | not known (null) |
//! | low / critical voltage, V (pack) | — | `BATT_LOW_VOLT` / `BATT_CRT_VOLT` (ArduPilot); `BAT1_V_EMPTY` × cells as critical (PX4) | none |
//!
//! A voltage that fits two cell counts (a full 6S LiHV pack at 26.1 V is also a 7S pack at
//! 3.73 V a cell) takes the fewer cells (a pack is far more often flown full than nearly
//! empty) and says so in a warning, never silently. No float `ceil`: in floating point
//! 12.6 / 4.2 is 3.0000000000000004, which `ceil` made 4 cells.
//!
//! and [`crate::report::Provenance`] says which, all the way to the terminal, the JSON lines and the
//! dashboard. A parameter that is absent or out of range falls back to the next column
//! with one warning, never an error: the vehicle's word is a better default, not a
//! requirement.

pub mod pack_spec;
pub mod params;
mod resolve;
pub mod store;
pub mod streams;

use crate::battery::Chemistry;
use crate::report::{M100_CAPACITY_WH, M100_CELL_COUNT, M100_PACK};
pub(crate) use resolve::cells_from;
pub use resolve::{battery_from_config, resolve_battery};

/// What the configuration says about the battery (the `[energy]` keys that may be left
/// to the vehicle).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BatteryConfig {
    /// `[energy] capacity_wh`, when set.
    pub capacity_wh: Option<f64>,
    /// `[energy] cell_count`, when set.
    pub cell_count: Option<u32>,
    /// `[energy] nominal_cell_v`: mAh × cells × this = capacity, V; None: the chemistry's.
    pub nominal_cell_v: Option<f64>,
    /// `[energy] chemistry`, when set.
    pub chemistry: Option<Chemistry>,
    /// What named the pack these keys describe (`--pack …`, the M100 data set), when not
    /// the config file: said as the figures' provenance.
    pub named: Option<String>,
}

impl BatteryConfig {
    /// The M100's TB48D: the data set's pack, and the M100 profile's.
    pub fn m100() -> Self {
        Self {
            capacity_wh: Some(M100_CAPACITY_WH),
            cell_count: Some(M100_CELL_COUNT),
            nominal_cell_v: None,
            chemistry: Some(Chemistry::LiHv),
            named: Some(M100_PACK.into()),
        }
    }
}

/// The pack's identity from BATTERY_INFO: its `serial_number` (ASCII, 0-terminated),
/// trimmed of blanks. Empty, all zeros, blanks or not text is no identity: such a monitor
/// does not tell its packs apart (BATTERY_INFO and BATTERY_STATUS `id` only says which of
/// the vehicle's batteries, not which pack is in it). Control characters are dropped (the
/// identity goes to the store and the terminal).
pub fn pack_identity(b: &crate::dialect::BATTERY_INFO_DATA) -> Option<String> {
    let raw: &[u8] = &b.serial_number[..];
    let end = raw.iter().position(|&c| c == 0).unwrap_or(raw.len());
    let text = std::str::from_utf8(&raw[..end]).ok()?;
    let id: String = text.trim().chars().filter(|c| !c.is_control()).collect();
    (!id.is_empty() && id.chars().any(|c| c != '0')).then_some(id)
}

#[cfg(test)]
mod tests {
    use super::params::VehicleParams;
    use super::*;
    use crate::report::{BatteryFacts, Provenance, Sourced};

    #[test]
    fn a_pack_is_told_by_its_serial_and_a_blank_one_is_no_pack() {
        let info = |serial: &str| crate::dialect::BATTERY_INFO_DATA {
            serial_number: serial.into(),
            ..Default::default()
        };
        assert_eq!(
            pack_identity(&info("TB48D-0042 ")).as_deref(),
            Some("TB48D-0042")
        );
        for blank in ["", "   ", "0000", "\t\n"] {
            assert_eq!(pack_identity(&info(blank)), None, "{blank:?}");
        }
        let mut bad = info("");
        bad.serial_number = [0xff_u8; 32].into();
        assert_eq!(pack_identity(&bad), None, "not text");
    }

    fn cfg(capacity_wh: Option<f64>, cell_count: Option<u32>) -> BatteryConfig {
        BatteryConfig {
            capacity_wh,
            cell_count,
            nominal_cell_v: Some(3.7),
            chemistry: None,
            named: None,
        }
    }
    fn cap(f: &BatteryFacts) -> f64 {
        f.capacity().unwrap_or(f64::NAN)
    }
    fn cap_source(f: &BatteryFacts) -> Provenance {
        f.capacity_wh
            .clone()
            .map(|c| c.source)
            .unwrap_or(Provenance::Default)
    }

    #[test]
    fn config_beats_vehicle_beats_default() {
        let p = VehicleParams::from_pairs(&[
            ("BATT_CAPACITY", 3300.0),
            ("BATT_LOW_VOLT", 10.5),
            ("BATT_CRT_VOLT", 9.9),
        ]);
        // Nothing configured: 3300 mAh, 3 cells from the first voltage (12.4 V), 3.7 V a cell.
        let (f, notes) = resolve_battery(&cfg(None, None), &p, Some(12.4));
        assert!(notes.is_empty());
        assert_eq!(f.cell_count, Sourced::new(3, Provenance::FirstVoltage));
        assert!((cap(&f) - 3.3 * 3.0 * 3.7).abs() < 1e-9);
        assert_eq!(f.capacity_source(), "vehicle parameter BATT_CAPACITY");
        assert_eq!(f.low_voltage_v.as_ref().map(|s| s.value), Some(10.5));
        // The config wins where it speaks.
        let (f, _) = resolve_battery(&cfg(Some(50.0), Some(4)), &p, Some(12.4));
        assert_eq!((cap(&f), cap_source(&f)), (50.0, Provenance::Config));
        assert_eq!(f.cell_count.source, Provenance::Config);
        // Nothing at all: the capacity is not known (never the M100's pack), and says why.
        let f = battery_from_config(&cfg(None, None));
        assert_eq!(f.capacity_wh, None);
        assert!(f.capacity_source().starts_with("not known"), "{f:?}");
        assert_eq!(f.chemistry.value, "lipo");
        // BATT_CAPACITY without anything that gives the cells: still not known, said.
        let (f, notes) = resolve_battery(&cfg(None, None), &p, None);
        assert_eq!(f.capacity_wh, None);
        assert_eq!(notes.len(), 1, "{notes:?}");
        // The M100's pack only where it is named.
        let f = battery_from_config(&BatteryConfig::m100());
        assert_eq!(
            (cap(&f), f.cell_count.value, f.chemistry.value.as_str()),
            (M100_CAPACITY_WH, 6, "lihv")
        );
        assert_eq!(f.capacity_source(), M100_PACK);
    }

    #[test]
    fn a_pack_from_the_flag() {
        let p = pack_spec::parse_pack("4S2P:5000mAh:li-ion").expect("a pack");
        assert_eq!(
            (p.cell_count, p.chemistry),
            (Some(4), Some(Chemistry::LiIon))
        );
        assert!((p.capacity_wh.unwrap_or(0.0) - 5.0 * 4.0 * 3.6).abs() < 1e-9);
        let f = battery_from_config(&p);
        assert_eq!(f.capacity_source(), "--pack 4S2P:5000mAh:li-ion");
        let p = pack_spec::parse_pack("6s:129.96Wh:LiHV").expect("a pack");
        assert_eq!(p.capacity_wh, Some(129.96));
        assert_eq!(
            pack_spec::parse_pack("3S:2.2Ah").expect("a pack").chemistry,
            Some(Chemistry::LiPo)
        );
        for bad in [
            "",
            "4S",
            "0S:5000mAh",
            "30S:5000mAh",
            "4S:0mAh",
            "4S:5000",
            "4S:5000mAh:nimh",
            "4S0P:5000mAh",
            "4S:1000000000mAh",
            "4S:NaNmAh",
            "4S:5000mAh:lipo:x",
        ] {
            let e = pack_spec::parse_pack(bad).expect_err(bad);
            assert!(e.starts_with("--pack"), "{e}");
        }
    }

    #[test]
    fn the_battery_says_its_chemistry_cells_and_capacity() {
        let p = VehicleParams {
            battery_chemistry: Some(Chemistry::LiIon),
            battery_info: Some((Some(10.0), Some(4))),
            ..VehicleParams::from_pairs(&[("MOT_BAT_VOLT_MAX", 16.8)])
        };
        let (f, _) = resolve_battery(&cfg(None, None), &p, Some(15.0));
        assert_eq!(f.chemistry.value, "liion");
        assert_eq!(
            f.chemistry.source.to_string(),
            "vehicle parameter BATTERY_STATUS type"
        );
        assert_eq!(f.cell_count.value, 4);
        assert_eq!(f.capacity_source(), "vehicle parameter BATTERY_INFO");
        assert!((cap(&f) - 10.0 * 4.0 * 3.7).abs() < 1e-9, "{f:?}");
        // A "LiPo" type at 4.35 V a cell is a LiHV (MAVLink has no LiHV type).
        let p = VehicleParams {
            battery_chemistry: Some(Chemistry::LiPo),
            ..VehicleParams::from_pairs(&[("MOT_BAT_VOLT_MAX", 26.1)])
        };
        assert_eq!(
            resolve_battery(&cfg(None, None), &p, None)
                .0
                .chemistry
                .value,
            "lihv"
        );
    }

    #[test]
    fn px4_cells_and_empty_voltage() {
        let p = VehicleParams::from_pairs(&[
            ("BAT1_CAPACITY", 5000.0),
            ("BAT1_N_CELLS", 4.0),
            ("BAT1_V_EMPTY", 3.5),
        ]);
        let (f, _) = resolve_battery(&cfg(None, None), &p, Some(12.0));
        assert_eq!(
            f.cell_count,
            Sourced::new(4, Provenance::Parameter("BAT1_N_CELLS".into()))
        );
        assert!((cap(&f) - 5.0 * 4.0 * 3.7).abs() < 1e-9);
        assert_eq!(f.critical_voltage_v.map(|s| s.value), Some(14.0));
        // PX4's "unset" capacity (−1) is absent, quietly.
        let p = VehicleParams::from_pairs(&[("BAT1_CAPACITY", -1.0)]);
        let (f, notes) = resolve_battery(&cfg(None, None), &p, None);
        assert!(notes.is_empty());
        assert_eq!(f.capacity_wh, None);
    }

    #[test]
    fn wrong_parameters_degrade_with_a_message() {
        let p = VehicleParams::from_pairs(&[
            ("BATT_CAPACITY", 0.0),
            ("BAT1_N_CELLS", 99.0),
            ("BATT_LOW_VOLT", f64::NAN),
        ]);
        let (f, notes) = resolve_battery(&cfg(None, None), &p, Some(f64::NAN));
        assert_eq!(f.capacity_wh, None);
        assert_eq!(f.cell_count.source, Provenance::Default);
        assert!(f.low_voltage_v.is_none());
        assert_eq!(notes.len(), 3, "{notes:?}");
        assert!(
            notes.iter().any(|n| n.contains("BATT_CAPACITY = 0")),
            "{notes:?}"
        );
    }

    #[test]
    fn cell_count_from_the_vehicle_never_by_float_ceil() {
        // A full 3S pack at exactly 12.6 V is 3 cells (12.6 / 4.2 = 3.0000000000000004).
        let ardu = VehicleParams::from_pairs(&[("BATT_CAPACITY", 3300.0)]);
        let (f, notes) = resolve_battery(&cfg(None, None), &ardu, Some(12.6));
        assert_eq!(
            f.cell_count,
            Sourced::new(3, Provenance::FirstVoltage),
            "{notes:?}"
        );
        // ArduCopter's default 3300 mAh on 3S: 36-44 Wh.
        assert!((36.0..=44.0).contains(&cap(&f)), "{}", cap(&f));
        assert_eq!(f.chemistry.value, "lipo");
        // MOT_BAT_VOLT_MAX says the cells and, at 4.35 V a cell, the chemistry; 0 is off.
        let p =
            VehicleParams::from_pairs(&[("MOT_BAT_VOLT_MAX", 16.8), ("MOT_BAT_VOLT_MIN", 13.2)]);
        assert_eq!(
            resolve_battery(&cfg(None, None), &p, Some(12.0))
                .0
                .cell_count
                .value,
            4
        );
        let p = VehicleParams::from_pairs(&[("MOT_BAT_VOLT_MAX", 26.1)]);
        let (f, _) = resolve_battery(&cfg(None, None), &p, None);
        assert_eq!(
            (f.cell_count.value, f.chemistry.value.as_str()),
            (6, "lihv")
        );
        let p = VehicleParams::from_pairs(&[("MOT_BAT_VOLT_MAX", 0.0), ("MOT_BAT_VOLT_MIN", 9.9)]);
        assert_eq!(
            resolve_battery(&cfg(None, None), &p, None)
                .0
                .cell_count
                .source,
            Provenance::Parameter("MOT_BAT_VOLT_MIN".into())
        );
        // A voltage that fits two counts is said, not picked silently: a full 6S LiHV (the
        // default pack) at 26.1 V could be a low 7S.
        let (f, notes) = resolve_battery(&cfg(None, None), &VehicleParams::default(), Some(26.1));
        assert_eq!(f.cell_count.value, 6);
        assert!(notes.iter().any(|n| n.contains("6 or 7")), "{notes:?}");
        // Where the config or the vehicle gives the count, the voltage decides nothing and
        // its ambiguity is not said (nor "set [energy] cell_count" to one who has).
        let (f, notes) =
            resolve_battery(&cfg(None, Some(6)), &VehicleParams::default(), Some(26.1));
        assert_eq!(f.cell_count, Sourced::new(6, Provenance::Config));
        assert!(notes.is_empty(), "{notes:?}");
        let p = VehicleParams::from_pairs(&[("BAT1_N_CELLS", 6.0)]);
        let (f, notes) = resolve_battery(&cfg(None, None), &p, Some(26.1));
        assert_eq!(f.cell_count.value, 6);
        assert!(notes.is_empty(), "{notes:?}");
        // Nothing plausible: said, and the default stands.
        let (f, notes) = resolve_battery(&cfg(None, None), &VehicleParams::default(), Some(500.0));
        assert_eq!(f.cell_count.source, Provenance::Default);
        assert_eq!(notes.len(), 1, "{notes:?}");
    }

    #[test]
    fn cell_counts_of_exact_full_and_empty_packs_property() {
        // Every full pack of 1-12 cells at exactly 4.2 V (LiPo) reads as its own count.
        for n in 1..=12u32 {
            let p = VehicleParams::from_pairs(&[("BATT_CAPACITY", 5000.0)]);
            let v = 4.2 * f64::from(n);
            let (f, _) = resolve_battery(&cfg(None, None), &p, Some(v));
            assert_eq!(f.cell_count.value, n, "{v} V");
            assert_eq!(cells_from(v, 4.2, 0.03), Some(n));
            assert_eq!(cells_from(3.3 * f64::from(n), 3.3, 0.1), Some(n));
        }
    }

    #[test]
    fn cells_the_battery_monitor_reports_one_by_one() {
        use crate::dialect::BATTERY_STATUS_DATA;
        let mut b = BATTERY_STATUS_DATA {
            voltages: [u16::MAX; 10],
            ..Default::default()
        };
        // A monitor that knows only the pack: one entry, the whole pack. No cell count.
        b.voltages[0] = 16_400;
        assert_eq!(params::cells_reported(&b), None);
        // Four cells at 3.9-4.1 V, the rest 65535 ("no cell").
        b.voltages[..4].copy_from_slice(&[4_100, 4_050, 3_900, 4_000]);
        assert_eq!(params::cells_reported(&b), Some(4));
        // Cells past the tenth in voltages_ext (0: none).
        b.voltages = [3_800; 10];
        b.voltages_ext[..2].copy_from_slice(&[3_800, 3_790]);
        assert_eq!(params::cells_reported(&b), Some(12));
        // A nonsense entry (0.1 V) is no cell voltage: no count.
        b.voltages[3] = 100;
        assert_eq!(params::cells_reported(&b), None);
        let p = VehicleParams {
            battery_cells: Some(4),
            ..Default::default()
        };
        let (f, _) = resolve_battery(&cfg(None, None), &p, Some(12.6));
        assert_eq!(
            f.cell_count,
            Sourced::new(
                4,
                Provenance::Parameter("BATTERY_STATUS cell voltages".into())
            )
        );
    }
}
