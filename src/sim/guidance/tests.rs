//! Tests of the parent module.

use super::*;

/// Fly a route with a perfect velocity loop (position += v_des·dt).
fn fly(route: Route) -> Vec<(Phase, Vector3<f64>)> {
    let mut g = Guidance::new(route);
    let (mut pos, mut vel) = (Vector3::zeros(), Vector3::zeros());
    let mut out = Vec::new();
    for _ in 0..2_000_000 {
        let c = g.step(&pos, &vel, 0.01);
        if c.finished {
            return out;
        }
        vel = if c.phase.in_air() {
            c.velocity_ned.unwrap_or_else(Vector3::zeros)
        } else {
            Vector3::zeros()
        };
        pos += vel * 0.01;
        if c.touchdown {
            pos.z = 0.0;
        }
        out.push((c.phase, pos));
    }
    panic!("route never finished");
}

#[test]
fn flies_every_waypoint_in_order_holds_and_lands_below_the_last() {
    let home = Home {
        lat_deg: 40.0,
        lon_deg: -80.0,
        alt_amsl_m: 300.0,
    };
    let far = home.waypoint(40.0009, -80.0, 30.0, 8.0, 4.0); // ~100 m north
    assert!(
        (far.north_m - 100.2).abs() < 0.5 && far.east_m.abs() < 1e-9,
        "{far:?}"
    );
    let route = Route {
        takeoff_alt_m: 20.0,
        climb_mps: 3.0,
        waypoints: vec![
            far,
            Waypoint {
                north_m: 100.0,
                east_m: 60.0,
                alt_m: 15.0,
                speed_mps: 5.0,
                hold_s: 0.0,
            },
        ],
        descent_mps: 2.0,
    };
    route.validate().expect("valid");
    let track = fly(route);
    let phases: Vec<Phase> = track.iter().map(|p| p.0).fold(Vec::new(), |mut v, p| {
        if v.last() != Some(&p) {
            v.push(p);
        }
        v
    });
    use Phase::*;
    assert_eq!(
        phases,
        [
            PreArm,
            Spinup,
            Climb,
            Leg(0),
            Hold(0),
            Leg(1),
            Hold(1),
            Descent,
            Landed,
            Done
        ]
    );
    // The hold at waypoint 0 lasts its hold time, at the waypoint's altitude.
    let hold0: Vec<_> = track.iter().filter(|p| p.0 == Hold(0)).collect();
    assert!(
        (hold0.len() as f64 * 0.01 - 4.0).abs() < 0.02,
        "hold {} steps",
        hold0.len()
    );
    assert!(hold0
        .iter()
        .all(|p| (p.1 - far.ned()).norm() < ARRIVAL_M + 0.1));
    // Lands below the last waypoint, not at home.
    let end = track.last().expect("track").1;
    assert!(
        (end.x - 100.0).abs() < 1.6 && (end.y - 60.0).abs() < 1.6 && end.z == 0.0,
        "{end:?}"
    );
    // Leg 1 never faster than its 5 m/s.
    let max_h = track
        .windows(2)
        .filter(|w| w[1].0 == Leg(1))
        .map(|w| ((w[1].1 - w[0].1) / 0.01).xy().norm())
        .fold(0.0, f64::max);
    assert!(max_h <= 5.0 + 1e-9 && max_h > 4.9, "leg 1 speed {max_h}");
}

#[test]
fn geodetic_round_trip_and_triangle_shape() {
    let home = Home {
        lat_deg: 40.459060,
        lon_deg: -79.782820,
        alt_amsl_m: 268.7,
    };
    let ned = Vector3::new(350.0, -120.0, -25.0);
    let (lat, lon, alt) = home.to_geodetic(&ned);
    let w = home.waypoint(lat, lon, alt - home.alt_amsl_m, 10.0, 0.0);
    assert!(
        (w.north_m - 350.0).abs() < 1e-6
            && (w.east_m + 120.0).abs() < 1e-6
            && (w.alt_m - 25.0).abs() < 1e-9,
        "{w:?}"
    );
    let r = Triangle {
        leg_m: 300.0,
        altitude_m: 25.0,
        speed_mps: 10.0,
        hover_s: 20.0,
    }
    .route();
    let p: Vec<_> = r.waypoints.iter().map(Waypoint::ned).collect();
    for (a, b) in [(0, 1), (1, 2), (2, 0)] {
        assert!(((p[a] - p[b]).norm() - 300.0).abs() < 1e-9, "equilateral");
    }
    assert_eq!(
        (
            r.waypoints[2].north_m,
            r.waypoints[2].east_m,
            r.waypoints[2].hold_s
        ),
        (0.0, 0.0, 20.0)
    );
}

#[test]
fn out_of_range_options_are_named() {
    let bad = Triangle {
        leg_m: 300.0,
        altitude_m: 25.0,
        speed_mps: 30.0,
        hover_s: 0.0,
    };
    assert_eq!(bad.validate().unwrap_err().key, "speed_mps");
    let mut r = Triangle {
        leg_m: 300.0,
        altitude_m: 25.0,
        speed_mps: 10.0,
        hover_s: 0.0,
    }
    .route();
    r.waypoints[1].hold_s = -1.0;
    let e = r.validate().unwrap_err();
    assert_eq!(e.key, "waypoints[1].hold_s");
    assert!(e.to_string().contains("-1"), "{e}");
    r.waypoints.clear();
    assert_eq!(r.validate().unwrap_err().key, "waypoints");
}
