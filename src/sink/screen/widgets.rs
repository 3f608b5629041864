//! How one frame of the screen is drawn from a [`ScreenState`]: the title bar, the alert
//! banner, two rows of tiles for the selected vehicle ([`super::tiles`]: the pilot's first),
//! the power chart (measured, the forecast model's estimate, the forecast, over the last
//! minutes), the alerts as they fired, the vehicle list in fleet mode, and the newest log
//! line. Pure drawing: everything comes from the state.

use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::{
    Axis, Block, Chart, Dataset, GraphType, List, ListItem, ListState, Paragraph,
};
use ratatui::Frame;

use super::state::{ScreenState, VehicleView, HISTORY_S};
use super::tiles::{self, tile};
use crate::report::status::StatsSnapshot;
use crate::report::{AlertState, Severity};

/// What the screen shows beside the reports: the link's counters and whether it is silent.
pub struct LinkView {
    pub stats: StatsSnapshot,
    pub silent: bool,
    /// Reports the screen missed (stuck for longer than the sinks' patience).
    pub missed: u64,
}

/// A number, or `?` for NaN/infinity (a sensor glitch must not look like a value).
pub fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "?".into()
    }
}

fn opt(v: Option<f64>, decimals: usize, unit: &str) -> String {
    v.map_or("—".into(), |v| format!("{} {unit}", num(v, decimals)))
}

/// `12 min 05 s`, or `45 s`.
pub fn duration(s: f64) -> String {
    if !s.is_finite() {
        return "?".into();
    }
    let s = s.max(0.0).round() as u64;
    if s >= 60 {
        format!("{} min {:02} s", s / 60, s % 60)
    } else {
        format!("{s} s")
    }
}

fn severity_style(s: Severity) -> Style {
    match s {
        Severity::Emergency | Severity::Alert | Severity::Critical | Severity::Error => {
            Style::default().fg(Color::Red).add_modifier(Modifier::BOLD)
        }
        Severity::Warning => Style::default().fg(Color::Yellow),
        _ => Style::default().fg(Color::Cyan),
    }
}

/// Draw one frame: the title, the alert banner, the pilot's tiles (time left, the state
/// of charge, the voltage, the margins), power, the pack and the link, then the power chart
/// (beside every model's estimate with `detail`) over the alerts (and the vehicle list in
/// fleet mode), and the newest log line. Fits 80×24 whole.
pub fn draw(f: &mut Frame, s: &ScreenState, link: &LinkView, detail: bool) {
    let fleet = s.is_fleet();
    let [title, banner, tiles1, tiles2, middle, bottom] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Length(1),
        Constraint::Length(5),
        Constraint::Length(5),
        Constraint::Min(6),
        Constraint::Length(1),
    ])
    .areas(f.area());
    draw_title(f, title, s);
    let v = s.selected();
    let r = v.map(|v| &*v.report);
    tiles::banner(f, banner, v, link.silent);
    let [time, charge, volts, margins] =
        Layout::horizontal([Constraint::Ratio(1, 4); 4]).areas(tiles1);
    tile(f, time, "Time left", tiles::time_lines(r));
    tile(f, charge, "State of charge", tiles::charge_lines(r));
    tile(f, volts, "Voltage", tiles::voltage_lines(r));
    tile(f, margins, "Margins", tiles::margin_lines(r));
    let [power, pack, link_area] = Layout::horizontal([Constraint::Ratio(1, 3); 3]).areas(tiles2);
    tile(f, power, "Power", tiles::power_lines(r));
    tile(f, pack, "Pack model", tiles::pack_lines(r));
    tile(f, link_area, "Link", tiles::link_lines(s.rate, link, r));
    let [chart, lists] =
        Layout::vertical([Constraint::Percentage(55), Constraint::Percentage(45)]).areas(middle);
    if detail {
        let [chart, models] =
            Layout::horizontal([Constraint::Percentage(60), Constraint::Percentage(40)])
                .areas(chart);
        draw_chart(f, chart, v);
        tile(f, models, "Models (raw~adapted)", tiles::model_lines(r));
    } else {
        draw_chart(f, chart, v);
    }
    if fleet {
        let [alerts, vehicles] =
            Layout::horizontal([Constraint::Percentage(60), Constraint::Percentage(40)])
                .areas(lists);
        draw_alerts(f, alerts, s);
        draw_vehicles(f, vehicles, s);
    } else {
        draw_alerts(f, lists, s);
    }
    let log = if s.ended {
        "the input has ended: press any key to leave".to_string()
    } else {
        s.log.back().map_or(String::new(), |l| format!("log: {l}"))
    };
    let style = if s.ended {
        Style::default().fg(Color::Black).bg(Color::Cyan)
    } else {
        Style::default().fg(Color::DarkGray)
    };
    f.render_widget(Paragraph::new(log).style(style), bottom);
}

fn draw_title(f: &mut Frame, area: Rect, s: &ScreenState) {
    let mut spans = vec![Span::styled(
        " dronewatt ",
        Style::default().add_modifier(Modifier::BOLD | Modifier::REVERSED),
    )];
    match s.selected() {
        Some(v) => spans.push(Span::raw(format!(
            "  vehicle {} ({})  t {} s",
            v.report.vehicle,
            v.report.estimate.sample.vehicle.describe(),
            num(v.report.estimate.t_s, 1)
        ))),
        None => spans.push(Span::raw("  waiting for the first window")),
    }
    let keys = if s.is_fleet() {
        "   ↑/↓ vehicle  q quit"
    } else {
        "   q quit"
    };
    spans.push(Span::styled(keys, Style::default().fg(Color::DarkGray)));
    f.render_widget(Paragraph::new(Line::from(spans)), area);
}

