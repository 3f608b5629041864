//! Who may send what on the fleet's NATS, with real parts: nats-server run on the shipped
//! `config/nats-server.conf` (on a free loopback port), a real `dronewatt gateway` with the
//! gateway's credentials, a UDP socket as the vehicle, and raw NATS clients with the
//! workers' and the viewer's credentials as the misbehaving parties; and a whole fleet on
//! the shipped config, read back by `dronewatt vehicles --nats` as the viewer.

use std::net::UdpSocket;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use async_nats::jetstream;

use crate::fleet_nats::server;
use crate::fleet_nats_secured::{login, vehicle_socket, SecuredGateway, CONFIG};
use crate::harness::dronewatt;

/// How many frames the frame stream holds.
async fn frames_stored(js: &jetstream::Context) -> u64 {
    let mut s = js.get_stream("DRONEWATT_FRAMES").await.unwrap();
    s.info().await.unwrap().state.messages
}

/// What the server has said to a client (its errors, one a line), once `done` holds of it or
/// 10 s have passed: the server's answer to a refused publish comes back asynchronously, late
/// on a loaded machine.
async fn server_said(errors: &Mutex<Vec<String>>, done: impl Fn(&str) -> bool) -> String {
    let said = || errors.lock().unwrap().join("\n");
    let end = Instant::now() + Duration::from_secs(10);
    while !done(&said()) && Instant::now() < end {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    said()
}

#[test]
fn the_shipped_server_config_refuses_strangers_and_keeps_each_role_to_its_subjects() {
    let Some(nats) = server(Some(CONFIG)) else {
        return;
    };
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        // No credentials: refused at the door.
        let e = async_nats::connect(nats.url.as_str()).await.unwrap_err();
        assert_eq!(
            e.kind(),
            async_nats::ConnectErrorKind::AuthorizationViolation,
            "{e}"
        );
        let (gw, _) = login(&nats.url, "gateway").await;
        let gjs = jetstream::new(gw.clone());
        gjs.create_stream(jetstream::stream::Config {
            name: "DRONEWATT_FRAMES".into(),
            subjects: vec!["dronewatt.frames.>".into()],
            ..Default::default()
        })
        .await
        .unwrap();
        let mut downlink = gw.subscribe("dronewatt.to.>").await.unwrap();
        gw.flush().await.unwrap();
        // A worker's credentials: not onto the frame stream, not as another worker, not
        // the stream's configuration; its own downlink subtree, yes.
        let (w1, w1_errors) = login(&nats.url, "worker1").await;
        w1.publish("dronewatt.frames.3.0.3", "forged frame".into())
            .await
            .unwrap();
        w1.publish("dronewatt.to.worker2.i.0.3", "as worker2".into())
            .await
            .unwrap();
        w1.publish("dronewatt.to.worker1.i.0.3", "as itself".into())
            .await
            .unwrap();
        let update = tokio::time::timeout(
            Duration::from_secs(1),
            w1.request(
                "$JS.API.STREAM.UPDATE.DRONEWATT_FRAMES",
                r#"{"name":"DRONEWATT_FRAMES","subjects":["dronewatt.frames.>","dronewatt.to.>"]}"#
                    .into(),
            ),
        )
        .await;
        assert!(
            !matches!(update, Ok(Ok(_))),
            "the JetStream API answered a worker's stream update"
        );
        w1.flush().await.unwrap();
        let m = tokio::time::timeout(
            Duration::from_secs(10),
            futures_util::StreamExt::next(&mut downlink),
        )
        .await
        .expect("the worker's own downlink frame never came")
        .unwrap();
        assert_eq!(m.subject.as_str(), "dronewatt.to.worker1.i.0.3");
        // Nothing else came through: the frame as worker2 was dropped by the server.
        let more = tokio::time::timeout(
            Duration::from_millis(500),
            futures_util::StreamExt::next(&mut downlink),
        )
        .await;
        assert!(
            more.is_err(),
            "{:?}",
            more.ok().flatten().map(|m| m.subject)
        );
        assert_eq!(frames_stored(&gjs).await, 0, "a worker's frame was stored");
        // The server's answers come back asynchronously: wait for both (10 s at most).
        let told_w1 =
            |e: &str| e.contains("dronewatt.frames.3.0.3") && e.contains("dronewatt.to.worker2");
        let errors = server_said(&w1_errors, told_w1).await;
        assert!(
            told_w1(&errors),
            "the server did not tell the worker: {errors}"
        );
        // The gateway's credentials do store a frame (the count above means something).
        gjs.publish("dronewatt.frames.3.0.3", "frame".into())
            .await
            .unwrap()
            .await
            .unwrap();
        assert_eq!(frames_stored(&gjs).await, 1);
        // A viewer reads the estimates and publishes nothing.
        let (viewer, viewer_errors) = login(&nats.url, "viewer").await;
        let mut est = viewer.subscribe("dronewatt.estimates.>").await.unwrap();
        viewer.flush().await.unwrap();
        // Core NATS delivers at most once (a publish can be lost on a loaded machine's
        // reconnect): publish again every 500 ms until the viewer has one (10 s at most).
        let end = Instant::now() + Duration::from_secs(10);
        let mut got = None;
        while got.is_none() && Instant::now() < end {
            w1.publish("dronewatt.estimates.3.0.3", "{}".into())
                .await
                .unwrap();
            w1.flush().await.unwrap();
            got = tokio::time::timeout(
                Duration::from_millis(500),
                futures_util::StreamExt::next(&mut est),
            )
            .await
            .ok()
            .flatten();
        }
        assert!(got.is_some(), "the viewer saw no estimate");
        viewer
            .publish("dronewatt.estimates.3.0.3", "{}".into())
            .await
            .unwrap();
        viewer.flush().await.unwrap();
        // The server's answer comes back asynchronously: wait for it (10 s at most).
        let errors = server_said(&viewer_errors, |e| {
            e.to_lowercase().contains("permissions violation")
        })
        .await;
        assert!(
            errors.to_lowercase().contains("permissions violation"),
            "{errors}"
        );
    });
    drop(nats);
}

