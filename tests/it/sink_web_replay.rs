//! The dashboard against a replay, end to end: `dronewatt replay replay/demo.tlog` with the
//! demo config and the dashboard on a free loopback port; once the replay has ended (the
//! dashboard lingers), headless Chromium loads the page and the DOM must show the last
//! estimate's measured power, the demo's mission alert, the route panel drawing the plan
//! (its points and the vehicle's place), the mission tiles and the pack's tiles with
//! numbers. Skips loudly without chromium.

use crate::harness::{dronewatt, last_estimate, summary_written, Monitor, RunExt};
use crate::sink_web::{chromium, chromium_or_skip, headless, headless_at};
use std::path::Path;
use std::time::{Duration, Instant};

#[test]
fn dashboard_of_the_demo_replay_in_chromium() {
    let Some(browser) = chromium_or_skip() else {
        return;
    };
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dir = tempfile::tempdir().unwrap();
    let demo = std::fs::read_to_string(root.join("config/demo.toml")).unwrap();
    let cfg = dir.path().join("demo.toml");
    let web = format!("enabled = true\nbind = \"127.0.0.1:{port}\"\nlinger_s = 60\n");
    // Paths in the config are relative to it: the copy names the repository's.
    let vehicles = format!(
        "calibrated_profile = \"{}/",
        root.join("config/vehicles").display()
    );
    std::fs::write(
        &cfg,
        demo.replace("enabled = true", &web)
            .replace("calibrated_profile = \"vehicles/", &vehicles),
    )
    .unwrap();
    let json = dir.path().join("out.jsonl");
    let dw = replay_lingering(&cfg, &json, &root.join("replay/demo.tlog"));
    // The JSON summary line means the replay is over and every report reached the sinks.
    let start = Instant::now();
    let text = summary_written(&json);
    let last = last_estimate(&text);
    let measured = format!("{:.0} W", last["measured_w"].as_f64().unwrap());
    let volts = format!(
        "{:.2} V",
        last["battery_v"]
            .as_f64()
            .expect("the pack's measured voltage")
    );

    let url = format!("http://127.0.0.1:{port}/");
    let shot = dir.path().join("web_replay.png");
    let run = |extra: &str| headless_at(browser, "1280,1800", &url, &[extra]);
    let dom = run("--dump-dom");
    let shot_out = run(&format!("--screenshot={}", shot.display()));
    let (status, _) = dw.stop();
    let html = String::from_utf8_lossy(&dom.stdout);
    assert!(
        dom.status.success() && shot_out.status.success(),
        "{}",
        String::from_utf8_lossy(&dom.stderr)
    );
    assert!(
        html.contains(&format!("id=\"v-measured\">{measured}<")),
        "expected {measured} in:\n{html}"
    );
    assert!(
        html.contains("CRITICAL  Return now: margin"),
        "no mission margin alert in:\n{html}"
    );
    assert!(
        html.contains("WARNING  Sag 20.8V"),
        "no voltage forecast alert in:\n{html}"
    );
    assert!(
        html.contains("t = 231."),
        "the page did not reach the end of the flight:\n{html}"
    );
    // The route panel draws the plan: the demo plan's route, the vehicle at its end.
    let attr = |id: &str, name: &str| -> Option<String> {
        let tag = html
            .split(&format!("id=\"{id}\""))
            .nth(1)?
            .split('>')
            .next()?
            .to_string();
        Some(
            tag.split(&format!("{name}=\""))
                .nth(1)?
                .split('"')
                .next()?
                .to_string(),
        )
    };
    let points: usize = attr("c-route", "data-points")
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let at: usize = attr("c-route", "data-at")
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    assert!(
        points >= 6,
        "the route panel drew {points} points of the plan:\n{html}"
    );
    assert!(
        at > 0 && at < points,
        "the vehicle on the route: point {at} of {points}"
    );
    // Tiles that hold a number, by id.
    let tile = |id: &str| -> String {
        html.split(&format!("id=\"{id}\">"))
            .nth(1)
            .and_then(|t| t.split('<').next())
            .unwrap_or("")
            .to_string()
    };
    let number = |id: &str| {
        let t = tile(id);
        assert!(
            t.chars()
                .next()
                .is_some_and(|c| c.is_ascii_digit() || c == '-'),
            "tile {id} holds no number: {t:?}"
        );
    };
    for id in ["v-mission", "v-mmargin", "v-batt", "v-batt-model", "v-soc"] {
        number(id);
    }
    // The page is read after the landing: no rest of the flight is left to forecast, so the
    // forecast tiles say so (the "Sag" alert above is the forecast made in flight).
    for id in ["v-vmin", "v-tlow"] {
        let t = tile(id);
        assert!(
            t == "–" || t.starts_with(|c: char| c.is_ascii_digit()),
            "tile {id}: {t:?}"
        );
    }
    assert_eq!(
        tile("v-batt"),
        volts,
        "the measured voltage tile shows the last estimate's"
    );
    assert!(
        tile("v-mission").contains("item "),
        "mission tile: {}",
        tile("v-mission")
    );
    assert_eq!(
        tile("v-source"),
        "resting voltage",
        "the demo's pack starts from its resting voltage"
    );
    assert!(
        tile("v-batt-rest").starts_with("at rest before take-off 23."),
        "{}",
        tile("v-batt-rest")
    );
    let png = std::fs::read(&shot).expect("the screenshot");
    assert!(
        png.len() > 10_000 && png.starts_with(b"\x89PNG"),
        "a screenshot of the page"
    );
    // Kept for people to look at (target/test-artifacts/, ignored by git).
    let keep = root.join("target/test-artifacts/web_replay.png");
    if std::fs::create_dir_all(keep.parent().unwrap()).is_ok() {
        let _ = std::fs::copy(&shot, &keep);
    }
    assert!(
        status.success(),
        "dronewatt ended with {status} on SIGTERM while lingering"
    );
    assert!(
        start.elapsed() < Duration::from_secs(50),
        "SIGTERM must end the linger"
    );
}

