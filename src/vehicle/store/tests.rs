//! Tests of the parent module.

use super::*;
use crate::report::Report;
use crate::vehicle::params::Autopilot;
use flight::PowerBins;

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

#[test]
fn data_dir_rule() {
    let flag = Path::new("/tmp/x");
    let platform = || Some(PathBuf::from("/x"));
    assert_eq!(
        data_dir(Some(flag), Some("/e"), platform()),
        Some(PathBuf::from("/tmp/x"))
    );
    assert_eq!(
        data_dir(None, Some("/e"), platform()),
        Some(PathBuf::from("/e"))
    );
    assert_eq!(
        data_dir(None, None, platform()),
        Some(PathBuf::from("/x/dronewatt"))
    );
    assert_eq!(
        data_dir(None, Some(""), platform()),
        Some(PathBuf::from("/x/dronewatt"))
    );
    assert_eq!(data_dir(None, Some("off"), platform()), None);
    assert_eq!(data_dir(Some(Path::new("off")), None, platform()), None);
    assert_eq!(data_dir(None, None, None), None);
}

#[test]
fn keys_prefer_the_uid() {
    assert_eq!(
        VehicleKey::of(&id(Some(0xdead_beef))).key,
        "uid:00000000deadbeef"
    );
    let k = VehicleKey::of(&id(None));
    assert_eq!(
        (k.key.as_str(), k.kind),
        ("sys1-ardupilot-MAV_TYPE_QUADROTOR", "heartbeat")
    );
    // System id 1 of a second network (separate networks): another vehicle.
    let other = Identity {
        network: 2,
        ..id(None)
    };
    assert_eq!(
        VehicleKey::of(&other).key,
        "sys1-ardupilot-MAV_TYPE_QUADROTOR@net2"
    );
    let uid = Identity {
        network: 2,
        ..id(Some(7))
    };
    assert_eq!(
        VehicleKey::of(&uid).key,
        "uid:0000000000000007",
        "a uid is the board's own"
    );
}

#[test]
fn a_corrupt_file_fails_to_open_with_its_path() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join(DB_FILE),
        b"this is not sqlite, just forty-odd bytes of text",
    )
    .unwrap();
    let err = format!(
        "{:#}",
        Store::open(dir.path())
            .err()
            .expect("opened a corrupt file")
    );
    assert!(err.contains(DB_FILE), "{err}");
}

#[test]
fn records_and_lists_with_the_capacity_trend() {
    let dir = tempfile::tempdir().unwrap();
    let mut st = Store::open(dir.path()).unwrap();
    let flight = |eff: Option<f64>| FlightSummary {
        airborne_s: 600.0,
        energy_wh: 30.0,
        pct_start: Some(100.0),
        pct_end: Some(20.0),
        effective_capacity_wh: eff,
        rated_capacity_wh: 40.0,
        capacity_source: "vehicle parameter BATT_CAPACITY".into(),
        ..Default::default()
    };
    let fits = vec![("lstm".to_string(), ModelFit::default())];
    st.record(&id(None), Some(&fits), Some(&flight(Some(37.5))))
        .unwrap();
    st.record(&id(None), None, Some(&flight(Some(34.0))))
        .unwrap();
    let v = st.vehicles().unwrap();
    assert_eq!(v.len(), 1);
    assert_eq!(v[0].flights.len(), 2);
    assert_eq!(v[0].capacity_trend_pct(), vec![93.75, 85.0]);
    assert!((v[0].wh_per_min().unwrap() - 3.0).abs() < 1e-9);
    let text = list(dir.path(), false).unwrap();
    assert!(
        text.contains("sys1-ardupilot-MAV_TYPE_QUADROTOR") && text.contains("94 % → 85 %"),
        "{text}"
    );
    // A record without fits keeps the ones learned before.
    assert_eq!(
        st.learned_fits(&VehicleKey::of(&id(None))).unwrap(),
        Some(fits)
    );
    // The capacity learned: the posterior over the last three flights that measured one
    // (each fell 80 points: they outweigh the rated 40 Wh about 15 to 1).
    st.record(&id(None), None, Some(&flight(None))).unwrap();
    st.record(&id(None), None, Some(&flight(Some(36.0))))
        .unwrap();
    let (wh, n) = st
        .learned_capacity(&VehicleKey::of(&id(None)))
        .unwrap()
        .expect("learned");
    assert_eq!(n, 3);
    assert!((wh - 36.0).abs() < 0.2, "{wh}");
    // `vehicles` shows it with its ±2 sd interval (the three flights and the rated 40 Wh)
    let text = list(dir.path(), false).unwrap();
    assert!(
        text.contains("capacity 36 Wh (32–40, 3 flight(s))"),
        "{text}"
    );
    assert_eq!(
        st.learned_capacity(&VehicleKey::of(&id(Some(7)))).unwrap(),
        None
    );
}

