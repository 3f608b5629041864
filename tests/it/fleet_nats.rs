//! The fleet on NATS JetStream, with real parts: Debian's `nats-server -js` on a free
//! loopback port with a throwaway store (`scripts/setup-nats.sh` installs it), `dronewatt
//! gateway udpin:… --nats …`, workers `dronewatt monitor --nats … --data-dir off --json
//! FILE`, and a 12-vehicle pymavlink fleet (`tests/peers/fleet.py`) over UDP.
//!
//! Without nats-server the tests skip with a message, except under `CI=true`, where they
//! fail.

use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::harness::{dronewatt, Monitor};
use crate::link_common::{free_tcp_port, free_udp_port};

/// A nats-server run for one test, killed when dropped.
pub(crate) struct Server {
    child: Child,
    pub(crate) url: String,
    port: u16,
    /// The command line it was started with (a restart runs it again on the same store).
    cmd: Vec<std::ffi::OsString>,
    _dir: tempfile::TempDir,
}

impl Server {
    /// Kill the server (SIGKILL: JetStream keeps what it had synced), and start it again on
    /// the same port and store.
    pub(crate) fn restart(&mut self, down: Duration) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        std::thread::sleep(down);
        self.child = Command::new(&self.cmd[0])
            .args(&self.cmd[1..])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        wait_port(self.port);
    }
}

fn wait_port(port: u16) {
    let start = Instant::now();
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "nats-server never listened"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn nats_server_bin() -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain([
            "/usr/sbin".into(),
            "/usr/bin".into(),
            "/usr/local/bin".into(),
        ])
        .map(|d: PathBuf| d.join("nats-server"))
        .find(|p| p.is_file())
}

/// Start nats-server with JetStream (and `config`'s text as its config file, when given),
/// or `None` (the test skips) without it, unless CI=true.
pub(crate) fn server(config: Option<&str>) -> Option<Server> {
    let Some(bin) = nats_server_bin() else {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true"),
            "nats-server is not installed (scripts/setup-nats.sh)"
        );
        eprintln!("skipped: nats-server is not installed (scripts/setup-nats.sh)");
        return None;
    };
    let dir = tempfile::tempdir().unwrap();
    let port = free_tcp_port();
    let mut cmd: Vec<std::ffi::OsString> = vec![bin.into()];
    for a in ["-js", "-a", "127.0.0.1", "-p", &port.to_string(), "-sd"] {
        cmd.push(a.into());
    }
    cmd.push(dir.path().join("js").into());
    if let Some(text) = config {
        let f = dir.path().join("nats.conf");
        std::fs::write(&f, text).unwrap();
        cmd.push("-c".into());
        cmd.push(f.into());
    }
    let child = Command::new(&cmd[0])
        .args(&cmd[1..])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_port(port);
    Some(Server {
        child,
        url: format!("nats://127.0.0.1:{port}"),
        port,
        cmd,
        _dir: dir,
    })
}

/// Every JSON line of `path` that parses (a worker killed mid-write leaves half a line).
pub(crate) fn lines(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

/// Real estimates (with model output) of vehicle `sys` in `lines`: (t, energy used).
pub(crate) fn estimates(lines: &[Value], sys: u64) -> Vec<(f64, f64)> {
    let mut v: Vec<(f64, f64)> = lines
        .iter()
        .filter(|l| l["type"] == "estimate" && l["system_id"].as_u64() == Some(sys))
        .filter(|l| l["models"].as_object().is_some_and(|m| !m.is_empty()))
        .filter_map(|l| Some((l["t"].as_f64()?, l["energy_used_wh"].as_f64()?)))
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

/// How many times each (vehicle, rule) alert was raised in `lines`.
pub(crate) fn raised(lines: &[Value]) -> std::collections::BTreeMap<(u64, String), usize> {
    let mut m = std::collections::BTreeMap::new();
    for l in lines
        .iter()
        .filter(|l| l["type"] == "alert" && l["state"] == "raised")
    {
        let key = (
            l["system_id"].as_u64().unwrap_or(0),
            l["rule"].as_str().unwrap_or("").to_string(),
        );
        *m.entry(key).or_insert(0) += 1;
    }
    m
}

pub(crate) fn python() -> Command {
    Command::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.venv-py/bin/python"))
}

/// Publish a STATUSTEXT "rogue" for vehicle `sys` as a worker that holds no lease.
fn rogue_statustext(url: &str, sys: u8) {
    let msg = dronewatt::MavMessage::STATUSTEXT(dronewatt::dialect::STATUSTEXT_DATA {
        severity: dronewatt::dialect::MavSeverity::MAV_SEVERITY_CRITICAL,
        text: "rogue".into(),
        id: 0,
        chunk_seq: 0,
    });
    let header = mavlink::MavHeader {
        system_id: sys.into(),
        component_id: 191,
        sequence: 0,
    };
    let mut frame = Vec::new();
    mavlink::write_versioned_msg(&mut frame, mavlink::MavlinkVersion::V2, header, &msg).unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let c = async_nats::connect(url).await.unwrap();
        for _ in 0..3 {
            c.publish(
                format!("dronewatt.to.anon.rogue.0.{sys}"),
                frame.clone().into(),
            )
            .await
            .unwrap();
        }
        c.flush().await.unwrap();
    });
}

