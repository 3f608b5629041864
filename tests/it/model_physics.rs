//! Every physics model, published and calibrated, on every window of the data set (ground
//! tests 211–219 included): no NaN, no infinity, nothing negative. Reads the real data set
//! (`DRONEWATT_DATA`) through the live ingest path.

use dronewatt::model::physics;
use dronewatt::model::profile::VehicleProfile;
use dronewatt::offline::data::load_flights;
use dronewatt::telemetry::{MissionConfig, TelemetryConfig};

#[test]
fn every_model_finite_on_every_window() {
    let path = dronewatt::default_data_path();
    let flights = load_flights(
        &path,
        None,
        &TelemetryConfig::default(),
        &MissionConfig::default(),
    )
    .expect("the data set (set DRONEWATT_DATA)");
    assert!(flights.len() >= 200, "{} flights", flights.len());
    for g in 211..=219 {
        assert!(
            flights
                .iter()
                .any(|f| f.flight == g && !f.windows.is_empty()),
            "ground test {g} missing"
        );
    }
    let cal = VehicleProfile::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config/vehicles/m100-calibrated.toml"),
    )
    .expect("committed calibrated profile");
    let mut models = physics::models(&VehicleProfile::m100());
    models.extend(physics::models(&cal));
    let mut out = Vec::new();
    let mut n = 0usize;
    for f in &flights {
        for m in models.iter_mut() {
            m.predict(&f.windows, &mut out);
            assert_eq!(out.len(), f.windows.len());
            for (i, p) in out.iter().enumerate() {
                assert!(
                    p.power_w.is_finite(),
                    "{} on flight {} window {i}: {}",
                    m.name(),
                    f.flight,
                    p.power_w
                );
                assert!(
                    p.power_w >= 0.0,
                    "{} on flight {} window {i}: negative power {} W",
                    m.name(),
                    f.flight,
                    p.power_w
                );
            }
            n += out.len();
        }
    }
    assert!(n > 1_000_000, "only {n} predictions");
}