#[test]
fn effective_capacity_needs_a_real_drop() {
    use crate::features::{Sample, N_FEATURES};
    use crate::report::{EnergyState, Estimate};
    let report = |t: f64, pct: f32, used: f64| Report {
        estimate: Estimate {
            arrived: None,
            t_s: t,
            sample: Sample {
                voltage_v: Some(12.0),
                battery_remaining_pct: Some(pct),
                ..Sample::new(t, [0.0; N_FEATURES], Some(300.0))
            },
            models: vec![],
        },
        energy: EnergyState {
            energy_used_wh: used,
            ..Default::default()
        },
        alerts: vec![],
        vehicle: 1.into(),
    };
    let mut log = FlightLog::default();
    log.observe(&report(0.0, 90.0, 0.0));
    log.observe(&report(60.0, 85.0, 5.0));
    assert_eq!(
        log.summary().unwrap().effective_capacity_wh,
        None,
        "5 % is the gauge's noise"
    );
    log.observe(&report(120.0, 70.0, 10.0));
    let s = log.summary().unwrap();
    assert!(
        (s.effective_capacity_wh.unwrap() - 50.0).abs() < 1e-9,
        "{s:?}"
    );
    assert!(
        (s.airborne_s - 2.0).abs() < 1e-9,
        "steps are capped at 1 s: {s:?}"
    );
}

/// Ten hours at 10 Hz: 60 s on the ground at 20 W, then hover around 350 W with a
/// climb at 600 W every minute, repeated. The motors-turning time is the flight's
/// (everything but the ground idle), and the log's memory stays a few hundred bins.
#[test]
fn a_long_flight_is_summed_in_bounded_memory() {
    use crate::features::{Sample, N_FEATURES};
    use crate::report::{EnergyState, Estimate};
    let mut log = FlightLog::default();
    let n = 360_000;
    for i in 0..n {
        let t = f64::from(i) * 0.1;
        let p = if t < 60.0 {
            20.0
        } else if i % 600 < 50 {
            600.0
        } else {
            350.0 + (i % 37) as f32
        };
        let sample = Sample::new(t, [0.0; N_FEATURES], Some(p));
        log.observe(&Report {
            estimate: Estimate {
                t_s: t,
                sample,
                models: vec![],
                arrived: None,
            },
            energy: EnergyState::default(),
            alerts: vec![],
            vehicle: 1.into(),
        });
    }
    let s = log.summary().unwrap();
    let flown = f64::from(n - 1) * 0.1 - 60.0;
    assert!(
        (s.airborne_s - flown).abs() < 0.2,
        "airborne {} s, flown {flown} s",
        s.airborne_s
    );
    assert!(log.power.0.len() < 100, "{} bins", log.power.0.len());
    // Every bin is where its power is: the centre within half a bin (0.5 %).
    for p in [1.0f32, 20.0, 350.0, 5_000.0] {
        assert!(
            (PowerBins::power(PowerBins::bin(p)) / f64::from(p) - 1.0).abs() < 0.0051,
            "{p} W"
        );
    }
    assert_eq!(PowerBins::bin(0.3), 0);
    assert_eq!(PowerBins::bin(1e9), PowerBins::MAX - 1);
}