/// `replay --speed max` of `log` with the dashboard `config` (which lingers after the
/// replay), JSON lines to `json`; left running.
fn replay_lingering(config: &Path, json: &Path, log: &Path) -> Monitor {
    Monitor::spawn(
        dronewatt()
            .args(["replay", "--speed", "max", "-q", "--config"])
            .arg(config)
            .arg("--json")
            .arg(json)
            .arg(log),
    )
}

/// GET `path` from the dashboard; the body as JSON.
pub(crate) fn get_json(port: u16, path: &str) -> serde_json::Value {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    serde_json::from_str(body).unwrap_or_else(|e| panic!("{path}: {e}: {text}"))
}

#[test]
fn dashboard_of_a_fleet_lists_every_vehicle_and_shows_the_one_asked_for() {
    let Some(browser) = chromium() else {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true" && v != "1"),
            "CI must test the web dashboard"
        );
        eprintln!("\n!!!!!!!! SKIPPED: no chromium on this machine; the fleet dashboard is NOT tested !!!!!!!!\n");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let tlog = dir.path().join("fleet.tlog");
    dronewatt()
        .args([
            "simulate",
            "--vehicles",
            "3",
            "--leg-m",
            "120",
            "--hover-s",
            "5",
            "--out",
        ])
        .arg(&tlog)
        .ok();
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let cfg = dir.path().join("web.toml");
    std::fs::write(
        &cfg,
        format!("[sinks.web]\nenabled = true\nbind = \"127.0.0.1:{port}\"\nlinger_s = 60\n"),
    )
    .unwrap();
    let json = dir.path().join("out.jsonl");
    let dw = replay_lingering(&cfg, &json, &tlog);
    let text = summary_written(&json);
    // Each vehicle's last estimate time, from the JSON lines.
    let mut last_t = std::collections::BTreeMap::new();
    for v in text
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v["type"] == "estimate")
    {
        last_t.insert(v["system_id"].as_u64().unwrap(), v["t"].as_f64().unwrap());
    }
    assert_eq!(last_t.len(), 3);

    // The API: every vehicle in `fleet`; the lowest by default; the one asked for otherwise.
    let s = get_json(port, "/api/state");
    let rows: Vec<u64> = s["fleet"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["system_id"].as_u64().unwrap())
        .collect();
    assert_eq!(rows, vec![1, 2, 3], "{s}");
    assert_eq!(s["vehicle"], 1);
    let s2 = get_json(port, "/api/state?vehicle=2");
    assert_eq!(s2["vehicle"], 2);
    assert_eq!(
        s2["latest"]["t"].as_f64(),
        Some(last_t[&2]),
        "vehicle 2's own last report"
    );
    assert!(s2["points"].as_array().unwrap().len() > 50);

    // The page: the fleet table shown, one clickable row per vehicle, the first selected.
    let url = format!("http://127.0.0.1:{port}/");
    let dom = headless(browser, &url, &["--dump-dom"]);
    let (status, _) = dw.stop();
    let html = String::from_utf8_lossy(&dom.stdout);
    assert!(
        html.contains("<div id=\"fleet-box\">"),
        "the fleet table is shown:\n{html}"
    );
    for v in 1..=3 {
        assert!(
            html.contains(&format!("data-vehicle=\"{v}\"")),
            "row for vehicle {v}:\n{html}"
        );
    }
    assert!(
        html.contains("<tr data-vehicle=\"1\" class=\"selected\">"),
        "vehicle 1 selected:\n{html}"
    );
    assert!(
        html.contains("vehicle 1, t = "),
        "the status names the vehicle shown:\n{html}"
    );
    assert!(status.success(), "dronewatt ended with {status}");
}
