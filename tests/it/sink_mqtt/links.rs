//! Per-link health where the operator looks: with two links (pymavlink's
//! `tests/peers/redundant.py`, one vehicle over two lossy radios), the MQTT sink keeps one
//! retained `<prefix>/links/<link>/health` per link on the real Mosquitto, and the
//! dashboard (headless Chromium) shows a row per link in its links panel.

use crate::harness::{dronewatt, Monitor};
use std::time::{Duration, Instant};

use super::{broker, config, retained};
use crate::link_common;

#[test]
fn each_link_has_a_retained_health_topic_and_a_row_on_the_dashboard() {
    let Some(b) = broker() else { return };
    let dir = tempfile::tempdir().unwrap();
    let web = link_common::free_tcp_port();
    let cfg = config(
        dir.path(),
        &b,
        "links",
        &format!("[sinks.web]\nenabled = true\nbind = \"127.0.0.1:{web}\"\nlinger_s = 0\n"),
    );
    let ports = [link_common::free_udp_port(), link_common::free_udp_port()];
    let addrs = ports.map(|p| format!("udpin:127.0.0.1:{p}"));
    let mut dw = Monitor::spawn(
        dronewatt()
            .arg("monitor")
            .args(&addrs)
            .args(["-q", "--data-dir", "off", "--config"])
            .arg(&cfg)
            .env("RUST_LOG", "dronewatt=info"),
    );
    for p in ports {
        dw.wait_listening(p, false);
    }
    // While the vehicle flies: the state endpoint and the page, once both links are heard.
    let page = std::thread::spawn(move || {
        let until = Instant::now() + Duration::from_secs(8);
        let state = loop {
            let s = crate::sink_web_replay::get_json(web, "/api/state");
            let heard = s["links"]
                .as_array()
                .is_some_and(|l| l.len() == 2 && l.iter().all(|l| l["frames"].as_u64() > Some(0)));
            if heard || Instant::now() > until {
                break s;
            }
            std::thread::sleep(Duration::from_millis(200));
        };
        let dom = crate::sink_web::chromium().map(|c| {
            let out =
                crate::sink_web::headless(c, &format!("http://127.0.0.1:{web}/"), &["--dump-dom"]);
            String::from_utf8_lossy(&out.stdout).into_owned()
        });
        (state, dom)
    });
    let p = format!("{},{}", ports[0], ports[1]);
    let (peer, stderr) = link_common::peer_then_stop(
        dw,
        "redundant.py",
        &[
            "--ports",
            &p,
            "--seconds",
            "10",
            "--loss",
            "0.3,0.3",
            "--seed",
            "11",
        ],
    );
    let (state, dom) = page.join().unwrap();
    let ctx = format!("peer: {peer}\nstate: {state}\ndronewatt: {stderr}");

    // The broker keeps each link's last health: its name, what it brought, live.
    let kept = retained(&b, &["dw/links/+/health"]);
    assert_eq!(kept.len(), 2, "{kept:?}\n{ctx}");
    for (i, a) in addrs.iter().enumerate() {
        let topic = format!("dw/links/{a}/health");
        let m = kept
            .iter()
            .find(|m| m.topic == topic)
            .unwrap_or_else(|| panic!("no {topic}: {kept:?}\n{ctx}"));
        assert!(m.retained, "{m:?}");
        let h: serde_json::Value = serde_json::from_str(&m.payload).unwrap();
        assert_eq!(h["name"], a.as_str(), "{h}");
        assert_eq!(h["frames"].as_u64(), peer["sent"][i].as_u64(), "{h}\n{ctx}");
        assert!(
            h["loss_pct"].as_f64().is_some() && h["rate_hz"].as_f64().is_some(),
            "{h}"
        );
        assert!(h.get("network").is_none(), "one network: none named: {h}");
    }

    // The dashboard's JSON while flying: both links, live.
    let links = state["links"].as_array().unwrap_or_else(|| panic!("{ctx}"));
    assert_eq!(links.len(), 2, "{ctx}");
    assert!(links.iter().all(|l| l["live"] == true), "{ctx}");
    // And its page: the links panel shown, one row per link, each live.
    let Some(dom) = dom else {
        assert!(
            std::env::var("CI").is_err(),
            "CI must test the dashboard (scripts/setup-chromium.sh)"
        );
        eprintln!(
            "\n!!!!!!!! SKIPPED: no chromium; the dashboard's links panel is NOT tested !!!!!!!!\n"
        );
        return;
    };
    assert!(
        dom.contains("id=\"links-box\">"),
        "the links panel is hidden: {dom}"
    );
    for a in &addrs {
        let row = format!("<tr data-link=\"{a}\"><td>{a}</td><td>–</td><td class=\"up\">live</td>");
        assert!(dom.contains(&row), "no live row for {a}: {dom}");
    }
}
