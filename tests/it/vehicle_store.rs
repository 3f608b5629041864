//! The vehicle store across runs, end to end: the simulator flies an X500 (not the M100 the
//! models were made for) into a `.tlog`; `dronewatt replay` runs it twice with one
//! `--data-dir`. The first run is the vehicle's first flight: the models start as they are
//! and learn. The second run starts from what the first learned (read back from the SQLite
//! file the first wrote), so its adapted estimates carry the correction from the first
//! window on.
//! `dronewatt vehicles` then lists the vehicle with both flights. A corrupt or locked
//! database degrades to a run without the store, with a message, never a failure.

use crate::harness::{dronewatt, run, RunExt};
use std::path::Path;
use std::process::{Command, Output};

const PYTHON: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/.venv-py/bin/python");

/// A short X500 triangle (ArduPilot style, with its PARAM_VALUEs and battery %).
fn x500_tlog(dir: &Path) -> String {
    let tlog = dir.join("x500.tlog").to_string_lossy().into_owned();
    run(&[
        "simulate",
        "--vehicle",
        "x500",
        "--payload-g",
        "0",
        "--leg-m",
        "200",
        "--hover-s",
        "20",
        "--out",
        &tlog,
    ]);
    tlog
}

/// Replay with this data dir; (estimate lines, stderr).
fn replay(tlog: &str, data_dir: &Path, tag: &str) -> (Vec<serde_json::Value>, String) {
    let json = data_dir.parent().unwrap().join(format!("{tag}.jsonl"));
    let out = run(&[
        "replay",
        "--speed",
        "max",
        "-q",
        "--data-dir",
        data_dir.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        tlog,
    ]);
    let text = std::fs::read_to_string(&json).unwrap();
    let est = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["type"] == "estimate")
        .collect();
    (est, String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Mean |adapted − measured| / measured of the LSTM over the first `n` in-flight estimates, %.
fn early_error_pct(est: &[serde_json::Value], n: usize) -> f64 {
    let errs: Vec<f64> = est
        .iter()
        .filter_map(|e| Some((e["measured_w"].as_f64()?, e["adapted"]["lstm"].as_f64()?)))
        .filter(|(m, _)| *m > 100.0)
        .take(n)
        .map(|(m, a)| (a - m).abs() / m)
        .collect();
    assert_eq!(
        errs.len(),
        n,
        "fewer than {n} in-flight estimates with an adapted LSTM"
    );
    100.0 * errs.iter().sum::<f64>() / n as f64
}

#[test]
fn the_second_flight_starts_from_what_the_first_learned() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("store");
    let tlog = x500_tlog(dir.path());

    let (first, err1) = replay(&tlog, &data, "first");
    assert!(err1.contains("first flight in the store"), "{err1}");
    assert!(data.join("dronewatt.sqlite").exists());
    // The first estimate of the first flight: nothing learned yet, adapted = raw (never
    // below 0 W).
    let lstm = |e: &serde_json::Value| {
        (
            e["models"]["lstm"].as_f64().unwrap().max(0.0),
            e["adapted"]["lstm"].as_f64().unwrap(),
        )
    };
    let e0 = first
        .iter()
        .find(|e| e["adapted"]["lstm"].is_number())
        .expect("no adapted estimate");
    let (raw, adapted) = lstm(e0);
    assert!((raw - adapted).abs() < 1e-3, "{e0}");

    let (second, err2) = replay(&tlog, &data, "second");
    assert!(
        err2.contains("found what earlier flights learned") && err2.contains("warm start"),
        "{err2}"
    );
    // The first estimate of the second flight already carries the first flight's correction.
    let e0 = second
        .iter()
        .find(|e| e["adapted"]["lstm"].is_number())
        .unwrap();
    let (raw, adapted) = lstm(e0);
    assert!((raw - adapted).abs() > 1.0, "{e0}");
    // And the first 3 s in the air (30 windows: the take-off, before this flight has taught
    // much) are closer to the measured power than the first flight's were.
    let (cold, warm) = (early_error_pct(&first, 30), early_error_pct(&second, 30));
    assert!(
        warm < cold,
        "first 3 s in flight: {cold:.1} % cold, {warm:.1} % warm"
    );

    // The listing: one vehicle (no uid in the simulator's ArduPilot style: the heartbeat
    // key), two flights with their energy.
    let out = run(&["vehicles", "--data-dir", data.to_str().unwrap(), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let v = v.as_array().unwrap();
    assert_eq!(v.len(), 1, "{v:?}");
    assert_eq!(v[0]["key_kind"], "heartbeat");
    assert!(
        v[0]["key"].as_str().unwrap().starts_with("sys1-ardupilot-"),
        "{v:?}"
    );
    let flights = v[0]["flights"].as_array().unwrap();
    assert_eq!(flights.len(), 2);
    let used = first.last().unwrap()["energy_used_wh"].as_f64().unwrap();
    for f in flights {
        assert!(
            (f["energy_wh"].as_f64().unwrap() - used).abs() < 1e-6,
            "{f}"
        );
        assert!(f["airborne_s"].as_f64().unwrap() > 60.0, "{f}");
        assert_eq!(
            f["capacity_source"], "vehicle parameter BATT_CAPACITY",
            "{f}"
        );
    }
    // The second flight took the pack's capacity from what the first measured (energy used
    // over the autopilot's % drop) against the rated BATT_CAPACITY, each weighed by what it
    // can show (the store's posterior): between the two, and where the posterior says.
    let effective = flights[0]["effective_capacity_wh"]
        .as_f64()
        .expect("the first flight measured no capacity");
    let rated = flights[0]["rated_capacity_wh"].as_f64().unwrap();
    let fall = flights[0]["pct_start"].as_f64().unwrap() - flights[0]["pct_end"].as_f64().unwrap();
    let e = second.last().unwrap();
    assert_eq!(e["capacity_source"], "learned over 1 flight(s)", "{e}");
    let learned = e["capacity_wh"].as_f64().unwrap();
    let (w_r, w_f) = ((0.2 * rated).powi(-2), (effective * 8.0 / fall).powi(-2));
    let want = (w_r * rated + w_f * effective) / (w_r + w_f);
    assert!(
        (learned - want).abs() < 1e-6
            && learned >= effective.min(rated) - 1e-9
            && learned <= effective.max(rated) + 1e-9,
        "{e}: learned {learned}, effective {effective}, rated {rated}, fall {fall}"
    );
    // `vehicles --json` gives the capacity and the resistance with their uncertainty
    let cap = &v[0]["capacity_wh"];
    assert!(
        cap["flights"]
            .as_u64()
            .is_some_and(|n| (1..=2).contains(&n)),
        "{cap}"
    );
    assert!(
        cap["sd"]
            .as_f64()
            .is_some_and(|s| s > 0.0 && s < 0.2 * rated),
        "{cap}"
    );
    assert_eq!(
        first.last().unwrap()["capacity_source"],
        "vehicle parameter BATT_CAPACITY"
    );
    let table =
        String::from_utf8(run(&["vehicles", "--data-dir", data.to_str().unwrap()]).stdout).unwrap();
    assert!(
        table.contains("1 vehicle(s)")
            && table.contains("QUADROTOR")
            && table.contains("capacity "),
        "{table}"
    );
}

#[test]
fn a_corrupt_or_locked_store_degrades_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let tlog = x500_tlog(dir.path());
    // Not a database at all.
    let bad = dir.path().join("corrupt");
    std::fs::create_dir_all(&bad).unwrap();
    std::fs::write(bad.join("dronewatt.sqlite"), vec![0x5a; 8192]).unwrap();
    let (est, err) = replay(&tlog, &bad, "corrupt");
    assert!(!est.is_empty());
    assert!(
        err.contains("vehicle store:") && err.contains("dronewatt.sqlite"),
        "{err}"
    );
    // Held by another program (an exclusive lock for longer than the store waits).
    let locked = dir.path().join("locked");
    let (_, _) = replay(&tlog, &locked, "create");
    let db = locked.join("dronewatt.sqlite");
    let mut holder = Command::new(PYTHON)
        .args(["-c", "import sqlite3,sys,time; c=sqlite3.connect(sys.argv[1], isolation_level=None); c.execute('BEGIN EXCLUSIVE'); print('locked', flush=True); time.sleep(15)"])
        .arg(&db)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("run .venv-py/bin/python");
    let mut line = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(holder.stdout.as_mut().unwrap()),
        &mut line,
    )
    .unwrap();
    assert_eq!(line.trim(), "locked");
    let (est, err) = replay(&tlog, &locked, "locked");
    let _ = holder.kill();
    let _ = holder.wait();
    assert!(!est.is_empty());
    assert!(
        err.contains("vehicle store:") && err.contains("locked"),
        "{err}"
    );
}