/// A NATS viewer: what is published on `subject` (a wildcard) until `stop` is set, as
/// (subject, JSON) pairs.
fn viewer(
    url: &str,
    subject: &str,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> std::thread::JoinHandle<Vec<(String, Value)>> {
    let (url, subject) = (url.to_string(), subject.to_string());
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let h = std::thread::spawn(move || {
        let rt = tokio::runtime::Runtime::new().unwrap();
        rt.block_on(async {
            use futures_util::StreamExt;
            let c = async_nats::connect(url.as_str()).await.unwrap();
            let mut sub = c.subscribe(subject).await.unwrap();
            c.flush().await.unwrap();
            ready_tx.send(()).unwrap();
            let mut got = Vec::new();
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                if let Ok(Some(m)) =
                    tokio::time::timeout(Duration::from_millis(200), sub.next()).await
                {
                    if let Ok(v) = serde_json::from_slice(&m.payload) {
                        got.push((m.subject.to_string(), v));
                    }
                }
            }
            got
        })
    });
    ready_rx.recv().unwrap();
    h
}

pub(crate) fn worker(url: &str, json: &Path) -> Monitor {
    Monitor::spawn(
        dronewatt()
            .args([
                "monitor",
                "--nats",
                url,
                "--data-dir",
                "off",
                "-q",
                "--json",
            ])
            .arg(json)
            .env("RUST_LOG", "dronewatt=info"),
    )
}

/// `dronewatt gateway udpin:127.0.0.1:PORT --nats URL`, once it listens.
pub fn gateway(url: &str, port: u16) -> Monitor {
    let mut g = Monitor::spawn(
        dronewatt()
            .args(["gateway", &format!("udpin:127.0.0.1:{port}"), "--nats", url])
            .env("RUST_LOG", "dronewatt=info"),
    );
    g.wait_listening(port, false);
    g
}

/// The pymavlink fleet (`tests/peers/fleet.py`) flying `vehicles` (its JSON list) at `port`.
pub fn fly_fleet(port: u16, vehicles: &str) -> std::process::Child {
    python()
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/fleet.py"))
        .args(["--to", &format!("udpout:127.0.0.1:{port}")])
        .args(["--vehicles", vehicles])
        .stdout(Stdio::null())
        .spawn()
        .expect("run .venv-py/bin/python (make setup creates it)")
}

