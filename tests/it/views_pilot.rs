//! The pilot's views (`sink::pilot`, `sink::terminal`, `sink::screen`, `sink::web`) with real
//! parts: the plain line over a real replay of `replay/demo.tlog` and a pymavlink vehicle at
//! 1 Hz over UDP is at most 120 characters and holds what a pilot needs, every model's
//! figures only with `--detail`; the screen in tmux at 80×24 and 120×40 shows every tile
//! whole and the critical alert, holds the replay's final state until a key, and shows the
//! same state of charge as the JSON; the dashboard in Chromium at 1280×800 shows the
//! critical alert's banner and the pilot's cards without scrolling.
//!
//! The demo's `energy_low` rule is made critical here ("Land now"), so that a critical alert
//! stands at the end of the replay (in the demo as shipped the critical `mission_margin`
//! clears before the landing).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use crate::harness::{
    bin, dronewatt, json_lines, last_estimate, root, summary_written, Monitor, RunExt,
};
use crate::link_common::{free_tcp_port, free_udp_port, peer_then_stop};

/// The plain line's most characters.
const MAX_LINE: usize = 120;

/// The demo config (vehicle profile named from the repository), `energy_low` critical, the
/// dashboard on `web`'s port (lingering) or off.
fn demo_config(dir: &Path, web: Option<u16>) -> PathBuf {
    let root = root();
    let demo = std::fs::read_to_string(root.join("config/demo.toml")).unwrap();
    let vehicles = format!(
        "calibrated_profile = \"{}/",
        root.join("config/vehicles").display()
    );
    let dash = match web {
        Some(port) => format!("enabled = true\nbind = \"127.0.0.1:{port}\"\nlinger_s = 60\n"),
        None => "enabled = false".into(),
    };
    let text = demo
        .replace("enabled = true", &dash)
        .replace("calibrated_profile = \"vehicles/", &vehicles)
        .replace(
            "severity = \"warning\"\nmessage = \"Battery low\"",
            "severity = \"critical\"\nmessage = \"Land now: battery low\"",
        );
    assert!(
        text.contains("Land now: battery low"),
        "the demo's energy_low rule moved"
    );
    let cfg = dir.join("demo.toml");
    std::fs::write(&cfg, text).unwrap();
    cfg
}

/// The plain view's status lines in `stderr`: those that start with the power (or say they
/// wait for the first window).
fn status_lines(stderr: &str) -> Vec<&str> {
    stderr
        .lines()
        .filter(|l| {
            let head = l.split("  ").next().unwrap_or("");
            head == "waiting for the first window"
                || head == "— W"
                || ((head.ends_with(" W") || head.ends_with(" W est"))
                    && head
                        .trim_start_matches('~')
                        .starts_with(|c: char| c.is_ascii_digit()))
        })
        .collect()
}

fn assert_pilot_lines(lines: &[&str], what: &str) {
    for l in lines {
        assert!(
            l.chars().count() <= MAX_LINE,
            "{what}: {} characters: {l}",
            l.chars().count()
        );
        for model in ["dandrea", "lstm", "tseng", "dorling", "liu"] {
            assert!(
                !l.contains(model),
                "{what}: a model's figure without --detail: {l}"
            );
        }
        assert!(
            !l.contains("msg/s"),
            "{what}: link counters without --detail: {l}"
        );
    }
}