fn series_line(name: String, color: Color, data: &[(f64, f64)]) -> Dataset<'_> {
    Dataset::default()
        .name(name)
        .marker(Marker::Braille)
        .graph_type(GraphType::Line)
        .style(Style::default().fg(color))
        .data(data)
}

fn draw_chart(f: &mut Frame, area: Rect, v: Option<&VehicleView>) {
    let block = Block::bordered().title(" Power, last 5 min (W) ");
    let Some(v) = v.filter(|v| !v.history.is_empty()) else {
        f.render_widget(Paragraph::new("no power yet").block(block), area);
        return;
    };
    let t1 = v.history.back().map_or(0.0, |p| p.t_s);
    let t0 = (t1 - HISTORY_S).max(v.history.front().map_or(0.0, |p| p.t_s));
    let series = |get: fn(&super::state::PowerPoint) -> Option<f64>| -> Vec<(f64, f64)> {
        v.history
            .iter()
            .filter_map(|p| get(p).map(|w| (p.t_s, w)))
            .collect()
    };
    let measured = series(|p| p.measured_w);
    let model = series(|p| p.model_w);
    let forecast = series(|p| p.forecast_w);
    let (lo, hi) = measured
        .iter()
        .chain(&model)
        .chain(&forecast)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &(_, w)| {
            (lo.min(w), hi.max(w))
        });
    let (lo, hi) = if lo.is_finite() {
        let pad = ((hi - lo) * 0.1).max(10.0);
        ((lo - pad).max(0.0), hi + pad)
    } else {
        (0.0, 1.0)
    };
    let model_name = v
        .report
        .energy
        .forecast_model
        .clone()
        .unwrap_or_else(|| "model".into());
    let chart = Chart::new(vec![
        series_line("forecast".into(), Color::Magenta, &forecast),
        series_line(model_name, Color::Cyan, &model),
        series_line("measured".into(), Color::Yellow, &measured),
    ])
    .block(block)
    .x_axis(
        Axis::default()
            .bounds([t0, t1.max(t0 + 1.0)])
            .labels([format!("{} s", num(t0, 0)), format!("{} s", num(t1, 0))])
            .style(Style::default().fg(Color::DarkGray)),
    )
    .y_axis(
        Axis::default()
            .bounds([lo, hi])
            .labels([num(lo, 0), num(hi, 0)])
            .style(Style::default().fg(Color::DarkGray)),
    )
    .legend_position(Some(ratatui::widgets::LegendPosition::TopLeft))
    .hidden_legend_constraints((Constraint::Ratio(1, 3), Constraint::Ratio(2, 3)));
    f.render_widget(chart, area);
}

fn draw_alerts(f: &mut Frame, area: Rect, s: &ScreenState) {
    let fleet = s.is_fleet();
    let width = usize::from(area.width.saturating_sub(2));
    let items: Vec<ListItem> = s
        .alerts
        .iter()
        .map(|a| {
            let e = &a.event;
            let style = match e.state {
                AlertState::Raised => severity_style(e.severity),
                AlertState::Cleared => Style::default().fg(Color::Green),
            };
            let who = if fleet {
                format!("v{} ", a.vehicle)
            } else {
                String::new()
            };
            let text = match e.state {
                AlertState::Raised => format!(
                    "{who}{:>6} s  {:<8} {} [{}]",
                    num(e.t, 0),
                    e.severity.name().to_uppercase(),
                    e.message,
                    e.rule
                ),
                AlertState::Cleared => format!(
                    "{who}{:>6} s  cleared  {}: {}",
                    num(e.t, 0),
                    e.rule,
                    e.message
                ),
            };
            ListItem::new(tiles::clip(Line::styled(text, style), width))
        })
        .collect();
    let title = format!(" Alerts ({}) ", s.alerts.len());
    let block = Block::bordered().title(title);
    if items.is_empty() {
        f.render_widget(Paragraph::new("none yet").block(block), area);
    } else {
        f.render_widget(List::new(items).block(block), area);
    }
}

fn draw_vehicles(f: &mut Frame, area: Rect, s: &ScreenState) {
    let items: Vec<ListItem> = s
        .vehicles
        .iter()
        .map(|(id, v)| {
            let e = &v.report.energy;
            let power = v
                .report
                .estimate
                .sample
                .measured_w
                .map(f64::from)
                .or(e.forecast_w);
            let worst = v.worst();
            let mut line = Line::raw(format!(
                "{id:>4} {:>9} {:>9} {:>10} ",
                opt(power, 0, "W"),
                opt(e.remaining_wh, 1, "Wh"),
                e.time_to_empty_s.map_or("—".into(), duration)
            ));
            if let Some((rule, sev)) = worst {
                line.push_span(Span::styled(rule.to_string(), severity_style(sev)));
            }
            ListItem::new(line)
        })
        .collect();
    let list = List::new(items)
        .block(Block::bordered().title(format!(" Vehicles ({}) ", s.vehicles.len())))
        .highlight_style(Style::default().add_modifier(Modifier::REVERSED))
        .highlight_symbol("▶");
    let mut state = ListState::default().with_selected(s.selected_index());
    f.render_stateful_widget(list, area, &mut state);
}
