use super::*;
use crate::model::physics::testutil::{kinematics, sample};

const FIVE: &str = r#"
name = "Spec quad"
[vehicle]
takeoff_kg = 1.3
rotors = 4
prop_diameter_m = 0.254
[battery]
cells = 3
capacity_mah = 5100
chemistry = "lipo"
"#;

fn load(text: &str) -> anyhow::Result<VehicleProfile> {
    VehicleProfile::from_toml(text, "spec.toml")
}

fn err(text: &str) -> String {
    format!("{:#}", load(text).unwrap_err())
}

#[test]
fn five_facts_make_a_vehicle_flying_momentum_theory_with_the_priors() {
    let p = load(FIVE).unwrap();
    assert_eq!(p.name, "Spec quad");
    assert!((p.mass_kg(0.0) - 1.3).abs() < 1e-9, "take-off mass kept");
    // 3S 5100 mAh LiPo: 56.6 Wh at 150 Wh/kg = 0.377 kg.
    assert!((p.vehicle.battery_kg - 5.1 * 3.0 * 3.7 / 150.0).abs() < 1e-9);
    let b = p.battery.as_ref().unwrap();
    assert_eq!((b.cells, b.capacity_mah), (3, 5100.0));
    assert!((b.ocv_cell_at(1.0) - 4.20).abs() < 1e-9 && (b.ocv_cell_at(0.0) - 3.27).abs() < 1e-9);
    let f = p.forecast.as_ref().unwrap();
    assert_eq!(f.model, "stolaroff");
    assert!(f.why.contains("tseng (the M100's regression)"), "{}", f.why);
    // P90 = exp(1.2816·√(0.318² + (0.25·0.5)²)) = 1.549
    assert!(
        (f.p90_ratio.unwrap() - 1.549).abs() < 0.002,
        "{:?}",
        f.p90_ratio
    );
    // Hover: T = 12.753 N on 4·π·0.127² = 0.20268 m²: ideal T^1.5/√(2ρA) = 45.543/0.70470 =
    // 64.63 W. Disk loading 12.753/0.20268 = 62.92 N/m²: η_h = exp(−1.9392 + 0.2572·ln 62.92)
    // = 0.4173; 64.63 / 0.4173 + 8 W avionics = 162.9 W.
    assert!(
        (p.stolaroff.eta - 0.4173).abs() < 5e-4,
        "{}",
        p.stolaroff.eta
    );
    let k = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 0.0, 0.0), &p);
    let w = stolaroff::power_w(&k, &p, &p.stolaroff);
    assert!((w - 162.9).abs() < 0.3, "{w}");
    // Drag: 0.0249 m²/kg^(2/3) × 1.3^(2/3) = 0.0297 m²; `[priors] drag_per_kg23` replaces it
    // (the leave-one-airframe-out scoring's).
    assert!((p.stolaroff.drag_area_m2 - 0.0297).abs() < 1e-4);
    let q = load(&format!("{FIVE}[priors]\ndrag_per_kg23 = 0.02\n")).unwrap();
    assert!((q.stolaroff.drag_area_m2 - 0.02 * 1.3f64.powf(2.0 / 3.0)).abs() < 1e-9);
    assert!(err(&format!("{FIVE}[priors]\ndrag_per_kg23 = -1\n")).contains("priors.drag_per_kg23"));
}

#[test]
fn a_partial_spec_is_filled_from_priors_and_a_key_of_a_profile_overrides_one() {
    let p = load("[vehicle]\ntakeoff_kg = 2.0\n").unwrap();
    assert_eq!(p.vehicle.rotors, 4);
    // disk loading 80 N/m²: A = 19.62/80 = 0.24525 m² over 4 rotors -> D = 0.2794 m
    assert!((p.vehicle.prop_diameter_m - 0.2794).abs() < 1e-3);
    assert!(p.name.contains("spec.toml"));
    // a declared frame gives the rotors it has
    let p = load("[vehicle]\ntakeoff_kg = 5.0\nframe = \"hexa\"\n").unwrap();
    assert_eq!(p.vehicle.rotors, 6);
    let own = FIVE.replace("[battery]", "[stolaroff]\neta = 0.5\n[battery]");
    let p = load(&own).unwrap();
    assert_eq!(p.stolaroff.eta, 0.5);
    // the efficiency is the file's: only the drag prior's spread is left
    let r = p.forecast.unwrap().p90_ratio.unwrap();
    assert!((r - (1.2816f64 * 0.125).exp()).abs() < 0.002, "{r}");
    let p = load(&FIVE.replace("takeoff_kg = 1.3", "takeoff_kg = 1.3\ndiagonal_m = 0.45")).unwrap();
    assert_eq!(p.vehicle.diagonal_m, 0.45);
    assert!(err(&format!("{FIVE}\n[stolaroff]\netaa = 1\n")).contains("spec.toml"));
}

