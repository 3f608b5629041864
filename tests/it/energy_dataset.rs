//! Energy used on a real flight: flight 276 of the M100 data set (`DRONEWATT_DATA`)
//! replayed through the live path (`dronewatt replay flights.csv.gz --flight 276`) must
//! integrate to the energy the CSV itself holds, ∫ V·I dt over its own irregular rows,
//! within 0.5 %, and its remaining energy must be the TB48D's 129.96 Wh minus that.

use crate::harness::{dronewatt, RunExt};

#[test]
fn flight_276_energy_matches_the_csv() {
    let data = dronewatt::default_data_path();
    assert!(
        data.exists(),
        "the data set is not at {} (set DRONEWATT_DATA)",
        data.display()
    );
    let set = dronewatt::source::logs::dataset::read_flights(&data, Some(&[276])).unwrap();
    let rows = &set
        .flights
        .iter()
        .find(|f| f.flight == 276)
        .expect("flight 276")
        .rows;
    // The reference: trapezoidal ∫ V·I over the CSV's own timestamps, Wh.
    let reference_wh: f64 = rows
        .windows(2)
        .map(|w| {
            0.5 * (w[0].voltage_v * w[0].current_a + w[1].voltage_v * w[1].current_a)
                * (w[1].time_s - w[0].time_s)
        })
        .sum::<f64>()
        / 3600.0;
    assert!(
        reference_wh > 5.0,
        "flight 276 should draw several Wh, not {reference_wh}"
    );

    let out = dronewatt()
        .args([
            "replay", "--speed", "max", "--flight", "276", "-q", "--json", "-",
        ])
        .arg(&data)
        .ok();
    let text = String::from_utf8_lossy(&out.stdout);
    let last = text
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .rfind(|v| v["type"] == "estimate")
        .expect("no estimates");
    let used = last["energy_used_wh"].as_f64().unwrap();
    let err_pct = 100.0 * (used - reference_wh).abs() / reference_wh;
    eprintln!(
        "flight 276: CSV ∫V·I = {reference_wh:.3} Wh, dronewatt {used:.3} Wh ({err_pct:.3} %)"
    );
    assert!(
        err_pct < 0.5,
        "CSV {reference_wh} Wh, dronewatt {used} Wh: {err_pct} % off"
    );
    // Remaining is no longer "129.96 Wh − used" (a full pack assumed): the pack started from
    // its resting voltage, and what is left is to the usable floor, under what its OCV curve
    // holds to empty.
    assert_eq!(last["remaining_source"], "resting voltage", "{last}");
    let remaining = last["remaining_wh"].as_f64().unwrap();
    let rest_v = last["battery_rest_v"].as_f64().unwrap();
    let to_empty = dronewatt::battery::OcvCurve::tb48d().energy(rest_v / 6.0) - used;
    assert!(
        remaining > 0.0 && remaining <= to_empty + 1e-6 && remaining < 129.96 - used - 20.0,
        "remaining {remaining} Wh, {to_empty} Wh to empty from {rest_v} V"
    );
}
