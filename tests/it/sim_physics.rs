//! The simulator's power model and battery (the M100 of `config/vehicles/m100.toml`): hover
//! power in the data set's range, power rising with payload and, beyond the minimum-power
//! speed, with speed; the battery's V·I = P; a whole mission's energy use.

use dronewatt::model::profile::VehicleProfile;
use dronewatt::sim::guidance::{Phase, Triangle};
use dronewatt::sim::physics::{Airframe, Battery, BatteryStart};
use dronewatt::sim::{simulate, SimFlight, SimOptions};
use nalgebra::Vector3;

/// The M100 the simulator flies: the built-in profile, the one the models read too.
fn m100() -> Airframe {
    Airframe::from_profile(&VehicleProfile::m100())
        .expect("the M100 profile has the simulator's sections")
}

fn mass(payload_g: f64) -> f64 {
    m100().mass_kg(payload_g / 1000.0)
}

fn level_w(payload_g: f64, airspeed: f64) -> f64 {
    m100()
        .power(
            mass(payload_g),
            Vector3::new(airspeed, 0.0, 0.0),
            Vector3::zeros(),
        )
        .electrical_w
}

#[test]
fn hover_power_lands_in_the_data_sets_range() {
    // The M100 data set: median power of hover rows is 523 W at 500 g and 466 W at 0 g;
    // flight 276 (500 g) has a whole-flight median of 503 W.
    let p500 = level_w(500.0, 0.0);
    let p0 = level_w(0.0, 0.0);
    assert!((480.0..=570.0).contains(&p500), "500 g hover {p500:.0} W");
    assert!((360.0..=500.0).contains(&p0), "0 g hover {p0:.0} W");
    // The breakdown adds up: (induced + profile) / η + avionics.
    let frame = m100();
    let b = frame.power(mass(500.0), Vector3::zeros(), Vector3::zeros());
    let sum = (b.induced_w + b.profile_w + b.parasitic_w + b.climb_w) / frame.efficiency
        + frame.avionics_w;
    assert!((sum - b.electrical_w).abs() < 1e-6);
    // In hover thrust equals weight and v_i is the momentum-theory value √(T/(2ρA_total)).
    let w = mass(500.0) * 9.80665;
    assert!((b.thrust_n - w).abs() < 1e-6);
    let vh = (w / (2.0 * frame.rho * 4.0 * frame.disk_area_m2())).sqrt();
    assert!(
        (b.induced_velocity_mps - vh).abs() < 1e-3,
        "v_i {} vs v_h {vh}",
        b.induced_velocity_mps
    );
}

#[test]
fn power_rises_with_payload_at_every_speed() {
    for v in [0.0, 5.0, 10.0, 15.0] {
        let ps: Vec<f64> = [0.0, 250.0, 500.0, 750.0]
            .iter()
            .map(|&g| level_w(g, v))
            .collect();
        assert!(
            ps.windows(2).all(|w| w[1] > w[0] + 5.0),
            "at {v} m/s: {ps:?}"
        );
    }
}

#[test]
fn power_has_a_bucket_and_rises_beyond_the_minimum_power_speed() {
    for payload in [0.0, 500.0] {
        let speeds: Vec<f64> = (0..=40).map(|i| i as f64 * 0.5).collect();
        let ps: Vec<f64> = speeds.iter().map(|&v| level_w(payload, v)).collect();
        let (imin, pmin) =
            ps.iter()
                .enumerate()
                .fold((0, f64::MAX), |a, (i, &p)| if p < a.1 { (i, p) } else { a });
        let vmin = speeds[imin];
        assert!(
            (4.0..=12.0).contains(&vmin),
            "minimum-power speed {vmin} m/s at {payload} g"
        );
        assert!(
            pmin < ps[0] * 0.95,
            "translational lift should save power: min {pmin:.0} vs hover {:.0}",
            ps[0]
        );
        assert!(
            ps[imin..].windows(2).all(|w| w[1] > w[0]),
            "power must rise beyond {vmin} m/s: {ps:?}"
        );
        assert!(
            ps[..=imin].windows(2).all(|w| w[1] < w[0]),
            "power must fall up to {vmin} m/s"
        );
        assert!(
            ps[40] > ps[0],
            "20 m/s must cost more than hover at {payload} g"
        );
    }
}

