//! The simulator's other airframes (`config/vehicles/x500.toml`, `quad-3s.toml`): hover
//! power against momentum theory and published figures, the PARAM_VALUEs each autopilot
//! style sends, and each airframe flown through the whole pipeline (`dronewatt replay` of
//! its tlog) with the measured power the telemetry stage sees checked against the
//! simulator's truth.

use crate::harness::{dronewatt, RunExt};
use std::path::Path;

use dronewatt::model::profile::VehicleProfile;
use dronewatt::sim::guidance::{Phase, Triangle};
use dronewatt::sim::physics::Airframe;
use dronewatt::sim::{simulate, Autopilot, SimFlight, SimOptions};
use dronewatt::MavMessage;
use nalgebra::Vector3;

fn profile(name: &str) -> VehicleProfile {
    VehicleProfile::named_or_file(name).unwrap_or_else(|e| panic!("{e:#}"))
}

fn short(vehicle: &str, autopilot: Autopilot) -> SimOptions {
    SimOptions {
        vehicle: profile(vehicle),
        route: Triangle {
            leg_m: 120.0,
            altitude_m: 20.0,
            speed_mps: 8.0,
            hover_s: 10.0,
        }
        .route(),
        payload_g: 0.0,
        autopilot,
        ..Default::default()
    }
}

#[test]
fn hover_power_agrees_with_momentum_theory_and_published_figures() {
    // (profile, take-off mass kg, published hover power range W): X500 V2 on 4S ≈ 250–350 W;
    // a 1 kg 3S quad with 7-inch props ≈ 100–180 W; the M100's data set (466 W at 0 g).
    for (name, mass_kg, lo, hi) in [
        ("x500", 2.0, 250.0, 350.0),
        ("quad-3s", 1.0, 100.0, 180.0),
        ("m100", 2.431, 360.0, 500.0),
    ] {
        let frame = Airframe::from_profile(&profile(name)).expect("simulator sections");
        assert!(
            (frame.mass_kg(0.0) - mass_kg).abs() < 1e-9,
            "{name}: empty mass {}",
            frame.mass_kg(0.0)
        );
        let b = frame.power(mass_kg, Vector3::zeros(), Vector3::zeros());
        assert!(
            (lo..=hi).contains(&b.electrical_w),
            "{name}: hover {:.0} W, published {lo}–{hi} W",
            b.electrical_w
        );
        // Momentum theory: ideal power T^1.5/√(2ρA). A small rotor's figure of merit is 0.5–0.75.
        let ideal = frame.ideal_hover_w(mass_kg);
        let fm = ideal / (b.induced_w + b.profile_w);
        assert!(
            (0.5..=0.75).contains(&fm),
            "{name}: figure of merit {fm:.2} (ideal {ideal:.0} W)"
        );
        // And the electrical draw is the mechanical one over η plus avionics, nothing else.
        assert!(
            ((b.induced_w + b.profile_w) / frame.efficiency + frame.avionics_w - b.electrical_w)
                .abs()
                < 1e-9
        );
    }
    // Endurance follows: the X500's 74 Wh pack hovers ~15 min, the 3S quad's 36 Wh ~15 min.
    for (name, lo_min, hi_min) in [("x500", 12.0, 19.0), ("quad-3s", 12.0, 19.0)] {
        let p = profile(name);
        let frame = Airframe::from_profile(&p).expect("sections");
        let wh = p.battery.as_ref().expect("battery").energy_wh();
        let min = wh
            / frame
                .power(frame.mass_kg(0.0), Vector3::zeros(), Vector3::zeros())
                .electrical_w
            * 60.0;
        assert!(
            (lo_min..=hi_min).contains(&min),
            "{name}: {wh:.0} Wh lasts {min:.1} min in the hover"
        );
    }
}

/// The PARAM_VALUEs of a flight, by name: (value, type, index, count).
fn params(f: &SimFlight) -> Vec<(String, f32, dronewatt::dialect::MavParamType, u16, u16)> {
    f.records
        .iter()
        .filter_map(|r| match &r.msg {
            MavMessage::PARAM_VALUE(p) => Some((
                p.param_id.to_str().unwrap_or("").to_string(),
                p.param_value,
                p.param_type,
                p.param_index,
                p.param_count,
            )),
            _ => None,
        })
        .collect()
}

