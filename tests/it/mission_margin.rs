//! A simulated flight of a hand-written plan (`simulate --plan`), replayed: with a battery
//! too small for the mission and its reserve, `mission_margin_below` must be raised before
//! the point of no return, defined from the simulator's truth; with a battery big enough,
//! never.
//!
//! The plan is an out-and-back: take off, fly 1.5 km north, return to launch. The point of
//! no return is the first moment on the way out when the energy drawn so far plus what the
//! simulated vehicle actually drew flying back home from that distance (and landing) is
//! more than the usable energy (capacity − reserve): after it, turning back no longer
//! lands with the reserve left.
//!
//! Each battery is the simulated vehicle's own (an M100 profile with that capacity): the
//! simulator's pack sags as the pack model says, and the replay reads its resting voltage,
//! so remaining energy is what the pack gives before its loaded voltage reaches
//! BATT_LOW_VOLT.

use crate::harness::{dronewatt, RunExt};

use dronewatt::sim::guidance::Phase;
use dronewatt::sim::{self, SimMission, SimOptions, TruthSample};
use serde_json::Value;

const PLAN: &str = "QGC WPL 110\n\
0\t1\t0\t16\t0\t0\t0\t0\t40.4590600\t-79.7828200\t268.7\t1\n\
1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t25\t1\n\
2\t0\t3\t16\t0\t0\t0\t0\t40.4725350\t-79.7828200\t25\t1\n\
3\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1\n";

const RESERVE_PCT: f64 = 20.0;

/// Energy (Wh) of the truth samples (10 Hz).
fn wh(s: &[TruthSample]) -> f64 {
    s.iter().map(|x| x.power_w * 0.1 / 3600.0).sum()
}

/// The point of no return, s since the start of the simulation, for `usable_wh`.
fn point_of_no_return(truth: &[TruthSample], usable_wh: f64) -> f64 {
    let back_start = truth
        .iter()
        .position(|s| s.phase == Phase::Leg(1))
        .expect("a return leg");
    for (i, s) in truth.iter().enumerate().take(back_start) {
        if !matches!(s.phase, Phase::Climb | Phase::Leg(0) | Phase::Hold(0)) {
            continue;
        }
        // flying back from here: from where the return leg passes this distance, to the end
        let j = truth[back_start..]
            .iter()
            .position(|b| b.north_m <= s.north_m)
            .map_or(truth.len(), |k| back_start + k);
        if wh(&truth[..=i]) + wh(&truth[j..]) > usable_wh {
            return s.t_s;
        }
    }
    f64::INFINITY
}

/// The same flight (`simulate --plan`, no wind, 500 g) on an M100 whose TB48D-like pack
/// holds `capacity_wh` (6S LiHV, mAh × 6 × 3.8 V), so the simulated pack's voltage is the one
/// the replay's pack model expects of that capacity.
fn fly_with_pack(
    dir: &std::path::Path,
    plan: &std::path::Path,
    capacity_wh: f64,
) -> std::path::PathBuf {
    let m100 = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/vehicles/m100.toml"
    ))
    .unwrap();
    let mah = capacity_wh / (6.0 * 3.8) * 1000.0;
    let profile = dir.join(format!("m100-{capacity_wh:.0}.toml"));
    std::fs::write(
        &profile,
        m100.replace(
            "capacity_mah = 5700.0 ",
            &format!("capacity_mah = {mah:.3} "),
        ),
    )
    .unwrap();
    let tlog = dir.join(format!("flight-{capacity_wh:.0}.tlog"));
    let out = dronewatt()
        .arg("simulate")
        .arg("--plan")
        .arg(plan)
        .args([
            "--speed-mps",
            "10",
            "--wind-mps",
            "0",
            "--payload-g",
            "500",
            "--vehicle",
        ])
        .arg(&profile)
        .arg("--out")
        .arg(&tlog)
        .out();
    assert!(
        out.status.success(),
        "simulate --vehicle {}: {}",
        profile.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    tlog
}

