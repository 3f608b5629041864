//! Many vehicles on one link, over real UDP on 127.0.0.1: pymavlink
//! (`tests/peers/fleet.py`) plays three vehicles (system ids 1, 2, 3 at 300, 500 and 700 W),
//! a ground station's heartbeat (255) and a companion computer's (42) to `dronewatt monitor
//! udpin:…`. Vehicle 3 falls silent after 4 s. What must hold:
//!
//! - one chain per vehicle: estimates for exactly 1, 2 and 3, each on its own power (no
//!   cross-talk), none for the ground station or the companion;
//! - the silent vehicle is reported lost, then dropped (`[fleet]` keys), the others never;
//! - what goes back over MAVLink is sent as each vehicle's own system id (component 191),
//!   with its own values, heartbeat and STATUSTEXT;
//! - the terminal shows the fleet view (one row per vehicle);
//! - `--vehicles` keeps only the vehicles asked for.

use crate::harness::{dronewatt, Monitor};
use crate::link_common;

use std::collections::{BTreeMap, BTreeSet};

use serde_json::Value;

const POWER: [(u8, f64); 3] = [(1, 300.0), (2, 500.0), (3, 700.0)];

struct Run {
    lines: Vec<Value>,
    peer: Value,
    stderr: String,
}

impl Run {
    fn of(&self, kind: &str) -> impl Iterator<Item = &Value> {
        let kind = kind.to_string();
        self.lines
            .iter()
            .filter(move |l| l["type"] == kind.as_str())
    }
    /// Real estimates (with model output) per system id.
    fn estimates(&self) -> BTreeMap<u64, Vec<&Value>> {
        let mut m: BTreeMap<u64, Vec<&Value>> = BTreeMap::new();
        for e in self
            .of("estimate")
            .filter(|e| e["models"].as_object().is_some_and(|m| !m.is_empty()))
        {
            m.entry(e["system_id"].as_u64().unwrap())
                .or_default()
                .push(e);
        }
        m
    }
    fn alerts(&self, rule: &str) -> Vec<&Value> {
        self.of("alert").filter(|a| a["rule"] == rule).collect()
    }
}

/// Monitor a free UDP port with `config` and `args`, fly the fleet at it, stop with SIGTERM.
fn fly(config: &str, args: &[&str]) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("dw.toml");
    std::fs::write(&cfg, config).unwrap();
    let json = dir.path().join("out.jsonl");
    let port = link_common::free_udp_port();
    let dw = Monitor::listening(
        dronewatt()
            .args(["monitor", &format!("udpin:127.0.0.1:{port}"), "--config"])
            .arg(&cfg)
            .arg("--json")
            .arg(&json)
            .args(args),
        port,
        false,
    );
    let vehicles = r#"[{"id": 1, "power_w": 300, "send_s": 10}, {"id": 2, "power_w": 500, "send_s": 10}, {"id": 3, "power_w": 700, "send_s": 4}]"#;
    let (peer, stderr) = link_common::peer_then_stop(
        dw,
        "fleet.py",
        &[
            "--to",
            &format!("udpout:127.0.0.1:{port}"),
            "--vehicles",
            vehicles,
        ],
    );
    let lines = std::fs::read_to_string(&json)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    Run {
        lines,
        peer,
        stderr,
    }
}

fn on_profile(id: u8, w: f64) -> bool {
    let p = POWER.iter().find(|(v, _)| *v == id).unwrap().1;
    (p - 45.0..=p + 45.0).contains(&w)
}

