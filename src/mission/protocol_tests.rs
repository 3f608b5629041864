//! Tests of `src/mission/protocol.rs` (a file of their own: the module stays under 600 lines).

use super::*;

fn hdr(sys: u8, comp: u8) -> mavlink::MavHeader {
    mavlink::MavHeader {
        system_id: sys.into(),
        component_id: comp,
        sequence: 0,
    }
}

fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(d::HEARTBEAT_DATA {
        autopilot: d::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        mavtype: d::MavType::MAV_TYPE_QUADROTOR,
        ..Default::default()
    })
}

fn item(seq: u16) -> MavMessage {
    MavMessage::MISSION_ITEM_INT(d::MISSION_ITEM_INT_DATA {
        seq,
        command: d::MavCmd::MAV_CMD_NAV_WAYPOINT,
        frame: d::MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        x: 473_977_000 + i32::from(seq) * 1000,
        y: 85_455_000,
        z: 20.0,
        ..Default::default()
    })
}

fn count(n: u16) -> MavMessage {
    MavMessage::MISSION_COUNT(d::MISSION_COUNT_DATA {
        count: n,
        ..Default::default()
    })
}

fn requested(out: &[MavMessage]) -> Vec<u16> {
    out.iter()
        .filter_map(|m| match m {
            MavMessage::MISSION_REQUEST_INT(r) => Some(r.seq),
            _ => None,
        })
        .collect()
}

#[test]
fn downloads_with_a_resend_acks_and_redownloads_on_a_new_mission_id() {
    let v = hdr(1, 1);
    let mut c = MissionClient::new(true, Some(1), 191);
    let mut out = Vec::new();
    assert_eq!(c.on_message(0.0, &v, &heartbeat(), &mut out), None);
    assert!(
        matches!(out.as_slice(), [MavMessage::MISSION_REQUEST_LIST(_)]),
        "{out:?}"
    );
    out.clear();
    c.on_message(0.1, &v, &count(3), &mut out);
    assert_eq!(requested(&out), [0]);
    c.on_message(0.2, &v, &item(0), &mut out);
    assert_eq!(requested(&out), [0, 1]);
    // item 1 is lost: nothing before the timeout, one resend after it
    out.clear();
    c.tick(1.0, &mut out);
    assert!(out.is_empty());
    c.tick(0.2 + RESEND_S + 0.01, &mut out);
    assert_eq!(requested(&out), [1]);
    assert_eq!(c.stats.resends, 1);
    c.on_message(2.0, &v, &item(1), &mut out);
    out.clear();
    let ev = c.on_message(2.1, &v, &item(2), &mut out);
    let Some(Event::Mission(m)) = ev else {
        panic!("{ev:?}")
    };
    assert_eq!(m.items.len(), 3);
    assert_eq!(m.items[2].seq, 2);
    assert!((m.items[1].lat_deg - 47.3978).abs() < 1e-9);
    assert!(m.home_is_item0 && m.origin == Origin::Downloaded);
    assert!(
        matches!(out.as_slice(), [MavMessage::MISSION_ACK(a)] if a.mavtype == d::MavMissionResult::MAV_MISSION_ACCEPTED)
    );
    // same mission: nothing; a new mission_id: download again
    out.clear();
    let cur = |id| {
        MavMessage::MISSION_CURRENT(d::MISSION_CURRENT_DATA {
            seq: 1,
            total: 2,
            mission_id: id,
            ..Default::default()
        })
    };
    c.on_message(3.0, &v, &cur(0), &mut out);
    c.on_message(4.0, &v, &cur(0), &mut out);
    assert!(out.is_empty(), "unchanged: {out:?}");
    c.on_message(5.0, &v, &cur(77), &mut out);
    assert!(
        matches!(out.as_slice(), [MavMessage::MISSION_REQUEST_LIST(_)]),
        "{out:?}"
    );
}

#[test]
fn gives_up_after_max_tries_and_retries_later() {
    let v = hdr(1, 1);
    let mut c = MissionClient::new(true, Some(1), 191);
    let mut out = Vec::new();
    c.on_message(0.0, &v, &heartbeat(), &mut out);
    let mut t = 0.0;
    let mut failed = None;
    for _ in 0..MAX_TRIES {
        t += RESEND_S + 0.01;
        if let Some(e) = c.tick(t, &mut out) {
            failed = Some(e);
        }
    }
    assert!(matches!(failed, Some(Event::Failed(_))), "{failed:?}");
    assert_eq!(
        out.len() as u32,
        MAX_TRIES,
        "the list requested MAX_TRIES times: {out:?}"
    );
    out.clear();
    c.tick(t + 1.0, &mut out);
    assert!(out.is_empty(), "waits before trying again");
    c.tick(t + RETRY_AFTER_S + 0.1, &mut out);
    assert!(matches!(
        out.as_slice(),
        [MavMessage::MISSION_REQUEST_LIST(_)]
    ));
}

#[test]
fn a_passive_client_assembles_overheard_items_and_sends_nothing() {
    let mut c = MissionClient::new(false, Some(1), 191);
    let mut out = Vec::new();
    c.on_message(0.0, &hdr(1, 1), &heartbeat(), &mut out);
    c.on_message(0.1, &hdr(1, 1), &count(2), &mut out);
    assert_eq!(c.on_message(0.2, &hdr(1, 1), &item(1), &mut out), None);
    let ev = c.on_message(0.3, &hdr(1, 1), &item(0), &mut out);
    assert!(
        matches!(
            ev,
            Some(Event::Mission(Mission {
                origin: Origin::Overheard,
                ..
            }))
        ),
        "{ev:?}"
    );
    assert!(out.is_empty());
}