/// Replay `tlog` flat out with this battery; the `mission_margin` alert events (t, state)
/// and the estimates' mission margins.
fn replay(tlog: &std::path::Path, capacity_wh: f64) -> (Vec<(f64, String)>, Vec<f64>) {
    let dir = tlog.parent().unwrap();
    let cfg = dir.join(format!("dw-{capacity_wh:.0}.toml"));
    let calibrated = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/vehicles/m100-calibrated.toml"
    );
    std::fs::write(
        &cfg,
        format!(
            "[energy]\ncapacity_wh = {capacity_wh}\nchemistry = \"lihv\"\ncell_count = 6\nreserve_pct = {RESERVE_PCT}\nuse_battery_pct = false\n\n\
             [mission]\npayload_g = 500\n\n\
             [forecast.live]\ncalibrated_profile = \"{calibrated}\"\n\n\
             [[alerts]]\nname = \"mission_margin\"\nkind = \"mission_margin_below\"\nbelow_wh = 0\nclear_wh = 2\nfor_s = 3\n\
             severity = \"critical\"\nmessage = \"mission cannot finish with reserve - return now\"\n"
        ),
    )
    .unwrap();
    let json = dir.join(format!("out-{capacity_wh:.0}.jsonl"));
    let _out = dronewatt()
        .arg("replay")
        .arg(tlog)
        .args(["--speed", "max", "-q", "--config"])
        .arg(&cfg)
        .arg("--json")
        .arg(&json)
        .ok();
    let (mut alerts, mut margins) = (Vec::new(), Vec::new());
    for line in std::fs::read_to_string(&json).unwrap().lines() {
        let v: Value = serde_json::from_str(line).unwrap();
        if v["type"] == "alert" && v["rule"] == "mission_margin" {
            alerts.push((
                v["t"].as_f64().unwrap(),
                v["state"].as_str().unwrap().to_string(),
            ));
        }
        if let Some(m) = v["mission_margin_wh"].as_f64() {
            margins.push(m);
        }
    }
    (alerts, margins)
}

