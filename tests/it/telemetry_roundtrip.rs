//! The key test of issue 3: a data-set flight replayed through the MAVLink encoder and the
//! live ingest path (tlog bytes → decode → `Telemetry`) yields the same windows as the
//! CSV's own columns put through the same resampler, on every sample, within the
//! resolution of the MAVLink fields that carry them.
//!
//! Needs the data set (`DRONEWATT_DATA`, default `../shared/data/m100/flights.csv.gz`).

use dronewatt::features::{idx, FEATURE_NAMES, N_FEATURES};
use dronewatt::offline::data::flight_windows;
use dronewatt::source::logs::dataset::{read_flights, Flight};
use dronewatt::telemetry::resample::{Resampler, Signal};
use dronewatt::telemetry::window::{Window, WindowRing};
use dronewatt::telemetry::{MissionConfig, TelemetryConfig};

/// The CSV columns resampled directly, windowed the way `Telemetry` windows.
fn csv_windows(f: &Flight, cfg: &TelemetryConfig) -> Vec<Window> {
    let mut rs = Resampler::new(cfg.rate_hz, cfg.stale_after_s, cfg.max_gap_s);
    rs.set_mission(f.speed_m_s as f32, f.payload_g as f32, f.altitude_m as f32);
    if let Some(r) = f.rows.iter().find(|r| r.lat_deg != 0.0 || r.lon_deg != 0.0) {
        rs.set_home([r.lat_deg, r.lon_deg, r.alt_m]);
    }
    let mut ring = WindowRing::new(cfg.window);
    let (mut samples, mut out) = (Vec::new(), Vec::new());
    for r in &f.rows {
        let t = (r.time_s * 1e6).round() as i64;
        rs.update(Signal::Wind, t, &[r.wind_speed, r.wind_angle]);
        rs.update(Signal::Position, t, &[r.lon_deg, r.lat_deg, r.alt_m]);
        rs.update(Signal::Attitude, t, &r.q_wxyz());
        rs.update(Signal::Velocity, t, &r.vel);
        rs.update(Signal::Rates, t, &r.ang);
        rs.update(Signal::Accel, t, &r.acc);
        rs.update(
            Signal::Power,
            t,
            &[r.voltage_v, r.current_a, r.voltage_v * r.current_a],
        );
        if rs.take_restart() {
            ring.clear();
        }
        rs.poll(&mut samples);
        out.extend(samples.drain(..).filter_map(|s| ring.push(s)));
    }
    rs.finish(&mut samples);
    out.extend(samples.drain(..).filter_map(|s| ring.push(s)));
    out
}

/// Encoding resolution per feature (absolute), on top of one f32 step of the value:
/// - wind speed: f32 WIND vector minus f32 ground velocity, ~1e-6 m/s;
/// - wind angle: 0.01° (f32 vector arithmetic at ≥ 0.05 m/s; not compared when a
///   bracketing row has a wind speed under 0.05 m/s, where a vector carries no angle);
/// - longitude/latitude: 1e-7° (GLOBAL_POSITION_INT), half of it by rounding;
/// - altitude: 1 mm, half of it by rounding;
/// - quaternion: f32 ATTITUDE_QUATERNION and two exact rotations, 1e-6;
/// - velocity: f32 LOCAL_POSITION_NED plus the heading from the f32 quaternion, 1e-5 m/s;
/// - rates, acceleration: f32 HIGHRES_IMU/ATTITUDE, 1e-6;
/// - mission: f32 NAMED_VALUE_FLOAT of small integers, exact.
const RES: [f32; N_FEATURES] = [
    1e-4, 0.01, 5e-8, 5e-8, 5e-4, 1e-6, 1e-6, 1e-6, 1e-6, 1e-5, 1e-5, 1e-5, 1e-6, 1e-6, 1e-6, 1e-6,
    1e-6, 1e-6, 0.0, 0.0, 0.0,
];
/// Power: voltage in mV (±0.5 mV) and current in cA (±5 mA, ±15 mA where −0.01 A, the
/// "not measured" sentinel, is sent as 0): |ΔP| ≤ 0.0005·47.2 + 0.015·25.9 ≈ 0.41 W.
const POWER_TOL_W: f32 = 0.42;
const VOLT_TOL_V: f32 = 6e-4;

fn ulp(x: f32) -> f32 {
    let a = x.abs();
    f32::from_bits(a.to_bits() + 1) - a
}

