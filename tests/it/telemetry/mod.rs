//! The live telemetry stage on hand-made MAVLink streams: ArduPilot-style and PX4-style
//! message mixes at their real rates, frame conversions on cases whose answer is known,
//! staleness, source fallback, gaps, bad values and foreign senders.

use dronewatt::dialect::*;
use dronewatt::features::idx;
use dronewatt::source::TimedMessage;
use dronewatt::telemetry::window::Window;
use dronewatt::telemetry::{MissionConfig, Telemetry, TelemetryConfig};
use dronewatt::MavMessage;

mod mix;
use mix::*;

#[test]
fn ardupilot_mix_fills_every_feature_in_the_data_set_frames() {
    // Nose north, flying north at 8 m/s, climbing 1 m/s.
    let f = Flight {
        v_ned: [8.0, 0.0, -1.0],
        heading_deg: 0.0,
    };
    let cfg = TelemetryConfig::default();
    let (tel, out) = ardupilot(f, 10.0).run(&cfg, &MissionConfig::default());
    // Deterministic input: exactly 90 windows in 10 s at 10 Hz (a lower bound would let
    // lost samples or a late first window pass).
    assert_eq!(out.len(), 90, "windows in 10 s at 10 Hz");
    for w in &out {
        let s = w.last();
        assert_eq!(s.stale_mask, 0, "t={}: stale {:b}", s.t_s, s.stale_mask);
        let x = &s.features;
        assert!(x.iter().all(|v| v.is_finite()));
        // Forward is velocity_y; climbing is velocity_z > 0.
        assert!(
            close(x[idx::VX], 0.0, 0.02)
                && close(x[idx::VY], 8.0, 0.02)
                && close(x[idx::VZ], 1.0, 0.02),
            "{x:?}"
        );
        // At constant velocity the specific force is −g along body z.
        assert!(close(x[idx::AZ], -9.80665, 1e-3) && close(x[idx::AX], 0.0, 1e-6));
        // Level, nose north: the data set's identity quaternion.
        assert!(close(x[idx::QW], 1.0, 1e-6) && close(x[idx::QZ], 0.0, 1e-6));
        // Anemometer: air from the west at 3 m/s seen from a vehicle going north at 8 m/s
        // comes at √73 m/s from 339.4°.
        assert!(
            close(x[idx::WIND_SPEED], 73f64.sqrt(), 1e-3),
            "wind {}",
            x[idx::WIND_SPEED]
        );
        assert!(close(
            x[idx::WIND_ANGLE],
            360.0 - 3f64.atan2(8.0).to_degrees(),
            0.01
        ));
        assert!(close(x[idx::POS_Y], LAT0, 1e-3) && close(x[idx::POS_X], LON0, 1e-3));
        assert_eq!(s.measured_w, Some(460.0));
        // Mission defaults.
        assert_eq!(
            (x[idx::SPEED], x[idx::PAYLOAD], x[idx::ALTITUDE]),
            (10.0, 0.0, 25.0)
        );
        // Home is the first fix (t = 0.04 s): 8 m/s north, 1 m/s up. (Past the last fix,
        // at the end of the stream, the position is held.)
        let home = s.home.expect("home from the first fix");
        let t = s.t_s - 1000.0 - 0.04;
        assert!(
            t > 9.76
                || (home.distance_m as f64 - 8.0 * t).abs() < 0.1
                    && (home.height_m as f64 - t).abs() < 0.05,
            "{home:?} at {t}"
        );
    }
    assert_eq!(source(&tel, "attitude"), Some("ATTITUDE"));
    assert_eq!(source(&tel, "acceleration"), Some("RAW_IMU"));
    assert_eq!(source(&tel, "velocity"), Some("GLOBAL_POSITION_INT"));
    assert_eq!(source(&tel, "wind"), Some("WIND"));
    assert_eq!(source(&tel, "power"), Some("BATTERY_STATUS"));
    assert_eq!(source(&tel, "mission"), Some("default"));
}