#[test]
fn three_vehicles_get_three_chains_and_the_silent_one_is_lost_then_dropped() {
    let r = fly("[fleet]\nlost_after_s = 2\ndrop_after_s = 4\n", &[]);
    let est = r.estimates();
    assert_eq!(
        est.keys().copied().collect::<Vec<_>>(),
        vec![1, 2, 3],
        "one chain per vehicle, none for the GCS or companion\n{}",
        r.stderr
    );
    for (&id, es) in &est {
        for e in es {
            let w = e["measured_w"].as_f64().unwrap();
            assert!(
                on_profile(id as u8, w),
                "vehicle {id}: measured {w} W is not its own: {e}"
            );
        }
    }
    // 10 s at 10 Hz for 1 and 2, 4 s for 3 (less the first window).
    assert!(
        est[&1].len() >= 80 && est[&2].len() >= 80,
        "{} / {} estimates",
        est[&1].len(),
        est[&2].len()
    );
    assert!(
        (20..=45).contains(&est[&3].len()),
        "vehicle 3 flew 4 s: {} estimates",
        est[&3].len()
    );
    let summary = r.of("summary").next().expect("summary line");
    assert_eq!(summary["missed_reports"], 0, "{summary}");

    // Lost once (after 2 s), then dropped (after 4 s), only vehicle 3, in that order.
    let lost = r.alerts("vehicle_lost");
    let dropped = r.alerts("vehicle_dropped");
    assert_eq!(lost.len(), 1, "{lost:?}");
    assert_eq!(dropped.len(), 1, "{dropped:?}\n{}", r.stderr);
    assert_eq!(
        (lost[0]["system_id"].as_u64(), lost[0]["state"].as_str()),
        (Some(3), Some("raised"))
    );
    assert_eq!(dropped[0]["system_id"], 3);
    let last3 = est[&3].last().unwrap()["t"].as_f64().unwrap();
    let (t_lost, t_dropped) = (
        lost[0]["t"].as_f64().unwrap(),
        dropped[0]["t"].as_f64().unwrap(),
    );
    assert!(
        (1.8..=3.5).contains(&(t_lost - last3)),
        "lost {t_lost} s, last estimate {last3} s"
    );
    assert!(
        (3.8..=5.5).contains(&(t_dropped - last3)),
        "dropped {t_dropped} s, last estimate {last3} s"
    );

    // Back over MAVLink: each vehicle's values under its own system id, component 191.
    let heard = r.peer["heard"].as_object().unwrap();
    let ours: BTreeSet<&str> = heard
        .keys()
        .map(String::as_str)
        .filter(|k| k.ends_with(",191"))
        .collect();
    assert_eq!(
        ours,
        BTreeSet::from(["1,191", "2,191", "3,191"]),
        "{}",
        r.peer
    );
    for (id, _) in POWER {
        let h = &heard[&format!("{id},191")];
        let meas: Vec<f64> = h["values"]["dw_meas_w"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert!(
            meas.len() >= 4 && meas.iter().all(|&w| on_profile(id, w)),
            "vehicle {id}'s values {meas:?}"
        );
        assert!(
            h["heartbeats"].as_u64().unwrap() >= 3,
            "a heartbeat per vehicle: {h}"
        );
    }
    let texts3 = heard["3,191"]["statustexts"].as_array().unwrap();
    assert!(
        texts3
            .iter()
            .any(|t| t.as_str().unwrap().starts_with("vehicle 3: nothing heard")),
        "{texts3:?}"
    );
    assert!(
        texts3
            .iter()
            .any(|t| t.as_str().unwrap().starts_with("vehicle 3 dropped")),
        "{texts3:?}"
    );
    for id in [1, 2] {
        assert_eq!(
            heard[&format!("{id},191")]["statustexts"],
            serde_json::json!([]),
            "{}",
            r.peer
        );
    }

    // The terminal's fleet view: three rows, then two once vehicle 3 is dropped.
    assert!(
        r.stderr.contains("fleet: 3 vehicles") && r.stderr.contains("fleet: 2 vehicles"),
        "{}",
        r.stderr
    );
    assert!(r.stderr.contains("worst alert"), "{}", r.stderr);
    assert!(
        r.stderr
            .lines()
            .any(|l| l.trim_start().starts_with("3 ") && l.contains("vehicle_lost (warning)")),
        "{}",
        r.stderr
    );
}

#[test]
fn vehicles_keeps_only_the_ids_asked_for() {
    let r = fly("", &["-q", "--vehicles", "2-3"]);
    let est = r.estimates();
    assert_eq!(
        est.keys().copied().collect::<Vec<_>>(),
        vec![2, 3],
        "{}",
        r.stderr
    );
    let ours: BTreeSet<&str> = r.peer["heard"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .filter(|k| k.ends_with(",191"))
        .collect();
    assert_eq!(ours, BTreeSet::from(["2,191", "3,191"]), "{}", r.peer);
    assert!(
        r.stderr.contains("outside fleet.vehicles ignored"),
        "{}",
        r.stderr
    );
}
