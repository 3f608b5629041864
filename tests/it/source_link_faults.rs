//! Link faults over real sockets on 127.0.0.1, with pymavlink (`tests/peers/vehicle.py`)
//! as the vehicle and `dronewatt monitor` as the operator runs it: what the operator sees
//! (`--json`) through a silent link, a reboot, a TCP reconnect, a UDP peer on a new port,
//! bursts at ten times the rate, MAVLink 1 and 2 interleaved and another vehicle's stray
//! messages (with `[fleet] vehicles` set to the one watched). Every test also checks that no report is lost and no estimate invented
//! ([`link_common::check_consistent`]).

use crate::link_common;

use link_common::*;

const LOST_RULE: &str =
    "[[alerts]]\nname = \"lost\"\nkind = \"telemetry_lost\"\nfor_s = 2\nseverity = \"critical\"\n\
                         message = \"Telemetry lost\"\n";

/// Energy one second at the profile's highest power may add, Wh (the integration's cap on
/// one step, `[energy] max_dt_s` = 1 s, at 540 W).
const ONE_STEP_WH: f64 = 540.0 / 3600.0;

/// A flight over the link as `plan` says ([`fly`], no extra peer arguments), checked for
/// lost reports and invented estimates ([`check_consistent`]).
fn fly_checked(config: &str, tcp: bool, plan: &str) -> Run {
    let r = fly(config, tcp, plan, &[]);
    check_consistent(&r);
    r
}

#[test]
fn a_ten_second_silence_is_one_alert_raised_and_cleared_and_no_energy_jump() {
    let r = fly_checked(
        LOST_RULE,
        false,
        r#"[{"send_s": 6}, {"quiet_s": 10}, {"send_s": 6}]"#,
    );
    let holes = r.holes_over(1.0);
    assert_eq!(
        holes.len(),
        1,
        "one hole in the estimates, the silence: {holes:?}"
    );
    let (before, after) = holes[0];
    assert!(
        (9.0..=13.0).contains(&(after - before)),
        "the hole spans the 10 s silence: {holes:?}"
    );
    assert!(
        expected_estimates(12.0, 2).contains(&r.estimates.len()),
        "{} estimates for 12 s of telemetry",
        r.estimates.len()
    );

    let lost: Vec<_> = r.alerts.iter().filter(|a| a["rule"] == "lost").collect();
    assert_eq!(lost.len(), 2, "raised once, cleared once: {lost:?}");
    assert_eq!(
        (lost[0]["state"].as_str(), lost[1]["state"].as_str()),
        (Some("raised"), Some("cleared")),
        "{lost:?}"
    );
    let raised_at = lost[0]["t"].as_f64().unwrap();
    assert!(
        raised_at > before && raised_at < after,
        "raised inside the silence ({before}..{after}): {raised_at}"
    );
    assert_eq!(r.count("silences"), 1, "{}", r.summary);

    // Across the silence the integration adds at most one capped step, and the flight's
    // total is what 12 s of ~500 W make (the 10 s of silence would add 1.4 Wh more).
    let used = |t: f64| {
        r.estimates
            .iter()
            .find(|e| e["t"].as_f64() == Some(t))
            .unwrap()["energy_used_wh"]
            .as_f64()
            .unwrap()
    };
    let jump = used(after) - used(before);
    assert!(
        (0.0..=ONE_STEP_WH + 1e-6).contains(&jump),
        "energy jumped {jump} Wh across the silence"
    );
    let total = r.estimates.last().unwrap()["energy_used_wh"]
        .as_f64()
        .unwrap();
    assert!(
        (1.2..=1.9).contains(&total),
        "used {total} Wh over 12 s at ~500 W"
    );
}

