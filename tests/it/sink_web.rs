//! The web dashboard in headless Chromium (Debian's `chromium`, installed by
//! `scripts/setup-chromium.sh`, which `make test` runs): the page polls the JSON endpoint,
//! draws its charts and shows the numbers and the alert log. Asserts on the DOM Chromium
//! dumps after the page has polled, and leaves a screenshot in
//! `target/test-artifacts/web_dashboard.png` for a person to look at.

use std::process::Command;

use dronewatt::alert::AlertEngine;
use dronewatt::config::Config;
use dronewatt::energy::EnergyTracker;
use dronewatt::features::{HomeVector, Sample, N_FEATURES};
use dronewatt::report::MissionStatus;
use dronewatt::report::Report;
use dronewatt::report::{Estimate, ModelEstimate};
use dronewatt::sink::web;

pub(crate) fn chromium() -> Option<&'static str> {
    ["chromium", "chromium-browser"].into_iter().find(|c| {
        Command::new(c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// The browser, else None and the test skips, loudly; under CI a missing browser fails: a
/// green run must mean the dashboard was tested.
pub(crate) fn chromium_or_skip() -> Option<&'static str> {
    let browser = chromium();
    if browser.is_none() {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true" && v != "1"),
            "CI={}: no chromium on this machine, and CI must test the web dashboard (run scripts/setup-chromium.sh)",
            std::env::var("CI").unwrap_or_default()
        );
        eprintln!("\n!!!!!!!! SKIPPED: no chromium on this machine (scripts/setup-chromium.sh could not install it); the web dashboard is NOT tested !!!!!!!!\n");
    }
    browser
}

pub(crate) fn headless(browser: &str, url: &str, extra: &[&str]) -> std::process::Output {
    headless_at(browser, "1280,1100", url, extra)
}

/// Headless Chromium on `url` in a window of `size` (`W,H`), with `extra` arguments (what
/// to dump or where to screenshot), given 4 s of virtual time.
pub(crate) fn headless_at(
    browser: &str,
    size: &str,
    url: &str,
    extra: &[&str],
) -> std::process::Output {
    Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--hide-scrollbars",
        ])
        .args([
            format!("--window-size={size}").as_str(),
            "--virtual-time-budget=4000",
        ])
        .args(extra)
        .arg(url)
        .output()
        .expect("run chromium")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dashboard_shows_estimates_and_alerts_in_chromium() {
    let Some(browser) = chromium_or_skip() else {
        return;
    };
    let cfg: Config = toml::from_str(
        r#"
        [energy]
        capacity_wh = 18
        [[alerts]]
        name = "energy_low"
        kind = "remaining_below"
        below_pct = 40
        clear_pct = 42
        message = "Battery low"
        "#,
    )
    .unwrap();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("http://{}/", listener.local_addr().unwrap());
    let mut fanout = dronewatt::sink::Fanout::default();
    let rx = fanout.subscribe();
    let wcfg = web::WebSinkConfig {
        enabled: true,
        min_step_s: 0.2,
        ..Default::default()
    };
    let server = tokio::spawn(web::serve(wcfg, listener, rx, Default::default()));

    // A 90 s flight: take-off surge, cruise with a gentle oscillation, a last reading of
    // exactly 512 W so the page's number can be asserted.
    let mut energy = EnergyTracker::new(&cfg.energy, cfg.mission.speed_m_s).unwrap();
    let mut alerts = AlertEngine::new(&cfg.alerts).unwrap();
    let mut raised = 0;
    let mut last_margin = None;
    for i in 0..=900 {
        if i == 450 {
            // a mission becomes known halfway: 5 Wh left, flying to item 3 of 6, 40 % along
            // its route: a 200 m square, 40 points, the vehicle at the 17th
            let route: Vec<[f32; 2]> = (0..40)
                .map(|i| {
                    let (side, f) = (i / 10, (i % 10) as f32 * 20.0);
                    [[f, 0.0], [200.0, f], [200.0 - f, 200.0], [0.0, 200.0 - f]][side]
                })
                .collect();
            let m = MissionStatus {
                t_s: 45.0,
                current_seq: 3,
                items: 6,
                time_left_s: 60.0,
                energy_p50_wh: 5.0,
                energy_p90_wh: 5.5,
                progress_pct: 40.0,
                route_en_m: std::sync::Arc::new(route),
                route_at: 16,
            };
            energy.set_mission(Some(m));
        }
        let t_s = i as f64 * 0.1;
        let w = if i == 900 {
            512.0
        } else {
            450.0 + 120.0 * (-(t_s as f32) / 8.0).exp() + 30.0 * ((t_s as f32) / 6.0).sin()
        };
        let est = Estimate {
            arrived: None,
            t_s,
            sample: Sample {
                t_s,
                features: [0.0; N_FEATURES],
                measured_w: Some(w),
                voltage_v: Some(22.5),
                home: Some(HomeVector {
                    distance_m: 10.0 * t_s as f32,
                    height_m: 25.0,
                }),
                stale_mask: 0,
                battery_remaining_pct: None,
                vehicle: Default::default(),
                air: Default::default(),
            },
            models: vec![
                ModelEstimate::new("tseng", 470.0, None),
                ModelEstimate::new("dandrea", w * 0.8, None),
                ModelEstimate::new("lstm", w + 8.0, None),
            ],
        };
        let state = energy.update(&est);
        last_margin = state.mission_margin_wh;
        let events = alerts.evaluate(&est, &state);
        raised += events.len();
        fanout
            .send(Report {
                estimate: est,
                energy: state,
                alerts: events,
                vehicle: 1.into(),
            })
            .await;
    }
    assert_eq!(raised, 1, "the flight is built to raise one alert");

    let dom = tokio::task::spawn_blocking({
        let (b, u) = (browser, url.clone());
        move || headless(b, &u, &["--dump-dom"])
    })
    .await
    .unwrap();
    let html = String::from_utf8_lossy(&dom.stdout);
    assert!(
        dom.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&dom.stderr)
    );
    let text_of = |id: &str| -> String {
        let start = html
            .find(&format!("id=\"{id}\""))
            .unwrap_or_else(|| panic!("no #{id} in the DOM:\n{html}"));
        let rest = &html[start..];
        let open = rest.find('>').unwrap() + 1;
        let close = rest.find('<').unwrap_or(rest.len());
        rest[open..close.max(open)].to_string()
    };
    assert_eq!(text_of("v-measured"), "512 W");
    // The Wh in the detail; the one percentage on the state of charge's card.
    let remaining = text_of("v-remaining");
    assert!(
        remaining.ends_with(" Wh") && !remaining.contains('%'),
        "{remaining}"
    );
    assert!(
        text_of("v-charge").ends_with(" %"),
        "{}",
        text_of("v-charge")
    );
    assert!(
        text_of("status").starts_with("t = 90.0 s"),
        "{}",
        text_of("status")
    );
    assert_eq!(text_of("v-mission"), "5.0 Wh · item 3/6 · 40%");
    // The route the map draws, as the page gets it.
    let addr = url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    let body = tokio::task::spawn_blocking(move || {
        use std::io::{Read, Write};
        let mut c = std::net::TcpStream::connect(addr).unwrap();
        c.write_all(b"GET /api/state HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
            .unwrap();
        let mut r = String::new();
        c.read_to_string(&mut r).unwrap();
        r
    })
    .await
    .unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&body[body.find("\r\n\r\n").unwrap() + 4..]).unwrap();
    let route = &json["latest"]["route"];
    assert_eq!(
        route["points"].as_array().map(Vec::len),
        Some(40),
        "{route}"
    );
    assert_eq!(route["points"][10], serde_json::json!([200.0, 0.0]));
    assert_eq!(route["at"], 16);
    let shown: f64 = text_of("v-mmargin")
        .trim_end_matches(" Wh")
        .parse()
        .unwrap();
    assert!(
        (shown - last_margin.unwrap()).abs() < 0.051,
        "{shown} vs {last_margin:?}"
    );
    // Every model in the table, and the alert in the log with its severity class.
    for m in ["tseng", "dandrea", "lstm"] {
        assert!(
            html.contains(&format!("</span>{m}</td>")),
            "model {m} missing:\n{html}"
        );
    }
    assert!(
        html.contains("class=\"alert sev-warning\"") && html.contains("WARNING  Battery low"),
        "alert missing:\n{html}"
    );

    let shots = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/test-artifacts");
    std::fs::create_dir_all(&shots).unwrap();
    let png = shots.join("web_dashboard.png");
    let _ = std::fs::remove_file(&png);
    let arg = format!("--screenshot={}", png.display());
    let shot = tokio::task::spawn_blocking(move || headless(browser, &url, &[&arg]))
        .await
        .unwrap();
    assert!(
        shot.status.success(),
        "{}",
        String::from_utf8_lossy(&shot.stderr)
    );
    let bytes = std::fs::read(&png).unwrap();
    assert!(
        bytes.starts_with(b"\x89PNG") && bytes.len() > 20_000,
        "screenshot too small to hold charts"
    );

    drop(fanout);
    server.await.unwrap().unwrap();
}
