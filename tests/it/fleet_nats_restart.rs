//! The fleet on NATS JetStream past a worker's death and restarts, with real parts (see
//! `fleet_nats`): a checkpoint of another chain card is said and rebuilt from the stream;
//! the gateway and nats-server restarted mid-flight lose nothing the stream kept.

use std::time::Duration;

use crate::fleet_nats::{estimates, fly_fleet, gateway, lines, raised, server, worker};
use crate::harness::{dronewatt, Monitor};
use crate::link_common::free_udp_port;

/// A worker whose chain differs from the checkpoint's (another `[energy]` table here)
/// says so and rebuilds the vehicles from the stream, whose energy then still counts
/// from the flight's start.
#[test]
fn a_checkpoint_of_another_card_is_said_and_rebuilt_from_the_stream() {
    let Some(nats) = server(None) else { return };
    let dir = tempfile::tempdir().unwrap();
    let gw_port = free_udp_port();
    let gateway = gateway(&nats.url, gw_port);
    let (ja, jb) = (dir.path().join("a.jsonl"), dir.path().join("b.jsonl"));
    let a = worker(&nats.url, &ja);
    std::thread::sleep(Duration::from_secs(2));
    let vehicles =
        r#"[{"id": 1, "power_w": 300, "send_s": 16}, {"id": 2, "power_w": 500, "send_s": 16}]"#;
    let fleet = fly_fleet(gw_port, vehicles);
    std::thread::sleep(Duration::from_secs(8));
    // Stopped cleanly: its checkpoints written, its leases released at once.
    let (sa, ea) = a.stop();
    assert!(sa.success(), "{ea}");
    let cfg = dir.path().join("other.toml");
    std::fs::write(&cfg, "[energy]\nreserve_pct = 25\n").unwrap();
    let b = Monitor::spawn(
        dronewatt()
            .args(["monitor", "--nats", &nats.url, "--data-dir", "off", "-q"])
            .arg("--config")
            .arg(&cfg)
            .arg("--json")
            .arg(&jb)
            .env("RUST_LOG", "dronewatt=info"),
    );
    assert!(fleet.wait_with_output().unwrap().status.success());
    std::thread::sleep(Duration::from_secs(3));
    let (sb, eb) = b.stop();
    let _ = gateway.stop();
    assert!(sb.success(), "{eb}");
    assert!(
        eb.contains("another card") && eb.contains("rebuilt from the stream"),
        "{eb}"
    );
    assert!(!eb.contains("restored from the fleet's checkpoint"), "{eb}");
    let (la, lb) = (lines(&ja), lines(&jb));
    for sys in 1..=2u64 {
        let (wa, wb) = (estimates(&la, sys), estimates(&lb, sys));
        assert!(!wa.is_empty() && !wb.is_empty(), "vehicle {sys}: {eb}");
        // Rebuilt from the first frame: b's energy goes on from a's, not from zero.
        let (end_a, first_b) = (wa.last().unwrap(), wb[0]);
        assert!(
            first_b.0 > end_a.0 - 2.0,
            "vehicle {sys}: b re-sent a's reports"
        );
        assert!(
            first_b.1 >= end_a.1 * 0.95,
            "vehicle {sys}: b starts at {:.3} Wh, a ended at {:.3} Wh",
            first_b.1,
            end_a.1
        );
    }
}

/// The stream's (first, last) sequence and message count.
fn stream_state(url: &str) -> (u64, u64, u64) {
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let c = async_nats::connect(url).await.unwrap();
        let js = async_nats::jetstream::new(c);
        let mut s = js.get_stream("DRONEWATT_FRAMES").await.unwrap();
        let st = s.info().await.unwrap().state.clone();
        (st.first_sequence, st.last_sequence, st.messages)
    })
}

/// The gateway restarted mid-flight, then nats-server (JetStream on disk): nothing the
/// stream kept is lost, the worker says it lost the server and got it back, and goes on
/// estimating every vehicle after each, with no alert raised twice.
#[test]
fn a_gateway_and_a_nats_server_restarted_mid_flight_lose_nothing_kept() {
    let Some(mut nats) = server(None) else { return };
    let dir = tempfile::tempdir().unwrap();
    let gw_port = free_udp_port();
    let url = nats.url.clone();
    let gateway = || gateway(&url, gw_port);
    let g1 = gateway();
    let jw = dir.path().join("w.jsonl");
    let w = worker(&nats.url, &jw);
    std::thread::sleep(Duration::from_secs(2));
    let vehicles =
        r#"[{"id": 1, "power_w": 300, "send_s": 24}, {"id": 2, "power_w": 500, "send_s": 24}]"#;
    let fleet = fly_fleet(gw_port, vehicles);
    std::thread::sleep(Duration::from_secs(6));
    // The gateway restarted: the frames sent while it is down are not heard by anyone.
    let (_, e1) = g1.stop();
    std::thread::sleep(Duration::from_secs(1));
    let g2 = gateway();
    std::thread::sleep(Duration::from_secs(5));
    // nats-server killed and started again on its store.
    let before = stream_state(&nats.url);
    nats.restart(Duration::from_secs(2));
    let after = stream_state(&nats.url);
    assert_eq!(
        before.0, after.0,
        "first sequence: {before:?} then {after:?}"
    );
    assert!(
        after.1 >= before.1 && after.2 >= before.2,
        "frames lost by the restart: {before:?} then {after:?}"
    );
    assert!(fleet.wait_with_output().unwrap().status.success());
    std::thread::sleep(Duration::from_secs(3));
    let (sw, ew) = w.stop();
    let (_, e2) = g2.stop();
    let ctx = format!("worker: {ew}\ngateway 1: {e1}\ngateway 2: {e2}");
    assert!(sw.success(), "{ctx}");
    assert!(
        ew.contains("NATS: disconnected; reconnecting") && ew.contains("NATS: reconnected"),
        "the worker did not say it lost and found the server: {ctx}"
    );
    let end = stream_state(&nats.url);
    assert!(end.1 > after.1, "nothing stored after the restart: {ctx}");
    let lines = lines(&jw);
    for sys in 1..=2u64 {
        let est = estimates(&lines, sys);
        let (t0, t1) = (est[0].0, est.last().unwrap().0);
        // Estimated on past both restarts: the flight's last seconds are there.
        assert!(
            t1 - t0 > 18.0,
            "vehicle {sys}: estimated {t0:.1}..{t1:.1} s: {ctx}"
        );
        // Energy goes on, never back.
        assert!(
            est.windows(2).all(|p| p[1].1 >= p[0].1 - 1e-9),
            "vehicle {sys}: energy went back: {ctx}"
        );
    }
    for (k, n) in raised(&lines) {
        assert_eq!(n, 1, "{k:?} raised {n} times: {ctx}");
    }
    eprintln!("stream before the restart {before:?}, after {after:?}, at the end {end:?}");
}
