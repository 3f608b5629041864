//! Tests of the parent module.

use super::route::*;
use super::*;
use crate::features::Lift;
use crate::mission::forecast::{forecast, Calibration, Member};
use crate::mission::plan::{AltFrame, GeoPoint, Item};
use crate::mission::trajectory::Wind;
use crate::model::physics::fixed_wing::{load_factor, FixedWing, Params};
use crate::model::PowerModel;

const HOME: GeoPoint = GeoPoint {
    lat_deg: 40.0,
    lon_deg: -80.0,
    alt_m: 300.0,
};

fn cond(wind: Wind) -> Conditions {
    Conditions {
        wind,
        payload_g: 0.0,
        speed_m_s: None,
        rate_hz: 10.0,
    }
}

/// A plan item: MAV_CMD, kind, (north, east, alt) offset from home (`None`: no position).
type Spec = (u16, ItemKind, Option<(f64, f64, f64)>);

/// A plan of these items.
fn plan(items: &[Spec]) -> Plan {
    Plan {
        source: "test".into(),
        home: HOME,
        items: items
            .iter()
            .enumerate()
            .map(|(index, &(command, kind, at))| Item {
                index,
                origin: format!("item {index}"),
                command,
                kind,
                position: at.map(|(n, e, alt_m)| HOME.offset(n, e, alt_m)),
                frame: if at.is_some() {
                    AltFrame::Relative
                } else {
                    AltFrame::None
                },
                loiter_radius_m: match kind {
                    ItemKind::LoiterTurns { .. } => Some(100.0),
                    _ => None,
                },
            })
            .collect(),
        hover_speed_m_s: None,
        cruise_speed_m_s: None,
    }
}

fn builder(f: &Flight) -> Builder<'_> {
    Builder {
        f,
        vtol: false,
        wind: V2::zeros(),
        segs: Vec::new(),
        pos: V3::new(0.0, 0.0, 50.0),
        psi: std::f64::consts::FRAC_PI_2,
        airspeed: 15.0,
        airborne: true,
        on_rotors: false,
        leg: 0,
        dist: 0.0,
    }
}

#[test]
fn a_180_degree_turn_has_the_bank_limits_radius_and_lasts_pi_r_over_v() {
    let f = Flight::default();
    // ArduPlane's 45° at 15 m/s: R = 15² / (9.80665 · tan 45°) = 22.94 m
    let r = f.turn_radius_m(15.0);
    assert!((r - 22.944).abs() < 0.01, "{r}");
    // heading north; the next point lies 2R east and far south: a right turn of exactly 180°
    let mut b = builder(&f);
    b.turn_toward(V2::new(2.0 * r, -1000.0));
    assert_eq!(b.segs.len(), 1);
    let seg = b.segs[0];
    let expect = std::f64::consts::PI * r / 15.0;
    assert!(
        (seg.duration_s - expect).abs() < 1e-6,
        "{} vs {expect}",
        seg.duration_s
    );
    assert!(
        (b.pos.xy() - V2::new(2.0 * r, 0.0)).norm() < 1e-6,
        "{:?}",
        b.pos
    );
    assert!((super::super::wrap_pi(b.psi + std::f64::consts::FRAC_PI_2)).abs() < 1e-9);
    assert!((b.dist - std::f64::consts::PI * r).abs() < 1e-6);
    // the turn's samples carry the bank: load factor 1/cos 45° = √2 for the model
    let At::Wing { bank, .. } = state(&seg, seg.duration_s / 2.0, &f, V2::zeros()) else {
        panic!("a turn is wing-borne")
    };
    assert!((bank.abs() - std::f64::consts::FRAC_PI_4).abs() < 1e-9);
    let pl = plan(&[(
        16,
        ItemKind::Waypoint { hold_s: 0.0 },
        Some((0.0, 0.0, 50.0)),
    )]);
    let s = wing_sample(
        &pl,
        &cond(Wind::default()),
        50.0,
        0.0,
        (V3::new(0.0, 0.0, 50.0), V3::new(15.0, 0.0, 0.0)),
        (15.0, 0.0, bank, -15.0 / r),
        V2::zeros(),
        VehicleKind::default(),
        15.0,
    );
    assert!(
        (load_factor(&s) - 2f64.sqrt()).abs() < 1e-4,
        "{}",
        load_factor(&s)
    );
}

