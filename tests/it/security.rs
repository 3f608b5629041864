//! Security over real sockets on 127.0.0.1.
//!
//! - MAVLink 2 signing against pymavlink's own signing, both ways (`tests/peers/vehicle.py`
//!   signs with `setup_signing`, and then also verifies and drops what fails): the right key
//!   is accepted and pymavlink accepts what dronewatt signs; a wrong key is dropped and
//!   counted (and pymavlink rejects dronewatt's frames); replayed frames are dropped; with
//!   `require_signing` unsigned frames are refused; a key file others can read is refused.
//! - The dashboard with a raw HTTP/1.1 client (a plain `TcpStream`): headers, read-only,
//!   request size, the token beyond loopback, the connection limit; and in headless
//!   Chromium with a token.

use crate::harness::{dronewatt, Monitor, RunExt};
use crate::link_common;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::Command;
use std::time::Duration;

use link_common::*;

const KEY_HEX: &str = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";
const OTHER_KEY_HEX: &str = "ff0102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";

/// A config with the key in a private file beside it (written into a temp dir that lives as
/// long as the returned guard).
fn signed_config(require: bool) -> (tempfile::TempDir, String) {
    let dir = tempfile::tempdir().unwrap();
    let key = dir.path().join("link.key");
    std::fs::write(&key, format!("{KEY_HEX}\n")).unwrap();
    #[cfg(unix)]
    std::fs::set_permissions(&key, std::os::unix::fs::PermissionsExt::from_mode(0o600)).unwrap();
    let cfg = format!(
        "[link]\nsigning_key_file = \"{}\"\nrequire_signing = {require}\n",
        key.display()
    );
    (dir, cfg)
}

