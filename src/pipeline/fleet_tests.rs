//! The demultiplexer's routing and timing ([`super::Demux`]).

use super::*;
use crate::dialect::{MavAutopilot, MavType, HEARTBEAT_DATA};

const ONE: VehicleId = VehicleId::single(1);
const TWO: VehicleId = VehicleId::single(2);

fn msg(sys: u32, t_s: f64, msg: MavMessage) -> TimedMessage {
    let header = mavlink::MavHeader {
        system_id: sys,
        component_id: 1,
        sequence: 0,
    };
    TimedMessage::new(t_s, header, msg)
}
fn hb(mavtype: MavType, autopilot: MavAutopilot) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype,
        autopilot,
        ..Default::default()
    })
}

#[test]
fn filters_parse_ids_and_ranges_and_name_what_is_wrong() {
    let f = VehicleFilter::parse("3, 7,10-20").unwrap();
    assert!(f.contains(3) && f.contains(7) && f.contains(10) && f.contains(20));
    assert!(!f.contains(4) && !f.contains(21) && !f.contains(0) && !f.contains(300));
    assert!(VehicleFilter::parse("1-250").unwrap().contains(250));
    assert!(VehicleFilter::parse("0").unwrap_err().contains("\"0\""));
    assert!(VehicleFilter::parse("20-10")
        .unwrap_err()
        .contains("backwards"));
    assert!(VehicleFilter::parse("5,x").unwrap_err().contains("\"x\""));
    let bad = FleetConfig {
        vehicles: Some("1-300".into()),
        drop_after_s: 1.0,
        ..Default::default()
    };
    let e = bad.validate().unwrap_err();
    assert!(
        e.contains("fleet.vehicles") && e.contains("fleet.drop_after_s"),
        "{e}"
    );
}

#[test]
fn only_vehicles_open_chains_and_silence_makes_them_lost_then_dropped() {
    let mut d = Demux::new(&FleetConfig::default(), None).unwrap();
    let quad = || {
        hb(
            MavType::MAV_TYPE_QUADROTOR,
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        )
    };
    // A ground station and a companion are not vehicles; their telemetry-less chatter is ignored.
    assert_eq!(
        d.route(&msg(
            255,
            0.0,
            hb(MavType::MAV_TYPE_GCS, MavAutopilot::MAV_AUTOPILOT_INVALID)
        )),
        Route::Ignore
    );
    assert_eq!(
        d.route(&msg(255, 0.1, MavMessage::ATTITUDE(Default::default()))),
        Route::Ignore
    );
    assert_eq!(
        d.route(&msg(
            9,
            0.0,
            hb(
                MavType::MAV_TYPE_ONBOARD_CONTROLLER,
                MavAutopilot::MAV_AUTOPILOT_GENERIC
            )
        )),
        Route::Ignore
    );
    assert_eq!(
        d.route(&msg(1, 0.0, quad())),
        Route::Vehicle {
            id: VehicleId::single(1),
            new: true,
            back: false
        }
    );
    assert_eq!(
        d.route(&msg(1, 0.1, quad())),
        Route::Vehicle {
            id: VehicleId::single(1),
            new: false,
            back: false
        }
    );
    // Telemetry before a heartbeat opens a vehicle too (a log cut between heartbeats).
    assert_eq!(
        d.route(&msg(2, 0.2, MavMessage::ATTITUDE(Default::default()))),
        Route::Vehicle {
            id: VehicleId::single(2),
            new: true,
            back: false
        }
    );
    assert_eq!(d.vehicles().collect::<Vec<_>>(), vec![ONE, TWO]);
    let mut ev = Vec::new();
    d.route(&msg(2, 9.0, quad()));
    d.advance(10.5, &mut ev);
    assert!(
        matches!(ev.as_slice(), [FleetEvent::Lost { id: ONE, .. }]),
        "{ev:?}"
    );
    d.advance(11.0, &mut ev);
    assert_eq!(ev.len(), 1, "lost is said once");
    assert_eq!(
        d.route(&msg(1, 11.0, quad())),
        Route::Vehicle {
            id: VehicleId::single(1),
            new: false,
            back: true
        }
    );
    ev.clear();
    d.advance(70.0, &mut ev);
    assert!(
        matches!(
            ev.as_slice(),
            [
                FleetEvent::Lost { id: ONE, .. },
                FleetEvent::Dropped { id: TWO, .. }
            ]
        ),
        "{ev:?}"
    );
    assert_eq!(d.vehicles().collect::<Vec<_>>(), vec![ONE]);
    assert_eq!(
        d.route(&msg(2, 72.0, quad())),
        Route::Vehicle {
            id: VehicleId::single(2),
            new: true,
            back: false
        }
    );
}