#[test]
fn the_plain_line_of_the_demo_replay_is_at_most_120_characters() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = demo_config(dir.path(), None);
    let demo = root().join("replay/demo.tlog");
    let out = dronewatt()
        .args([
            "replay",
            "--speed",
            "25",
            "--plain",
            "--data-dir",
            "off",
            "--config",
        ])
        .arg(&cfg)
        .arg(&demo)
        .ok();
    let err = String::from_utf8_lossy(&out.stderr);
    let lines = status_lines(&err);
    assert!(lines.len() >= 5, "status lines: {lines:?}\n{err}");
    assert_pilot_lines(&lines, "demo");
    let full: Vec<_> = lines.iter().filter(|l| !l.starts_with("waiting")).collect();
    // Power, the state of charge with its source, the time left, the voltage and its
    // forecast minimum, the mission margin and the worst alert: each on some line.
    let on_some = |needle: &str| full.iter().any(|l| l.contains(needle));
    for needle in [
        " W  ",
        " % ",
        "(resting voltage)",
        " to low V",
        " V min ",
        "mission ",
        "WARNING sag_forecast",
        "CRITICAL energy_low",
    ] {
        assert!(on_some(needle), "no line holds {needle:?}: {full:#?}");
    }

    // With --detail: every model's figure and the link's counters, as before.
    let out = dronewatt()
        .args([
            "replay",
            "--speed",
            "50",
            "--plain",
            "--detail",
            "--data-dir",
            "off",
        ])
        .arg("--config")
        .arg(&cfg)
        .arg(&demo)
        .ok();
    let err = String::from_utf8_lossy(&out.stderr);
    let detail: Vec<_> = err.lines().filter(|l| l.contains("msg/s")).collect();
    assert!(
        detail
            .iter()
            .any(|l| l.contains("lstm") && l.contains("dandrea")),
        "--detail shows every model: {err}"
    );
    assert!(
        err.contains("feeds: "),
        "--detail says what feeds each signal: {err}"
    );
}

#[test]
fn the_plain_line_of_a_1_hz_vehicle_is_at_most_120_characters() {
    let port = free_udp_port();
    let dw = Monitor::listening(
        dronewatt().args([
            "monitor",
            &format!("udpin:127.0.0.1:{port}"),
            "--plain",
            "--listen-only",
        ]),
        port,
        false,
    );
    let to = format!("udpout:127.0.0.1:{port}");
    let (_, err) = peer_then_stop(
        dw,
        "slow_link.py",
        &["--to", &to, "--seconds", "14", "--ground-s", "2"],
    );
    let lines = status_lines(&err);
    assert!(lines.len() >= 8, "status lines: {lines:?}\n{err}");
    assert_pilot_lines(&lines, "1 Hz vehicle");
    // The vehicle's 22.2 V pack and its ~500 W in flight reach the line.
    assert!(lines.iter().any(|l| l.contains("22.2 V")), "{lines:#?}");
    assert!(
        lines.iter().any(|l| {
            let w: f64 = l.split(" W").next().unwrap_or("").parse().unwrap_or(0.0);
            (400.0..600.0).contains(&w)
        }),
        "{lines:#?}"
    );
}

/// tmux, or why the test cannot run (skipped loudly; under CI a failure).
fn tmux() -> bool {
    let ok = Command::new("tmux")
        .arg("-V")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true" && v != "1"),
            "CI: no tmux, and CI must test the terminal screen (scripts/setup-tmux.sh)"
        );
        eprintln!("\n!!!!!!!! SKIPPED: no tmux (scripts/setup-tmux.sh could not install it); the screen's sizes are NOT tested !!!!!!!!\n");
    }
    ok
}

/// A tmux server of the test's own (its own socket), removed when dropped.
struct Tmux {
    socket: String,
}