#[test]
fn each_style_sends_its_battery_parameters_in_its_own_encoding() {
    use dronewatt::dialect::MavParamType::*;
    let ap = simulate(&short("x500", Autopilot::Ardupilot)).expect("simulate");
    let got = params(&ap);
    let find = |g: &[(String, f32, _, u16, u16)], k: &str| {
        g.iter()
            .find(|p| p.0 == k)
            .cloned()
            .unwrap_or_else(|| panic!("{k} missing: {g:?}"))
    };
    // ArduPilot casts integers to the float.
    let cap = find(&got, "BATT_CAPACITY");
    assert_eq!((cap.1, cap.2), (5000.0, MAV_PARAM_TYPE_INT32));
    assert_eq!(find(&got, "FRAME_CLASS").1, 1.0);
    assert!(
        (find(&got, "BATT_LOW_VOLT").1 - 14.4).abs() < 1e-5,
        "4S × 3.6 V"
    );
    assert!(
        got.iter()
            .enumerate()
            .all(|(i, p)| p.3 as usize == i && p.4 as usize == got.len()),
        "index/count: {got:?}"
    );
    // At the start: within the first second, after the first heartbeat.
    let first = ap
        .records
        .iter()
        .position(|r| matches!(r.msg, MavMessage::PARAM_VALUE(_)))
        .expect("params");
    assert!(
        matches!(ap.records[0].msg, MavMessage::HEARTBEAT(_))
            && ap.records[first].t_us - ap.records[0].t_us < 1_000_000
    );
    // PX4 packs integers bytewise into the float.
    let px4 = params(&simulate(&short("quad-3s", Autopilot::Px4)).expect("simulate"));
    let cells = find(&px4, "BAT1_N_CELLS");
    assert_eq!((cells.1.to_bits(), cells.2), (3, MAV_PARAM_TYPE_INT32));
    assert_eq!(find(&px4, "BAT1_CAPACITY").1, 3300.0);
    assert!(
        px4.iter().all(|p| !p.0.starts_with("BATT_")),
        "PX4 has no ArduPilot names"
    );
}

#[test]
fn each_airframe_through_the_pipeline_measures_the_simulators_power() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (vehicle, autopilot, hover_lo, hover_hi) in [
        ("x500", Autopilot::Ardupilot, 250.0, 350.0),
        ("x500", Autopilot::Px4, 250.0, 350.0),
        ("quad-3s", Autopilot::Ardupilot, 100.0, 180.0),
        ("quad-3s", Autopilot::Px4, 100.0, 180.0),
    ] {
        let flight = simulate(&short(vehicle, autopilot)).expect("simulate");
        let tlog = dir.path().join(format!("{vehicle}-{autopilot:?}.tlog"));
        std::fs::write(&tlog, flight.to_tlog()).expect("write");
        let out = dronewatt()
            .env("RUST_LOG", "warn")
            .args([
                "replay",
                tlog.to_str().expect("utf-8"),
                "--speed",
                "max",
                "-q",
                "--json",
                "-",
            ])
            .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")))
            .ok();
        // Pair each estimate's measured power with the truth at its time (10 Hz samples).
        let mut pairs = Vec::new();
        for line in String::from_utf8_lossy(&out.stdout).lines() {
            let v: serde_json::Value = serde_json::from_str(line).expect("JSON line");
            if v["type"] != "estimate" {
                continue;
            }
            let (Some(t), Some(w)) = (v["t"].as_f64(), v["measured_w"].as_f64()) else {
                continue;
            };
            if let Some(s) = flight.truth.get((t * 10.0).round() as usize) {
                assert!((s.t_s - t).abs() < 0.051, "truth at {} for t {t}", s.t_s);
                pairs.push((s.phase, s.power_w, w));
            }
        }
        let label = format!("{vehicle} {autopilot:?}");
        let flying: Vec<_> = pairs.iter().filter(|p| p.0.in_air()).collect();
        assert!(
            flying.len() > 300,
            "{label}: {} in-flight estimates",
            flying.len()
        );
        // Over the flight the means agree within 2 % (the current sensor's noise averages out).
        let mean = |f: &dyn Fn(&(Phase, f64, f64)) -> f64| {
            flying.iter().map(|p| f(p)).sum::<f64>() / flying.len() as f64
        };
        let (truth_w, measured_w) = (mean(&|p| p.1), mean(&|p| p.2));
        assert!(
            (measured_w / truth_w - 1.0).abs() < 0.02,
            "{label}: measured {measured_w:.1} W vs truth {truth_w:.1} W"
        );
        // Window by window, the median error is the sensor's (σ_I ≈ 7 %), not a bias.
        let mut rel: Vec<f64> = flying.iter().map(|p| (p.2 / p.1 - 1.0).abs()).collect();
        rel.sort_by(f64::total_cmp);
        assert!(
            rel[rel.len() / 2] < 0.06,
            "{label}: median |error| {:.3}",
            rel[rel.len() / 2]
        );
        // And the hover the pipeline sees is in the airframe's published range.
        let mut hover: Vec<f64> = pairs
            .iter()
            .filter(|p| matches!(p.0, Phase::Hold(_)))
            .map(|p| p.2)
            .collect();
        hover.sort_by(f64::total_cmp);
        let med = hover[hover.len() / 2];
        assert!(
            (hover_lo..=hover_hi).contains(&med),
            "{label}: hover {med:.0} W"
        );
    }
}
