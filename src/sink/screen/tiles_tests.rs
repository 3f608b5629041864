use std::sync::Arc;

use ratatui::backend::TestBackend;
use ratatui::Terminal;

use super::super::{draw, LinkView, ScreenState};
use crate::features::Sample;
use crate::report::{
    AlertEvent, AlertState, BatteryFacts, EnergyState, Estimate, MissionStatus, ModelEstimate,
    RemainingSource, Report, Severity,
};

/// A report with every figure at a realistic widest: a 12S pack, a long mission, every
/// model, a critical alert raised.
fn report() -> Arc<Report> {
    let mut e = EnergyState {
        energy_used_wh: 1234.5,
        remaining_wh: Some(1234.5),
        remaining_pct: Some(100.0),
        remaining_source: RemainingSource::LoadCompensated,
        forecast_w: Some(12345.0),
        forecast_model: Some("tseng_solo".into()),
        forecast_adapted: true,
        time_to_empty_s: Some(5999.0),
        home_margin_wh: Some(-1234.5),
        mission_margin_wh: Some(-1234.5),
        mission: Some(MissionStatus {
            t_s: 0.0,
            current_seq: 999,
            items: 999,
            time_left_s: 5999.0,
            energy_p50_wh: 999.0,
            energy_p90_wh: 999.0,
            progress_pct: 100.0,
            route_en_m: Default::default(),
            route_at: 0,
        }),
        battery: BatteryFacts::m100().into(),
        ..Default::default()
    };
    e.pack.battery_v = Some(50.42);
    e.pack.battery_v_model = Some(50.41);
    e.pack.v_min_forecast_v = Some(44.44);
    e.pack.low_threshold_v = Some(45.0);
    e.pack.time_to_low_v_s = Some(5998.0);
    e.pack.soc_pct = Some(100.0);
    e.pack.internal_r_ohm = Some(0.123);
    let names = [
        "dandrea",
        "tseng_cal",
        "tseng_solo",
        "lstm",
        "liu",
        "dorling",
    ];
    Arc::new(Report {
        estimate: Estimate {
            t_s: 12345.6,
            sample: Sample::new(12345.6, [0.0; crate::features::N_FEATURES], Some(12345.0)),
            models: names
                .iter()
                .map(|n| {
                    let mut m = ModelEstimate::new(*n, 12345.0, None);
                    m.adapted_w = Some(12345.0);
                    m
                })
                .collect(),
            arrived: None,
        },
        energy: e,
        alerts: vec![AlertEvent {
            t: 12345.6,
            rule: "low_voltage_before_home".into(),
            severity: Severity::Critical,
            state: AlertState::Raised,
            message: "Return now: low voltage before home".into(),
        }],
        vehicle: 1.into(),
    })
}

fn screen(cols: u16, rows: u16, detail: bool) -> Vec<String> {
    let mut t = Terminal::new(TestBackend::new(cols, rows)).unwrap();
    let mut state = ScreenState::default();
    state.push(report());
    let link = LinkView {
        stats: Default::default(),
        silent: false,
        missed: 0,
    };
    t.draw(|f| draw(f, &state, &link, detail)).unwrap();
    let buf = t.backend().buffer();
    (0..rows)
        .map(|y| (0..cols).map(|x| buf[(x, y)].symbol()).collect())
        .collect()
}

#[test]
fn every_tile_is_whole_at_80x24_and_120x40() {
    for (cols, rows) in [(80, 24), (120, 40)] {
        for detail in [false, true] {
            let rows = screen(cols, rows, detail);
            let text = rows.join("\n");
            // The tiles' rows: nothing cut.
            for row in &rows[..12] {
                assert!(!row.contains('…'), "{cols}×{rows:?}: cut: {row}\n{text}");
            }
            let n = |c: char| text.chars().filter(|&x| x == c).count();
            assert!(
                n('┌') >= 9 && n('┌') == n('┘') && n('┌') == n('┐'),
                "{text}"
            );
            assert!(
                rows[1].contains("CRITICAL low_voltage_before_home: Return now"),
                "the banner: {text}"
            );
            for figure in [
                "100 %",
                "1234.5 Wh left",
                "voltage under load",
                "-1234.5 Wh",
            ] {
                assert!(text.contains(figure), "{figure}: {text}");
            }
        }
    }
}