/// A STATUSTEXT frame saying `text`, for vehicle 3.
fn statustext(text: &str) -> Vec<u8> {
    let msg = dronewatt::MavMessage::STATUSTEXT(dronewatt::dialect::STATUSTEXT_DATA {
        severity: dronewatt::dialect::MavSeverity::MAV_SEVERITY_CRITICAL,
        text: text.into(),
        id: 0,
        chunk_seq: 0,
    });
    let header = mavlink::MavHeader {
        system_id: 3,
        component_id: 191,
        sequence: 0,
    };
    let mut frame = Vec::new();
    mavlink::write_versioned_msg(&mut frame, mavlink::MavlinkVersion::V2, header, &msg).unwrap();
    frame
}

/// Publish a STATUSTEXT saying `text` on `subject` as client `c`, flushed.
fn send(rt: &tokio::runtime::Runtime, c: &async_nats::Client, subject: &str, text: &str) {
    rt.block_on(async {
        c.publish(subject.to_string(), statustext(text).into())
            .await
            .unwrap();
        c.flush().await.unwrap();
    })
}

/// Vehicle 3's HEARTBEAT frame.
fn heartbeat() -> Vec<u8> {
    let hb = dronewatt::MavMessage::HEARTBEAT(dronewatt::dialect::HEARTBEAT_DATA::default());
    let mut frame = Vec::new();
    let h = mavlink::MavHeader {
        system_id: 3,
        component_id: 1,
        sequence: 0,
    };
    mavlink::write_versioned_msg(&mut frame, mavlink::MavlinkVersion::V2, h, &hb).unwrap();
    frame
}