#[test]
fn a_ground_stations_mission_messages_go_to_the_vehicle_they_are_for() {
    let mut d = Demux::new(
        &FleetConfig::default(),
        Some(VehicleFilter::parse("1-2").unwrap()),
    )
    .unwrap();
    let count = |target_system| {
        MavMessage::MISSION_COUNT(crate::dialect::MISSION_COUNT_DATA {
            target_system,
            count: 3,
            ..Default::default()
        })
    };
    // Before the vehicle is heard there is no chain to give it to.
    assert_eq!(d.route(&msg(255, 0.0, count(2))), Route::Ignore);
    let quad = hb(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
    assert!(matches!(
        d.route(&msg(2, 0.1, quad)),
        Route::Vehicle { new: true, .. }
    ));
    // A logged upload to vehicle 2 from the ground station (outside the filter) is
    // vehicle 2's; one to a vehicle never heard, and a broadcast, are nobody's.
    assert_eq!(
        d.route(&msg(255, 0.2, count(2))),
        Route::Vehicle {
            id: TWO,
            new: false,
            back: false
        }
    );
    assert_eq!(d.route(&msg(255, 0.3, count(1))), Route::Ignore);
    assert_eq!(d.route(&msg(255, 0.4, count(0))), Route::Ignore);
    // It keeps the vehicle alive no longer: silent since 0.1 s, it is lost at 10.5 s.
    d.route(&msg(255, 10.0, count(2)));
    let mut ev = Vec::new();
    d.advance(10.5, &mut ev);
    assert!(
        matches!(ev.as_slice(), [FleetEvent::Lost { id: TWO, .. }]),
        "{ev:?}"
    );
}

#[test]
fn a_filter_ignores_and_counts_other_vehicles() {
    let mut d = Demux::new(
        &FleetConfig::default(),
        Some(VehicleFilter::parse("1-2").unwrap()),
    )
    .unwrap();
    let quad = hb(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
    assert_eq!(d.route(&msg(3, 0.0, quad.clone())), Route::Ignore);
    assert_eq!(
        d.route(&msg(2, 0.0, quad)),
        Route::Vehicle {
            id: VehicleId::single(2),
            new: true,
            back: false
        }
    );
    assert_eq!(d.filtered(), 1);
}

#[test]
fn the_same_system_id_on_two_networks_is_two_vehicles() {
    let mut d = Demux::new(&FleetConfig::default(), None).unwrap();
    let quad = || hb(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
    let on = |net: u8, t: f64| TimedMessage {
        network: net,
        ..msg(1, t, quad())
    };
    let a = VehicleId {
        network: 1,
        system_id: 1,
    };
    let b = VehicleId {
        network: 2,
        system_id: 1,
    };
    assert_eq!(
        d.route(&on(1, 0.0)),
        Route::Vehicle {
            id: a,
            new: true,
            back: false
        }
    );
    assert_eq!(
        d.route(&on(2, 0.1)),
        Route::Vehicle {
            id: b,
            new: true,
            back: false
        }
    );
    assert_eq!(d.vehicles().collect::<Vec<_>>(), vec![a, b]);
    assert_eq!((a.to_string(), b.to_string()), ("1:1".into(), "2:1".into()));
    assert_eq!(ONE.to_string(), "1", "on the only network, as always");
}

proptest::proptest! {
    /// The bound that lets `advance` skip its walk changes nothing: the same messages and
    /// clock give the same lost, back and dropped events, in the same order, as a walk over
    /// every vehicle at every step (the bound forced off), gaps around both thresholds.
    #[test]
    fn advance_with_its_bound_says_what_a_walk_every_time_says(
        steps in proptest::collection::vec((1u32..5, 0.0f64..25.0, proptest::bool::ANY), 1..120),
    ) {
        let cfg = FleetConfig::default();
        let (mut fast, mut walk) = (Demux::new(&cfg, None).unwrap(), Demux::new(&cfg, None).unwrap());
        let quad = hb(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
        let (mut t, mut said_fast, mut said_walk) = (0.0, Vec::new(), Vec::new());
        for (sys, dt, send) in steps {
            t += dt;
            if send {
                let m = msg(sys, t, quad.clone());
                proptest::prop_assert_eq!(fast.route(&m), walk.route(&m));
            }
            fast.advance(t, &mut said_fast);
            walk.next_due_s = f64::NEG_INFINITY;
            walk.advance(t, &mut said_walk);
            proptest::prop_assert_eq!(&said_fast, &said_walk);
        }
        proptest::prop_assert_eq!(fast.vehicles().collect::<Vec<_>>(), walk.vehicles().collect::<Vec<_>>());
    }
}