#[test]
fn a_worker_killed_mid_flight_hands_its_vehicles_over_with_their_energy() {
    let Some(nats) = server(None) else { return };
    let dir = tempfile::tempdir().unwrap();
    let (gw_port, single_port) = (free_udp_port(), free_udp_port());
    let gateway = gateway(&nats.url, gw_port);
    let (ja, jb, js) = (
        dir.path().join("a.jsonl"),
        dir.path().join("b.jsonl"),
        dir.path().join("single.jsonl"),
    );
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let view = viewer(&nats.url, "dronewatt.*.>", stop.clone());
    let a = worker(&nats.url, &ja);
    std::thread::sleep(Duration::from_secs(2));
    let b = worker(&nats.url, &jb);
    let single = Monitor::listening(
        dronewatt()
            .args([
                "monitor",
                &format!("udpin:127.0.0.1:{single_port}"),
                "-q",
                "--json",
            ])
            .arg(&js),
        single_port,
        false,
    );
    // Let the two workers split the partitions (a lease tick or two).
    std::thread::sleep(Duration::from_secs(3));
    let vehicles: Vec<Value> = (1..=12)
        .map(|id| serde_json::json!({"id": id, "power_w": 200 + 40 * id, "send_s": 40}))
        .collect();
    let fleet = python()
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/fleet.py"))
        .args(["--to", &format!("udpout:127.0.0.1:{gw_port}")])
        .args(["--to", &format!("udpout:127.0.0.1:{single_port}")])
        .args(["--vehicles", &Value::Array(vehicles).to_string()])
        .stdout(Stdio::piped())
        .spawn()
        .expect("run .venv-py/bin/python (make setup creates it)");
    std::thread::sleep(Duration::from_secs(15));
    a.kill();
    let killed = std::time::SystemTime::now();
    // A client that holds no lease tries to talk to vehicle 3: the gateway refuses it.
    rogue_statustext(&nats.url, 3);
    let out = fleet.wait_with_output().unwrap();
    assert!(out.status.success(), "fleet.py failed");
    std::thread::sleep(Duration::from_secs(3));
    let (sb, eb) = b.stop();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let seen = view.join().unwrap();
    let (_, eg) = gateway.stop();
    let (ss, es) = single.stop();
    assert!(sb.success() && ss.success(), "worker: {eb}\nsingle: {es}");
    let ctx = format!("worker b: {eb}\ngateway: {eg}");
    let workers: Vec<Value> = lines(&ja).into_iter().chain(lines(&jb)).collect();
    let one = lines(&js);
    assert!(
        eb.contains("took partition") && eb.contains("from worker"),
        "no takeover: {ctx}"
    );
    // The vehicles came back from their checkpoints (energy, pack, alerts), and only the
    // stream's last seconds were replayed.
    assert!(
        eb.contains("restored from the fleet's checkpoint")
            && eb.contains("replaying from stream sequence")
            && !eb.contains("does not read")
            && !eb.contains("another card"),
        "not restored from the checkpoints: {ctx}"
    );
    let (mut worst_hole, mut worst_diff) = (0.0f64, 0.0f64);
    for sys in 1..=12u64 {
        let w = estimates(&workers, sys);
        let s = estimates(&one, sys);
        assert!(
            !w.is_empty() && !s.is_empty(),
            "vehicle {sys} never estimated: {ctx}"
        );
        // Estimated throughout, with no hole over 15 s (the gateway's clock).
        let hole = w.windows(2).map(|p| p[1].0 - p[0].0).fold(0.0, f64::max);
        assert!(hole <= 15.0, "vehicle {sys}: a {hole:.1} s hole: {ctx}");
        let span = w.last().unwrap().0 - w[0].0;
        assert!(
            span > 30.0,
            "vehicle {sys}: estimated over {span:.1} s only: {ctx}"
        );
        // Its energy at the end as one process had it, within 2 %.
        let (ew, es) = (w.last().unwrap().1, s.last().unwrap().1);
        worst_hole = worst_hole.max(hole);
        worst_diff = worst_diff.max((ew - es).abs() / es.max(1e-9));
        assert!(
            (ew - es).abs() <= 0.02 * es,
            "vehicle {sys}: {ew:.3} Wh over NATS, {es:.3} Wh in one process: {ctx}"
        );
    }
    eprintln!(
        "failover: longest hole {worst_hole:.2} s, worst energy difference {:.3} %",
        100.0 * worst_diff
    );
    eprintln!("worker a killed at {killed:?}");
    for l in eb.lines().filter(|l| {
        l.contains("took partition")
            || l.contains("gave partition")
            || l.contains("NATS: partition")
            || l.contains("restored from")
    }) {
        eprintln!("worker b: {l}");
    }
    // The workers published their estimates and alerts on NATS too, each on its vehicle's
    // partition's subject, as many as their files hold (the killed worker's last lines
    // may not have gone out), and no alert twice.
    let nats_lines: Vec<Value> = seen.iter().map(|(_, v)| v.clone()).collect();
    for (subject, v) in &seen {
        let sys = v["system_id"].as_u64().unwrap_or(0);
        let part = (sys + 17 * v["network"].as_u64().unwrap_or(0)) % 16;
        let kind = if v["type"] == "alert" {
            "alerts"
        } else {
            "estimates"
        };
        assert_eq!(subject, &format!("dronewatt.{kind}.{part}.0.{sys}"), "{v}");
    }
    for sys in 1..=12u64 {
        let (on_nats, in_files) = (
            estimates(&nats_lines, sys).len(),
            estimates(&workers, sys).len(),
        );
        assert!(
            on_nats * 10 >= in_files * 9 && on_nats <= in_files,
            "vehicle {sys}: {on_nats} estimates on NATS, {in_files} in the workers' files"
        );
    }
    assert_eq!(
        raised(&nats_lines),
        raised(&workers),
        "alerts on NATS and in the files"
    );
    eprintln!("on NATS: {} estimates and alerts", seen.len());
    // No alert raised twice for one cause: never more often than the one process raised it.
    let (rw, rs) = (raised(&workers), raised(&one));
    for (k, n) in &rw {
        assert!(
            *n <= rs.get(k).copied().unwrap_or(0).max(1),
            "{k:?} raised {n} times over NATS, {:?} in one process: {ctx}",
            rs.get(k)
        );
    }
    // The rogue's frame never reached the vehicle, and the gateway said why.
    assert!(
        !String::from_utf8_lossy(&out.stdout).contains("rogue"),
        "{ctx}"
    );
    assert!(eg.contains("refused a frame for vehicle 0:3"), "{ctx}");
    // What the workers send the vehicles reached them through the gateway.
    let heard: Value = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
    // Every vehicle heard dronewatt's estimates (NAMED_VALUE_FLOAT, sent as the vehicle)
    // from the worker that held it: workers' frames, through the gateway, on its link.
    let back: Vec<u64> = (1..=12)
        .filter(|s| {
            heard["heard"].as_object().is_some_and(|h| {
                h.iter().any(|(k, v)| {
                    k.starts_with(&format!("{s},"))
                        && v["values"].as_object().is_some_and(|m| !m.is_empty())
                })
            })
        })
        .collect();
    assert_eq!(back.len(), 12, "heard back: {back:?}\n{ctx}");
}