fn check_flight(flight: u32) -> (usize, usize) {
    let path = dronewatt::default_data_path();
    let ds = read_flights(&path, Some(&[flight])).expect("data set readable");
    let f = &ds.flights[0];
    let cfg = TelemetryConfig::default();
    let want = csv_windows(f, &cfg);
    let got = flight_windows(f, &cfg, &MissionConfig::default()).windows;
    assert_eq!(got.len(), want.len(), "flight {flight}: window count");
    assert!(!got.is_empty());
    // decode_tlog counts t_s from the first record, which is the first row.
    let base_s = -f.rows[0].time_s;
    let row_t: Vec<f64> = f.rows.iter().map(|r| r.time_s).collect();
    let mut compared = 0;
    for (wi, (g, w)) in got.iter().zip(&want).enumerate() {
        for (a, b) in g.samples.iter().zip(&w.samples) {
            assert!(
                (a.t_s - base_s - b.t_s).abs() < 1e-5,
                "flight {flight} window {wi}: t {} vs {}",
                a.t_s - base_s,
                b.t_s
            );
            assert_eq!(
                a.stale_mask, b.stale_mask,
                "flight {flight} t={}: stale mask",
                b.t_s
            );
            // Rows bracketing this grid time (for the wind-angle rule).
            let k = row_t.partition_point(|&t| t < b.t_s);
            let calm = [k.saturating_sub(1), k.min(row_t.len() - 1)]
                .iter()
                .any(|&j| f.rows[j].wind_speed < 0.05);
            for i in 0..N_FEATURES {
                if i == idx::WIND_ANGLE && calm {
                    continue;
                }
                let (x, y) = (a.features[i], b.features[i]);
                let d = if i == idx::WIND_ANGLE {
                    ((x - y + 180.0).rem_euclid(360.0) - 180.0).abs()
                } else {
                    (x - y).abs()
                };
                let tol = RES[i] + ulp(y).max(ulp(x));
                assert!(
                    d <= tol,
                    "flight {flight} t={:.2}: {} = {x} via MAVLink, {y} from the CSV (tol {tol})",
                    b.t_s,
                    FEATURE_NAMES[i]
                );
            }
            let (pa, pb) = (
                a.measured_w.expect("power present"),
                b.measured_w.expect("power present"),
            );
            assert!(
                (pa - pb).abs() <= POWER_TOL_W,
                "flight {flight} t={:.2}: power {pa} vs {pb}",
                b.t_s
            );
            let (va, vb) = (a.voltage_v.expect("voltage"), b.voltage_v.expect("voltage"));
            assert!(
                (va - vb).abs() <= VOLT_TOL_V,
                "flight {flight} t={:.2}: voltage {va} vs {vb}",
                b.t_s
            );
            // Home: HOME_POSITION carries 1e-7° (≈ 1 cm) and 1 mm.
            let (ha, hb) = (a.home.expect("home"), b.home.expect("home"));
            assert!(
                (ha.distance_m - hb.distance_m).abs() < 0.03
                    && (ha.height_m - hb.height_m).abs() < 2e-3,
                "{ha:?} vs {hb:?}"
            );
            compared += 1;
        }
    }
    (got.len(), compared)
}

#[test]
fn flight_276_replayed_as_mavlink_matches_the_csv() {
    let (windows, samples) = check_flight(276);
    // 147.9 s at 10 Hz, minus the first T−1 samples.
    assert!((1460..=1480).contains(&windows), "{windows} windows");
    assert_eq!(samples, windows * 10);
}

#[test]
fn flight_278_with_a_5_s_gap_matches_and_no_window_spans_the_gap() {
    check_flight(278);
    let path = dronewatt::default_data_path();
    let ds = read_flights(&path, Some(&[278])).expect("data set readable");
    let cfg = TelemetryConfig::default();
    let fw = flight_windows(&ds.flights[0], &cfg, &MissionConfig::default());
    let span = (cfg.window - 1) as f64 / cfg.rate_hz + 1e-6;
    for w in &fw.windows {
        assert!(
            w.samples.last().unwrap().t_s - w.samples[0].t_s <= span,
            "a window spans a gap"
        );
    }
    // The 5.28 s gap is in this flight: some consecutive windows are more than a step apart.
    assert!(fw.windows.windows(2).any(|p| p[1].t_s() - p[0].t_s() > 5.0));
    assert_eq!(fw.route, "R7");
}
