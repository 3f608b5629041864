use super::*;
use crate::dialect as d;
use crate::mission::plan::GeoPoint;

fn msg(t_s: f64, msg: MavMessage) -> TimedMessage {
    let header = mavlink::MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    };
    TimedMessage::new(t_s, header, msg)
}

fn live() -> LiveMission {
    LiveMission::new(LiveSetup {
        follows: Default::default(),
        forecast: Default::default(),
        models: crate::model::physics::models(&crate::model::profile::VehicleProfile::m100()),
        rate_hz: 10.0,
        window: 10,
        payload_g: 0.0,
        speed_m_s: None,
        active: false,
        system_id: Some(1),
        component_id: 191,
        class: None,
        flight: Default::default(),
    })
}

/// Feed a logged download of an out-and-back (1 km north) into `l`; the status after it.
fn download(l: &mut LiveMission) -> Option<MissionUpdate> {
    download_from(l, d::MavType::MAV_TYPE_GENERIC)
}

/// [`download`] from a vehicle whose HEARTBEAT says `mavtype`.
fn download_from(l: &mut LiveMission, mavtype: d::MavType) -> Option<MissionUpdate> {
    let home = GeoPoint {
        lat_deg: 40.0,
        lon_deg: -80.0,
        alt_m: 300.0,
    };
    let wp = GeoPoint {
        lat_deg: 40.0 + 1000.0 / 111_320.0,
        lon_deg: -80.0,
        alt_m: 25.0,
    };
    let items = Plan::from_waypoints("t", home, &[wp], 10.0).to_mission_items();
    let mut out = Vec::new();
    let hb = MavMessage::HEARTBEAT(d::HEARTBEAT_DATA {
        autopilot: d::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        mavtype,
        ..Default::default()
    });
    l.on_message(0.0, &msg(0.0, hb), &mut out);
    l.on_message(
        0.0,
        &msg(
            0.0,
            MavMessage::MISSION_COUNT(d::MISSION_COUNT_DATA {
                count: items.len() as u16,
                ..Default::default()
            }),
        ),
        &mut out,
    );
    let mut last = None;
    for it in &items {
        let m = MavMessage::MISSION_ITEM_INT(d::MISSION_ITEM_INT_DATA {
            seq: it.seq,
            command: num_traits::FromPrimitive::from_u32(it.command).unwrap(),
            frame: num_traits::FromPrimitive::from_u32(it.frame).unwrap(),
            param2: it.params[1] as f32,
            x: (it.lat_deg * 1e7) as i32,
            y: (it.lon_deg * 1e7) as i32,
            z: it.alt_m as f32,
            ..Default::default()
        });
        last = l.on_message(0.0, &msg(0.0, m), &mut out);
    }
    assert!(out.is_empty(), "a replay sends nothing");
    last
}

#[test]
fn a_plane_heard_in_its_heartbeat_flies_the_mission_as_a_plane_and_a_vtol_as_one() {
    let mut l = live();
    l.setup
        .models
        .push(Box::new(crate::model::physics::fixed_wing::FixedWing::new(
            Default::default(),
        )));
    let start = download_from(&mut l, d::MavType::MAV_TYPE_FIXED_WING)
        .and_then(|u| u.status)
        .expect("a status once the mission is whole");
    assert_eq!(l.class(), VehicleClass::FixedWing);
    let fl = l.flown.as_ref().expect("flown");
    assert_eq!(fl.class, VehicleClass::FixedWing);
    assert_eq!(fl.forecast.model, "fixed_wing");
    assert!(fl
        .traj
        .samples
        .iter()
        .all(|s| s.vehicle.lift() == crate::features::Lift::Wing));
    assert!((fl.forecast.p90_ratio - super::super::forecast::UNCALIBRATED_P90).abs() < 1e-12);
    // 2 km out and back and a glide: a few Wh for a 2 kg plane, far under a multirotor's
    assert!(
        start.energy_p50_wh > 0.5 && start.energy_p50_wh < 5.0,
        "{start:?}"
    );
    // the vehicle says it hovers (EXTENDED_SYS_STATE MC): a VTOL, flown again as one
    let ess = MavMessage::EXTENDED_SYS_STATE(d::EXTENDED_SYS_STATE_DATA {
        vtol_state: d::MavVtolState::MAV_VTOL_STATE_MC,
        ..Default::default()
    });
    let mut out = Vec::new();
    let again = l.on_message(1.0, &msg(1.0, ess), &mut out);
    assert!(
        again.and_then(|u| u.status).is_some(),
        "flown again, published"
    );
    let fl = l.flown.as_ref().expect("flown");
    assert_eq!(fl.class, VehicleClass::Vtol);
    assert!(
        fl.forecast.model.contains("fixed_wing"),
        "{}",
        fl.forecast.model
    );
}

