//! The mission protocol on a real link: `dronewatt monitor udpin:127.0.0.1:PORT` against
//! pymavlink as an ArduPilot vehicle (`tests/peers/mission_server.py`) that serves its
//! mission over MISSION_REQUEST_LIST / MISSION_COUNT / MISSION_REQUEST_INT / MISSION_ITEM_INT
//! / MISSION_ACK, drops one request, and changes the mission halfway. What the vehicle saw
//! dronewatt ask and say, and what the operator sees (`--json`), are checked.

use crate::harness::{monitor_udp, Monitor};
use crate::link_common;

use serde_json::Value;

/// Run `monitor` on a free port with `config`, the peer with `peer_args`; (peer JSON,
/// dronewatt's JSON lines, its stderr).
fn run(config: &str, peer_args: &[&str]) -> (Value, Vec<Value>, String) {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("dw.toml");
    std::fs::write(&cfg, config).unwrap();
    let json = dir.path().join("out.jsonl");
    let port = link_common::free_udp_port();
    let dw = Monitor::listening(
        monitor_udp(port)
            .arg("--config")
            .arg(&cfg)
            .arg("--json")
            .arg(&json)
            // The peer sends no capacity: its pack, named (no pack is assumed).
            .args(["--pack", "6S:5000mAh:lipo"])
            .env("RUST_LOG", "dronewatt=info"),
        port,
        false,
    );
    let to = format!("udpout:127.0.0.1:{port}");
    let args: Vec<&str> = ["--to", to.as_str()]
        .into_iter()
        .chain(peer_args.iter().copied())
        .collect();
    let (peer, stderr) = link_common::peer_then_stop(dw, "mission_server.py", &args);
    let lines = std::fs::read_to_string(&json)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    (peer, lines, stderr)
}

#[test]
fn the_mission_is_downloaded_with_a_resend_acked_redownloaded_on_change_and_forecast() {
    let (peer, lines, stderr) = run(
        "",
        &["--seconds", "12", "--drop-seq", "2", "--change-at", "7"],
    );
    let ctx = format!("peer: {peer}\ndronewatt: {stderr}");
    // One download at the first heartbeat, one after the mission changed at 7 s.
    let lists = peer["request_list"].as_array().unwrap();
    assert_eq!(lists.len(), 2, "two downloads: {ctx}");
    assert!(
        lists[0].as_f64().unwrap() < 3.0 && lists[1].as_f64().unwrap() >= 7.0,
        "{ctx}"
    );
    // Every item asked for in order; the dropped request for seq 2 asked again ~1.5 s later.
    let reqs: Vec<(f64, u64)> = peer["requests"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| (r[0].as_f64().unwrap(), r[1].as_u64().unwrap()))
        .collect();
    assert_eq!(peer["dropped"], serde_json::json!([2]), "{ctx}");
    let twos: Vec<f64> = reqs.iter().filter(|r| r.1 == 2).map(|r| r.0).collect();
    assert!(
        twos.len() >= 3,
        "seq 2 asked twice in the first download and once in the second: {ctx}"
    );
    let gap = twos[1] - twos[0];
    assert!(
        (1.2..3.0).contains(&gap),
        "resent after the timeout (1.5 s): {gap} s; {ctx}"
    );
    let first: Vec<u64> = reqs
        .iter()
        .filter(|r| r.0 < lists[1].as_f64().unwrap())
        .map(|r| r.1)
        .collect();
    assert_eq!(first, [0, 1, 2, 2, 3, 4, 5], "{ctx}");
    let second: Vec<u64> = reqs
        .iter()
        .filter(|r| r.0 >= lists[1].as_f64().unwrap())
        .map(|r| r.1)
        .collect();
    assert_eq!(
        second,
        [0, 1, 2, 3, 4, 5, 6],
        "the changed mission has 7 items: {ctx}"
    );
    assert_eq!(
        peer["acks"],
        serde_json::json!([0, 0]),
        "each download acked MAV_MISSION_ACCEPTED: {ctx}"
    );
    assert!(
        peer["senders"]
            .as_array()
            .unwrap()
            .contains(&serde_json::json!([1, 191])),
        "{ctx}"
    );
    // The not-modelled item is listed, not dropped.
    assert!(stderr.contains("MAV_CMD 206 not modelled"), "{ctx}");
    // What the operator sees: the mission energy, falling as the mission is flown, and the
    // margin = remaining − mission − reserve.
    let est: Vec<&Value> = lines
        .iter()
        .filter(|l| l["type"] == "estimate" && l["mission_energy_wh"].is_f64())
        .collect();
    assert!(
        est.len() > 20,
        "estimates with the mission forecast: {} ({ctx})",
        est.len()
    );
    let first_e = est[0]["mission_energy_wh"].as_f64().unwrap();
    // 1.4 km of route at 10 m/s and the landing, ~200 s, at an M100's few hundred watts
    assert!(
        (5.0..60.0).contains(&first_e),
        "mission energy {first_e} Wh: {ctx}"
    );
    let reserve = |e: &Value| {
        e["remaining_wh"].as_f64().unwrap()
            - e["mission_energy_wh"].as_f64().unwrap()
            - e["mission_margin_wh"].as_f64().unwrap()
    };
    let r0 = reserve(est[0]);
    assert!(
        r0 > 0.0 && est.iter().all(|e| (reserve(e) - r0).abs() < 1e-6),
        "the same reserve throughout: {r0} Wh; {ctx}"
    );
    let last_e = est.last().unwrap()["mission_energy_wh"].as_f64().unwrap();
    assert!(
        last_e != first_e,
        "re-forecast as the vehicle flies (and the mission grows): {first_e} → {last_e}; {ctx}"
    );
    // The vehicle heard the values and dronewatt's own battery (id 9, a real time left).
    let named = &peer["named"];
    assert!(
        named["dw_mis_wh"].as_f64().is_some_and(|v| v > 0.0) && named["dw_mis_mrg"].is_f64(),
        "{ctx}"
    );
    let batt = peer["battery"].as_array().unwrap();
    assert!(!batt.is_empty() && batt.iter().all(|b| b[0] == 9), "{ctx}");
    assert!(
        batt.iter().any(|b| b[1].as_i64().unwrap() > 60),
        "time_remaining from dronewatt's forecast: {ctx}"
    );
}