#[test]
fn a_reboot_restarts_sequence_and_boot_time_and_moves_home() {
    // Phase 2 starts from a new home 1 km north, boot time and sequence at 0, right away.
    // The vehicle sends no capacity: the config gives its pack (none is assumed).
    let r = fly_checked(
        "[energy]\ncapacity_wh = 130.0\n",
        false,
        r#"[{"send_s": 6}, {"send_s": 6, "reboot": true}]"#,
    );
    assert!(
        r.holes_over(0.5).is_empty(),
        "a reboot on a live link loses no estimate: {:?}",
        r.holes_over(0.5)
    );
    r.assert_estimates(12.0, 1);
    assert_eq!(
        r.count("gaps"),
        1,
        "the sequence restart is one gap: {}",
        r.summary
    );
    assert_eq!(
        r.count("clock_jumps"),
        0,
        "a live link is timed by arrival: {}",
        r.summary
    );
    // The same moment of both phases: 2.9 s after take-off, climbing at the home (the
    // first estimate comes a window, ~1 s, after the first frame, and phase 2 starts 6 s
    // after phase 1). Had the old home stayed, the way back from 1 km would cost ~14 Wh
    // more (100 s at ~500 W) and the margin would drop by as much; what else differs (the
    // 0.8 Wh used meanwhile, the forecast power) is a few Wh at most.
    let margin_at = |t: f64| {
        let e = r
            .estimates
            .iter()
            .rfind(|e| e["t"].as_f64().unwrap() <= t)
            .unwrap();
        // The energy home and the reserve, remaining − margin (the margin alone also moves
        // with the pack's start state, which the reboot's new start re-reads
        // load-compensated).
        let (Some(left), Some(margin)) = (e["remaining_wh"].as_f64(), e["home_margin_wh"].as_f64())
        else {
            panic!("no home margin at {t}: {e}")
        };
        left - margin
    };
    let t0 = r.times()[0];
    let (m1, m2) = (margin_at(t0 + 2.0), margin_at(t0 + 8.0));
    assert!(
        (m1 - m2).abs() < 4.0,
        "home margin {m1} Wh before the reboot, {m2} Wh after: the new home was not taken"
    );
}

#[test]
fn a_tcp_peer_that_closes_and_reconnects_is_heard_and_answered_again() {
    let r = fly_checked(
        "",
        true,
        r#"[{"send_s": 5}, {"quiet_s": 1.5}, {"send_s": 5, "reconnect": true}]"#,
    );
    let holes = r.holes_over(1.0);
    assert_eq!(holes.len(), 1, "{holes:?}");
    r.assert_estimates(10.0, 2);
    let phases = r.peer["phases"].as_array().unwrap();
    assert!(
        phases[2]["heard"].as_u64().unwrap() >= 5,
        "dronewatt answers the new connection: {}",
        r.peer
    );
    assert_eq!(r.count("frames_bad"), 0, "{}", r.summary);
}

#[test]
fn a_udp_peer_on_a_new_port_is_followed() {
    let r = fly_checked(
        "",
        false,
        r#"[{"send_s": 5}, {"send_s": 5, "reconnect": true}]"#,
    );
    assert!(r.holes_over(0.5).is_empty(), "{:?}", r.holes_over(0.5));
    r.assert_estimates(10.0, 1);
    let phases = r.peer["phases"].as_array().unwrap();
    assert!(
        phases[1]["heard"].as_u64().unwrap() >= 5,
        "dronewatt answers the new port: {}",
        r.peer
    );
    r.assert_every_frame_read();
}

#[test]
fn a_burst_at_ten_times_the_rate_loses_nothing_and_adds_no_estimates() {
    let r = fly_checked(
        "",
        false,
        r#"[{"send_s": 2}, {"send_s": 4, "rate_hz": 100}]"#,
    );
    assert_eq!(
        r.count("frames_ok"),
        r.peer["frames"].as_u64().unwrap(),
        "every frame of the burst: {}",
        r.summary
    );
    assert_eq!(r.count("gaps"), 0, "{}", r.summary);
    // Resampled to 10 Hz whatever the input rate: ~60 estimates, not ~420.
    r.assert_estimates(6.0, 1);
}

#[test]
fn mavlink_1_and_2_interleaved_are_one_stream() {
    let r = fly_checked("", false, r#"[{"send_s": 6, "v1": true}]"#);
    r.assert_every_frame_read();
    assert_eq!(
        (r.count("frames_bad"), r.count("gaps")),
        (0, 0),
        "one sequence across both versions: {}",
        r.summary
    );
    r.assert_estimates(6.0, 1);
}

#[test]
fn a_second_vehicles_stray_messages_are_counted_and_ignored() {
    // A second vehicle gets a chain of its own (tests/it/pipeline_fleet.rs); an instance told to
    // watch vehicle 1 only reads every frame and estimates nothing from the other's.
    // check_consistent asserts no measured power near the stray vehicle's 2000 W.
    let r = fly_checked(
        "[fleet]\nvehicles = \"1\"\n",
        false,
        r#"[{"send_s": 6, "stray": true}]"#,
    );
    let sent = r.peer["frames"].as_u64().unwrap() + r.peer["stray_frames"].as_u64().unwrap();
    assert_eq!(r.count("frames_ok"), sent, "{}", r.summary);
    assert_eq!(
        r.count("gaps"),
        0,
        "each sender's sequence is its own: {}",
        r.summary
    );
    r.assert_estimates(6.0, 1);
}