#[test]
fn nats_unreachable_is_retried_with_backoff_then_a_clear_error() {
    if nats_server_bin().is_none() && std::env::var("CI").map_or(true, |v| v != "true") {
        eprintln!("skipped: nats-server is not installed");
        return;
    }
    let port = free_tcp_port();
    let out = dronewatt()
        .args([
            "monitor",
            "--nats",
            &format!("nats://127.0.0.1:{port}"),
            "-q",
            "--data-dir",
            "off",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("retry 1/") && err.contains("cannot connect after"),
        "{err}"
    );
}

#[test]
fn a_client_without_credentials_is_refused_and_a_stream_of_another_layout_named() {
    let conf = "authorization { users = [ {user: gw, password: s3cret} ] }\n";
    let Some(nats) = server(Some(conf)) else {
        return;
    };
    let out = dronewatt()
        .args(["monitor", "--nats", &nats.url, "-q", "--data-dir", "off"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.to_lowercase().contains("authorization"), "{err}");
    // With the user's password (a private file), the gateway gets in, and refuses a stream
    // made with another layout, by name.
    let dir = tempfile::tempdir().unwrap();
    let pw = dir.path().join("pw");
    std::fs::write(&pw, "s3cret\n").unwrap();
    std::fs::set_permissions(
        &pw,
        <std::fs::Permissions as std::os::unix::fs::PermissionsExt>::from_mode(0o600),
    )
    .unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let c = async_nats::ConnectOptions::with_user_and_password("gw".into(), "s3cret".into())
            .connect(nats.url.as_str())
            .await
            .unwrap();
        let js = async_nats::jetstream::new(c);
        js.create_stream(async_nats::jetstream::stream::Config {
            name: "DRONEWATT_FRAMES".into(),
            subjects: vec!["somebody.else.>".into()],
            ..Default::default()
        })
        .await
        .unwrap();
    });
    let port = free_udp_port();
    let out = dronewatt()
        .args([
            "gateway",
            &format!("udpin:127.0.0.1:{port}"),
            "--nats",
            &nats.url,
        ])
        .args(["--nats-user", "gw", "--nats-password-file"])
        .arg(&pw)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("DRONEWATT_FRAMES") && err.contains("another layout"),
        "{err}"
    );
}

/// Off loopback, a worker and a gateway refuse to start without credentials and TLS, before
/// any connection (no server needed: the address is never dialled).
#[test]
fn off_loopback_nats_needs_credentials_and_tls() {
    for args in [
        vec![
            "monitor",
            "--nats",
            "nats://10.255.255.1:4222",
            "-q",
            "--data-dir",
            "off",
        ],
        vec![
            "gateway",
            "udpin:127.0.0.1:0",
            "--nats",
            "nats://10.255.255.1:4222",
        ],
    ] {
        let out = dronewatt().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}: {err}");
        assert!(
            err.contains("needs credentials") && err.contains("TLS"),
            "{args:?}: {err}"
        );
    }
}