/// One MAVLink identity, one writer: the sink (HEARTBEAT, NAMED_VALUE_FLOAT,
/// BATTERY_STATUS), the parameter reader (PARAM_REQUEST_READ) and the mission client
/// (MISSION_REQUEST_LIST, MISSION_REQUEST_INT, MISSION_ACK) all send as (1, 191) on the one
/// link; pymavlink, the vehicle, sees one unbroken sequence across them (with a counter
/// each, it saw three interleaved ones: losses that never happened).
#[test]
fn the_sink_the_parameter_reader_and_the_mission_client_share_one_sequence() {
    let (peer, _, stderr) = run("", &["--seconds", "8", "--drop-seq", "99"]);
    let ctx = format!("peer: {peer}\ndronewatt: {stderr}");
    let frames = peer["from_191"].as_array().unwrap();
    let kinds: std::collections::BTreeSet<&str> =
        frames.iter().map(|f| f[2].as_str().unwrap()).collect();
    for k in [
        "HEARTBEAT",
        "NAMED_VALUE_FLOAT",
        "PARAM_REQUEST_READ",
        "MISSION_REQUEST_LIST",
        "MISSION_REQUEST_INT",
    ] {
        assert!(kinds.contains(k), "no {k} from (1, 191): {kinds:?}; {ctx}");
    }
    assert!(frames.iter().all(|f| f[0] == 1), "{ctx}");
    let seq: Vec<u64> = frames.iter().map(|f| f[1].as_u64().unwrap()).collect();
    let breaks: Vec<(usize, u64, u64)> = seq
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[1] != (w[0] + 1) % 256)
        .map(|(i, w)| (i, w[0], w[1]))
        .collect();
    assert!(
        seq.len() > 50 && breaks.is_empty(),
        "{} frames from (1, 191), sequence breaks (index, from, to): {breaks:?}",
        seq.len()
    );
}