impl Tmux {
    fn cmd(&self) -> Command {
        let mut c = Command::new("tmux");
        c.args(["-L", &self.socket]);
        c
    }
    fn capture(&self) -> String {
        let out = self
            .cmd()
            .args(["capture-pane", "-p", "-t", "dw"])
            .output()
            .expect("tmux capture-pane");
        String::from_utf8_lossy(&out.stdout).into_owned()
    }
    /// Wait (90 s at most) until the pane shows `text`; the capture.
    fn wait_for(&self, text: &str) -> String {
        let start = Instant::now();
        loop {
            let pane = self.capture();
            if pane.contains(text) {
                return pane;
            }
            assert!(
                start.elapsed() < Duration::from_secs(90),
                "the pane never showed {text:?}:\n{pane}"
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        let _ = self.cmd().arg("kill-server").output();
    }
}

/// Every box drawn whole: as many of each corner, at least `tiles`; no figure in the tile
/// rows (the first 13) cut with `…`.
fn assert_tiles_whole(pane: &str, tiles: usize, size: &str) {
    let n = |c: char| pane.chars().filter(|&x| x == c).count();
    let tl = n('┌');
    assert!(tl >= tiles, "{size}: {tl} boxes:\n{pane}");
    assert!(
        n('┐') == tl && n('┘') == tl,
        "{size}: a box without all its corners (cut):\n{pane}"
    );
    for (i, row) in pane.lines().take(13).enumerate() {
        assert!(!row.contains('…'), "{size}: row {i} cut: {row}\n{pane}");
    }
    for title in [
        "Time left",
        "State of charge",
        "Voltage",
        "Margins",
        "Power",
        "Pack model",
        "Link",
        "Alerts",
    ] {
        assert!(pane.contains(title), "{size}: no {title} tile:\n{pane}");
    }
}

#[test]
fn the_screen_fits_80x24_and_120x40_and_holds_the_end_of_a_replay() {
    if !tmux() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = demo_config(dir.path(), None);
    for (cols, rows) in [(80, 24), (120, 40)] {
        let size = format!("{cols}×{rows}");
        let json = dir.path().join(format!("{cols}.jsonl"));
        let done = dir.path().join(format!("{cols}.exit"));
        let command = format!(
            "{} replay {} --speed 40 --data-dir off --config {} --json {}; echo $? > {}; sleep 60",
            bin("dronewatt").display(),
            root().join("replay/demo.tlog").display(),
            cfg.display(),
            json.display(),
            done.display()
        );
        let t = Tmux {
            socket: format!("dw-views-{}-{cols}", std::process::id()),
        };
        let started = t
            .cmd()
            .args(["-f", "/dev/null", "new-session", "-d", "-s", "dw"])
            .args(["-x", &cols.to_string(), "-y", &rows.to_string()])
            .env("TERM", "xterm-256color")
            .env("RUST_LOG", "dronewatt=info,warn")
            .env("DRONEWATT_HOME", "off")
            .arg(&command)
            .status()
            .expect("tmux new-session");
        assert!(started.success(), "{size}: tmux did not start");
        // The replay ends; the screen holds its final state until a key.
        let pane = t.wait_for("press any key");
        assert_tiles_whole(&pane, 9, &size);
        assert!(
            pane.contains("CRITICAL energy_low: Land now: battery low"),
            "{size}: the critical alert's banner:\n{pane}"
        );
        // The state of charge on the screen is the JSON's (the one percentage).
        let last = json_lines(&json)
            .into_iter()
            .rfind(|v| v["type"] == "estimate")
            .expect("an estimate");
        let pct = format!(
            "{:.0} %",
            last["remaining_pct"].as_f64().expect("remaining_pct")
        );
        assert!(
            pane.contains(&pct),
            "{size}: the state of charge {pct}:\n{pane}"
        );
        // Still held a second later; a key ends it, with exit status 0.
        std::thread::sleep(Duration::from_secs(1));
        assert!(!done.exists(), "{size}: the screen did not hold the end");
        let key = t
            .cmd()
            .args(["send-keys", "-t", "dw", "x"])
            .status()
            .unwrap();
        assert!(key.success());
        let start = Instant::now();
        while !done.exists() {
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "{size}: a key did not end the held screen:\n{}",
                t.capture()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        std::thread::sleep(Duration::from_millis(200));
        let code = std::fs::read_to_string(&done).unwrap();
        assert_eq!(code.trim(), "0", "{size}: exit status");
        // Kept for people to look at (target/test-artifacts/, ignored by git).
        let keep = root().join(format!("target/test-artifacts/screen_{cols}x{rows}.txt"));
        if std::fs::create_dir_all(keep.parent().unwrap()).is_ok() {
            let _ = std::fs::write(&keep, &pane);
        }
    }
}

#[test]
fn the_dashboard_at_1280x800_leads_with_the_critical_alert() {
    let Some(browser) = crate::sink_web::chromium() else {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true" && v != "1"),
            "CI: no chromium, and CI must test the web dashboard (scripts/setup-chromium.sh)"
        );
        eprintln!(
            "\n!!!!!!!! SKIPPED: no chromium; the dashboard's banner is NOT tested !!!!!!!!\n"
        );
        return;
    };
    let port = free_tcp_port();
    let dir = tempfile::tempdir().unwrap();
    let cfg = demo_config(dir.path(), Some(port));
    let json = dir.path().join("out.jsonl");
    let dw = Monitor::spawn(
        dronewatt()
            .args([
                "replay",
                "--speed",
                "max",
                "-q",
                "--data-dir",
                "off",
                "--config",
            ])
            .arg(&cfg)
            .arg("--json")
            .arg(&json)
            .arg(root().join("replay/demo.tlog")),
    );
    let text = summary_written(&json);
    let last = last_estimate(&text);
    let url = format!("http://127.0.0.1:{port}/");
    let shot = dir.path().join("dashboard.png");
    let run = |extra: &str| crate::sink_web::headless_at(browser, "1280,800", &url, &[extra]);
    let dom = run("--dump-dom");
    let shot_out = run(&format!("--screenshot={}", shot.display()));
    let (status, _) = dw.stop();
    assert!(status.success(), "dronewatt ended with {status}");
    assert!(dom.status.success() && shot_out.status.success());
    let html = String::from_utf8_lossy(&dom.stdout);
    let tag = |id: &str| -> String {
        html.split(&format!("id=\"{id}\""))
            .nth(1)
            .and_then(|t| t.split('<').next())
            .unwrap_or("")
            .to_string()
    };
    let banner = tag("banner");
    assert!(
        banner.contains("class=\"critical\"")
            && banner.contains("CRITICAL · Land now: battery low"),
        "the banner: {banner}\n{html}"
    );
    // The banner and the pilot's cards within the first 800 px (no scrolling).
    let body = html
        .split("<body")
        .nth(1)
        .and_then(|b| b.split('>').next())
        .unwrap_or("");
    let attr = |name: &str| -> f64 {
        body.split(&format!("{name}=\""))
            .nth(1)
            .and_then(|v| v.split('"').next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no {name} on <body{body}>"))
    };
    let viewport = attr("data-viewport");
    assert!((700.0..=800.0).contains(&viewport), "viewport {viewport}");
    assert!(attr("data-banner-bottom") <= viewport, "<body{body}>");
    assert!(attr("data-cards-bottom") <= viewport, "<body{body}>");
    // The one percentage: the state of charge card is the JSON's remaining_pct.
    let pct = format!("{:.0} %", last["remaining_pct"].as_f64().unwrap());
    assert!(
        tag("v-charge").ends_with(&format!(">{pct}")),
        "{}",
        tag("v-charge")
    );
    assert!(
        tag("v-charge-note").contains("resting voltage"),
        "{}",
        tag("v-charge-note")
    );
    for id in ["v-time", "v-volt", "v-pmargin", "v-power"] {
        let t = tag(id);
        assert!(
            t.split('>')
                .nth(1)
                .is_some_and(|v| v != "–" && !v.is_empty()),
            "{id}: {t}"
        );
    }
    // Every model's figures behind the toggle.
    assert!(html.contains("id=\"detail\" hidden"), "the detail is shown");
    let png = std::fs::read(&shot).expect("the screenshot");
    assert!(png.starts_with(b"\x89PNG") && png.len() > 10_000);
    let keep = root().join("target/test-artifacts/dashboard_1280x800.png");
    if std::fs::create_dir_all(keep.parent().unwrap()).is_ok() {
        let _ = std::fs::copy(&shot, &keep);
    }
}
