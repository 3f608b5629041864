//! How one frame of the screen is drawn from a [`ScreenState`]: the title bar, two rows of
//! tiles for the selected vehicle (power, forecast, remaining energy, time to empty,
//! margins, the pack, the link), the power chart (measured, the forecast model's estimate,
//! the forecast, over the last minutes), the alerts as they fired, the vehicle list in
//! fleet mode, and the newest log line. Pure drawing: everything comes from the state.

use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style, Stylize};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::{
    Axis, Block, Chart, Dataset, GraphType, List, ListItem, ListState, Paragraph,
};
use ratatui::Frame;

use super::state::{ScreenState, VehicleView, HISTORY_S};
use crate::report::status::StatsSnapshot;
use crate::report::{AlertState, RemainingSource, Report, Severity};

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

fn signed(v: f64) -> String {
    format!("{}{}", if v >= 0.0 { "+" } else { "" }, num(v, 1))
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

fn tile<'a>(f: &mut Frame, area: Rect, title: &'a str, lines: Vec<Line<'a>>) {
    let block = Block::bordered().title(Span::styled(
        format!(" {title} "),
        Style::default().add_modifier(Modifier::BOLD),
    ));
    f.render_widget(Paragraph::new(lines).block(block), area);
}

/// Draw one frame.
pub fn draw(f: &mut Frame, s: &ScreenState, link: &LinkView) {
    let fleet = s.is_fleet();
    let [title, tiles1, tiles2, middle, bottom] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Length(7),
        Constraint::Length(6),
        Constraint::Min(8),
        Constraint::Length(1),
    ])
    .areas(f.area());
    draw_title(f, title, s);
    let v = s.selected();
    let r = v.map(|v| &*v.report);
    let [power, forecast, remaining, tte] =
        Layout::horizontal([Constraint::Ratio(1, 4); 4]).areas(tiles1);
    tile(f, power, "Power", power_lines(r));
    tile(f, forecast, "Forecast", forecast_lines(r));
    tile(f, remaining, "Remaining energy", remaining_lines(r));
    tile(f, tte, "Time to empty", tte_lines(r));
    let [margins, pack, link_area] = Layout::horizontal([
        Constraint::Ratio(1, 3),
        Constraint::Ratio(1, 3),
        Constraint::Ratio(1, 3),
    ])
    .areas(tiles2);
    tile(f, margins, "Margins", margin_lines(r));
    tile(f, pack, "Pack", pack_lines(r));
    tile(f, link_area, "Link", link_lines(s, link, r));
    let [chart, lists] =
        Layout::vertical([Constraint::Percentage(55), Constraint::Percentage(45)]).areas(middle);
    draw_chart(f, chart, v);
    if fleet {
        let [alerts, vehicles] =
            Layout::horizontal([Constraint::Percentage(60), Constraint::Percentage(40)])
                .areas(lists);
        draw_alerts(f, alerts, s);
        draw_vehicles(f, vehicles, s);
    } else {
        draw_alerts(f, lists, s);
    }
    let log = s.log.back().map_or(String::new(), |l| format!("log: {l}"));
    f.render_widget(Paragraph::new(log).fg(Color::DarkGray), bottom);
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

fn power_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let mut lines = vec![Line::from(vec![
        Span::raw("measured "),
        Span::styled(
            opt(r.estimate.sample.measured_w.map(f64::from), 1, "W"),
            Style::default().fg(Color::Yellow).bold(),
        ),
    ])];
    // The forecast model first (the tile may not hold every model), then the others.
    let forecast = r.energy.forecast_model.as_deref();
    let mut models: Vec<_> = r.estimate.models.iter().collect();
    models.sort_by_key(|m| Some(m.name.as_str()) != forecast);
    if models.is_empty() && r.estimate.sample.vehicle.lift() == crate::features::Lift::Unmodelled {
        lines.push(Line::styled(
            "no power model for this vehicle class",
            Style::default().fg(Color::DarkGray),
        ));
    }
    for m in models {
        let is_forecast = forecast == Some(m.name.as_str());
        let mut txt = format!("{} {}", m.name, num(f64::from(m.power_w), 1));
        if let Some(a) = m.adapted_w {
            txt.push_str(&format!("~{}", num(f64::from(a), 1)));
        }
        txt.push_str(" W");
        lines.push(if is_forecast {
            Line::styled(format!("{txt} ◀"), Style::default().fg(Color::Cyan))
        } else {
            Line::raw(txt)
        });
    }
    lines
}

fn forecast_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let e = &r.energy;
    let on = match &e.forecast_model {
        Some(m) => format!(
            "on {m}{}",
            if e.forecast_adapted { " (adapted)" } else { "" }
        ),
        None => "on measured power".into(),
    };
    let mut lines = vec![
        Line::styled(opt(e.forecast_w, 1, "W"), Style::default().bold()),
        Line::raw(on),
    ];
    if let Some(why) = &e.forecast_why {
        lines.push(Line::styled(
            format!("why: {why}"),
            Style::default().fg(Color::DarkGray),
        ));
    }
    lines
}

