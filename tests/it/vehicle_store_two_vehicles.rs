//! One vehicle is one vehicle: two simulated ArduPilot quadrotors on the same system id
//! (1), with no AUTOPILOT_VERSION uid — an X500 on 4S 5000 mAh and a 1 kg quad on 3S
//! 3300 mAh — are two vehicles in the store, because their packs (`BATT_CAPACITY`) differ.
//! The second is said to be new, naming the difference, and starts from nothing the first
//! learned; `dronewatt vehicles` says why each flight was matched to its vehicle.

use crate::harness::{dronewatt, RunExt};
use std::path::Path;

fn simulate(vehicle: &str, out: &Path) {
    dronewatt()
        .args(["simulate", "--vehicle", vehicle, "--payload-g", "0"])
        .args(["--leg-m", "150", "--hover-s", "10", "--out"])
        .arg(out)
        .ok();
}

/// Replay into the store in `data`; its stderr.
fn replay(tlog: &Path, data: &Path) -> String {
    let out = dronewatt()
        .args(["replay", "--speed", "max", "-q", "--data-dir"])
        .arg(data)
        .arg(tlog)
        .ok();
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn two_quads_on_system_id_1_with_different_packs_are_two_vehicles() {
    let dir = tempfile::tempdir().unwrap();
    let (x500, quad) = (dir.path().join("x500.tlog"), dir.path().join("quad3s.tlog"));
    simulate("x500", &x500);
    simulate("quad-3s", &quad);
    let data = dir.path().join("store");
    let first = replay(&x500, &data);
    assert!(!first.contains("not the vehicle remembered"), "{first}");
    let other = replay(&quad, &data);
    assert!(
        other.contains("not the vehicle remembered under this key")
            && other.contains("3300 mAh, not 5000"),
        "the second quad is not said to be new: {other}"
    );
    assert!(
        !other.contains("found what earlier flights learned"),
        "{other}"
    );
    let again = replay(&x500, &data);
    assert!(!again.contains("not the vehicle remembered"), "{again}");
    assert!(
        again.contains("found what earlier flights learned"),
        "{again}"
    );

    let out = dronewatt()
        .args(["vehicles", "--json", "--data-dir"])
        .arg(&data)
        .ok();
    let vs: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(vs.len(), 2, "{vs:#?}");
    let by_key = |k: &str| {
        vs.iter()
            .find(|v| v["key"] == k)
            .unwrap_or_else(|| panic!("{k}: {vs:#?}"))
    };
    let base = by_key("sys1-ardupilot-MAV_TYPE_QUADROTOR");
    let new = by_key("sys1-ardupilot-MAV_TYPE_QUADROTOR#2");
    assert_eq!(base["pack"]["capacity_mah"].as_f64(), Some(5000.0));
    assert_eq!(new["pack"]["capacity_mah"].as_f64(), Some(3300.0));
    let why = |v: &serde_json::Value| -> Vec<String> {
        v["flights"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f["matched"].as_str().unwrap_or("").to_string())
            .collect()
    };
    let (b, n) = (why(base), why(new));
    assert_eq!(b.len(), 2, "{b:?}");
    assert_eq!(b[0], "first flight");
    assert!(b[1].starts_with("key + pack"), "{b:?}");
    assert!(n.len() == 1 && n[0].starts_with("new: pack"), "{n:?}");
    let table = dronewatt().args(["vehicles", "--data-dir"]).arg(&data).ok();
    let table = String::from_utf8_lossy(&table.stdout);
    assert!(table.contains("flights matched by: new: pack"), "{table}");
}
