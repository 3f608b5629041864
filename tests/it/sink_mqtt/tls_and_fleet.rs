//! The MQTT sink over TLS with a login, and two instances splitting one link's vehicles
//! (the broker and subscriber helpers are the parent module's).

use super::*;
use crate::harness::{monitor_udp, Monitor, RunExt};

fn sh(dir: &Path, program: &str, args: &[&str]) {
    Command::new(find(program).unwrap())
        .args(args)
        .current_dir(dir)
        .ok();
}

/// A test CA and a server certificate for 127.0.0.1 signed by it (rustls wants the IP in
/// subjectAltName), and a password file with user `dronewatt`, password `s3cret`.
fn tls_and_login(dir: &Path) {
    let ec = [
        "-newkey",
        "ec",
        "-pkeyopt",
        "ec_paramgen_curve:prime256v1",
        "-nodes",
    ];
    sh(
        dir,
        "openssl",
        &[
            &["req", "-x509"][..],
            &ec,
            &[
                "-keyout",
                "ca.key",
                "-out",
                "ca.pem",
                "-days",
                "2",
                "-subj",
                "/CN=dronewatt test CA",
            ],
        ]
        .concat(),
    );
    sh(
        dir,
        "openssl",
        &[
            &["req"][..],
            &ec,
            &[
                "-keyout",
                "server.key",
                "-out",
                "server.csr",
                "-subj",
                "/CN=127.0.0.1",
            ],
        ]
        .concat(),
    );
    std::fs::write(dir.join("san.ext"), "subjectAltName=IP:127.0.0.1\n").unwrap();
    sh(
        dir,
        "openssl",
        &[
            "x509",
            "-req",
            "-in",
            "server.csr",
            "-CA",
            "ca.pem",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-out",
            "server.pem",
            "-days",
            "2",
            "-extfile",
            "san.ext",
        ],
    );
    sh(
        dir,
        "mosquitto_passwd",
        &["-b", "-c", "passwords", "dronewatt", "s3cret"],
    );
}

#[test]
fn tls_with_a_password_from_the_environment_and_a_wrong_password_never_stalls_the_run() {
    if !have(&["openssl", "mosquitto_passwd"]) {
        return;
    }
    let Some(b) = broker_with(|dir, _| {
        tls_and_login(dir);
        let d = dir.display();
        (
            format!("cafile {d}/ca.pem\ncertfile {d}/server.pem\nkeyfile {d}/server.key\nallow_anonymous false\npassword_file {d}/passwords\n"),
            ["--cafile", &format!("{d}/ca.pem"), "-u", "dronewatt", "-P", "s3cret"].map(String::from).to_vec(),
        )
    }) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let ca = b._dir.path().join("ca.pem");
    let login = format!("[sinks.mqtt]\ntls = true\nca_file = \"{}\"\nusername = \"dronewatt\"\npassword_env = \"DW_TEST_MQTT_PW\"\n", ca.display());
    let cfg = dir.path().join("tls.toml");
    let demo = std::fs::read_to_string(config(dir.path(), &b, "tls", ""))
        .unwrap()
        .replace("[sinks.mqtt]\n", &login);
    std::fs::write(&cfg, demo).unwrap();
    let sub = Subscriber::start(&b, "dw/#");
    let json = dir.path().join("out.jsonl");
    let tlog = root().join("replay/demo.tlog");

    // The right password: everything arrives over TLS.
    let (out, _) = replay_env(&cfg, &tlog, &json, &[("DW_TEST_MQTT_PW", "s3cret")]);
    let estimates = lines_of(&json, "estimate").len();
    let seen = sub.wait_for(Duration::from_secs(20), |s| {
        on(s, "dw/1/estimate").len() >= estimates
    });
    assert_eq!(
        on(&seen, "dw/1/estimate").len(),
        estimates,
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr)
        .contains(" 0 dropped (queue full), 0 undelivered at exit"));

    // A wrong one: refused, retried with back-off, the small queue overflows and counts its
    // drops, and the run still ends with every JSON line written.
    let small = dir.path().join("small-queue.toml");
    std::fs::write(
        &small,
        std::fs::read_to_string(&cfg)
            .unwrap()
            .replace("[sinks.mqtt]\n", "[sinks.mqtt]\nqueue = 100\n"),
    )
    .unwrap();
    let json2 = dir.path().join("refused.jsonl");
    let (out, took) = replay_env(&small, &tlog, &json2, &[("DW_TEST_MQTT_PW", "wrong")]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        lines_of(&json2, "estimate").len(),
        estimates,
        "the other sinks lose nothing"
    );
    assert!(
        stderr.contains("mqtt summary: 0 messages published"),
        "{stderr}"
    );
    let dropped: u64 = stderr
        .split("published, ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("a summary");
    assert!(
        dropped > estimates as u64 / 2,
        "a 100-message queue drops most of {estimates} reports: {dropped}"
    );
    assert!(stderr.contains("retrying in"), "{stderr}");
    eprintln!(
        "refused broker: run ended after {:.1} s (flush timeout included)",
        took.as_secs_f64()
    );
}

