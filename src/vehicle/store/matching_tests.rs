//! Tests of the parent module.

use super::*;
use crate::vehicle::params::Autopilot;
use crate::vehicle::store::{FlightSummary, LOG_WAIT_S};

fn id(uid: Option<u64>) -> Identity {
    Identity {
        system_id: 1,
        component_id: 1,
        autopilot: Autopilot::ArduPilot,
        vehicle_type: "MAV_TYPE_QUADROTOR".into(),
        uid,
        network: 0,
    }
}

fn sig(cells: Option<u32>, mah: Option<f64>) -> PackSig {
    PackSig {
        cells,
        capacity_mah: mah,
    }
}

fn flight() -> FlightSummary {
    FlightSummary {
        airborne_s: 300.0,
        energy_wh: 20.0,
        rated_capacity_wh: 74.0,
        capacity_source: "vehicle parameter BATT_CAPACITY".into(),
        ..Default::default()
    }
}

/// Fly `s` once under `id`, as the end of a run does; the match it was recorded under.
fn fly(st: &mut Store, id: &Identity, s: PackSig) -> Matched {
    let m = st.resolve(id, &s).unwrap();
    st.record_matched(id, &m, &s, None, Some(&flight()))
        .unwrap();
    m
}

#[test]
fn a_different_pack_under_the_same_key_is_a_new_vehicle() {
    let dir = tempfile::tempdir().unwrap();
    let mut st = Store::open(dir.path()).unwrap();
    let base = "sys1-ardupilot-MAV_TYPE_QUADROTOR";
    let m100 = sig(Some(6), Some(5700.0));
    let quad = sig(Some(4), Some(5000.0));
    assert_eq!(fly(&mut st, &id(None), m100).reason, "first flight");
    // the same pack again: the same vehicle, said by key and pack
    let again = fly(&mut st, &id(None), m100);
    assert_eq!(again.key.key, base);
    assert!(
        again.reason.starts_with("key + pack (6S, 5700 mAh)"),
        "{}",
        again.reason
    );
    // another 4S quad on system id 1: a new vehicle, the differences named
    let other = fly(&mut st, &id(None), quad);
    assert_eq!(other.key.key, format!("{base}#2"));
    assert!(other.new_by_pack);
    assert!(other.reason.contains("4 cells, not 6"), "{}", other.reason);
    assert!(
        other.reason.contains("5000 mAh, not 5700"),
        "{}",
        other.reason
    );
    // each comes back to its own, whichever flew last
    assert_eq!(st.resolve(&id(None), &m100).unwrap().key.key, base);
    assert_eq!(
        st.resolve(&id(None), &quad).unwrap().key.key,
        format!("{base}#2")
    );
    // capacity alone differing (beyond 5 %) is enough; within it, the same pack
    let bigger = st.resolve(&id(None), &sig(None, Some(8000.0))).unwrap();
    assert!(
        bigger.new_by_pack && bigger.key.key.ends_with("#3"),
        "{bigger:?}"
    );
    let near = st.resolve(&id(None), &sig(None, Some(5100.0))).unwrap();
    assert_eq!(near.key.key, format!("{base}#2"));
    // a pack not reported contradicts nothing: the most recent vehicle, said as key only
    let unknown = st.resolve(&id(None), &PackSig::default()).unwrap();
    assert_eq!(unknown.reason, "key only (pack not reported)");
    // the listing says why each flight was matched, and each vehicle's pack
    let vs = st.vehicles().unwrap();
    assert_eq!(vs.len(), 2);
    let first = vs.iter().find(|v| v.key == base).unwrap();
    assert_eq!(first.pack, m100);
    let why: Vec<_> = first
        .flights
        .iter()
        .map(|f| f.matched.clone().unwrap())
        .collect();
    assert_eq!(why[0], "first flight");
    assert!(why[1].starts_with("key + pack"));
    let table = crate::vehicle::store::list(dir.path(), false).unwrap();
    assert!(table.contains("new: pack 4S, 5000 mAh differs"), "{table}");
}