#[test]
fn px4_mix_without_wind_fills_every_feature() {
    // Nose east, drifting north at 5 m/s (to its left), descending 0.5 m/s.
    let f = Flight {
        v_ned: [5.0, 0.0, 0.5],
        heading_deg: 90.0,
    };
    let cfg = TelemetryConfig::default();
    let (tel, out) = px4(f, 0.0, 10.0).run(
        &cfg,
        &MissionConfig {
            speed_m_s: Some(6.0),
            payload_g: Some(250.0),
            altitude_m: None,
        },
    );
    assert_eq!(out.len(), 90, "windows in 10 s at 10 Hz");
    let h = std::f64::consts::FRAC_1_SQRT_2;
    for w in &out {
        let s = w.last();
        assert_eq!(s.stale_mask, 0, "t={}", s.t_s);
        let x = &s.features;
        assert!(
            close(x[idx::VX], -5.0, 1e-4)
                && close(x[idx::VY], 0.0, 1e-4)
                && close(x[idx::VZ], -0.5, 1e-4),
            "{x:?}"
        );
        assert!(close(x[idx::AZ], -9.81, 1e-5));
        // Facing east: the data-set quaternion is a −90° (clockwise) turn about ENU up.
        assert!(
            close(x[idx::QW], h, 1e-6) && close(x[idx::QZ], -h, 1e-6),
            "{x:?}"
        );
        // No WIND: airspeed from VFR_HUD, the angle from the heading.
        assert!(close(x[idx::WIND_SPEED], 5.0, 1e-6) && close(x[idx::WIND_ANGLE], 90.0, 1e-6));
        assert_eq!(s.measured_w, Some(220.0));
        assert_eq!(
            (x[idx::SPEED], x[idx::PAYLOAD], x[idx::ALTITUDE]),
            (6.0, 250.0, 25.0)
        );
    }
    assert!(out.last().unwrap().last().home.is_some());
    assert_eq!(source(&tel, "attitude"), Some("ATTITUDE_QUATERNION"));
    assert_eq!(source(&tel, "acceleration"), Some("HIGHRES_IMU"));
    assert_eq!(source(&tel, "velocity"), Some("LOCAL_POSITION_NED"));
    assert_eq!(source(&tel, "wind"), Some("VFR_HUD"));
    assert_eq!(source(&tel, "mission"), Some("config"));
}

#[test]
fn hover_at_rest_reads_minus_g_and_zero_velocity() {
    let f = Flight {
        v_ned: [0.0, 0.0, 0.0],
        heading_deg: 0.0,
    };
    let (_, out) = ardupilot(f, 4.0).run(&TelemetryConfig::default(), &MissionConfig::default());
    let s = out.last().expect("windows").last();
    assert!(close(s.features[idx::AZ], -9.80665, 1e-3));
    for i in [idx::VX, idx::VY, idx::VZ] {
        assert!(close(s.features[i], 0.0, 1e-6));
    }
    // Hovering in a 3 m/s westerly, the anemometer reads the wind itself.
    assert!(
        close(s.features[idx::WIND_SPEED], 3.0, 1e-4)
            && close(s.features[idx::WIND_ANGLE], 270.0, 1e-3)
    );
}

#[test]
fn a_quiet_source_is_held_and_marked_stale_without_stalling_the_stream() {
    let f = Flight {
        v_ned: [5.0, 0.0, 0.0],
        heading_deg: 0.0,
    };
    let mut mix = px4(f, 0.0, 10.0);
    // GLOBAL_POSITION_INT stops at 5 s; everything else goes on.
    mix.msgs
        .retain(|(t, _, m)| !(matches!(m, MavMessage::GLOBAL_POSITION_INT(_)) && *t > 5.0));
    let cfg = TelemetryConfig::default();
    let mut tel = Telemetry::new(&cfg, &MissionConfig::default());
    mix.msgs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out = Vec::new();
    for (i, (t, sys, msg)) in mix.msgs.into_iter().enumerate() {
        let header = mavlink::MavHeader {
            system_id: sys,
            component_id: 1,
            sequence: i as u8,
        };
        tel.push(&TimedMessage::new(t, header, msg), &mut out);
    }
    // Before finish(): the stream kept flowing (latency bounded by the stale limit).
    // Power comes at 1 Hz here, and every signal gates the grid: at most 1 s behind.
    let last_t = out.last().unwrap().t_s();
    assert!(last_t > 10.0 - 1.0 - 0.11, "last sample at {last_t}");
    let pos_bits = (1 << idx::POS_X) | (1 << idx::POS_Y) | (1 << idx::POS_Z);
    let mut held = None;
    for w in &out {
        let s = w.last();
        if s.t_s <= 5.0 {
            assert_eq!(s.stale_mask, 0, "t={}", s.t_s);
        } else if s.t_s > 5.0 + cfg.stale_after_s + 0.2 {
            assert_eq!(s.stale_mask, pos_bits, "t={}", s.t_s);
            let p = s.features[idx::POS_Y];
            assert_eq!(*held.get_or_insert(p), p, "a stale value is held");
            // Velocity still comes from LOCAL_POSITION_NED.
            assert!(close(s.features[idx::VY], 5.0, 1e-4));
        }
    }
    let h = tel.health();
    assert!(h.iter().find(|x| x.signal == "position").unwrap().stale);
    assert!(!h.iter().find(|x| x.signal == "velocity").unwrap().stale);
}