#[test]
fn a_battery_too_small_for_the_plan_raises_mission_margin_below_before_the_point_of_no_return() {
    let dir = tempfile::tempdir().unwrap();
    let plan_path = dir.path().join("out-and-back.waypoints");
    std::fs::write(&plan_path, PLAN).unwrap();
    let tlog = dir.path().join("flight.tlog");
    let _out = dronewatt()
        .arg("simulate")
        .arg("--plan")
        .arg(&plan_path)
        .args([
            "--speed-mps",
            "10",
            "--wind-mps",
            "0",
            "--payload-g",
            "500",
            "--out",
        ])
        .arg(&tlog)
        .ok();

    // The same flight in-process, for the truth (the simulator is deterministic: the CLI's
    // tlog is byte for byte this one's).
    let plan = dronewatt::mission::plan::Plan::load(&plan_path).unwrap();
    let (route, mission) = SimMission::from_plan(&plan, 10.0, sim::Autopilot::Ardupilot).unwrap();
    let opts = SimOptions {
        route,
        mission: Some(mission),
        wind_mps: 0.0,
        payload_g: 500.0,
        ..Default::default()
    };
    let flight = sim::simulate(&opts).unwrap();
    let again = dir.path().join("again.tlog");
    sim::output::write_tlog(&again, &flight).unwrap();
    assert_eq!(
        std::fs::read(&tlog).unwrap(),
        std::fs::read(&again).unwrap(),
        "the CLI flew the same flight"
    );
    let north_max = flight.truth.iter().map(|s| s.north_m).fold(0.0, f64::max);
    assert!(
        (1450.0..1550.0).contains(&north_max),
        "flew the plan's 1.5 km out: {north_max} m"
    );
    let total_wh = wh(&flight.truth);

    // Too small: usable energy 75 % of what the mission takes.
    let small = 0.75 * total_wh / (1.0 - RESERVE_PCT / 100.0);
    let pnr = point_of_no_return(&flight.truth, small * (1.0 - RESERVE_PCT / 100.0));
    let takeoff = flight
        .truth
        .iter()
        .find(|s| s.phase == Phase::Climb)
        .unwrap()
        .t_s;
    assert!(
        pnr.is_finite() && pnr > takeoff + 30.0,
        "a point of no return on the way out: {pnr} s (take-off {takeoff} s)"
    );
    // The simulated pack is this small one: its voltage, from the pack model, says so.
    let (alerts, margins) = replay(&fly_with_pack(dir.path(), &plan_path, small), small);
    assert!(
        !margins.is_empty(),
        "the mission was taken from the log and forecast"
    );
    // A replay's clock starts at the tlog's first stamp, the simulation's t = 0.
    let t0 = flight
        .records
        .first()
        .map_or(0.0, |r| (r.t_us - sim::EPOCH_START_US) as f64 / 1e6);
    let raised: Vec<f64> = alerts
        .iter()
        .filter(|a| a.1 == "raised")
        .map(|a| a.0 - t0)
        .collect();
    assert!(
        !raised.is_empty(),
        "mission_margin_below raised; margins {:?}…",
        &margins[..margins.len().min(5)]
    );
    assert!(
        raised[0] < pnr,
        "raised at {:.1} s, the point of no return is {pnr:.1} s",
        raised[0]
    );
    let cleared_before_pnr = alerts.iter().any(|a| a.1 == "cleared" && a.0 - t0 < pnr);
    assert!(
        !cleared_before_pnr,
        "stays raised on the way out: {alerts:?}"
    );
    eprintln!("total {total_wh:.1} Wh, capacity {small:.1} Wh, raised at {:.1} s, point of no return {pnr:.1} s", raised[0]);

    // Big enough: never raised. The energy usable is what the pack gives before its loaded
    // voltage sags to BATT_LOW_VOLT (the simulated pack sags), the reserve kept on top: a
    // pack of 2.5 × the mission over the reserve (was 1.3 × before the simulator sagged;
    // 1.6 × dips under 0, 2.0 × does not).
    let big = 2.5 * total_wh / (1.0 - RESERVE_PCT / 100.0);
    let (alerts, margins) = replay(&fly_with_pack(dir.path(), &plan_path, big), big);
    assert!(
        margins.iter().all(|m| *m > 0.0) && !margins.is_empty(),
        "positive margin throughout"
    );
    assert!(alerts.is_empty(), "{alerts:?}");
}

#[test]
fn a_px4_log_without_a_home_item_is_forecast_like_the_ardupilot_one() {
    let dir = tempfile::tempdir().unwrap();
    let plan_path = dir.path().join("out-and-back.waypoints");
    std::fs::write(&plan_path, PLAN).unwrap();
    let mut first = Vec::new();
    for ap in ["ardupilot", "px4"] {
        let tlog = dir.path().join(format!("{ap}.tlog"));
        let _out = dronewatt()
            .arg("simulate")
            .arg("--plan")
            .arg(&plan_path)
            .args(["--wind-mps", "0", "--autopilot", ap, "--out"])
            .arg(&tlog)
            .ok();
        let (alerts, margins) = replay(&tlog, 200.0);
        assert!(alerts.is_empty(), "{ap}: {alerts:?}");
        assert!(
            margins.len() > 100,
            "{ap}: the mission was forecast ({} estimates with it)",
            margins.len()
        );
        first.push(margins[margins.len() / 2]);
    }
    // The same mission at the same point of the flight: the same margin within 1.5 Wh.
    assert!(
        (first[0] - first[1]).abs() < 1.5,
        "ArduPilot vs PX4 margin half way: {first:?}"
    );
}