#[test]
fn a_loiter_of_n_turns_lasts_n_times_2_pi_r_over_v() {
    let f = Flight::default();
    let one = loiter_turn_s(100.0, 15.0, V2::zeros());
    let expect = std::f64::consts::TAU * 100.0 / 15.0;
    assert!((one - expect).abs() < 1e-9 * expect, "{one} vs {expect}");
    // in a wind the circle held over the ground takes longer than in calm air
    assert!(loiter_turn_s(100.0, 15.0, V2::new(5.0, 0.0)) > expect * 1.01);
    let mut b = builder(&f);
    b.loiter(V3::new(0.0, 2000.0, 50.0), 100.0, Some(3.0), 0.0);
    let Some(seg) = b.segs.last() else {
        panic!("no loiter")
    };
    assert!(matches!(seg.piece, Piece::Loiter { .. }));
    assert!(
        (seg.duration_s - 3.0 * expect).abs() < 1e-6,
        "{}",
        seg.duration_s
    );
    // and flown from a plan: the leg holds the approach and the three turns
    let pl = plan(&[
        (22, ItemKind::Takeoff { alt_m: 50.0 }, None),
        (
            18,
            ItemKind::LoiterTurns { turns: 3.0 },
            Some((2000.0, 0.0, 50.0)),
        ),
        (21, ItemKind::Land, Some((0.0, 0.0, 0.0))),
    ]);
    let tr = fly_plane(
        &pl,
        &KinematicsConfig::default(),
        &f,
        false,
        &cond(Wind::default()),
    );
    let leg = &tr.legs[1];
    assert_eq!(leg.label, "loiter turns");
    let loiter = leg.t_end_s - leg.t_start_s;
    assert!(
        loiter > 3.0 * expect && loiter < 3.0 * expect + 2000.0 / 15.0 + 10.0,
        "{loiter}"
    );
    // wing-borne everywhere, never a hover: the ground speed never falls to 0
    assert!(tr.samples.iter().all(|s| s.vehicle.lift() == Lift::Wing));
    let slow = tr.samples[..tr.samples.len() - 1]
        .iter()
        .filter(|s| f64::from(s.features[idx::VX]).hypot(f64::from(s.features[idx::VY])) < 5.0)
        .count();
    assert_eq!(
        slow, 0,
        "no sample slower than 5 m/s over the ground in calm air"
    );
}

fn models(profile: &crate::model::profile::VehicleProfile) -> Vec<Box<dyn PowerModel>> {
    let mut m = crate::model::physics::models(profile);
    m.push(Box::new(FixedWing::new(Params::default())));
    m
}