#[test]
fn a_logged_mission_is_forecast_located_and_flown_again_when_the_wind_changes() {
    let mut l = live();
    let start = download(&mut l)
        .and_then(|u| u.status)
        .expect("a status once the mission is whole");
    assert_eq!(start.items, 5, "home, speed, take-off, waypoint, RTL");
    assert!(
        start.energy_p50_wh > 5.0 && start.progress_pct < 1.0,
        "{start:?}"
    );
    // Flying to the waypoint (seq 3), half way out: a quarter of the way, ~3/4 left.
    let mut out = Vec::new();
    let cur = |t, seq| {
        msg(
            t,
            MavMessage::MISSION_CURRENT(d::MISSION_CURRENT_DATA {
                seq,
                ..Default::default()
            }),
        )
    };
    l.on_message(1.0, &cur(1.0, 3), &mut out);
    let pos = MavMessage::GLOBAL_POSITION_INT(d::GLOBAL_POSITION_INT_DATA {
        lat: ((40.0 + 500.0 / 111_320.0) * 1e7) as i32,
        lon: (-80.0 * 1e7) as i32,
        relative_alt: 25_000,
        ..Default::default()
    });
    let half = l
        .on_message(2.0, &msg(2.0, pos), &mut out)
        .and_then(|u| u.status)
        .expect("a status a second later");
    let share = half.energy_p50_wh / start.energy_p50_wh;
    assert!(
        (0.65..0.85).contains(&share) && (20.0..32.0).contains(&half.progress_pct),
        "half way out, {share} of the energy left: {half:?}"
    );
    assert_eq!(half.current_seq, 3);
    // A wind estimate 8 m/s from the north: too early to fly again at 10 s, done at 40 s.
    let wind = |t| {
        msg(
            t,
            MavMessage::WIND(d::WIND_DATA {
                direction: 0.0,
                speed: 8.0,
                speed_z: 0.0,
            }),
        )
    };
    assert_eq!(l.on_message(10.0, &wind(10.0), &mut out), None);
    let windy = l
        .on_message(40.0, &wind(40.0), &mut out)
        .and_then(|u| u.status)
        .expect("flown again in the wind");
    // (which way depends on the model: D'Andrea's induced power falls with airspeed)
    let change = windy.energy_p50_wh / half.energy_p50_wh - 1.0;
    assert!(
        change.abs() > 0.02,
        "the forecast moved with the wind: {windy:?} vs {half:?}"
    );
    // Past the last item: nothing left.
    let done = l
        .on_message(50.0, &cur(50.0, 9), &mut out)
        .and_then(|u| u.status)
        .unwrap();
    assert!(done.energy_p50_wh < 0.01 * start.energy_p50_wh, "{done:?}");
    // The vehicle's mission cleared (a new, empty list overheard): the update says none.
    let cleared = l.on_message(
        51.0,
        &msg(
            51.0,
            MavMessage::MISSION_COUNT(d::MISSION_COUNT_DATA {
                count: 0,
                ..Default::default()
            }),
        ),
        &mut out,
    );
    assert_eq!(
        cleared,
        Some(MissionUpdate {
            t_s: 51.0,
            status: None
        })
    );
}

/// A live monitor whose calibration's one member runs (the first physics model, live weight
/// 0.25), so the live correction applies.
fn live_corrected() -> LiveMission {
    let mut l = live();
    let first = l.setup.models[0].name().to_string();
    l.setup.forecast.calibration = crate::mission::forecast::Calibration {
        live_weight: 0.25,
        ..crate::mission::forecast::Calibration::uncorrected(&first)
    };
    l
}

/// Nearly out at the turn (900 m of 1 km) on the out-and-back of [`download`], about half
/// its energy flown, at `t_s`: MISSION_CURRENT and the position; the status after them.
fn near_the_turn(l: &mut LiveMission, t_s: f64) -> MissionStatus {
    let mut out = Vec::new();
    let cur = MavMessage::MISSION_CURRENT(d::MISSION_CURRENT_DATA {
        seq: 3,
        ..Default::default()
    });
    l.on_message(t_s, &msg(t_s, cur), &mut out);
    let pos = MavMessage::GLOBAL_POSITION_INT(d::GLOBAL_POSITION_INT_DATA {
        lat: ((40.0 + 900.0 / 111_320.0) * 1e7) as i32,
        lon: (-80.0 * 1e7) as i32,
        relative_alt: 25_000,
        ..Default::default()
    });
    l.on_message(t_s + 2.0, &msg(t_s + 2.0, pos), &mut out)
        .and_then(|u| u.status)
        .expect("a status")
}

