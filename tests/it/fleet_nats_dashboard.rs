//! `dronewatt dashboard --nats`: the web dashboard of the whole fleet, read off NATS as the
//! shipped config's `viewer`, with real parts: nats-server on `config/nats-server.conf`, a
//! gateway and two workers each with their own user, a pymavlink fleet over UDP, and the
//! dashboard's own HTTP endpoint read over TCP.

use std::time::{Duration, Instant};

use serde_json::Value;

use crate::fleet_nats::lines;
use crate::fleet_nats_secured::SecuredGateway;
use crate::harness::{dronewatt, Monitor};
use crate::link_common::free_tcp_port;

/// `GET path` on 127.0.0.1:`port`: the body as JSON (`Null` when it cannot be had).
fn get_json(port: u16, path: &str) -> Value {
    use std::io::{Read, Write};
    let Ok(mut c) = std::net::TcpStream::connect(("127.0.0.1", port)) else {
        return Value::Null;
    };
    let _ = c.set_read_timeout(Some(Duration::from_secs(5)));
    let req = format!("GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
    if c.write_all(req.as_bytes()).is_err() {
        return Value::Null;
    }
    let mut r = String::new();
    let _ = c.read_to_string(&mut r);
    r.find("\r\n\r\n")
        .and_then(|i| serde_json::from_str(&r[i + 4..]).ok())
        .unwrap_or(Value::Null)
}

/// Poll the dashboard's state until `done` holds of it (30 s at most): the last state read.
fn state_until(port: u16, done: impl Fn(&Value) -> bool) -> Value {
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let s = get_json(port, "/api/state");
        if done(&s) || Instant::now() > end {
            return s;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The fleet table's row of vehicle `sys`.
fn row(state: &Value, sys: u64) -> Option<&Value> {
    state["fleet"]
        .as_array()?
        .iter()
        .find(|r| r["system_id"].as_u64() == Some(sys))
}

/// The dashboard lists every vehicle with the estimates its worker wrote; when that worker
/// stops and another takes its partitions over, the same rows go on with the new holder's
/// estimates.
#[test]
fn the_dashboard_reads_the_fleet_from_nats_and_follows_a_takeover() {
    let Some(fleet_start) = SecuredGateway::start() else {
        return;
    };
    let (nats, port, dir) = (&fleet_start.nats, fleet_start.port, &fleet_start.dir);
    let vpw = fleet_start.password("viewer");
    let worker1 = fleet_start.worker("worker1");
    let web = free_tcp_port();
    let dashboard = Monitor::listening(
        dronewatt()
            .args(["dashboard", "--nats", &nats.url])
            .args(["--bind", &format!("127.0.0.1:{web}")])
            .args(["--nats-user", "viewer", "--nats-password-file"])
            .arg(&vpw)
            .env("RUST_LOG", "dronewatt=info"),
        web,
        true,
    );
    // 30 s of flight at most: the test stops the fleet once it has seen the takeover.
    let fleet = crate::fleet_nats::fly_fleet(
        port,
        r#"[{"id": 1, "power_w": 300, "send_s": 30}, {"id": 2, "power_w": 450, "send_s": 30}]"#,
    );
    // Both vehicles, with estimates, in the fleet table (the fleet's packs are not known to
    // dronewatt, so no remaining energy: the measured power and the energy used are there).
    let first = state_until(web, |s| {
        [1, 2]
            .iter()
            .all(|&v| row(s, v).is_some_and(|r| r["measured_w"].is_number()))
    });
    let ctx = |s: &Value| format!("state: {s}");
    for v in [1, 2] {
        let r = row(&first, v).unwrap_or_else(|| panic!("no vehicle {v}: {}", ctx(&first)));
        assert!(r["measured_w"].as_f64().is_some_and(|w| w > 100.0), "{r}");
    }
    // One vehicle's page: its estimate, the pilot's figures and its chart points.
    let two = get_json(web, "/api/state?vehicle=2");
    assert_eq!(two["vehicle"], 2, "{two}");
    assert!(two["latest"]["pilot"]["power_w"].is_number(), "{two}");
    assert!(
        two["latest"]["energy"]["energy_used_wh"].is_number(),
        "{two}"
    );
    assert!(
        !two["points"].as_array().is_some_and(Vec::is_empty),
        "{two}"
    );
    assert!(
        two["latest"]["models"]
            .as_array()
            .is_some_and(|m| !m.is_empty()),
        "{two}"
    );
    // worker2 joins; worker1 stops (releasing its leases): worker2 takes them over.
    let worker2 = fleet_start.worker("worker2");
    let (_, e1) = worker1.stop();
    let w1 = lines(&dir.path().join("worker1.jsonl"));
    let last_t = |v: u64, lines: &[Value]| {
        crate::fleet_nats::estimates(lines, v)
            .last()
            .map_or(0.0, |e| e.0)
    };
    let after = state_until(web, |s| {
        [1, 2]
            .iter()
            .all(|&v| row(s, v).and_then(|r| r["t"].as_f64()) > Some(last_t(v, &w1) + 2.0))
    });
    // Seen what it needed: the fleet need not fly on.
    let mut fleet = fleet;
    let _ = fleet.kill();
    let _ = fleet.wait();
    let (_, e2) = worker2.stop();
    let (_, ed) = dashboard.stop();
    let (_, eg) = fleet_start.gateway.stop();
    let w2 = lines(&dir.path().join("worker2.jsonl"));
    let ctx = format!(
        "{}\nworker1: {e1}\nworker2: {e2}\ndashboard: {ed}\ngateway: {eg}",
        ctx(&after)
    );
    for v in [1, 2] {
        let r = row(&after, v).unwrap_or_else(|| panic!("vehicle {v} gone: {ctx}"));
        let t = r["t"].as_f64().unwrap();
        assert!(
            t > last_t(v, &w1) + 2.0,
            "vehicle {v} stopped at {t}: {ctx}"
        );
        // The row's figures are worker2's estimate at that time.
        let theirs = w2
            .iter()
            .find(|l| l["type"] == "estimate" && l["system_id"] == v && l["t"].as_f64() == Some(t));
        let theirs = theirs.unwrap_or_else(|| panic!("t {t} not in worker2's lines: {ctx}"));
        let (ours, w) = (r["measured_w"].as_f64(), theirs["measured_w"].as_f64());
        assert!(
            ours.zip(w).is_some_and(|(a, b)| (a - b).abs() < 1e-3),
            "{ctx}"
        );
        assert_eq!(r["remaining_wh"], theirs["remaining_wh"], "{ctx}");
        if v == 1 {
            // The page's vehicle (the lowest): its energy as worker2 wrote it.
            let e = &after["latest"]["energy"]["energy_used_wh"];
            assert_eq!(e, &theirs["energy_used_wh"], "{ctx}");
        }
    }
    assert!(
        eg.contains(" 0 lease takeovers out of turn refused"),
        "an honest handover was taken for one out of turn: {ctx}"
    );
}
