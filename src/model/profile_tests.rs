//! Tests of `src/model/profile.rs` (a file of their own: the module stays under 600 lines).

use super::*;

#[test]
fn builtin_parses_and_matches_dji_figures() {
    let p = VehicleProfile::m100();
    assert_eq!(p.vehicle.rotors, 4);
    assert!((p.mass_kg(0.0) - (1.755 + 0.676)).abs() < 1e-12);
    // 13-inch props: 4·π·0.1651² = 0.3425 m².
    assert!((p.disk_area_m2() - 0.34253).abs() < 1e-4);
    assert!(p.calibration.is_none());
}

#[test]
fn roundtrip_and_unknown_keys_rejected() {
    let p = VehicleProfile::m100();
    let text = toml::to_string(&p).unwrap();
    assert_eq!(VehicleProfile::from_toml(&text, "x").unwrap(), p);
    let bad = format!("{text}\nbogus = 1\n");
    let e = VehicleProfile::from_toml(&bad, "bad.toml").unwrap_err();
    assert!(format!("{e:#}").contains("bad.toml"));
    let neg = text.replace("rho_kg_m3 = 1.225", "rho_kg_m3 = -1.0");
    assert!(
        format!("{:#}", VehicleProfile::from_toml(&neg, "n").unwrap_err()).contains("rho_kg_m3")
    );
}

#[test]
fn every_built_in_profile_parses_and_matches_its_file() {
    for (name, text) in BUILT_IN {
        let p = VehicleProfile::named_or_file(name).unwrap_or_else(|e| panic!("{e:#}"));
        let file =
            Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("config/vehicles/{name}.toml"));
        assert_eq!(
            std::fs::read_to_string(&file).unwrap(),
            text,
            "{name}: the compiled-in text is the file"
        );
        // What the simulator flies it with: rotors, or a wing ([plane]), or both.
        let rotors = p.rotor.is_some() && p.body.is_some() && p.powertrain.is_some();
        assert!(
            (rotors || p.plane.is_some()) && p.battery.is_some(),
            "{name}"
        );
        assert_eq!(p.plane.is_some(), p.fixed_wing.is_some(), "{name}");
    }
    let e = VehicleProfile::named_or_file("no-such-vehicle")
        .unwrap_err()
        .to_string();
    assert!(e.contains("no-such-vehicle") && e.contains("x500"), "{e}");
}

#[test]
fn the_simulators_sections_are_optional_checked_and_the_tb48d_holds_its_rating() {
    let p = VehicleProfile::m100();
    let b = p.battery.as_ref().expect("m100.toml has [battery]");
    // DJI rates the TB48D at 129.96 Wh (5.7 Ah × 22.8 V); the OCV curve's mean gives the same within 3 %.
    assert!(
        (b.energy_wh() / 129.96 - 1.0).abs() < 0.03,
        "{} Wh",
        b.energy_wh()
    );
    assert!(
        (b.ocv_cell_at(1.0) * 6.0 - 26.1).abs() < 1e-9,
        "charges to 26.1 V"
    );
    assert!(
        (b.ocv_cell_at(0.55) - 3.90).abs() < 1e-9,
        "linear between points"
    );
    // A profile for the models alone (no simulator sections) still loads.
    let bare = VehicleProfile {
        rotor: None,
        body: None,
        powertrain: None,
        battery: None,
        ..p.clone()
    };
    let text = toml::to_string(&bare).unwrap();
    assert!(!text.contains("[battery]"));
    assert_eq!(VehicleProfile::from_toml(&text, "bare").unwrap(), bare);
    // A falling OCV curve or a zero resistance is refused, naming the key.
    let mut bad = p.clone();
    if let Some(b) = bad.battery.as_mut() {
        b.ocv_cell_v[3][1] = 3.0;
    }
    assert!(bad
        .validate()
        .unwrap_err()
        .contains("battery.ocv_cell_v[3]"));
    let mut bad = p.clone();
    if let Some(b) = bad.battery.as_mut() {
        b.internal_resistance_ohm = 0.0;
    }
    assert!(bad
        .validate()
        .unwrap_err()
        .contains("battery.internal_resistance_ohm"));
    let mut bad = p;
    if let Some(w) = bad.powertrain.as_mut() {
        w.efficiency = 1.5;
    }
    assert!(bad
        .validate()
        .unwrap_err()
        .contains("powertrain.efficiency"));
}

#[test]
fn does_not_transfer_names_only_physics_models_and_lists_them() {
    let mut p = VehicleProfile::m100();
    p.does_not_transfer = vec!["tseng".into(), "tseng_solo".into()];
    assert_eq!(p.validate(), Ok(()));
    p.does_not_transfer = vec!["lstm".into()];
    let e = p.validate().unwrap_err();
    assert!(e.contains("does_not_transfer: 'lstm'"), "{e}");
    assert!(
        e.contains("dandrea, dandrea_headwind, dorling, stolaroff, kirschstein, tseng, tseng_solo"),
        "{e}"
    );
}