/// `monitor` on a free UDP port with `--vehicles ids`, the MQTT sink on as `instance`.
fn monitor_fleet(b: &Broker, dir: &Path, instance: &str, ids: &str) -> (Monitor, u16, PathBuf) {
    let cfg = config(dir, b, instance, "");
    let json = dir.join("out.jsonl");
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dw = Monitor::listening(
        monitor_udp(port)
            .args(["--vehicles", ids, "--json"])
            .arg(&json)
            .arg("--config")
            .arg(&cfg),
        port,
        false,
    );
    (dw, port, json)
}

#[test]
fn two_instances_split_one_links_vehicles_and_each_vehicle_is_published_by_one() {
    let Some(b) = broker() else { return };
    let (da, db) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let sub = Subscriber::start(&b, "dw/#");
    // The topology of the README: one link fanned out (here by the peer itself, as
    // mavlink-router would) to two instances, vehicles 1-2 and 3, one broker.
    let (a, pa, ja) = monitor_fleet(&b, da.path(), "gcs-a", "1-2");
    let (c, pc, jc) = monitor_fleet(&b, db.path(), "gcs-b", "3");
    let vehicles = r#"[{"id": 1, "power_w": 300, "send_s": 6}, {"id": 2, "power_w": 500, "send_s": 6}, {"id": 3, "power_w": 700, "send_s": 6}]"#;
    let peer = Command::new(root().join(".venv-py/bin/python"))
        .arg(root().join("tests/peers/fleet.py"))
        .args([
            "--to",
            &format!("udpout:127.0.0.1:{pa}"),
            "--to",
            &format!("udpout:127.0.0.1:{pc}"),
            "--vehicles",
            vehicles,
        ])
        .output()
        .expect("run .venv-py/bin/python (make setup creates it)");
    assert!(
        peer.status.success(),
        "peer failed: {}",
        String::from_utf8_lossy(&peer.stderr)
    );
    for dw in [a, c] {
        let (status, err) = dw.stop();
        assert!(status.success(), "dronewatt exited with {status}: {err}");
    }
    let (ea, ec) = (lines_of(&ja, "estimate"), lines_of(&jc, "estimate"));
    let seen = sub.wait_for(Duration::from_secs(20), |s| {
        ["1", "2", "3"]
            .iter()
            .map(|v| on(s, &format!("dw/{v}/estimate")).len())
            .sum::<usize>()
            >= ea.len() + ec.len()
            && ["gcs-a", "gcs-b"].iter().all(|i| {
                on(s, &format!("dw/status/{i}"))
                    .last()
                    .is_some_and(|m| m.payload == "offline")
            })
    });
    let ids = |lines: &[String]| -> std::collections::BTreeSet<u64> {
        lines
            .iter()
            .map(|l| {
                serde_json::from_str::<serde_json::Value>(l).unwrap()["system_id"]
                    .as_u64()
                    .unwrap()
            })
            .collect()
    };
    assert_eq!(
        ids(&ea).into_iter().collect::<Vec<_>>(),
        vec![1, 2],
        "instance a watches 1-2"
    );
    assert_eq!(
        ids(&ec).into_iter().collect::<Vec<_>>(),
        vec![3],
        "instance b watches 3"
    );
    // Each vehicle's estimate topic is exactly what its one instance wrote, byte for byte:
    // nothing from the other instance, nothing twice.
    for (v, mine) in [(1, &ea), (2, &ea), (3, &ec)] {
        let want: Vec<String> = mine
            .iter()
            .filter(|l| l.contains(&format!("\"system_id\":{v},")))
            .cloned()
            .collect();
        let got: Vec<String> = on(&seen, &format!("dw/{v}/estimate"))
            .into_iter()
            .map(|m| m.payload)
            .collect();
        assert!(want.len() > 30, "vehicle {v}: {} estimates", want.len());
        assert_eq!(
            got, want,
            "vehicle {v}'s estimates on the broker are its instance's"
        );
        assert!(
            on(&seen, &format!("dw/{v}/state")).len() >= 3,
            "vehicle {v}: retained state published"
        );
    }
    for i in ["gcs-a", "gcs-b"] {
        let status: Vec<String> = on(&seen, &format!("dw/status/{i}"))
            .into_iter()
            .map(|m| m.payload)
            .collect();
        assert_eq!(status, ["online", "offline"], "instance {i}");
    }
}