#[test]
fn the_live_forecast_of_the_rest_follows_a_first_half_that_cost_more_or_less_than_forecast() {
    // the forecast alone: nothing measured (never seen to arm)
    let mut plain = live_corrected();
    let start = download(&mut plain).and_then(|u| u.status).unwrap();
    let left = near_the_turn(&mut plain, 100.0);
    let done = start.energy_p50_wh - left.energy_p50_wh;
    assert!(
        done > crate::mission::forecast::LIVE_FROM_SHARE * start.energy_p50_wh,
        "{start:?} {left:?}"
    );
    assert_eq!(plain.energy_so_far_wh(), None);
    for (ratio, want) in [(1.2, 1.05), (0.9, 0.975)] {
        let mut l = live_corrected();
        download(&mut l);
        let mut out = Vec::new();
        // seen disarmed, then armed
        let hb = |base_mode| {
            MavMessage::HEARTBEAT(d::HEARTBEAT_DATA {
                autopilot: d::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                base_mode,
                ..Default::default()
            })
        };
        l.on_message(0.5, &msg(0.5, hb(d::MavModeFlag::empty())), &mut out);
        assert_eq!(l.energy_so_far_wh(), None);
        let armed = hb(d::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
        l.on_message(1.0, &msg(1.0, armed), &mut out);
        // SYS_STATUS at 1 Hz from 1 s to 101 s: `ratio` × the forecast of the part flown
        let watts = ratio * done * 3600.0 / 100.0;
        let volts = 22.0;
        for i in 0..=100 {
            let t = 1.0 + f64::from(i);
            let st = MavMessage::SYS_STATUS(d::SYS_STATUS_DATA {
                voltage_battery: (volts * 1000.0) as u16,
                current_battery: (watts / volts * 100.0).round() as i16,
                ..Default::default()
            });
            l.on_message(t, &msg(t, st), &mut out);
        }
        let so_far = l.energy_so_far_wh().expect("armed, measured");
        assert!(
            (so_far / (ratio * done) - 1.0).abs() < 0.01,
            "{so_far} Wh measured, {} wanted",
            ratio * done
        );
        let live = near_the_turn(&mut l, 100.0);
        // 1 + 0.25 · (ratio − 1) × the forecast alone
        let moved = live.energy_p50_wh / left.energy_p50_wh;
        assert!(
            (moved - want).abs() < 0.005,
            "first half at {ratio} × its forecast: the rest × {moved} (want {want}): {live:?} vs {left:?}"
        );
    }
}

/// The energy so far is read from the messages the telemetry stage reads: BATTERY_STATUS
/// where the vehicle sends it (preferred over SYS_STATUS, whose current may be −1), and a
/// SYS_STATUS of 0 V (no voltage monitor) counts nothing.
#[test]
fn the_energy_so_far_follows_battery_status_and_ignores_a_pack_without_voltage() {
    let hb = |base_mode| {
        MavMessage::HEARTBEAT(d::HEARTBEAT_DATA {
            autopilot: d::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            base_mode,
            ..Default::default()
        })
    };
    let sys = |mv: u16, ca: i16| {
        MavMessage::SYS_STATUS(d::SYS_STATUS_DATA {
            voltage_battery: mv,
            current_battery: ca,
            ..Default::default()
        })
    };
    let batt = |ca: i16| {
        let mut voltages = [u16::MAX; 10];
        voltages[..6].copy_from_slice(&[4_000; 6]); // 24 V
        MavMessage::BATTERY_STATUS(d::BATTERY_STATUS_DATA {
            id: 0,
            voltages,
            current_battery: ca,
            ..Default::default()
        })
    };
    // 100 s at 1 Hz after arming; `each` gives the messages of second i.
    let fly = |each: &dyn Fn(u32) -> Vec<MavMessage>| {
        let mut l = live();
        let mut out = Vec::new();
        l.on_message(0.0, &msg(0.0, hb(d::MavModeFlag::empty())), &mut out);
        let armed = hb(d::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
        l.on_message(0.5, &msg(0.5, armed), &mut out);
        for i in 0..=100 {
            let t = 1.0 + f64::from(i);
            for m in each(i) {
                l.on_message(t, &msg(t, m), &mut out);
            }
        }
        l.energy_so_far_wh()
    };
    // BATTERY_STATUS at 24 V × 15 A = 360 W for 100 s = 10 Wh; SYS_STATUS says no current.
    let wh = fly(&|_| vec![sys(24_000, -1), batt(1_500)]).expect("armed, measured");
    assert!((wh - 10.0).abs() < 1e-6, "{wh} Wh");
    // Both carry a current: BATTERY_STATUS's (360 W) is followed, not SYS_STATUS's (480 W).
    let wh = fly(&|_| vec![sys(24_000, 2_000), batt(1_500)]).unwrap();
    assert!((wh - 10.0).abs() < 1e-6, "{wh} Wh");
    // BATTERY_STATUS goes quiet after 50 s: SYS_STATUS takes over once it is stale (3 s),
    // the last BATTERY_STATUS reading held until then.
    let wh = fly(&|i| {
        let mut m = vec![sys(24_000, 2_000)];
        if i <= 50 {
            m.push(batt(1_500));
        }
        m
    })
    .unwrap();
    let want = (360.0 * 54.0 + 480.0 * 46.0) / 3600.0;
    assert!((wh - want).abs() < 1e-6, "{wh} Wh, about {want} wanted");
    // SYS_STATUS alone, 0 V: a current without a voltage is no power (not 0 W, not 15 A × 0 V).
    let wh = fly(&|_| vec![sys(0, 1_500)]).expect("armed");
    assert_eq!(wh, 0.0);
}
