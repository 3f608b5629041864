//! Property tests of the whole battery / energy stage ([`EnergyTracker`] with its pack):
//! random streams of readings, good and bad (a voltage of 0, NaN or 65.535 V a cell, a
//! negative current, a current stuck at 0 in flight, a pack swapped mid-stream, a voltage
//! stuck while the current swings), with random parameters (BATT_CAPACITY 0 or 1,000,000,
//! a cell count of 0 or 30) and config. Whatever comes in, nothing impossible goes out:
//!
//! - no panic; every figure finite where it is given;
//! - state of charge and remaining share in 0-100 %, remaining energy ≥ 0;
//! - resistance in 0..[`pack::MAX_R_CELL_OHM`] a cell;
//! - every modelled voltage within the chemistry's range for the cell count;
//! - times ≥ 0; never the M100's pack unless it was named.
//!
//! 10,000 streams in all (each a few seconds of readings), run in a few seconds.

use super::*;
use crate::features::{Sample, N_FEATURES};
use proptest::prelude::*;

/// One reading: (dt s, what the voltage does, current A, battery %).
type Reading = (f64, u8, f64, Option<f64>);

fn estimate(t_s: f64, v: Option<f64>, i: f64) -> Estimate {
    let measured = v.map(|v| (v * i) as f32);
    Estimate {
        arrived: None,
        t_s,
        sample: Sample {
            voltage_v: v.map(|v| v as f32),
            ..Sample::new(t_s, [0.0; N_FEATURES], measured)
        },
        models: Vec::new(),
    }
}

fn params(cap: u8, cells: u8, low: f64) -> VehicleParams {
    let mut p = Vec::new();
    match cap % 5 {
        0 => p.push(("BATT_CAPACITY", 0.0)),
        1 => p.push(("BATT_CAPACITY", 1_000_000.0)),
        2 => p.push(("BATT_CAPACITY", 500.0 + 100.0 * f64::from(cap))),
        _ => {}
    }
    match cells % 5 {
        0 => p.push(("BAT1_N_CELLS", 0.0)),
        1 => p.push(("BAT1_N_CELLS", 30.0)),
        2 => p.push(("BAT1_N_CELLS", f64::from(1 + cells % 12))),
        _ => {}
    }
    if low > 0.0 {
        p.push(("BATT_LOW_VOLT", low));
    }
    VehicleParams::from_pairs(&p)
}

/// The checks on one state (module docs).
fn possible(st: &EnergyState) -> Result<(), TestCaseError> {
    let b = &st.battery;
    let n = f64::from(b.cell_count.value.max(1));
    let chem = crate::battery::Chemistry::from_name(&b.chemistry.value)
        .unwrap_or(crate::battery::Chemistry::LiPo);
    let (lo, hi) = (
        n * chem.loaded_min_v(),
        n * (chem.full_v() + crate::battery::chemistry::FULL_TOL_V),
    );
    let pk = &st.pack;
    for (name, v) in [
        ("battery_v_model", pk.battery_v_model),
        ("battery_ocv_v", pk.battery_ocv_v),
        ("v_min_forecast_v", pk.v_min_forecast_v),
    ] {
        if let Some(v) = v {
            prop_assert!(
                v.is_finite() && (lo..=hi).contains(&v),
                "{name} = {v} ({lo}..{hi}): {st:?}"
            );
        }
    }
    if let Some(r) = pk.internal_r_ohm {
        prop_assert!(
            r.is_finite() && (0.0..=pack::MAX_R_CELL_OHM * n).contains(&r),
            "R {r}"
        );
    }
    for (name, x) in [("soc_pct", pk.soc_pct), ("remaining_pct", st.remaining_pct)] {
        if let Some(x) = x {
            prop_assert!(
                x.is_finite() && (0.0..=100.0).contains(&x),
                "{name} = {x}: {st:?}"
            );
        }
    }
    if let Some(w) = st.remaining_wh {
        prop_assert!(w.is_finite() && w >= 0.0, "remaining {w}: {st:?}");
    }
    for (name, t) in [
        ("time_to_empty_s", st.time_to_empty_s),
        ("time_to_low_v_s", pk.time_to_low_v_s),
    ] {
        if let Some(t) = t {
            prop_assert!(t.is_finite() && t >= 0.0, "{name} = {t}");
        }
    }
    prop_assert!(st.energy_used_wh.is_finite());
    prop_assert!(
        b.capacity_wh
            .as_ref()
            .is_none_or(|c| c.value.is_finite() && c.value > 0.0),
        "capacity {:?}",
        b.capacity_wh
    );
    prop_assert!(b.capacity_source() != crate::report::M100_PACK);
    Ok(())
}

fn stream() -> impl Strategy<Value = Vec<Reading>> {
    proptest::collection::vec(
        (
            0.05f64..0.6,
            any::<u8>(),
            -8.0f64..60.0,
            proptest::option::weighted(0.2, -20.0f64..120.0),
        ),
        1..40,
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 10_000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn the_energy_stage_never_says_the_impossible(
        readings in stream(),
        cells in 1u32..14,
        cell_v in 2.0f64..4.6,
        r_cell in 0.0f64..0.05,
        cap in any::<u8>(),
        param_cells in any::<u8>(),
        low in -1.0f64..60.0,
        chem in 0u8..6,
        cfg_cap in proptest::option::weighted(0.2, 0.5f64..400.0),
    ) {
        let chemistry = crate::battery::Chemistry::ALL.get(usize::from(chem)).copied();
        let cfg = EnergyConfig { capacity_wh: cfg_cap, chemistry, ..EnergyConfig::default() };
        let mut tr = EnergyTracker::new(&cfg, None).map_err(|e| TestCaseError::fail(e.to_string()))?.quiet();
        let mut t = 0.0;
        let mut base = f64::from(cells) * cell_v;
        for (k, (dt, kind, amps, pct)) in readings.into_iter().enumerate() {
            t += dt;
            if k == 5 {
                tr.set_vehicle(params(cap, param_cells, low));
            }
            // The pack's own sag, then what the sensor makes of it.
            let sagged = base - amps.max(0.0) * r_cell * f64::from(cells);
            let (v, i) = match kind % 16 {
                0 => (Some(0.0), amps),
                1 => (Some(f64::NAN), amps),
                2 => (Some(65.535 * f64::from(cells)), amps),
                3 => (None, amps),
                4 => (Some(sagged), 0.0),           // current stuck at 0
                5 => (Some(base), amps.abs() * 3.0), // a voltage that does not sag
                6 => {
                    base = f64::from(cells) * 4.2; // a fresh pack swapped in
                    (Some(base), 0.2)
                }
                7 => (Some(sagged), -amps.abs()),   // a negative current
                8..=10 => (Some(sagged), 0.3),     // resting
                _ => (Some(sagged), amps),
            };
            let st = tr.update_with_battery(&estimate(t, v, i), pct);
            possible(&st)?;
        }
    }
}
