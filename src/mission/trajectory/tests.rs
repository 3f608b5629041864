//! Tests of the parent module.

use super::*;
use crate::mission::plan::{GeoPoint, Plan};

fn square(speed: f64) -> Plan {
    let home = GeoPoint {
        lat_deg: 40.0,
        lon_deg: -80.0,
        alt_m: 300.0,
    };
    let at = |n, e| home.offset(n, e, 25.0);
    let wps = [at(200.0, 0.0), at(200.0, 200.0)];
    Plan::from_waypoints("square", home, &wps, speed)
}

fn cond() -> Conditions {
    Conditions {
        wind: Wind::default(),
        payload_g: 250.0,
        speed_m_s: None,
        rate_hz: 10.0,
    }
}

#[test]
fn a_plan_flies_takeoff_legs_and_landing_with_the_right_times() {
    let k = KinematicsConfig::default();
    let tr = fly(&square(10.0), &k, &cond());
    let labels: Vec<&str> = tr.legs.iter().map(|l| l.label.as_str()).collect();
    assert_eq!(labels, ["takeoff", "waypoint", "waypoint", "rtl"]);
    // 200 m north, 200 m east, 283 m home: three stop-to-stop legs at 10 m/s, a = k.accel_m_s2
    let legs_s: f64 = [200.0, 200.0, 200.0 * 2f64.sqrt()]
        .iter()
        .map(|&l| trapezoid_time(l, 10.0, k.accel_m_s2))
        .sum();
    let expect = k.spinup_s
        + 25.0 / 3.0
        + legs_s
        + 4.0 * k.waypoint_pause_s
        + 5.0 / k.descent_m_s
        + 20.0 / 1.0;
    assert!(
        (tr.duration_s() - expect).abs() < 0.2,
        "{} vs {expect}",
        tr.duration_s()
    );
    let dist: f64 = tr.legs.iter().map(|l| l.distance_m).sum();
    assert!((dist - (400.0 + 200.0 * 2f64.sqrt())).abs() < 1.0, "{dist}");
    // cruising north at 10 m/s: forward velocity 10, ~9° tilt, anemometer 10 m/s from the north bearing
    let mid = &tr.samples[tr.legs[1].samples.start + 120];
    assert!(
        (mid.features[idx::VY] - 10.0).abs() < 0.05 && mid.features[idx::VX].abs() < 0.05,
        "{:?}",
        mid.features
    );
    assert!((mid.features[idx::WIND_SPEED] - 10.0).abs() < 0.05);
    assert!(mid.features[idx::WIND_ANGLE] < 0.5 || mid.features[idx::WIND_ANGLE] > 359.5);
    assert_eq!(mid.features[idx::PAYLOAD], 250.0);
    assert_eq!(mid.features[idx::ALTITUDE], 25.0);
    let last = tr.samples.last().unwrap();
    assert!(
        last.home.unwrap().distance_m < 0.5 && last.home.unwrap().height_m.abs() < 0.2,
        "lands at home"
    );
}

#[test]
fn the_models_read_the_trajectory_as_the_motion_it_is() {
    // The physics models' own reading of the features must give back the motion.
    let tr = fly(
        &square(8.0),
        &KinematicsConfig::default(),
        &Conditions {
            wind: "4@90".parse().unwrap(),
            ..cond()
        },
    );
    let profile = crate::model::profile::VehicleProfile::m100();
    let j = tr.legs[2].samples.start + 100; // cruising east at 8 m/s, wind 4 m/s from the east
    let w = crate::telemetry::window::Window {
        samples: tr.samples[j - 9..=j].to_vec(),
        arrived: None,
    };
    let kin = crate::model::physics::Kinematics::from_window(&w, &profile);
    assert!(
        (kin.ground_m_s - Vector3::new(8.0, 0.0, 0.0)).norm() < 0.1,
        "{:?}",
        kin.ground_m_s
    );
    assert!(
        (kin.wind_m_s - Vector3::new(-4.0, 0.0, 0.0)).norm() < 0.1,
        "{:?}",
        kin.wind_m_s
    );
    assert!((kin.headwind() - 4.0).abs() < 0.1);
    assert!(
        kin.thrust_axis.x > 0.1,
        "nose down toward the airspeed: {:?}",
        kin.thrust_axis
    );
}

#[test]
fn wind_parses_and_points_downwind() {
    let w: Wind = "5@270".parse().unwrap();
    assert!(
        (w.velocity_enu() - Vector3::new(5.0, 0.0, 0.0)).norm() < 1e-9,
        "from the west blows east"
    );
    assert!(
        "5".parse::<Wind>().is_err()
            && "x@1".parse::<Wind>().is_err()
            && "99@0".parse::<Wind>().is_err()
    );
}

#[test]
fn locate_finds_the_vehicle_on_the_route() {
    let tr = fly(&square(10.0), &KinematicsConfig::default(), &cond());
    let j = tr.legs[2].samples.start + 50;
    let p = tr.enu_m[j];
    assert_eq!(tr.locate(tr.first_sample_of_item(2), 2000, p), j);
}