fn remaining_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let e = &r.energy;
    let mut left = opt(e.remaining_wh, 1, "Wh");
    if let Some(p) = e.remaining_pct {
        left.push_str(&format!(" ({}%)", num(p, 0)));
    }
    let from = match e.remaining_source {
        RemainingSource::AssumedFull => Line::styled(
            "from: ASSUMED FULL (no start state)",
            Style::default()
                .fg(Color::Black)
                .bg(Color::Yellow)
                .add_modifier(Modifier::BOLD),
        ),
        src => Line::raw(format!("from: {src}")),
    };
    let b = &e.battery;
    vec![
        Line::styled(left, Style::default().bold()),
        from,
        Line::raw(match b.capacity() {
            Some(c) => format!("of {} Wh [{}]", num(c, 1), b.capacity_source()),
            None => "capacity not known".to_string(),
        }),
        Line::raw(format!(
            "used {} Wh ({})",
            num(e.energy_used_wh, 2),
            e.power_source
        )),
    ]
}

fn tte_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let e = &r.energy;
    let mut lines = vec![Line::styled(
        e.time_to_empty_s.map_or("—".into(), duration),
        Style::default().bold(),
    )];
    if let Some(t) = e.pack.time_to_low_v_s {
        lines.push(Line::raw(format!("to low voltage {}", duration(t))));
    }
    if let Some(m) = &e.mission {
        lines.push(Line::raw(format!(
            "mission left {}",
            duration(m.time_left_s)
        )));
    }
    lines
}

fn margin_line(label: &str, v: Option<f64>) -> Line<'static> {
    match v {
        Some(m) => Line::from(vec![
            Span::raw(format!("{label} ")),
            Span::styled(
                format!("{} Wh", signed(m)),
                if m < 0.0 {
                    Style::default().fg(Color::Red).bold()
                } else {
                    Style::default().fg(Color::Green)
                },
            ),
        ]),
        None => Line::raw(format!("{label} —")),
    }
}

fn margin_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let e = &r.energy;
    let mut lines = vec![
        margin_line("home", e.home_margin_wh),
        margin_line("mission", e.mission_margin_wh),
    ];
    if let Some(m) = &e.mission {
        lines.push(Line::raw(format!(
            "item {}/{}  {}%  needs {} Wh",
            m.current_seq,
            m.items,
            num(m.progress_pct, 0),
            num(m.energy_p50_wh, 1)
        )));
    }
    lines
}

fn pack_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let pk = &r.energy.pack;
    let mut lines = vec![Line::raw(format!(
        "{} ~ {} model",
        opt(pk.battery_v, 2, "V"),
        opt(pk.battery_v_model, 2, "V")
    ))];
    lines.push(Line::raw(format!(
        "state of charge {}",
        opt(pk.soc_pct, 0, "%")
    )));
    let low = match (pk.v_min_forecast_v, pk.low_threshold_v) {
        (Some(lo), Some(th)) => Line::styled(
            format!("lowest {} V  low {} V", num(lo, 2), num(th, 2)),
            if lo < th {
                Style::default().fg(Color::Red).bold()
            } else {
                Style::default()
            },
        ),
        (lo, th) => Line::raw(format!(
            "lowest {}  low {}",
            opt(lo, 2, "V"),
            opt(th, 2, "V")
        )),
    };
    lines.push(low);
    lines
}

fn link_lines(s: &ScreenState, link: &LinkView, r: Option<&Report>) -> Vec<Line<'static>> {
    let n = &link.stats;
    let state = if link.silent {
        Line::styled(
            "SILENT (no valid frame for 5 s)",
            Style::default().fg(Color::Red).bold(),
        )
    } else {
        Line::styled("receiving", Style::default().fg(Color::Green))
    };
    let mut lines = vec![
        Line::raw(format!(
            "{} msg/s  ok {}  bad frames {}",
            num(s.rate, 0),
            n.frames_ok,
            n.frames_bad
        )),
        Line::raw(format!(
            "gaps {}  unknown {}  silent {}x",
            n.gaps, n.unknown, n.silences
        )),
        state,
    ];
    if let Some(r) = r {
        let stale = crate::features::stale_names(r.estimate.sample.stale_mask);
        if !stale.is_empty() {
            lines[2].push_span(Span::styled(
                format!("  stale: {}", stale.join(",")),
                Style::default().fg(Color::Yellow),
            ));
        }
    }
    if link.missed > 0 {
        lines.push(Line::styled(
            format!("{} reports missed by the screen", link.missed),
            Style::default().fg(Color::Yellow),
        ));
    }
    lines
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
    let items: Vec<ListItem> = s
        .alerts
        .iter()
        .map(|a| {
            let e = &a.event;
            let (state, style) = match e.state {
                AlertState::Raised => ("raised ", severity_style(e.severity)),
                AlertState::Cleared => ("cleared", Style::default().fg(Color::Green)),
            };
            let who = if fleet {
                format!("v{} ", a.vehicle)
            } else {
                String::new()
            };
            ListItem::new(Line::styled(
                format!(
                    "{who}t {:>6} s  {:<22} {:<9} {state}  {}",
                    num(e.t, 1),
                    e.rule,
                    e.severity.name(),
                    e.message
                ),
                style,
            ))
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