#[test]
fn a_vtol_plan_flies_its_takeoff_and_landing_on_the_rotors_at_hover_power() {
    let f = Flight::default();
    let pl = plan(&[
        (84, ItemKind::VtolTakeoff { alt_m: 40.0 }, None),
        (
            16,
            ItemKind::Waypoint { hold_s: 0.0 },
            Some((1500.0, 0.0, 60.0)),
        ),
        (85, ItemKind::VtolLand, Some((1500.0, 800.0, 0.0))),
    ]);
    let k = KinematicsConfig::default();
    let tr = fly_plane(&pl, &k, &f, true, &cond(Wind::default()));
    let labels: Vec<&str> = tr.legs.iter().map(|l| l.label.as_str()).collect();
    assert_eq!(labels, ["vtol takeoff", "waypoint", "vtol land"]);
    let up = &tr.legs[0];
    assert!(((up.t_end_s - up.t_start_s) - 40.0 / f.vtol_climb_m_s).abs() < 0.2);
    let states = |r: std::ops::Range<usize>| {
        tr.samples[r]
            .iter()
            .map(|s| s.vehicle.vtol_state)
            .collect::<Vec<_>>()
    };
    assert!(states(up.samples.clone())
        .iter()
        .all(|s| *s == VtolState::Mc));
    // the waypoint leg starts with the transition, then flies on the wing
    let wp = states(tr.legs[1].samples.clone());
    let n_tr = wp
        .iter()
        .filter(|s| **s == VtolState::TransitionToFw)
        .count();
    assert!(
        (n_tr as f64 - f.transition_fw_s * 10.0).abs() <= 1.0,
        "{n_tr}"
    );
    assert_eq!(wp.last(), Some(&VtolState::Fw));
    // the landing ends on the rotors: back transition, then descent in MC to the ground
    let down = states(tr.legs[2].samples.clone());
    assert!(down.contains(&VtolState::TransitionToMc));
    assert_eq!(down.last(), Some(&VtolState::Mc));
    assert!(tr.enu_m.last().is_some_and(|p| p[2].abs() < 0.1));

    // power: the rotor models on the MC climb, the fixed-wing model on the wing
    let m100 = crate::model::profile::VehicleProfile::m100();
    let cal = Calibration {
        members: vec![Member::of("dorling"), Member::of("fixed_wing")],
        ..Calibration::uncorrected("dorling")
    };
    let fc = forecast(&tr, &mut models(&m100), &cal, 10, 1);
    let mean_w = |r: &std::ops::Range<usize>| {
        (fc.energy_to_wh(r.end - 1) - fc.energy_to_wh(r.start)) * 3600.0
            / ((r.end - 1 - r.start) as f64 * tr.dt_s)
    };
    // dorling's hover power: a multirotor flying the same take-off stands still on the ground first
    let mc = crate::mission::trajectory::fly(&pl, &k, &cond(Wind::default()));
    let hover = forecast(
        &mc,
        &mut models(&m100),
        &Calibration::uncorrected("dorling"),
        10,
        1,
    );
    let spin = 1..(k.spinup_s * 10.0) as usize;
    let hover_w = (hover.energy_to_wh(spin.end) - hover.energy_to_wh(spin.start)) * 3600.0
        / ((spin.end - spin.start) as f64 * mc.dt_s);
    let climb = up.samples.start + 20..up.samples.end - 20;
    let climb_w = mean_w(&climb);
    assert!(
        climb_w > 0.95 * hover_w && climb_w < 1.2 * hover_w,
        "MC climb {climb_w:.1} W vs hover {hover_w:.1} W"
    );
    let cruise = tr.legs[1].samples.end - 300..tr.legs[1].samples.end - 100;
    let cruise_w = mean_w(&cruise);
    // the fixed-wing model's level flight at 15 m/s, 360 m above sea level (the leg also
    // climbs 20 m at 0.2 m/s: m·g·v_z/η = 16 W more)
    let level = crate::model::physics::fixed_wing::power_w(
        &Params::default(),
        crate::model::physics::fixed_wing::air_density(360.0, None),
        15.0,
        1.0,
        2.0,
        0.0,
    );
    assert!(
        cruise_w > level && cruise_w < level + 20.0 && cruise_w < hover_w,
        "cruise {cruise_w:.1} W on the wing (level {level:.1} W), hover {hover_w:.1} W"
    );
    assert!(
        fc.model.contains("dorling") && fc.model.contains("fixed_wing"),
        "{}",
        fc.model
    );
}

#[test]
fn the_energy_grows_with_the_wind_against_and_falls_with_it_behind() {
    // straight in to land (an into-wind approach flies part of the route downwind)
    let f = Flight {
        land_into_wind: false,
        ..Flight::default()
    };
    let pl = plan(&[
        (22, ItemKind::Takeoff { alt_m: 60.0 }, None),
        (
            16,
            ItemKind::Waypoint { hold_s: 0.0 },
            Some((3000.0, 0.0, 60.0)),
        ),
        (21, ItemKind::Land, Some((3500.0, 0.0, 0.0))),
    ]);
    let energy = |speed_m_s: f64, from_deg: f64| {
        let tr = fly_plane(
            &pl,
            &KinematicsConfig::default(),
            &f,
            false,
            &cond(Wind {
                speed_m_s,
                from_deg,
            }),
        );
        let mut m: Vec<Box<dyn PowerModel>> = vec![Box::new(FixedWing::new(Params::default()))];
        forecast(&tr, &mut m, &Calibration::uncorrected("fixed_wing"), 10, 5).energy_p50_wh
    };
    // the route runs north: a wind from the north (0°) is against it
    let against: Vec<f64> = [0.0, 3.0, 6.0, 9.0]
        .iter()
        .map(|&w| energy(w, 0.0))
        .collect();
    assert!(against.windows(2).all(|p| p[1] > p[0]), "{against:?}");
    let behind: Vec<f64> = [0.0, 3.0, 6.0, 9.0]
        .iter()
        .map(|&w| energy(w, 180.0))
        .collect();
    assert!(behind.windows(2).all(|p| p[1] < p[0]), "{behind:?}");
}
