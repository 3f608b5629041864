//! The MQTT sink against a real broker: Debian's Mosquitto (installed by
//! `scripts/setup-mosquitto.sh`), started per test on a free loopback port with a throwaway
//! config, and its own `mosquitto_sub` as the independent subscriber.
//!
//! - a replay flat out: every estimate and alert arrives, byte for byte the `--json` lines;
//!   the retained state is the last report's and the retained status `offline`;
//! - SIGKILL: the broker publishes the Last Will, retained `offline`;
//! - a long flight replayed flat out: every message arrives, none dropped (prints messages/s);
//! - two instances splitting one link's vehicles (`--vehicles`): each vehicle's topics come
//!   from exactly one of them.
//!
//! Without the broker the tests skip with a message, except under `CI=true`, where they fail.

use crate::harness::{dronewatt, monitor_udp, Monitor, RunExt};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A binary on PATH or in /usr/sbin (where Debian puts `mosquitto`).
fn find(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain([PathBuf::from("/usr/sbin")])
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

/// A Mosquitto broker of our own on 127.0.0.1, killed when dropped.
struct Broker {
    child: Child,
    port: u16,
    /// What `mosquitto_sub` and `mosquitto_pub` need beyond host and port (TLS, login).
    client_args: Vec<String>,
    _dir: tempfile::TempDir,
}

impl Drop for Broker {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Start a broker, or `None` (the test skips) when Mosquitto is not installed and CI is
/// not set.
fn broker() -> Option<Broker> {
    broker_with(|_, _| (String::new(), Vec::new()))
}

/// Skip (or under CI=true, fail) when one of these programs is missing.
fn have(programs: &[&str]) -> bool {
    let missing: Vec<&str> = programs
        .iter()
        .copied()
        .filter(|p| find(p).is_none())
        .collect();
    if missing.is_empty() {
        return true;
    }
    let why = format!(
        "{} not installed (run scripts/setup-mosquitto.sh)",
        missing.join(", ")
    );
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("{why}");
    }
    eprintln!("SKIPPED: {why}");
    false
}

/// A broker whose listener gets the config lines `listener(dir, port)` returns, with the
/// client arguments it returns too.
fn broker_with(listener: impl FnOnce(&Path, u16) -> (String, Vec<String>)) -> Option<Broker> {
    if !have(&["mosquitto", "mosquitto_sub", "mosquitto_pub"]) {
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let (extra, client_args) = listener(dir.path(), port);
    let conf = dir.path().join("mosquitto.conf");
    // No queue limits: a subscriber that falls behind a flat-out replay must get everything.
    // `user root` keeps a broker started as root able to read the test's files (no effect
    // otherwise); `allow_anonymous` may be overridden by `extra`.
    let anonymous = if extra.contains("allow_anonymous") {
        ""
    } else {
        "allow_anonymous true\n"
    };
    std::fs::write(
        &conf,
        format!("user root\nper_listener_settings false\npersistence false\nmax_queued_messages 0\nmax_inflight_messages 0\n{anonymous}listener {port} 127.0.0.1\n{extra}"),
    )
    .unwrap();
    let child = Command::new(find("mosquitto").unwrap())
        .arg("-c")
        .arg(&conf)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let b = Broker {
        child,
        port,
        client_args,
        _dir: dir,
    };
    let until = Instant::now() + Duration::from_secs(10);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(Instant::now() < until, "mosquitto did not listen on {port}");
        std::thread::sleep(Duration::from_millis(50));
    }
    Some(b)
}

/// One message a subscriber saw.
#[derive(Debug, Clone)]
struct Msg {
    retained: bool,
    qos: u8,
    topic: String,
    payload: String,
}

fn parse(line: &str) -> Option<Msg> {
    let mut it = line.splitn(4, ' ');
    let retained = it.next()? == "1";
    let qos = it.next()?.parse().ok()?;
    Some(Msg {
        retained,
        qos,
        topic: it.next()?.to_string(),
        payload: it.next().unwrap_or("").to_string(),
    })
}

/// `mosquitto_sub` on `topic`, every message collected as it comes.
struct Subscriber {
    child: Child,
    seen: Arc<Mutex<Vec<Msg>>>,
}

impl Subscriber {
    fn start(b: &Broker, topic: &str) -> Subscriber {
        let mut child = Command::new(find("mosquitto_sub").unwrap())
            .args([
                "-h",
                "127.0.0.1",
                "-p",
                &b.port.to_string(),
                "-q",
                "1",
                "-F",
                "%r %q %t %p",
                "-t",
                topic,
            ])
            .args(&b.client_args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let out = child.stdout.take().unwrap();
        let seen = Arc::new(Mutex::new(Vec::new()));
        let s = seen.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if let Some(m) = parse(&line) {
                    s.lock().unwrap().push(m);
                }
            }
        });
        let sub = Subscriber { child, seen };
        // Subscribed once a probe published after the start comes back.
        let probe = format!("{}/probe", topic.trim_end_matches("/#"));
        let until = Instant::now() + Duration::from_secs(10);
        while !sub.seen.lock().unwrap().iter().any(|m| m.topic == probe) {
            assert!(Instant::now() < until, "mosquitto_sub never subscribed");
            pub_once(b, &probe, "ready");
            std::thread::sleep(Duration::from_millis(100));
        }
        sub
    }

    /// Wait (at most `limit`) until `done` holds for what was seen; return it all.
    fn wait_for(&self, limit: Duration, done: impl Fn(&[Msg]) -> bool) -> Vec<Msg> {
        let until = Instant::now() + limit;
        loop {
            let seen = self.seen.lock().unwrap().clone();
            if done(&seen) || Instant::now() > until {
                return seen;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Subscriber {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn pub_once(b: &Broker, topic: &str, payload: &str) {
    let ok = Command::new(find("mosquitto_pub").expect("mosquitto_pub"))
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &b.port.to_string(),
            "-t",
            topic,
            "-m",
            payload,
        ])
        .args(&b.client_args)
        .status()
        .unwrap();
    assert!(ok.success());
}

/// The retained messages on `topics` now: a fresh subscriber, which the broker sends them
/// to at once.
fn retained(b: &Broker, topics: &[&str]) -> Vec<Msg> {
    let mut cmd = Command::new(find("mosquitto_sub").unwrap());
    cmd.args([
        "-h",
        "127.0.0.1",
        "-p",
        &b.port.to_string(),
        "-F",
        "%r %q %t %p",
        "--retained-only",
        "-W",
        "2",
    ])
    .args(&b.client_args);
    for t in topics {
        cmd.args(["-t", t]);
    }
    let out = cmd.out();
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(parse)
        .collect()
}

/// A config with the MQTT sink on, to this broker, under prefix `dw`.
fn config(dir: &Path, b: &Broker, instance: &str, extra: &str) -> PathBuf {
    let path = dir.join("mqtt.toml");
    std::fs::write(&path, format!("{extra}\n[sinks.mqtt]\nenabled = true\nport = {}\nprefix = \"dw\"\ninstance = \"{instance}\"\n", b.port)).unwrap();
    path
}

fn replay(cfg: &Path, file: &Path, json: &Path) -> (std::process::Output, Duration) {
    replay_env(cfg, file, json, &[])
}

fn replay_env(
    cfg: &Path,
    file: &Path,
    json: &Path,
    env: &[(&str, &str)],
) -> (std::process::Output, Duration) {
    let t0 = Instant::now();
    let out = dronewatt()
        .args(["replay", "--speed", "max", "-q", "--json"])
        .arg(json)
        .arg("--config")
        .arg(cfg)
        .arg(file)
        .envs(env.iter().copied())
        .out();
    let took = t0.elapsed();
    assert!(
        out.status.success(),
        "dronewatt failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    (out, took)
}

/// The `--json` lines of one type, as written.
fn lines_of(json: &Path, kind: &str) -> Vec<String> {
    let tag = format!("{{\"type\":\"{kind}\"");
    std::fs::read_to_string(json)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with(&tag))
        .map(str::to_string)
        .collect()
}

fn on(seen: &[Msg], topic: &str) -> Vec<Msg> {
    seen.iter().filter(|m| m.topic == topic).cloned().collect()
}

#[test]
fn a_replay_publishes_every_estimate_and_alert_the_retained_state_and_status() {
    let Some(b) = broker() else { return };
    let dir = tempfile::tempdir().unwrap();
    // The demo (its mission margin and pack alerts) without its dashboard; paths in the
    // config are relative to it, so the copy names the repository's.
    let vehicles = format!(
        "calibrated_profile = \"{}/",
        root().join("config/vehicles").display()
    );
    let demo = std::fs::read_to_string(root().join("config/demo.toml"))
        .unwrap()
        .replace("enabled = true", "enabled = false")
        .replace("calibrated_profile = \"vehicles/", &vehicles);
    let cfg = config(dir.path(), &b, "test", &demo);
    let sub = Subscriber::start(&b, "dw/#");
    let json = dir.path().join("out.jsonl");
    let (out, _) = replay(&cfg, &root().join("replay/demo.tlog"), &json);
    let estimates = lines_of(&json, "estimate");
    let alerts = lines_of(&json, "alert");
    assert!(
        estimates.len() > 100 && !alerts.is_empty(),
        "{} estimates, {} alerts",
        estimates.len(),
        alerts.len()
    );

    let seen = sub.wait_for(Duration::from_secs(20), |s| {
        on(s, "dw/1/estimate").len() >= estimates.len()
            && on(s, "dw/status/test")
                .last()
                .is_some_and(|m| m.payload == "offline")
    });
    // Every estimate, in order, byte for byte the JSON line; QoS 0, not retained.
    let got = on(&seen, "dw/1/estimate");
    assert_eq!(got.len(), estimates.len(), "estimates received vs written");
    for (i, (m, line)) in got.iter().zip(&estimates).enumerate() {
        assert_eq!(&m.payload, line, "estimate {i}");
        assert_eq!((m.qos, m.retained), (0, false), "estimate {i}");
    }
    // Every alert event, QoS 1.
    let got = on(&seen, "dw/1/alert");
    assert_eq!(
        got.iter().map(|m| &m.payload).collect::<Vec<_>>(),
        alerts.iter().collect::<Vec<_>>()
    );
    assert!(got.iter().all(|m| m.qos == 1));
    // Nothing under any other vehicle: the tlog's vehicle is system 1.
    assert!(seen.iter().all(|m| !m.topic.starts_with("dw/")
        || m.topic.starts_with("dw/1/")
        || m.topic.starts_with("dw/status/")
        || m.topic == "dw/probe"));
    // State: about once per second of flight (10 reports), plus the alert's.
    let states = on(&seen, "dw/1/state");
    assert!(
        states.len() >= estimates.len() / 12
            && states.len() <= estimates.len() / 10 + alerts.len() + 2,
        "{} states for {} estimates",
        states.len(),
        estimates.len()
    );
    // Status: online, then offline on the clean exit.
    let status: Vec<String> = on(&seen, "dw/status/test")
        .into_iter()
        .map(|m| m.payload)
        .collect();
    assert_eq!(status, ["online", "offline"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("0 dropped (queue full), 0 undelivered at exit, 0 reports missed"),
        "{stderr}"
    );

    // What a dashboard starting now sees: the last state and `offline`, retained.
    let r = retained(&b, &["dw/1/state", "dw/status/test"]);
    let state = r
        .iter()
        .find(|m| m.topic == "dw/1/state")
        .expect("a retained state");
    let status = r
        .iter()
        .find(|m| m.topic == "dw/status/test")
        .expect("a retained status");
    assert!(state.retained && status.retained && status.payload == "offline");
    let state: serde_json::Value = serde_json::from_str(&state.payload).unwrap();
    let last: serde_json::Value = serde_json::from_str(estimates.last().unwrap()).unwrap();
    assert_eq!(state["type"], "state");
    assert_eq!(
        state["t"], last["t"],
        "the retained state is the last report's"
    );
    assert_eq!(state["energy_used_wh"], last["energy_used_wh"]);
    assert_eq!(state["remaining_wh"], last["remaining_wh"]);
    // The demo's alerts raised and not cleared at the end: the state says so.
    let mut standing = std::collections::BTreeMap::new();
    for a in &alerts {
        let a: serde_json::Value = serde_json::from_str(a).unwrap();
        standing.insert(
            a["rule"].as_str().unwrap().to_string(),
            a["state"] == "raised",
        );
    }
    let mut want: Vec<&String> = standing
        .iter()
        .filter(|(_, up)| **up)
        .map(|(r, _)| r)
        .collect();
    let mut got: Vec<String> = state["active_alerts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    want.sort();
    got.sort();
    assert!(
        want.iter().any(|r| r.as_str() == "energy_low"),
        "the demo's energy warning stands at the end: {want:?}"
    );
    assert_eq!(got.iter().collect::<Vec<_>>(), want);
}

#[test]
fn the_last_will_says_offline_when_dronewatt_is_killed() {
    let Some(b) = broker() else { return };
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path(), &b, "victim", "");
    let udp = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dw = Monitor::spawn(monitor_udp(udp).arg("--config").arg(&cfg));
    let until = Instant::now() + Duration::from_secs(20);
    let status = || {
        retained(&b, &["dw/status/victim"])
            .into_iter()
            .next()
            .map(|m| (m.retained, m.payload))
    };
    while status() != Some((true, "online".into())) {
        assert!(
            Instant::now() < until,
            "dronewatt never announced itself online"
        );
    }
    dw.kill(); // SIGKILL: no chance to say goodbye
    let until = Instant::now() + Duration::from_secs(20);
    loop {
        match status() {
            Some((true, p)) if p == "offline" => break,
            s => assert!(Instant::now() < until, "no Last Will: status {s:?}"),
        }
    }
}

#[test]
fn a_long_flight_flat_out_is_published_without_drops() {
    let Some(b) = broker() else { return };
    let dir = tempfile::tempdir().unwrap();
    let tlog = dir.path().join("long.tlog");
    dronewatt()
        .args(["simulate", "--out"])
        .arg(&tlog)
        .args(["--leg-m", "4000", "--hover-s", "120"])
        .ok();
    let cfg = config(dir.path(), &b, "long", "");
    let sub = Subscriber::start(&b, "dw/#");
    let json = dir.path().join("out.jsonl");
    let (out, took) = replay(&cfg, &tlog, &json);
    let estimates = lines_of(&json, "estimate").len();
    let seen = sub.wait_for(Duration::from_secs(60), |s| {
        on(s, "dw/1/estimate").len() >= estimates
    });
    let got = on(&seen, "dw/1/estimate").len();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(estimates > 3000, "a long flight: {estimates} estimates");
    assert_eq!(got, estimates, "every estimate of the flight arrives");
    assert!(
        stderr.contains(" 0 dropped (queue full), 0 undelivered at exit"),
        "{stderr}"
    );
    let published = seen.iter().filter(|m| m.topic.starts_with("dw/1/")).count();
    eprintln!(
        "long flight: {estimates} reports, {published} messages in {:.2} s whole-process flat out: {:.0} messages/s",
        took.as_secs_f64(),
        published as f64 / took.as_secs_f64()
    );
}

/// Run a command in `dir`, asserting it succeeds.
// The TLS login and the fleet split, with their own helpers.
mod links;
mod tls_and_fleet;