#[test]
fn a_uid_is_the_vehicle_whatever_its_pack() {
    let dir = tempfile::tempdir().unwrap();
    let mut st = Store::open(dir.path()).unwrap();
    fly(&mut st, &id(Some(42)), sig(Some(6), Some(5700.0)));
    let m = fly(&mut st, &id(Some(42)), sig(Some(4), Some(5000.0)));
    assert_eq!(
        (m.key.key.as_str(), m.reason.as_str()),
        ("uid:000000000000002a", "uid")
    );
    assert_eq!(st.vehicles().unwrap().len(), 1);
}

#[test]
fn the_pack_comes_from_what_the_vehicle_reported_only() {
    let p = VehicleParams::from_pairs(&[("BATT_CAPACITY", 5000.0)]);
    assert_eq!(PackSig::of(&p), sig(None, Some(5000.0)));
    // ArduPilot's 0 and PX4's −1 are "not set"
    for unset in [0.0, -1.0] {
        let p = VehicleParams::from_pairs(&[("BATT_CAPACITY", unset), ("BAT1_CAPACITY", unset)]);
        assert!(!PackSig::of(&p).is_known());
    }
    let p = VehicleParams {
        battery_cells: Some(4),
        ..VehicleParams::from_pairs(&[("BAT1_CAPACITY", 3300.0)])
    };
    assert_eq!(PackSig::of(&p), sig(Some(4), Some(3300.0)));
    let p = VehicleParams {
        battery_info: Some((Some(5.2), Some(6))),
        ..Default::default()
    };
    assert_eq!(PackSig::of(&p), sig(Some(6), Some(5200.0)));
}

#[test]
fn the_lookup_waits_for_the_pack_or_a_few_seconds() {
    let mut p = VehicleParams {
        identity: Some(id(None)),
        ..Default::default()
    };
    let heard = (10.0, p.clone());
    // asked, not answered yet: waits; answered (or given up) with nothing: at once
    assert!(lookup_due(Some(&heard), 11.0, true, false).is_none());
    assert!(lookup_due(Some(&heard), 11.0, true, true).is_some());
    assert!(lookup_due(Some(&heard), 10.0 + PACK_WAIT_S, true, false).is_some());
    // overheard (a log): waits for the log's parameters, not as long
    assert!(lookup_due(Some(&heard), 11.0, false, true).is_none());
    assert!(lookup_due(Some(&heard), 10.0 + LOG_WAIT_S, false, true).is_some());
    // any figure of the pack: at once
    p.values.insert("BATT_CAPACITY".into(), 5000.0);
    p.values.insert("MOT_BAT_VOLT_MAX".into(), 16.8);
    let heard = (10.0, p);
    let (_, s) = lookup_due(Some(&heard), 10.1, false, true).unwrap();
    assert_eq!(s, sig(Some(4), Some(5000.0)), "4S from MOT_BAT_VOLT_MAX");
    assert!(lookup_due(None, 100.0, true, true).is_none());
}

/// A store written before schema 5 opens, its flights matched "not recorded".
#[test]
fn an_older_store_gains_the_columns() {
    let dir = tempfile::tempdir().unwrap();
    {
        let st = Store::open(dir.path()).unwrap();
        st.conn
            .execute_batch(
                "ALTER TABLE vehicles DROP COLUMN cells; ALTER TABLE vehicles DROP COLUMN capacity_mah;
                 ALTER TABLE flights DROP COLUMN matched; PRAGMA user_version = 4;",
            )
            .unwrap();
    }
    let mut st = Store::open(dir.path()).unwrap();
    fly(&mut st, &id(None), sig(Some(4), None));
    assert_eq!(st.vehicles().unwrap()[0].pack, sig(Some(4), None));
}
