use super::*;
use crate::features::Sample;
use crate::report::{EnergyState, Estimate, MissionStatus, ModelEstimate, Report};

fn report(energy: EnergyState, measured: Option<f32>) -> Report {
    Report {
        estimate: Estimate {
            t_s: 312.4,
            sample: Sample::new(312.4, [0.0; crate::features::N_FEATURES], measured),
            models: (0..9)
                .map(|i| ModelEstimate::new(format!("model_{i}"), 241.0, None))
                .collect(),
            arrived: None,
        },
        energy,
        alerts: vec![],
        vehicle: 1.into(),
    }
}

/// Every figure at its widest.
fn widest() -> EnergyState {
    let mut e = EnergyState {
        remaining_wh: Some(1234.5),
        remaining_pct: Some(100.0),
        remaining_source: RemainingSource::LoadCompensated,
        forecast_w: Some(12345.6),
        time_to_empty_s: Some(99_999.0),
        home_margin_wh: Some(-1234.5),
        mission_margin_wh: Some(-1234.5),
        mission: Some(MissionStatus {
            t_s: 0.0,
            current_seq: 999,
            items: 999,
            time_left_s: 9999.0,
            energy_p50_wh: 999.0,
            energy_p90_wh: 999.0,
            progress_pct: 99.0,
            route_en_m: Default::default(),
            route_at: 0,
        }),
        ..Default::default()
    };
    e.pack.battery_v = Some(50.42);
    e.pack.v_min_forecast_v = Some(44.44);
    e.pack.low_threshold_v = Some(45.0);
    e.pack.time_to_low_v_s = Some(88_888.0);
    e
}

fn alert(rule: &str, severity: Severity) -> WorstAlert {
    WorstAlert {
        rule: rule.into(),
        severity,
        message: "Return now: low voltage before home".into(),
        t: Some(300.0),
    }
}

/// Visible characters (colour codes stripped).
fn visible(s: &str) -> usize {
    let mut n = 0;
    let mut esc = false;
    for c in s.chars() {
        match (esc, c) {
            (false, '\x1b') => esc = true,
            (true, c) if c.is_ascii_alphabetic() => esc = false,
            (true, _) => {}
            (false, _) => n += 1,
        }
    }
    n
}

#[test]
fn the_widest_line_fits_and_keeps_what_a_pilot_needs() {
    let r = report(widest(), None);
    for colour in [false, true] {
        for worst in [
            None,
            Some(alert("low_voltage_before_home", Severity::Critical)),
            Some(alert(
                &"a_very_long_user_rule_name_".repeat(8),
                Severity::Warning,
            )),
        ] {
            for silent in [false, true] {
                let l = line(Some(&r), worst.as_ref(), silent, colour);
                assert!(visible(&l) <= MAX_LINE, "{} chars: {l}", visible(&l));
                assert!(l.contains("~12346 W est"), "{l}");
                assert!(l.contains("100 %"), "{l}");
                assert!(l.contains("to empty") || l.contains("to low V"), "{l}");
                assert!(l.contains("50.4 V min 44.4 V"), "{l}");
                assert!(l.contains("mission -1234.5 Wh"), "{l}");
                match (&worst, silent) {
                    (_, true) => assert!(l.contains("SILENT"), "{l}"),
                    (Some(w), _) => {
                        let head: String = w.rule.chars().take(10).collect();
                        assert!(l.contains(&head), "{l}");
                    }
                    _ => {}
                }
                // No model's figure on the pilot's line.
                assert!(!l.contains("model_"), "{l}");
            }
        }
    }
}

#[test]
fn a_typical_line_keeps_every_part_whole() {
    let mut e = EnergyState {
        remaining_wh: Some(32.3),
        remaining_pct: Some(31.0),
        remaining_source: RemainingSource::RestingVoltage,
        time_to_empty_s: Some(700.0),
        mission_margin_wh: Some(4.2),
        ..Default::default()
    };
    e.pack.soc_pct = Some(53.0);
    e.pack.battery_v = Some(22.81);
    e.pack.v_min_forecast_v = Some(21.42);
    e.pack.low_threshold_v = Some(21.0);
    e.pack.time_to_low_v_s = Some(720.0);
    let r = report(e, Some(241.7));
    let l = line(Some(&r), None, false, false);
    assert_eq!(
        l,
        "242 W  31 % 32.3 Wh (resting voltage)  12 min to empty  22.8 V min 21.4 V  mission +4.2 Wh"
    );
    // One percentage: the pack model's 53 % is not on the line.
    assert!(!l.contains("53"), "{l}");
    let crit = alert("low_voltage_before_home", Severity::Critical);
    let l = line(Some(&r), Some(&crit), false, false);
    assert!(l.ends_with("CRITICAL low_voltage_before_home"), "{l}");
    assert!(l.chars().count() <= MAX_LINE, "{l}");
}

#[test]
fn the_time_left_is_the_first_of_empty_and_low_voltage() {
    let mut e = EnergyState {
        time_to_empty_s: Some(600.0),
        ..Default::default()
    };
    assert_eq!(time_left(&e), Some((600.0, "empty")));
    e.pack.time_to_low_v_s = Some(300.0);
    assert_eq!(time_left(&e), Some((300.0, "low voltage")));
    e.time_to_empty_s = Some(f64::NAN);
    assert_eq!(time_left(&e), Some((300.0, "low voltage")));
    e.pack.time_to_low_v_s = None;
    e.time_to_empty_s = None;
    assert_eq!(time_left(&e), None);
}

#[test]
fn no_report_and_nan_say_so() {
    let l = line(None, None, true, false);
    assert!(
        l.contains("waiting for the first window") && l.contains("SILENT"),
        "{l}"
    );
    let e = EnergyState {
        remaining_pct: Some(f64::NAN),
        remaining_wh: Some(f64::INFINITY),
        ..Default::default()
    };
    let l = line(Some(&report(e, Some(f32::NAN))), None, false, false);
    assert!(l.starts_with("— W  charge — (assumed full)"), "{l}");
}

#[test]
fn the_source_is_named_in_words() {
    let mut e = EnergyState {
        remaining_source: RemainingSource::Battery,
        ..Default::default()
    };
    assert_eq!(charge_source(&e), "autopilot %");
    e.remaining_source = RemainingSource::UnknownPack;
    assert_eq!(charge_source(&e), "capacity not known");
    e.remaining_pct = Some(40.0);
    assert_eq!(charge_source(&e), "voltage only");
    e.remaining_source = RemainingSource::RestingVoltage;
    assert_eq!(charge_source(&e), "resting voltage");
}
