//! `simulate --vehicles N`: N vehicles with distinct system ids and missions in one tlog,
//! the same bytes for the same seed, and `replay` of that tlog follows every vehicle on
//! its own chain (`--json` lines carry each vehicle's system id).

use crate::harness::output;
use std::collections::BTreeMap;

fn simulate(out: &std::path::Path, n: &str, seed: &str) -> std::process::Output {
    let o = out.to_str().unwrap();
    output(&[
        "simulate",
        "--out",
        o,
        "--vehicles",
        n,
        "--seed",
        seed,
        "--leg-m",
        "120",
        "--hover-s",
        "5",
    ])
}

#[test]
fn three_vehicles_fly_their_own_missions_in_one_tlog_deterministically() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, c) = (
        dir.path().join("a.tlog"),
        dir.path().join("b.tlog"),
        dir.path().join("c.tlog"),
    );
    for (p, seed) in [(&a, "7"), (&b, "7"), (&c, "8")] {
        let o = simulate(p, "3", seed);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (ba, bb, bc) = (
        std::fs::read(&a).unwrap(),
        std::fs::read(&b).unwrap(),
        std::fs::read(&c).unwrap(),
    );
    assert!(ba == bb, "same seed, same bytes");
    assert!(ba != bc, "another seed, another flight");

    let o = output(&[
        "replay",
        a.to_str().unwrap(),
        "--speed",
        "max",
        "--json",
        "-",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Per vehicle: estimates, where it started (lon, lat), and the first point of its track
    // over ~55 m from there (east, north, in degrees of latitude): the first leg's way.
    struct Seen {
        estimates: usize,
        start: Option<(f64, f64)>,
        far: (f64, f64),
    }
    let mut per: BTreeMap<u64, Seen> = BTreeMap::new();
    for line in String::from_utf8_lossy(&o.stdout).lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let Some(id) = v["system_id"].as_u64() else {
            continue;
        };
        let e = per.entry(id).or_insert(Seen {
            estimates: 0,
            start: None,
            far: (0.0, 0.0),
        });
        if v["type"] == "estimate" && v["models"].as_object().is_some_and(|m| !m.is_empty()) {
            e.estimates += 1;
        }
        if v["type"] == "window" {
            let f = &v["features"];
            let (Some(lon), Some(lat)) = (f["position_x"].as_f64(), f["position_y"].as_f64())
            else {
                continue;
            };
            let (lon0, lat0) = *e.start.get_or_insert((lon, lat));
            let p = ((lon - lon0) * lat0.to_radians().cos(), lat - lat0);
            if e.far == (0.0, 0.0) && p.0.hypot(p.1) > 5e-4 {
                e.far = p;
            }
        }
    }
    assert_eq!(
        per.keys().copied().collect::<Vec<_>>(),
        vec![1, 2, 3],
        "one chain per simulated vehicle"
    );
    let counts: Vec<usize> = per.values().map(|v| v.estimates).collect();
    assert!(
        counts.iter().all(|&n| n > 300),
        "each flies a whole mission: {counts:?}"
    );
    // Distinct missions: the first legs point different ways (routes turned 137.5° apart).
    let dirs: Vec<f64> = per
        .values()
        .map(|v| v.far.0.atan2(v.far.1).to_degrees())
        .collect();
    for i in 0..dirs.len() {
        for j in i + 1..dirs.len() {
            let d = (dirs[i] - dirs[j]).rem_euclid(360.0);
            assert!(
                d.min(360.0 - d) > 30.0,
                "vehicles {} and {} fly the same way: {dirs:?}",
                i + 1,
                j + 1
            );
        }
    }
}

#[test]
fn a_paced_replay_reports_the_message_to_estimate_latency_of_every_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let tlog = dir.path().join("f.tlog");
    let o = simulate(&tlog, "3", "5");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Paced (as a live link delivers it, 20× faster); JSON to a file, so the terminal view
    // runs too and says it at exit.
    let json = dir.path().join("f.jsonl");
    let o = output(&[
        "replay",
        tlog.to_str().unwrap(),
        "--speed",
        "20",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&json)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // Estimates made from the link's messages (alert-only reports on a silent estimate
    // carry no models and no arrival), and per vehicle the time of its last one.
    let made: Vec<(u64, f64)> = lines
        .iter()
        .filter(|v| {
            v["type"] == "estimate" && v["models"].as_object().is_some_and(|m| !m.is_empty())
        })
        .map(|v| (v["system_id"].as_u64().unwrap(), v["t"].as_f64().unwrap()))
        .collect();
    let estimates = made.len() as u64;
    assert!(estimates > 900, "three whole flights: {estimates}");
    let mut last: BTreeMap<u64, f64> = BTreeMap::new();
    for &(id, t) in &made {
        let e = last.entry(id).or_insert(t);
        *e = e.max(t);
    }
    let final_second = made.iter().filter(|(id, t)| *t > last[id] - 1.0).count() as u64;
    let summary = lines.last().unwrap();
    assert_eq!(summary["type"], "summary");
    let l = &summary["latency"];
    // Each counted once; the only ones not counted are what the end of the log flushed
    // (no message arrived to make them): among each vehicle's final second.
    let count = l["count"].as_u64().unwrap();
    assert!(
        count <= estimates && estimates - count <= final_second,
        "{count} of {estimates} counted ({final_second} in the final seconds): {summary}"
    );
    let (p50, p99, max) = (
        l["p50_ms"].as_f64().unwrap(),
        l["p99_ms"].as_f64().unwrap(),
        l["max_ms"].as_f64().unwrap(),
    );
    assert!(0.0 <= p50 && p50 <= p99 && p99 <= max, "{l}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains(&format!("message → estimate p50 {p50:.2} ms, p99 {p99:.2} ms, max {max:.2} ms ({count} estimates)")), "{err}");
}

#[test]
fn a_fleet_of_zero_is_refused_with_the_flag_named() {
    let dir = tempfile::tempdir().unwrap();
    let o = simulate(&dir.path().join("x.tlog"), "0", "1");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--vehicles 0"), "{err}");
}

#[test]
fn lstm_rate_hz_runs_the_lstm_on_every_fifth_window_and_holds_it_between() {
    let dir = tempfile::tempdir().unwrap();
    let tlog = dir.path().join("f.tlog");
    assert!(simulate(&tlog, "2", "3").status.success());
    let cfg = dir.path().join("c.toml");
    // 2 Hz of LSTM on 10 Hz windows: every fifth window.
    std::fs::write(&cfg, "[fleet]\nlstm_rate_hz = 2\n").unwrap();
    let runs = |extra: &[&str]| -> BTreeMap<u64, Vec<(f64, f64)>> {
        let mut args = vec![
            "replay",
            tlog.to_str().unwrap(),
            "--speed",
            "max",
            "--json",
            "-",
        ];
        args.extend_from_slice(extra);
        let o = output(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let mut per: BTreeMap<u64, Vec<(f64, f64)>> = BTreeMap::new();
        for line in String::from_utf8_lossy(&o.stdout).lines() {
            let v: serde_json::Value = serde_json::from_str(line).unwrap();
            if v["type"] == "estimate" && v["models"].as_object().is_some_and(|m| !m.is_empty()) {
                let m = &v["models"];
                let lstm = m["lstm"]
                    .as_f64()
                    .unwrap_or_else(|| panic!("every estimate carries the LSTM: {v}"));
                per.entry(v["system_id"].as_u64().unwrap())
                    .or_default()
                    .push((lstm, m["dandrea"].as_f64().unwrap()));
            }
        }
        per
    };
    let changes = |xs: &[f64]| xs.windows(2).filter(|w| w[0] != w[1]).count();
    let every = runs(&[]);
    let fifth = runs(&["--config", cfg.to_str().unwrap()]);
    assert_eq!(
        every.keys().collect::<Vec<_>>(),
        fifth.keys().collect::<Vec<_>>()
    );
    for (id, est) in &fifth {
        let n = est.len();
        let lstm: Vec<f64> = est.iter().map(|e| e.0).collect();
        let physics: Vec<f64> = est.iter().map(|e| e.1).collect();
        assert_eq!(n, every[id].len(), "the same windows either way");
        assert!(
            changes(&lstm) <= n / 5 + 1 && changes(&lstm) >= n / 5 - 5,
            "vehicle {id}: LSTM changed {} times in {n} windows",
            changes(&lstm)
        );
        assert!(
            changes(&physics) > n * 4 / 5,
            "vehicle {id}: the physics models still run on every window"
        );
        // Where the LSTM ran, it says what it says at full rate (same window, same network).
        let full: Vec<f64> = every[id].iter().map(|e| e.0).collect();
        for i in (0..n).step_by(5) {
            assert!(
                (lstm[i] - full[i]).abs() < 1e-3,
                "vehicle {id}, window {i}: {} vs {}",
                lstm[i],
                full[i]
            );
        }
    }
}

#[test]
fn check_config_says_what_fleet_sets_and_names_a_bad_key() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.toml");
    std::fs::write(
        &good,
        "[fleet]\nvehicles = \"1-125\"\nlost_after_s = 3\nlstm_rate_hz = 2\n",
    )
    .unwrap();
    let o = output(&["check-config", good.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        out.contains("fleet: vehicles 1-125, lost after 3 s, dropped after 60 s")
            && out.contains("LSTM at 2 Hz per vehicle"),
        "{out}"
    );
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[fleet]\nvehicles = \"1-300\"\ndrop_after_s = 1\n").unwrap();
    let o = output(&["check-config", bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("fleet.vehicles")
            && err.contains("\"300\"")
            && err.contains("fleet.drop_after_s"),
        "{err}"
    );
    let o = output(&["monitor", "udpin:127.0.0.1:9", "--vehicles", "7-3"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("--vehicles 7-3") && err.contains("backwards"),
        "{err}"
    );
}