/// A store as an older dronewatt left it: the first schema, then `added` columns of
/// `flights`, `user_version` (none for the first schema) and one quadrotor heard as
/// `heard_by`. Its flights are the test's to insert.
fn old_store(dir: &Path, version: Option<i64>, added: &[&str], heard_by: &str) -> Connection {
    let conn = Connection::open(dir.join(DB_FILE)).unwrap();
    conn.execute_batch(SCHEMA).unwrap();
    for c in added {
        conn.execute_batch(&format!("ALTER TABLE flights ADD COLUMN {c} REAL;"))
            .unwrap();
    }
    if let Some(v) = version {
        conn.execute_batch(&format!("PRAGMA user_version = {v}"))
            .unwrap();
    }
    conn.execute(
        "INSERT INTO vehicles VALUES ('sys1-ardupilot-MAV_TYPE_QUADROTOR', ?1, 1, 'ardupilot', 'MAV_TYPE_QUADROTOR', 1, 1, NULL)",
        params![heard_by],
    )
    .unwrap();
    conn
}

/// The schema version a store is at.
fn user_version(st: &Store) -> i64 {
    st.conn
        .query_row("PRAGMA user_version", [], |r| r.get(0))
        .unwrap()
}

/// A store written by the first schema (no version, no pack columns) opens, keeps its
/// flights, and takes the pack's from then on; a store from a newer dronewatt is refused.
#[test]
fn an_old_store_migrates_and_the_pack_is_kept_and_carried() {
    let dir = tempfile::tempdir().unwrap();
    {
        let conn = old_store(dir.path(), None, &[], "system id");
        conn.execute(
            "INSERT INTO flights (vehicle, ended_at, airborne_s, energy_wh, rated_capacity_wh, capacity_source) VALUES ('sys1-ardupilot-MAV_TYPE_QUADROTOR', 1, 300, 20, 40, 'default')",
            [],
        )
        .unwrap();
    }
    let mut st = Store::open(dir.path()).expect("an old store opens");
    assert_eq!(user_version(&st), SCHEMA_VERSION);
    let v = st.vehicles().unwrap();
    assert_eq!(v[0].flights.len(), 1);
    assert_eq!(v[0].flights[0].summary.rest_v_start, None);
    let id = id(None);
    let key = VehicleKey::of(&id);
    assert_eq!(key.key, "sys1-ardupilot-MAV_TYPE_QUADROTOR");
    let pack = FlightSummary {
        airborne_s: 500.0,
        energy_wh: 30.0,
        rest_v_start: Some(24.3),
        rest_v_end: Some(23.3),
        r_scale: Some(1.2),
        internal_r_ohm: Some(0.045),
        heat_a2s: Some(90_000.0),
        pack_health_pct: Some(97.0),
        deep_slope: Some(5.5),
        ..Default::default()
    };
    st.record(&id, None, Some(&pack)).unwrap();
    let h = st
        .pack_history(&key, None, None)
        .unwrap()
        .expect("a history");
    assert_eq!(
        (h.r_scale, h.end_rest_v, h.heat, h.deep_slope),
        (Some(1.2), Some(23.3), 90_000.0, Some(5.5))
    );
    assert!(h.gap_s >= 0.0 && h.gap_s < 60.0, "{h:?}");
    assert!(
        h.same_pack(23.35, 6) && !h.same_pack(25.9, 6),
        "a recharged pack is another"
    );
    let listing = list::list(dir.path(), false).unwrap();
    assert!(
        listing.contains("health 97 %") && listing.contains("R 45 mΩ"),
        "{listing}"
    );
    drop(st);
    let conn = Connection::open(dir.path().join(DB_FILE)).unwrap();
    conn.execute_batch("PRAGMA user_version = 99").unwrap();
    drop(conn);
    let err = Store::open(dir.path())
        .err()
        .expect("a newer store is refused")
        .to_string();
    assert!(
        err.contains("newer dronewatt") || format!("{err:#}").contains("schema"),
        "{err}"
    );
}