#[test]
fn a_worse_source_takes_over_when_the_better_one_stops() {
    let f = Flight {
        v_ned: [0.0, 0.0, 0.0],
        heading_deg: 90.0,
    };
    let mut mix = px4(f, 0.0, 10.0);
    mix.msgs
        .retain(|(t, _, m)| !(matches!(m, MavMessage::ATTITUDE_QUATERNION(_)) && *t > 4.0));
    let yaw = std::f32::consts::FRAC_PI_2;
    mix.every(10.0, 0.0, 10.0, |_| {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            yaw,
            ..Default::default()
        })
    });
    let (tel, out) = mix.run(&TelemetryConfig::default(), &MissionConfig::default());
    assert_eq!(source(&tel, "attitude"), Some("ATTITUDE"));
    let h = std::f64::consts::FRAC_1_SQRT_2;
    for w in out.iter().filter(|w| w.t_s() > 1007.0) {
        let s = w.last();
        assert_eq!(s.stale_mask, 0);
        assert!(close(s.features[idx::QZ], -h, 1e-6));
    }
}

#[test]
fn a_gap_restarts_the_window_ring() {
    let f = Flight {
        v_ned: [5.0, 0.0, 0.0],
        heading_deg: 0.0,
    };
    let mut mix = px4(f, 0.0, 5.0);
    mix.msgs.extend(px4(f, 8.0, 13.0).msgs);
    let cfg = TelemetryConfig::default();
    let (tel, out) = mix.run(&cfg, &MissionConfig::default());
    assert_eq!(tel.restarts(), 1);
    let span = (cfg.window - 1) as f64 / cfg.rate_hz + 1e-6;
    assert!(
        out.iter().all(|w| w.t_s() - w.samples[0].t_s <= span),
        "a window spans the gap"
    );
    assert!(
        out.iter().any(|w| w.samples[0].t_s > 1008.0),
        "windows resume after the gap"
    );
    for w in &out {
        for s in &w.samples {
            assert_eq!(s.stale_mask, 0, "t={}", s.t_s);
        }
    }
}

#[test]
fn bad_values_and_other_systems_are_ignored() {
    let f = Flight {
        v_ned: [8.0, 0.0, 0.0],
        heading_deg: 0.0,
    };
    let mut mix = ardupilot(f, 5.0);
    // A ground station's heartbeat first: it must not capture the stream.
    mix.at(
        -0.5,
        255,
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype: MavType::MAV_TYPE_GCS,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            ..Default::default()
        }),
    );
    // Another vehicle flying south, and NaN attitude from ours.
    mix.every(10.0, 0.05, 5.0, |_| {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            yaw: 3.1,
            ..Default::default()
        })
    });
    for (_, sys, m) in mix.msgs.iter_mut() {
        if let MavMessage::ATTITUDE(a) = m {
            if a.yaw == 3.1 {
                *sys = 2;
            }
        }
    }
    mix.every(2.0, 0.01, 5.0, |_| {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            roll: f32::NAN,
            ..Default::default()
        })
    });
    let (tel, out) = mix.run(&TelemetryConfig::default(), &MissionConfig::default());
    // Exactly what was sent: NaN attitude at 2 Hz for 5 s (10), the other vehicle's
    // attitude at 10 Hz for 5 s (50; the ground station's heartbeat is no vehicle's).
    assert_eq!(tel.nonfinite(), 10);
    assert_eq!(tel.foreign(), 50);
    for w in &out {
        assert!(w
            .samples
            .iter()
            .all(|s| s.features.iter().all(|v| v.is_finite())));
        assert!(
            close(w.last().features[idx::QW], 1.0, 1e-6),
            "other system's attitude leaked in"
        );
    }
}

#[test]
fn mission_from_named_values_beats_the_config() {
    let f = Flight {
        v_ned: [0.0, 0.0, 0.0],
        heading_deg: 0.0,
    };
    let mut mix = ardupilot(f, 3.0);
    for (name, v) in [("cmd_speed", 12.0), ("payload_g", 500.0), ("cmd_alt", 50.0)] {
        mix.at(
            0.0,
            1,
            MavMessage::NAMED_VALUE_FLOAT(NAMED_VALUE_FLOAT_DATA {
                time_boot_ms: 0,
                value: v,
                name: name.into(),
            }),
        );
    }
    let mission = MissionConfig {
        speed_m_s: Some(4.0),
        payload_g: Some(0.0),
        altitude_m: Some(25.0),
    };
    let (tel, out) = mix.run(&TelemetryConfig::default(), &mission);
    let x = out.last().unwrap().last().features;
    assert_eq!(
        (x[idx::SPEED], x[idx::PAYLOAD], x[idx::ALTITUDE]),
        (12.0, 500.0, 50.0)
    );
    assert_eq!(source(&tel, "mission"), Some("NAMED_VALUE_FLOAT"));
}