#[test]
fn climbing_and_accelerating_cost_more_than_hover() {
    let frame = m100();
    let m = mass(500.0);
    let hover = frame
        .power(m, Vector3::zeros(), Vector3::zeros())
        .electrical_w;
    let climb = frame
        .power(m, Vector3::new(0.0, 0.0, -2.5), Vector3::zeros())
        .electrical_w;
    let descend = frame
        .power(m, Vector3::new(0.0, 0.0, 1.5), Vector3::zeros())
        .electrical_w;
    let accel = frame
        .power(m, Vector3::zeros(), Vector3::new(2.0, 0.0, 0.0))
        .electrical_w;
    assert!(climb > hover + 50.0, "climb {climb:.0} vs hover {hover:.0}");
    assert!(descend < hover, "descent {descend:.0} vs hover {hover:.0}");
    assert!(accel > hover, "accelerating {accel:.0} vs hover {hover:.0}");
}

#[test]
fn battery_voltage_times_current_is_the_power_and_sags_under_load() {
    let mut b =
        Battery::from_profile(&VehicleProfile::m100(), BatteryStart::Soc(0.9)).expect("TB48D");
    let ocv = b.ocv_v();
    assert!((24.0..=26.1).contains(&ocv), "OCV at 90 % {ocv}");
    for p in [0.0, 100.0, 500.0, 900.0] {
        let (v, i) = b.load(p);
        assert!(
            (v * i - p).abs() < 1e-6 * p.max(1.0),
            "V·I {} vs P {p}",
            v * i
        );
        assert!(v <= ocv + 1e-9);
    }
    let (v500, _) = b.load(500.0);
    assert!(
        ocv - v500 > 0.5,
        "a 500 W load should sag the pack: {ocv} → {v500}"
    );
    let before = b.ocv_v();
    for _ in 0..600 {
        b.step(500.0, 1.0);
    }
    // 10 min at 500 W ≈ 83 Wh of a 130 Wh pack.
    assert!((b.drawn_wh - 500.0 * 600.0 / 3600.0).abs() < 1e-6);
    assert!(b.soc < 0.9 - 0.5 && b.soc > 0.0, "soc {}", b.soc);
    assert!(b.ocv_v() < before - 1.0);
}

#[test]
fn a_mission_flies_every_phase_and_payload_costs_energy() {
    let route = Triangle {
        leg_m: 150.0,
        altitude_m: 25.0,
        speed_mps: 10.0,
        hover_s: 10.0,
    }
    .route();
    let short = SimOptions {
        route,
        ..Default::default()
    };
    let heavy = simulate(&short).expect("simulate");
    let light = simulate(&SimOptions {
        payload_g: 0.0,
        ..short.clone()
    })
    .expect("simulate");
    for ph in [
        Phase::PreArm,
        Phase::Spinup,
        Phase::Climb,
        Phase::Leg(0),
        Phase::Leg(1),
        Phase::Leg(2),
        Phase::Hold(2),
        Phase::Descent,
        Phase::Landed,
        Phase::Done,
    ] {
        assert!(
            heavy.truth.iter().any(|s| s.phase == ph),
            "phase {ph:?} never flown"
        );
    }
    let max_h = heavy.truth.iter().map(|s| s.height_m).fold(0.0, f64::max);
    assert!((24.0..=26.5).contains(&max_h), "cruise height {max_h}");
    let last = heavy.truth.last().expect("truth");
    assert!(
        last.height_m.abs() < 0.05,
        "must end on the ground: {}",
        last.height_m
    );
    let cruise = |f: &SimFlight| {
        let mut v: Vec<f64> = f
            .truth
            .iter()
            .filter(|s| matches!(s.phase, Phase::Leg(_)) && s.ground_speed_mps > 9.0)
            .map(|s| s.power_w)
            .collect();
        v.sort_by(|a, b| a.total_cmp(b));
        v[v.len() / 2]
    };
    let (ch, cl) = (cruise(&heavy), cruise(&light));
    assert!(ch > cl + 40.0, "cruise 500 g {ch:.0} W vs 0 g {cl:.0} W");
    let peak = heavy
        .truth
        .iter()
        .filter(|s| s.phase == Phase::Leg(0))
        .map(|s| s.ground_speed_mps)
        .fold(0.0, f64::max);
    assert!((9.5..=10.5).contains(&peak), "leg speed {peak}");
    let e = |f: &SimFlight| {
        f.truth
            .iter()
            .map(|s| s.power_w * 0.1 / 3600.0)
            .sum::<f64>()
    };
    assert!(
        e(&heavy) > e(&light) * 1.1,
        "energy 500 g {} vs 0 g {}",
        e(&heavy),
        e(&light)
    );
}