#[test]
fn a_vehicle_signing_with_the_right_key_is_heard_and_verifies_our_replies() {
    let (_dir, cfg) = signed_config(true);
    let r = fly(&cfg, false, r#"[{"send_s": 4}]"#, &["--sign-key", KEY_HEX]);
    check_consistent(&r);
    let frames = r.peer["frames"].as_u64().unwrap();
    assert_eq!(
        (r.count("frames_ok"), r.count("signed_ok")),
        (frames, frames),
        "{}",
        r.summary
    );
    assert_eq!(
        (
            r.count("signature_bad"),
            r.count("signature_replay"),
            r.count("unsigned_refused")
        ),
        (0, 0, 0)
    );
    r.assert_estimates(4.0, 1);
    // pymavlink with a key drops unsigned or badly signed frames: it heard our estimates,
    // and every frame of ours it checked was good.
    let sig = &r.peer["signing"];
    assert!(r.peer["named_values"].as_u64().unwrap() >= 5, "{}", r.peer);
    assert!(
        sig["goodsig"].as_u64().unwrap() >= 5 && sig["badsig"] == 0 && sig["unsigned"] == 0,
        "{}",
        r.peer
    );
}

#[test]
fn a_wrong_key_is_dropped_and_counted_both_ways() {
    let (_dir, cfg) = signed_config(false);
    // No frame is read, so no vehicle is ever heard: with its system id set, dronewatt still
    // sends its heartbeat (signed) from the start, which the peer must refuse.
    let cfg = format!("{cfg}[sinks.mavlink]\nsystem_id = 1\n");
    let r = fly(
        &cfg,
        false,
        r#"[{"send_s": 3}]"#,
        &["--sign-key", OTHER_KEY_HEX],
    );
    let frames = r.peer["frames"].as_u64().unwrap();
    assert_eq!(r.count("signature_bad"), frames, "{}", r.summary);
    assert_eq!(
        (r.count("frames_ok"), r.count("windows")),
        (0, 0),
        "nothing read from a wrong key: {}",
        r.summary
    );
    assert!(r.estimates.is_empty());
    // And pymavlink, holding the other key, refused every frame dronewatt signed.
    let sig = &r.peer["signing"];
    assert!(
        sig["badsig"].as_u64().unwrap() >= 1 && sig["goodsig"] == 0,
        "{}",
        r.peer
    );
    assert_eq!(r.peer["named_values"], 0, "{}", r.peer);
}

#[test]
fn replayed_frames_are_dropped_and_counted() {
    let (_dir, cfg) = signed_config(true);
    let r = fly(
        &cfg,
        false,
        r#"[{"send_s": 3, "replay": 40}]"#,
        &["--sign-key", KEY_HEX],
    );
    check_consistent(&r);
    let frames = r.peer["frames"].as_u64().unwrap();
    assert_eq!(r.peer["phases"][0]["replayed"], 40);
    assert_eq!(
        (r.count("signed_ok"), r.count("signature_replay")),
        (frames, 40),
        "{}",
        r.summary
    );
}

#[test]
fn with_require_signing_unsigned_frames_mavlink_1_included_are_refused() {
    let (_dir, cfg) = signed_config(true);
    let r = fly(&cfg, false, r#"[{"send_s": 2, "v1": true}]"#, &[]);
    let frames = r.peer["frames"].as_u64().unwrap();
    assert_eq!(
        (r.count("unsigned_refused"), r.count("frames_ok")),
        (frames, 0),
        "{}",
        r.summary
    );
    assert!(r.estimates.is_empty());
}

#[test]
fn a_key_file_others_can_read_stops_monitor_before_it_listens() {
    let (dir, cfg) = signed_config(false);
    #[cfg(unix)]
    std::fs::set_permissions(
        dir.path().join("link.key"),
        std::os::unix::fs::PermissionsExt::from_mode(0o644),
    )
    .unwrap();
    let path = dir.path().join("dw.toml");
    std::fs::write(&path, cfg).unwrap();
    let out = dronewatt()
        .args([
            "monitor",
            &format!("udpin:127.0.0.1:{}", free_udp_port()),
            "-q",
            "--config",
        ])
        .arg(&path)
        .out();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("link.signing_key_file") && err.contains("chmod 600"),
        "{err}"
    );
}

// ---- the dashboard ----

/// One raw HTTP/1.1 exchange: status, headers (lower-cased names) and body.
fn http(addr: std::net::SocketAddr, request: &str) -> (u16, Vec<(String, String)>, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut raw = Vec::new();
    let _ = s.read_to_end(&mut raw);
    let text = String::from_utf8_lossy(&raw).to_string();
    let (head, body) = text
        .split_once("\r\n\r\n")
        .unwrap_or_else(|| panic!("no HTTP response: {text:?}"));
    let mut lines = head.lines();
    let status = lines
        .next()
        .unwrap()
        .split(' ')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    (status, headers, body.to_string())
}

fn get(
    addr: std::net::SocketAddr,
    path: &str,
    extra: &str,
) -> (u16, Vec<(String, String)>, String) {
    http(
        addr,
        &format!("GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n{extra}\r\n"),
    )
}

fn header<'a>(h: &'a [(String, String)], name: &str) -> &'a str {
    h.iter()
        .find(|(k, _)| k == name)
        .map_or("", |(_, v)| v.as_str())
}

/// The dashboard served on a free loopback port from `cfg`, fed nothing; dropping the
/// sender ends it.
async fn dashboard(
    cfg: dronewatt::sink::web::WebSinkConfig,
) -> (std::net::SocketAddr, dronewatt::sink::Fanout) {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let mut fanout = dronewatt::sink::Fanout::default();
    let rx = fanout.subscribe();
    tokio::spawn(dronewatt::sink::web::serve(
        cfg,
        listener,
        rx,
        Default::default(),
    ));
    (addr, fanout)
}