#[test]
fn an_impossible_spec_names_its_key() {
    let e = err(&FIVE.replace("takeoff_kg = 1.3", "takeoff_kg = 0"));
    assert!(e.contains("vehicle.takeoff_kg"), "{e}");
    let e = err(&FIVE.replace("rotors = 4", "rotors = 0"));
    assert!(e.contains("vehicle.rotors"), "{e}");
    let e = err(&FIVE.replace("rotors = 4", "rotors = 3"));
    assert!(
        e.contains("vehicle.rotors = 3") && e.contains("Spec quad"),
        "{e}"
    );
    let tri = FIVE
        .replace("rotors = 4", "rotors = 3\nframe = \"quad\"")
        .replace("Spec quad", "T");
    let e = err(&tri);
    assert!(
        e.contains("vehicle.rotors = 3") && e.contains("frame"),
        "{e}"
    );
    let big = FIVE.replace(
        "prop_diameter_m = 0.254",
        "prop_diameter_m = 0.5\ndiagonal_m = 0.45",
    );
    let e = err(&big);
    assert!(
        e.contains("vehicle.prop_diameter_m") && e.contains("0.318"),
        "{e}"
    );
    let e = err(&FIVE.replace("\"lipo\"", "\"nimh\""));
    assert!(e.contains("battery.chemistry"), "{e}");
    let e = err(&FIVE.replace("cells = 3", "cells = 2.5"));
    assert!(e.contains("battery.cells"), "{e}");
    let e = err(&format!("{FIVE}\n[priors]\neta_h = 1.5\n"));
    assert!(e.contains("priors.eta_h"), "{e}");
    let e = err(&FIVE
        .replace("cells = 3", "cells = 3\n")
        .replace("[battery]", "[vehicle.x]\n[battery]"));
    assert!(e.contains("spec.toml"), "{e}");
}

#[test]
fn a_measured_hover_sets_the_efficiency_and_tightens_the_band() {
    let p = load(FIVE).unwrap();
    // 150 W measured: η_h = 64.63 / (150 − 8) = 0.4551; the stolaroff hover is then 150 W.
    let c = calibrate_hover(p.clone(), 150.0, 0.0).unwrap();
    assert!(
        (c.stolaroff.eta - 0.4551).abs() < 5e-4,
        "{}",
        c.stolaroff.eta
    );
    let k = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 0.0, 0.0), &c);
    assert!((stolaroff::power_w(&k, &c, &c.stolaroff) - 150.0).abs() < 0.01);
    let f = c.forecast.unwrap();
    assert!(
        f.why.contains("measured hover of 150 W") && f.why.contains("was 0.417"),
        "{}",
        f.why
    );
    assert!((f.p90_ratio.unwrap() - 1.174).abs() < 0.001);
    // Less than momentum theory's ideal power, or not a number: not a hover of this vehicle.
    let e = calibrate_hover(p.clone(), 60.0, 0.0).unwrap_err();
    assert!(e.contains("not a hover") && e.contains("65 W"), "{e}");
    assert!(calibrate_hover(p, f64::NAN, 0.0).is_err());
    // A plane does not hover: no calibration, said.
    let plane = VehicleProfile::named_or_file("plane").unwrap();
    let e = calibrate_hover(plane, 150.0, 0.0).unwrap_err();
    assert!(e.contains("does not hover"), "{e}");
}

#[test]
fn a_hover_measured_with_a_payload_is_the_loaded_mass() {
    let p = load(FIVE).unwrap();
    // 180 W measured with 300 g on board: the ideal power is the 1.6 kg's, 64.63 ×
    // (1.6/1.3)^1.5 = 88.25 W, so η_h = 88.25 / (180 − 8) = 0.5131 at 1.6 kg, where taking
    // the hover as the empty 1.3 kg's would read 64.63 / 172 = 0.376 (a poor efficiency the
    // loaded plan would pay for again). At the take-off mass (η_h grows with the disk
    // loading, d ln η / d ln m 0.2572): 0.5131 / (1.6/1.3)^0.2572 = 0.4864.
    assert!((p.stolaroff.eta_per_ln_mass - 0.2572).abs() < 1e-9);
    let c = calibrate_hover(p.clone(), 180.0, 0.3).unwrap();
    assert!(
        (c.stolaroff.eta - 0.4864).abs() < 5e-4,
        "{}",
        c.stolaroff.eta
    );
    // (the live first hover's the same: energy::hover's tests)
    // The calibrated vehicle hovers at the measured 180 W with that payload on board.
    let k = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 300.0, 0.0), &c);
    let w = stolaroff::power_w(&k, &c, &c.stolaroff);
    assert!((w - 180.0).abs() < 0.01, "{w}");
    let why = c.forecast.unwrap().why;
    assert!(why.contains("with 0.30 kg of payload"), "{why}");
    assert!(calibrate_hover(p, 180.0, -0.1)
        .unwrap_err()
        .contains("payload"));
}