/// A store written by schema 2 (the pack's columns, no log clock) opens, migrates to the
/// current schema keeping its flights and their packs, and its last flight's gap falls back
/// to the wall clock.
#[test]
fn a_schema_2_store_migrates() {
    let dir = tempfile::tempdir().unwrap();
    {
        let conn = old_store(dir.path(), Some(2), &ADDED_COLUMNS[..6], "heartbeat");
        let ended = now_s() - 120;
        conn.execute(
            "INSERT INTO flights (vehicle, ended_at, airborne_s, energy_wh, rated_capacity_wh, capacity_source, rest_v_start, rest_v_end, r_scale, heat_a2s)
             VALUES ('sys1-ardupilot-MAV_TYPE_QUADROTOR', ?1, 300, 20, 40, 'default', 12.4, 11.6, 1.1, 5000.0)",
            params![ended],
        )
        .unwrap();
    }
    let st = Store::open(dir.path()).expect("a schema 2 store opens");
    assert_eq!(user_version(&st), SCHEMA_VERSION);
    let v = st.vehicles().unwrap();
    let f = &v[0].flights[0].summary;
    assert_eq!(
        (f.rest_v_start, f.rest_v_end, f.r_scale, f.ended_log_s),
        (Some(12.4), Some(11.6), Some(1.1), None)
    );
    let key = VehicleKey::of(&id(None));
    // no log clock on the old flight: the wall clock's 2 minutes, whatever this run's clock
    for now in [None, Some(1.7e9)] {
        let h = st
            .pack_history(&key, None, now)
            .unwrap()
            .expect("a history");
        assert!((115.0..200.0).contains(&h.gap_s), "{h:?}");
        assert_eq!(h.r_scale, Some(1.1));
    }
}

/// Replays measure the gap between two flights on the logs' clock: a flight logged years
/// ago and replayed now, followed by the replay of the next flight on the same pack, is
/// 7 minutes before it, not years; a live run (no Unix clock) uses the wall clock.
#[test]
fn replays_measure_the_gap_by_log_time() {
    let dir = tempfile::tempdir().unwrap();
    let mut st = Store::open(dir.path()).unwrap();
    let id = id(None);
    let key = VehicleKey::of(&id);
    let logged_end = 1_500_000_000.0; // July 2017
    let flight = FlightSummary {
        airborne_s: 400.0,
        energy_wh: 40.0,
        rest_v_end: Some(23.3),
        r_scale: Some(1.3),
        heat_a2s: Some(80_000.0),
        ended_log_s: Some(logged_end),
        ..Default::default()
    };
    st.record(&id, None, Some(&flight)).unwrap();
    let h = st
        .pack_history(&key, None, Some(logged_end + 420.0))
        .unwrap()
        .expect("a history");
    assert_eq!(h.gap_s, 420.0);
    assert!(h.same_pack(23.35, 6), "{h:?}");
    // the same log replayed before the other (its clock runs backwards): not this pack's next
    let h = st
        .pack_history(&key, None, Some(logged_end - 3600.0))
        .unwrap()
        .unwrap();
    assert!(!h.same_pack(23.35, 6), "{h:?}");
    // a live run's clock is no Unix time: the wall clock since the record, seconds
    let h = st.pack_history(&key, None, Some(35.0)).unwrap().unwrap();
    assert!((0.0..60.0).contains(&h.gap_s), "{h:?}");
    assert_eq!(unix_clock(f64::NAN), None);
    assert_eq!(unix_clock(1.7e9), Some(1.7e9));
}