#[test]
fn the_autopilots_state_of_charge_rides_along_when_it_reports_one() {
    let f = Flight {
        v_ned: [0.0, 0.0, 0.0],
        heading_deg: 0.0,
    };
    // The helper's SYS_STATUS says −1 (unknown): no percentage.
    let (_, out) = ardupilot(f, 3.0).run(&TelemetryConfig::default(), &MissionConfig::default());
    assert!(out.iter().all(|w| w.last().battery_remaining_pct.is_none()));
    // A BATTERY_STATUS with 57 % from t = 2 s on (after the mix's own, which say −1, and
    // which must not erase it): later samples carry it.
    let mut m = ardupilot(f, 4.0);
    m.every(2.0, 2.15, 4.0, |_| {
        MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
            battery_remaining: 57,
            ..Default::default()
        })
    });
    let (_, out) = m.run(&TelemetryConfig::default(), &MissionConfig::default());
    assert_eq!(
        out.last().expect("windows").last().battery_remaining_pct,
        Some(57.0)
    );
}

#[test]
fn a_position_without_a_fix_is_never_used_as_a_position_or_home() {
    let f = Flight {
        v_ned: [8.0, 0.0, 0.0],
        heading_deg: 0.0,
    };
    let mut mix = ardupilot(f, 5.0);
    // No fix yet: an autopilot sends (0, 0) first, and a HOME_POSITION of (0, 0); then,
    // mid-flight, a GPS glitch of (0, 0) and a position beyond the poles.
    let zero = |_: f64| {
        MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            vx: 800,
            ..Default::default()
        })
    };
    mix.at(-0.2, 1, zero(0.0));
    mix.at(
        -0.1,
        1,
        MavMessage::HOME_POSITION(HOME_POSITION_DATA::default()),
    );
    mix.every(2.0, 1.07, 5.0, zero);
    mix.every(1.0, 1.09, 5.0, |t| {
        let mut m = gpi(f, t);
        if let MavMessage::GLOBAL_POSITION_INT(p) = &mut m {
            p.lat = 95 * 10_000_000;
        }
        m
    });
    let (tel, out) = mix.run(&TelemetryConfig::default(), &MissionConfig::default());
    assert!(!out.is_empty());
    for s in out.iter().flat_map(|w| &w.samples) {
        let (lon, lat) = (s.features[idx::POS_X], s.features[idx::POS_Y]);
        assert!(
            close(lat, LAT0, 0.01) && close(lon, LON0, 0.01),
            "{lat} {lon}"
        );
        let home = s.home.expect("home from the first real fix");
        assert!(home.distance_m < 100.0, "home {} m away", home.distance_m);
    }
    // Counted: the first (0, 0), 8 mid-flight ones and 4 beyond the poles (HOME_POSITION
    // of (0, 0) is ignored too).
    assert_eq!(tel.no_fix(), 1 + 8 + 4 + 1);
}

#[test]
fn a_vehicle_without_air_data_flies_in_still_air_until_air_data_comes() {
    // A PX4 mix flying north at 8 m/s, its VFR_HUD (airspeed 5 m/s) only from 6 s: before,
    // no WIND, WIND_COV or VFR_HUD at all. The air is then taken as still (the airspeed is
    // the ground speed, from the nose), not as no airspeed (a cruise at hover power).
    let f = Flight {
        v_ned: [8.0, 0.0, 0.0],
        heading_deg: 0.0,
    };
    let mut mix = px4(f, 0.0, 12.0);
    mix.msgs
        .retain(|(t, _, m)| !(matches!(m, MavMessage::VFR_HUD(_)) && *t < 6.0));
    let mut seen_still = false;
    let cfg = TelemetryConfig::default();
    let (tel, out) = mix.run(&cfg, &MissionConfig::default());
    for w in &out {
        let s = w.last();
        // the mix's clock starts at 1000 s
        let t = s.t_s - 1000.0;
        let (speed, angle) = (s.features[idx::WIND_SPEED], s.features[idx::WIND_ANGLE]);
        if t < 5.5 {
            assert!(close(speed, 8.0, 1e-3), "t={}: {speed} m/s", s.t_s);
            assert!(
                close(angle, 0.0, 1e-3) || close(angle, 360.0, 1e-3),
                "{angle}"
            );
            seen_still = true;
        } else if t > 7.0 {
            // the air data, once heard, for good
            assert!(close(speed, 5.0, 1e-3), "t={}: {speed} m/s", s.t_s);
        }
    }
    assert!(seen_still);
    assert_eq!(source(&tel, "wind"), Some("VFR_HUD"));
    // A vehicle that never sends air data says so in its health.
    let mut mix = px4(f, 0.0, 5.0);
    mix.msgs
        .retain(|(_, _, m)| !matches!(m, MavMessage::VFR_HUD(_)));
    let (tel, _) = mix.run(&cfg, &MissionConfig::default());
    assert_eq!(source(&tel, "wind"), Some("still air (no air data)"));
}