proptest::proptest! {
    /// Any spec within the keys' ranges loads into a profile that validates, keeps the
    /// take-off mass and widens its P90.
    #[test]
    fn any_plausible_spec_loads(kg in 0.05f64..200.0, rotors in 1u32..=12, d in 0.03f64..1.5,
                                cells in 1u32..=14, mah in 100.0f64..60000.0) {
        let text = format!("[vehicle]\ntakeoff_kg = {kg}\nrotors = {rotors}\nprop_diameter_m = {d}\n\
                            [battery]\ncells = {cells}\ncapacity_mah = {mah}\n");
        match load(&text) {
            Ok(p) => {
                proptest::prop_assert!((p.mass_kg(0.0) - kg).abs() < 1e-6 * kg);
                proptest::prop_assert!(p.forecast.unwrap().p90_ratio.unwrap() > 1.0);
            }
            // a pack heavier than the vehicle is the one refusal these ranges allow
            Err(e) => proptest::prop_assert!(format!("{e:#}").contains("vehicle.battery_kg"), "{e:#}"),
        }
    }
}

#[test]
fn the_hover_efficiency_prior_follows_the_disk_loading_within_the_fitted_range() {
    // exp(−1.9392 + 0.2572·ln DL): 0.393 at 50 N/m², 0.470 at 100; held to 45–110 N/m².
    let at = |dl: f64| {
        // one rotor of 1 m² disk: DL = m·g
        eta_h_prior(dl / 9.81, 1, (4.0 / std::f64::consts::PI).sqrt())
    };
    assert!((at(50.0) - 0.3934).abs() < 5e-4, "{}", at(50.0));
    assert!((at(100.0) - 0.4701).abs() < 5e-4, "{}", at(100.0));
    assert!((at(20.0) - at(45.0)).abs() < 1e-9);
    assert!((at(500.0) - at(110.0)).abs() < 1e-9);
    // and a spec sheet without `[priors]` flies it: the Mavic Pro's five facts (52 N/m²)
    let p = load("[vehicle]\ntakeoff_kg = 0.743\nrotors = 4\nprop_diameter_m = 0.2108\n").unwrap();
    assert!((p.stolaroff.eta - eta_h_prior(0.743, 4, 0.2108)).abs() < 1e-12);
    assert!(
        (0.39..0.41).contains(&p.stolaroff.eta),
        "{}",
        p.stolaroff.eta
    );
}

#[test]
fn the_profile_share_is_a_prior_a_file_may_replace_and_a_hover_calibrates_around_it() {
    let p = load(FIVE).unwrap();
    assert_eq!(p.stolaroff.profile_share, PROFILE_SHARE);
    // the leave-one-airframe-out scoring passes its own; a profile's key wins over the prior
    let held = load(&format!("{FIVE}[priors]\nprofile_share = 0.2\n")).unwrap();
    assert_eq!(held.stolaroff.profile_share, 0.2);
    let own = load(&format!("{FIVE}[stolaroff]\nprofile_share = 0.1\n")).unwrap();
    assert_eq!(own.stolaroff.profile_share, 0.1);
    let e = err(&format!("{FIVE}[priors]\nprofile_share = 0.95\n"));
    assert!(e.contains("priors.profile_share"), "{e}");
    let e = err(&format!("{FIVE}[stolaroff]\nprofile_share = -0.1\n"));
    assert!(e.contains("stolaroff.profile_share"), "{e}");
    // A measured hover of 180 W: the calibrated vehicle hovers at 180 W whatever the share
    // (the split leaves T·v_h/η in a hover), and its η_h is the same at any share.
    let hover = |c: &VehicleProfile| {
        let k = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 0.0, 0.0), c);
        stolaroff::power_w(&k, c, &c.stolaroff)
    };
    let a = calibrate_hover(held, 180.0, 0.0).unwrap();
    let b = calibrate_hover(own, 180.0, 0.0).unwrap();
    assert!((hover(&a) - 180.0).abs() < 0.01 && (hover(&b) - 180.0).abs() < 0.01);
    assert!((a.stolaroff.eta - b.stolaroff.eta).abs() < 1e-12);
}