/// A store written by schema 3 (the pack's columns and the log clock, no pack id) opens,
/// migrates to schema 4 keeping its flights (no pack id: they count for the vehicle), and
/// takes the pack id of the flights after.
#[test]
fn a_schema_3_store_migrates_and_its_flights_count_for_the_vehicle() {
    let dir = tempfile::tempdir().unwrap();
    {
        let conn = old_store(dir.path(), Some(3), &ADDED_COLUMNS, "heartbeat");
        conn.execute(
            "INSERT INTO flights (vehicle, ended_at, airborne_s, energy_wh, rated_capacity_wh, capacity_source, rest_v_end, r_scale, internal_r_ohm, pack_health_pct, ended_log_s)
             VALUES ('sys1-ardupilot-MAV_TYPE_QUADROTOR', 1, 300, 20, 40, 'default', 11.6, 1.1, 0.05, 96.0, 1500000000.0)",
            [],
        )
        .unwrap();
    }
    let mut st = Store::open(dir.path()).expect("a schema 3 store opens");
    assert_eq!((user_version(&st), SCHEMA_VERSION), (6, 6));
    let f = st.vehicles().unwrap()[0].flights[0].summary.clone();
    assert_eq!(
        (f.rest_v_end, f.r_scale, f.ended_log_s, f.pack_id),
        (Some(11.6), Some(1.1), Some(1.5e9), None)
    );
    let id = id(None);
    let key = VehicleKey::of(&id);
    let packs = st.pack_histories(&key, Some(1.5e9 + 60.0)).unwrap();
    assert!(packs.by_pack.is_empty(), "{packs:?}");
    assert_eq!(packs.pick(None).and_then(|h| h.r_scale), Some(1.1));
    assert_eq!(
        packs.pick(Some("A1")),
        None,
        "an identified pack never flown here"
    );
    let flight = FlightSummary {
        airborne_s: 400.0,
        r_scale: Some(1.4),
        internal_r_ohm: Some(0.06),
        pack_health_pct: Some(93.0),
        pack_id: Some("A1".into()),
        ..Default::default()
    };
    st.record(&id, None, Some(&flight)).unwrap();
    let packs = st.pack_histories(&key, None).unwrap();
    assert_eq!(packs.by_pack.len(), 1);
    assert_eq!(packs.pick(Some("A1")).and_then(|h| h.r_scale), Some(1.4));
    let listing = list::list(dir.path(), false).unwrap();
    assert!(
        listing.contains("pack A1 (1 flight(s)), by flight: health 93 %; R 60 mΩ")
            && listing
                .contains("pack (per vehicle: no pack id heard), by flight: health 96 %; R 50 mΩ"),
        "{listing}"
    );
}

/// Two packs on one vehicle: each keeps its own history, and a day-old flight of the same
/// pack still carries over (its identity makes it the same pack), while the vehicle's last
/// flight, of the other pack, does not.
#[test]
fn each_pack_keeps_its_own_history() {
    let dir = tempfile::tempdir().unwrap();
    let mut st = Store::open(dir.path()).unwrap();
    let id = id(Some(0xdead_beef));
    let key = VehicleKey::of(&id);
    let t0 = 1_500_000_000.0;
    for (pack, r, end) in [("A", 1.2, t0), ("B", 1.6, t0 + 3600.0)] {
        let f = FlightSummary {
            airborne_s: 300.0,
            rest_v_end: Some(23.3),
            r_scale: Some(r),
            ended_log_s: Some(end),
            pack_id: Some(pack.into()),
            ..Default::default()
        };
        st.record(&id, None, Some(&f)).unwrap();
    }
    let packs = st.pack_histories(&key, Some(t0 + 86_400.0)).unwrap();
    let a = packs.pick(Some("A")).expect("pack A");
    assert_eq!((a.r_scale, a.gap_s), (Some(1.2), 86_400.0));
    assert!(a.same_pack(23.35, 6), "pack A a day later is pack A: {a:?}");
    let b = packs.pick(Some("B")).expect("pack B");
    assert_eq!(b.r_scale, Some(1.6));
    let last = packs.pick(None).expect("the vehicle's last flight");
    assert_eq!(last.r_scale, Some(1.6));
    assert!(!last.same_pack(23.35, 6), "no identity, 23 h: the gap rule");
}

/// The autopilot as the store's `vehicles` table writes it (strum's `Display`).
#[test]
fn autopilots_are_stored_by_their_lower_case_names() {
    let names = [Autopilot::ArduPilot, Autopilot::Px4, Autopilot::Other].map(|a| a.to_string());
    assert_eq!(names, ["ardupilot", "px4", "other"]);
}