/// Send the vehicle's `frame` to the gateway's `port` (again every second) until the frame
/// stream holds one (read with `c`'s credentials): the gateway's link has its address then.
fn hello(
    rt: &tokio::runtime::Runtime,
    c: &async_nats::Client,
    vehicle: &UdpSocket,
    frame: &[u8],
    port: u16,
) {
    let js = rt.block_on(async { jetstream::new(c.clone()) });
    let end = Instant::now() + Duration::from_secs(20);
    let mut next = Instant::now();
    while rt.block_on(frames_stored(&js)) == 0 {
        assert!(
            Instant::now() < end,
            "the gateway never stored the vehicle's frame"
        );
        if Instant::now() >= next {
            vehicle.send_to(frame, ("127.0.0.1", port)).unwrap();
            next = Instant::now() + Duration::from_secs(1);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// What vehicle `v` hears, as text (its frames' bytes, lossy): until `last` has come and
/// half a second more (anything sent before it has come by then), or 10 s.
fn heard_until(v: &UdpSocket, last: &str) -> String {
    let mut all = String::new();
    let mut end = Instant::now() + Duration::from_secs(10);
    let mut buf = [0u8; 512];
    while Instant::now() < end {
        if let Ok(n) = v.recv(&mut buf) {
            let seen = all.contains(last);
            all.push_str(&String::from_utf8_lossy(&buf[..n]));
            if !seen && all.contains(last) {
                end = Instant::now() + Duration::from_millis(500);
            }
        }
    }
    all
}

#[test]
fn a_worker_cannot_send_to_a_vehicle_it_does_not_hold() {
    let Some((gateway, port, nats)) = SecuredGateway::start().map(SecuredGateway::parts) else {
        return;
    };
    // Vehicle 3 says hello, so the gateway knows where it is.
    let vehicle = vehicle_socket();
    let frame = heartbeat();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let (w1, w2) = rt.block_on(async {
        let (w1, _) = login(&nats.url, "worker1").await;
        let (w2, _) = login(&nats.url, "worker2").await;
        (w1, w2)
    });
    let send = |c: &async_nats::Client, subject: &str, text: &str| send(&rt, c, subject, text);
    // The gateway subscribed to the workers' downlink before it listened; the vehicle's
    // heartbeat gives the link its address (taken in once the gateway has stored it).
    hello(&rt, &w2, &vehicle, &frame, port);
    // Nobody holds partition 3: worker1's frame is refused.
    send(&w1, "dronewatt.to.worker1.i1.0.3", "nobody-holds");
    // worker2 takes partition 3's lease.
    rt.block_on(async {
        let kv = jetstream::new(w2.clone())
            .get_key_value("dronewatt_leases")
            .await
            .unwrap();
        kv.create("p3", "worker2.i2".into()).await.unwrap();
    });
    // No wait: a frame from a worker the gateway does not see holding the partition waits
    // there until the gateway has judged every lease write the bucket holds.
    // worker1 still holds nothing; forging worker2's subject is the server's to drop.
    send(&w1, "dronewatt.to.worker1.i1.0.3", "not-yours");
    send(&w1, "dronewatt.to.worker2.i2.0.3", "forged");
    // The holder's frame goes through.
    send(&w2, "dronewatt.to.worker2.i2.0.3", "holder-says");
    let got = heard_until(&vehicle, "holder-says");
    let (_, err) = gateway.stop();
    drop(nats);
    assert!(
        got.contains("holder-says"),
        "the holder's frame never came: {err}"
    );
    for bad in ["nobody-holds", "not-yours", "forged"] {
        assert!(!got.contains(bad), "{bad} reached the vehicle: {err}");
    }
    // Both of worker1's frames refused, each for the holder the gateway saw when it took the
    // frame: the first is "held by nobody" when the gateway takes it before worker2's lease,
    // "held by worker2.i2" when, under load, it takes it after.
    let refusals = err
        .matches("refused a frame for vehicle 0:3 from worker worker1.i1: partition 3 is held by ")
        .count();
    assert_eq!(refusals, 2, "{err}");
    assert!(
        err.contains("from worker worker1.i1: partition 3 is held by worker2.i2"),
        "{err}"
    );
    assert!(err.contains("to the vehicles 1 sent, 2 refused"), "{err}");
}

/// The shipped config runs a real fleet: a gateway, a worker and a viewer each with their
/// own user. The worker's estimates reach the vehicles through the gateway (it holds
/// their leases), and `dronewatt vehicles --nats` as the viewer lists each vehicle's
/// latest estimate, as the worker wrote it.
#[test]
fn vehicles_reads_the_fleet_from_nats_as_a_viewer() {
    let Some(fleet_start) = SecuredGateway::start() else {
        return;
    };
    let (nats, port) = (&fleet_start.nats, fleet_start.port);
    let vpw = fleet_start.password("viewer");
    let json = fleet_start.dir.path().join("worker1.jsonl");
    let worker = fleet_start.worker("worker1");
    let fleet = crate::fleet_nats::python()
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/fleet.py"))
        .args(["--to", &format!("udpout:127.0.0.1:{port}")])
        .args([
            "--vehicles",
            r#"[{"id": 1, "power_w": 300, "send_s": 12}, {"id": 2, "power_w": 450, "send_s": 12}]"#,
        ])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("run .venv-py/bin/python (make setup creates it)");
    // The viewers listen once the worker estimates both vehicles (the fleet sends 12 s).
    let end = Instant::now() + Duration::from_secs(30);
    while !(1..=2)
        .all(|v| !crate::fleet_nats::estimates(&crate::fleet_nats::lines(&json), v).is_empty())
        && Instant::now() < end
    {
        std::thread::sleep(Duration::from_millis(100));
    }
    let viewer = |json: bool| {
        let mut c = dronewatt();
        c.args(["vehicles", "--nats", &nats.url, "--listen", "3"])
            .args(["--nats-user", "viewer", "--nats-password-file"])
            .arg(&vpw);
        if json {
            c.arg("--json");
        }
        c.stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (as_json, as_table) = (viewer(true), viewer(false));
    let (as_json, as_table) = (
        as_json.wait_with_output().unwrap(),
        as_table.wait_with_output().unwrap(),
    );
    let out = fleet.wait_with_output().unwrap();
    let (_, ew) = worker.stop();
    let (_, eg) = fleet_start.gateway.stop();
    let ctx = format!(
        "viewer: {}\nworker: {ew}\ngateway: {eg}",
        String::from_utf8_lossy(&as_json.stderr)
    );
    assert!(
        as_json.status.success() && as_table.status.success(),
        "{ctx}"
    );
    let listed: Vec<serde_json::Value> = serde_json::from_slice(&as_json.stdout).unwrap();
    let written = crate::fleet_nats::lines(&json);
    let ids: Vec<u64> = listed
        .iter()
        .filter_map(|v| v["system_id"].as_u64())
        .collect();
    assert_eq!(ids, [1, 2], "{ctx}");
    for v in &listed {
        assert_eq!(v["type"], "estimate");
        assert!(written.contains(v), "not one the worker wrote: {v}\n{ctx}");
    }
    let table = String::from_utf8_lossy(&as_table.stdout);
    assert!(
        table.contains("\n0:1 ") && table.contains("\n0:2 ") && table.contains("2 vehicles heard"),
        "{table}"
    );
    // What the worker sent the vehicles went through: it holds their leases.
    let heard: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
    for s in 1..=2 {
        assert!(
            heard["heard"]
                .as_object()
                .is_some_and(|h| h.keys().any(|k| k.starts_with(&format!("{s},")))),
            "vehicle {s} heard nothing back: {heard}\n{ctx}"
        );
    }
    assert!(eg.contains(" sent, 0 refused"), "{eg}");
}

/// A worker cannot take a lease that has not run out: overwriting it, or deleting it (even
/// with a forged release marker, which the server drops) then creating it, leaves the
/// holder the holder in the gateway's eyes, and the usurper's frames are refused; the
/// holder's own release hands the partition over at once.
#[test]
fn a_worker_cannot_take_a_lease_that_has_not_run_out() {
    let Some((gateway, port, nats)) = SecuredGateway::start().map(SecuredGateway::parts) else {
        return;
    };
    let vehicle = vehicle_socket();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let ((w1, w1_errors), (w2, _)) = rt.block_on(async {
        (
            login(&nats.url, "worker1").await,
            login(&nats.url, "worker2").await,
        )
    });
    hello(&rt, &w2, &vehicle, &heartbeat(), port);
    let kv = |c: &async_nats::Client| {
        let c = c.clone();
        rt.block_on(async move {
            jetstream::new(c)
                .get_key_value("dronewatt_leases")
                .await
                .unwrap()
        })
    };
    let (kv1, kv2) = (kv(&w1), kv(&w2));
    let send = |c: &async_nats::Client, subject: &str, text: &str| send(&rt, c, subject, text);
    // worker2 (re)writes its lease over whatever is there: what a holder does each second,
    // and what it does when its renewal is refused while the lease still runs.
    let w2_writes = || {
        rt.block_on(async {
            let rev = kv2.entry("p3").await.unwrap().map_or(0, |e| e.revision);
            kv2.update("p3", "worker2.i2".into(), rev).await.unwrap();
        })
    };
    rt.block_on(async { kv2.create("p3", "worker2.i2".into()).await.unwrap() });
    // The gateway takes the downlink's frames in order, each judged against the holder at
    // that moment: a frame from worker2 heard by the vehicle says every frame before it was
    // judged (and the next step may go on).
    let mut got = String::new();
    let mut heard = |tag: &str| {
        send(&w2, "dronewatt.to.worker2.i2.0.3", tag);
        got.push_str(&heard_until(&vehicle, tag));
    };
    heard("w2-holds");
    // Out of turn, three ways, each right after the holder's write.
    w2_writes();
    rt.block_on(async { kv1.put("p3", "worker1.i1".into()).await.unwrap() });
    send(&w1, "dronewatt.to.worker1.i1.0.3", "w1-overwrote");
    heard("w2-after-overwrite");
    w2_writes();
    rt.block_on(async {
        kv1.delete("p3").await.unwrap();
        kv1.create("p3", "worker1.i1".into()).await.unwrap();
    });
    send(&w1, "dronewatt.to.worker1.i1.0.3", "w1-recreated");
    heard("w2-after-recreate");
    // The forged release marker: published, and dropped by the server (not worker1's
    // subtree; a core publish, as no acknowledgement comes).
    rt.block_on(async {
        w1.publish("$KV.dronewatt_leases.r.worker2.i2.p3", "".into())
            .await
            .unwrap();
        w1.flush().await.unwrap();
    });
    w2_writes();
    rt.block_on(async {
        kv1.delete("p3").await.unwrap();
        kv1.create("p3", "worker1.i1".into()).await.unwrap();
    });
    send(&w1, "dronewatt.to.worker1.i1.0.3", "w1-forged-release");
    // The holder writes its lease back, and is still heard.
    w2_writes();
    heard("w2-still");
    // Its own release: the marker, the deletion; worker1 takes it and is heard.
    rt.block_on(async {
        kv2.put("r.worker2.i2.p3", "".into()).await.unwrap();
        kv2.delete("p3").await.unwrap();
        kv1.create("p3", "worker1.i1".into()).await.unwrap();
    });
    send(&w1, "dronewatt.to.worker1.i1.0.3", "w1-after-release");
    got.push_str(&heard_until(&vehicle, "w1-after-release"));
    let (_, err) = gateway.stop();
    drop(nats);
    for good in [
        "w2-holds",
        "w2-after-overwrite",
        "w2-after-recreate",
        "w2-still",
        "w1-after-release",
    ] {
        assert!(got.contains(good), "{good} never came: {err}");
    }
    for bad in ["w1-overwrote", "w1-recreated", "w1-forged-release"] {
        assert!(!got.contains(bad), "{bad} reached the vehicle: {err}");
    }
    assert_eq!(
        err.matches(
            "refused a takeover of partition 3 by worker1.i1: worker2.i2's lease still ran"
        )
        .count(),
        3,
        "{err}"
    );
    assert!(
        err.contains("to the vehicles 5 sent, 3 refused; 3 lease takeovers out of turn refused"),
        "{err}"
    );
    // The server's answer comes back asynchronously: wait for it (10 s at most).
    let said = || w1_errors.lock().unwrap().join("\n");
    let end = Instant::now() + Duration::from_secs(10);
    while !said().contains("dronewatt_leases.r.worker2") && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(50));
    }
    let errors = said();
    assert!(
        errors.contains("dronewatt_leases.r.worker2"),
        "the server did not refuse the forged release marker: {errors}"
    );
}