/// Where `dronewatt vehicles` looks, as the environment says: `$DRONEWATT_HOME`, else the
/// XDG rule (`$XDG_DATA_HOME` when absolute, else `$HOME/.local/share`), `off` for none.
#[test]
fn the_data_dir_follows_the_environment() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let run = |home_env: Option<&str>, xdg: &str| {
        let mut c = dronewatt();
        c.arg("vehicles")
            .env_remove("DRONEWATT_HOME")
            .env("XDG_DATA_HOME", xdg)
            .env("HOME", d.join("home"));
        if let Some(h) = home_env {
            c.env("DRONEWATT_HOME", h);
        }
        c.out()
    };
    let listed = |out: Output| {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8(out.stdout).unwrap();
        text.split(": ").next().unwrap().to_string()
    };
    let xdg = d.join("xdg");
    assert_eq!(
        listed(run(None, xdg.to_str().unwrap())),
        xdg.join("dronewatt/dronewatt.sqlite").to_str().unwrap()
    );
    // A relative XDG_DATA_HOME is invalid (the XDG spec) and passed over.
    assert_eq!(
        listed(run(None, "relative/xdg")),
        d.join("home/.local/share/dronewatt/dronewatt.sqlite")
            .to_str()
            .unwrap()
    );
    let own = d.join("own");
    assert_eq!(
        listed(run(Some(own.to_str().unwrap()), xdg.to_str().unwrap())),
        own.join("dronewatt.sqlite").to_str().unwrap()
    );
    let off = run(Some("off"), xdg.to_str().unwrap());
    assert!(
        !off.status.success()
            && String::from_utf8_lossy(&off.stderr).contains("the vehicle store is off"),
        "{off:?}"
    );
}