fn token_file(dir: &tempfile::TempDir, token: &str) -> std::path::PathBuf {
    let p = dir.path().join("web.token");
    std::fs::write(&p, format!("{token}\n")).unwrap();
    #[cfg(unix)]
    std::fs::set_permissions(&p, std::os::unix::fs::PermissionsExt::from_mode(0o600)).unwrap();
    p
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_dashboard_sets_safe_headers_is_read_only_and_caps_request_size() {
    let (addr, _tx) = dashboard(dronewatt::sink::web::WebSinkConfig {
        enabled: true,
        ..Default::default()
    })
    .await;
    tokio::task::spawn_blocking(move || {
        let (status, h, body) = get(addr, "/", "");
        assert_eq!(status, 200);
        assert!(body.contains("<canvas"), "the page");
        let csp = header(&h, "content-security-policy");
        assert!(csp.contains("default-src 'none'") && csp.contains("script-src 'sha256-") && !csp.contains("unsafe"), "{csp}");
        assert!(csp.contains("frame-ancestors 'none'") && csp.contains("connect-src 'self'"), "{csp}");
        assert_eq!(header(&h, "x-content-type-options"), "nosniff");
        assert_eq!(header(&h, "referrer-policy"), "no-referrer");
        assert_eq!(header(&h, "cache-control"), "no-store");
        let (status, h, body) = get(addr, "/api/state", "");
        assert_eq!(status, 200, "loopback without a token configured: open");
        assert!(body.starts_with("{\"alerts\""), "{body}");
        assert_eq!(header(&h, "x-content-type-options"), "nosniff", "the API has the headers too");
        // No write endpoint, no bodies, no huge heads.
        let (status, h, _) = http(addr, "POST /api/state HTTP/1.1\r\nHost: x\r\nConnection: close\r\nContent-Length: 0\r\n\r\n");
        assert_eq!((status, header(&h, "allow")), (405, "GET, HEAD"));
        let (status, _, _) = http(addr, "GET /api/state HTTP/1.1\r\nHost: x\r\nConnection: close\r\nContent-Length: 5\r\n\r\nhello");
        assert_eq!(status, 413);
        let (status, _, _) = get(addr, "/api/state", &format!("X-Pad: {}\r\n", "a".repeat(9000)));
        assert_eq!(status, 431);
    })
    .await
    .unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_a_token_the_api_answers_only_to_its_bearer() {
    let dir = tempfile::tempdir().unwrap();
    let token = "s3cret-token-for-tests-0123";
    let cfg = dronewatt::sink::web::WebSinkConfig {
        enabled: true,
        token_file: Some(token_file(&dir, token)),
        ..Default::default()
    };
    let (addr, _tx) = dashboard(cfg).await;
    tokio::task::spawn_blocking(move || {
        let (status, h, _) = get(addr, "/api/state", "");
        assert_eq!(
            (status, header(&h, "www-authenticate")),
            (401, "Bearer realm=\"dronewatt\"")
        );
        assert_eq!(
            get(
                addr,
                "/api/state",
                "Authorization: Bearer wrong-token-wrong-token\r\n"
            )
            .0,
            401
        );
        assert_eq!(
            get(
                addr,
                "/api/state",
                &format!("Authorization: Bearer {token}x\r\n")
            )
            .0,
            401
        );
        assert_eq!(
            get(
                addr,
                "/api/state",
                &format!("Authorization: Bearer {token}\r\n")
            )
            .0,
            200
        );
        assert_eq!(
            get(addr, "/", "").0,
            200,
            "the page holds no data and loads without the token"
        );
    })
    .await
    .unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn connections_beyond_the_limit_wait_until_one_closes() {
    let cfg = dronewatt::sink::web::WebSinkConfig {
        enabled: true,
        max_connections: 2,
        ..Default::default()
    };
    let (addr, _tx) = dashboard(cfg).await;
    tokio::task::spawn_blocking(move || {
        let idle: Vec<TcpStream> = (0..2).map(|_| TcpStream::connect(addr).unwrap()).collect();
        std::thread::sleep(Duration::from_millis(300));
        let mut third = TcpStream::connect(addr).unwrap(); // the kernel's backlog takes it
        third
            .write_all(b"GET /api/state HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
            .unwrap();
        third
            .set_read_timeout(Some(Duration::from_millis(700)))
            .unwrap();
        let mut b = [0u8; 64];
        assert!(
            third.read(&mut b).is_err(),
            "a third connection must not be served while two are open"
        );
        drop(idle);
        third
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        let mut raw = Vec::new();
        let _ = third.read_to_end(&mut raw);
        assert!(
            raw.starts_with(b"HTTP/1.1 200"),
            "served once a slot is free: {:?}",
            String::from_utf8_lossy(&raw)
        );
    })
    .await
    .unwrap();
}

#[test]
fn beyond_loopback_the_dashboard_needs_a_token_from_the_environment() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let port = free_tcp_port();
    let cfg = dir.path().join("web.toml");
    std::fs::write(
        &cfg,
        format!("[sinks.web]\nenabled = true\nbind = \"0.0.0.0:{port}\"\nlinger_s = 30\n"),
    )
    .unwrap();
    let run = |token: Option<&str>| {
        let mut c = dronewatt();
        c.args(["replay", "--speed", "max", "-q", "--config"])
            .arg(&cfg)
            .arg(root.join("replay/demo.tlog"));
        c.env_remove("DRONEWATT_WEB_TOKEN");
        if let Some(t) = token {
            c.env("DRONEWATT_WEB_TOKEN", t);
        }
        c
    };
    let out = run(None).out();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "a public dashboard without a token must not start"
    );
    assert!(
        err.contains("sinks.web.bind") && err.contains("DRONEWATT_WEB_TOKEN"),
        "{err}"
    );
    let out = run(Some("short")).out();
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("at least 16"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let token = "token-from-the-environment-42";
    let dw = Monitor::listening(&mut run(Some(token)), port, true);
    let addr: std::net::SocketAddr = format!("127.0.0.1:{port}").parse().unwrap();
    let unauth = get(addr, "/api/state", "").0;
    let auth = get(
        addr,
        "/api/state",
        &format!("Authorization: Bearer {token}\r\n"),
    );
    let _ = dw.stop();
    assert_eq!(unauth, 401);
    assert_eq!(auth.0, 200, "{}", auth.2);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn chromium_shows_the_guarded_dashboard_with_its_token_and_asks_without() {
    let Some(browser) = crate::sink_web::chromium() else {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "CI=true: chromium is required (scripts/setup-chromium.sh)"
        );
        eprintln!("\n!!!!!!!! SKIPPED: no chromium on this machine; the token flow in the browser is NOT tested !!!!!!!!\n");
        return;
    };
    use dronewatt::features::{Sample, N_FEATURES};
    use dronewatt::report::{EnergyState, Report};
    use dronewatt::report::{Estimate, ModelEstimate};
    let dir = tempfile::tempdir().unwrap();
    let token = "browser-token-0123456789";
    let cfg = dronewatt::sink::web::WebSinkConfig {
        enabled: true,
        token_file: Some(token_file(&dir, token)),
        ..Default::default()
    };
    let (addr, mut tx) = dashboard(cfg).await;
    let sample = Sample {
        t_s: 1.0,
        features: [0.0; N_FEATURES],
        measured_w: Some(512.0),
        voltage_v: Some(22.5),
        home: None,
        stale_mask: 0,
        battery_remaining_pct: None,
        vehicle: Default::default(),
        air: Default::default(),
    };
    let est = Estimate {
        t_s: 1.0,
        sample,
        models: vec![ModelEstimate::new("tseng", 470.0, None)],
        arrived: None,
    };
    tx.send(Report {
        estimate: est,
        energy: EnergyState::default(),
        alerts: vec![],
        vehicle: 1.into(),
    })
    .await;
    let dump = move |url: String| {
        let out = Command::new(browser)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-dev-shm-usage",
                "--virtual-time-budget=3000",
                "--dump-dom",
            ])
            .arg(url)
            .out();
        String::from_utf8_lossy(&out.stdout).to_string()
    };
    let with = tokio::task::spawn_blocking({
        let d = dump;
        move || d(format!("http://{addr}/#token={token}"))
    })
    .await
    .unwrap();
    assert!(
        with.contains(">512 W<"),
        "with its token the page shows the numbers:\n{with}"
    );
    let without = tokio::task::spawn_blocking(move || dump(format!("http://{addr}/")))
        .await
        .unwrap();
    assert!(
        without.contains("needs its token") && !without.contains(">512 W<"),
        "without it, it asks:\n{without}"
    );
}
