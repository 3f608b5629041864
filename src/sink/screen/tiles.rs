//! The screen's tiles, pilot's first: the alert banner; time left, the state of charge,
//! the voltage and its forecast, the margins; then power, the pack model and the link.
//! Every line is written to fit a tile of an 80-column screen (18 characters inside a
//! quarter, 24 inside a third); [`tile`] cuts a longer one with `…` rather than let the
//! border hide it.

use ratatui::layout::Rect;
use ratatui::style::{Color, Modifier, Style, Stylize};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Paragraph};
use ratatui::Frame;

use super::state::VehicleView;
use super::widgets::{duration, num, LinkView};
use crate::report::{RemainingSource, Report};
use crate::sink::pilot::{self, is_critical};

fn opt(v: Option<f64>, decimals: usize, unit: &str) -> String {
    v.map_or("—".into(), |v| format!("{} {unit}", num(v, decimals)))
}

fn signed(v: f64) -> String {
    format!("{}{}", if v >= 0.0 { "+" } else { "" }, num(v, 1))
}

fn red() -> Style {
    Style::default().fg(Color::Red).add_modifier(Modifier::BOLD)
}

/// A line cut to `width` characters, the cut marked with `…`.
pub fn clip(line: Line<'static>, width: usize) -> Line<'static> {
    if line.width() <= width {
        return line;
    }
    let mut left = width.saturating_sub(1);
    let mut spans = Vec::new();
    for s in line.spans {
        if left == 0 {
            break;
        }
        let text: String = s.content.chars().take(left).collect();
        left -= text.chars().count();
        spans.push(Span::styled(text, s.style));
    }
    spans.push(Span::raw("…"));
    Line::from(spans)
}

/// A bordered tile; lines wider than its inside are cut with `…`.
pub fn tile(f: &mut Frame, area: Rect, title: &str, lines: Vec<Line<'static>>) {
    let inner = usize::from(area.width.saturating_sub(2));
    let block = Block::bordered().title(Span::styled(
        format!(" {title} "),
        Style::default().add_modifier(Modifier::BOLD),
    ));
    let lines: Vec<Line> = lines.into_iter().map(|l| clip(l, inner)).collect();
    f.render_widget(Paragraph::new(lines).block(block), area);
}

/// The banner: the most severe alert standing (red for one that calls for action now),
/// the link's silence, or that nothing stands.
pub fn banner(f: &mut Frame, area: Rect, v: Option<&VehicleView>, silent: bool) {
    let worst = v.and_then(VehicleView::worst_alert);
    let (text, style) = match (&worst, silent) {
        (_, true) => (
            " SILENT: no valid frame for 5 s".to_string(),
            Style::default().fg(Color::White).bg(Color::Red).bold(),
        ),
        (Some(w), _) => (
            {
                let text = format!(
                    " {} {}: {}",
                    w.severity.name().to_uppercase(),
                    w.rule,
                    w.message
                );
                // When it was raised, where the line has room (the message's figures are
                // that moment's).
                let at =
                    w.t.map_or(String::new(), |t| format!(" (raised at t {} s)", num(t, 0)));
                if text.chars().count() + at.chars().count() <= usize::from(area.width) {
                    text + &at
                } else {
                    text
                }
            },
            if is_critical(w.severity) {
                Style::default().fg(Color::White).bg(Color::Red).bold()
            } else {
                Style::default().fg(Color::Black).bg(Color::Yellow)
            },
        ),
        (None, false) => (
            " no alert standing".to_string(),
            Style::default().fg(Color::Green),
        ),
    };
    let line = clip(Line::styled(text, style), usize::from(area.width));
    f.render_widget(Paragraph::new(line).style(style), area);
}

pub fn time_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let e = &r.energy;
    let mut lines = match pilot::time_left(e) {
        Some((t, to)) => vec![
            Line::styled(duration(t), Style::default().bold()),
            Line::raw(format!("to {to}")),
        ],
        None => vec![Line::raw("—"), Line::raw("not known yet")],
    };
    if let Some(m) = &e.mission {
        lines.push(Line::raw(format!(
            "mission {}",
            pilot::short_duration(m.time_left_s)
        )));
    }
    lines
}

pub fn charge_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let e = &r.energy;
    let source = pilot::charge_source(e);
    let from = if e.remaining_source == RemainingSource::AssumedFull {
        Line::styled(
            "ASSUMED FULL",
            Style::default().fg(Color::Black).bg(Color::Yellow).bold(),
        )
    } else {
        Line::styled(source, Style::default().fg(Color::DarkGray))
    };
    vec![
        Line::styled(opt(e.remaining_pct, 0, "%"), Style::default().bold()),
        Line::raw(match e.remaining_wh {
            Some(w) => format!("{} Wh left", num(w, 1)),
            None => "— Wh left".into(),
        }),
        from,
    ]
}

pub fn voltage_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let pk = &r.energy.pack;
    let min = format!("min {}", opt(pk.v_min_forecast_v, 2, "V"));
    let below = pk
        .v_min_forecast_v
        .zip(pk.low_threshold_v)
        .is_some_and(|(lo, th)| lo < th);
    vec![
        Line::styled(
            format!("{} now", opt(pk.battery_v, 2, "V")),
            Style::default().bold(),
        ),
        if below {
            Line::styled(min, red())
        } else {
            Line::raw(min)
        },
        Line::styled(
            format!("low {}", opt(pk.low_threshold_v, 2, "V")),
            Style::default().fg(Color::DarkGray),
        ),
    ]
}

fn margin_line(label: &str, v: Option<f64>) -> Line<'static> {
    match v {
        Some(m) => Line::from(vec![
            Span::raw(format!("{label} ")),
            Span::styled(
                format!("{} Wh", signed(m)),
                if m < 0.0 {
                    red()
                } else {
                    Style::default().fg(Color::Green)
                },
            ),
        ]),
        None => Line::raw(format!("{label} —")),
    }
}

pub fn margin_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let e = &r.energy;
    let mut lines = vec![
        margin_line("mission", e.mission_margin_wh),
        margin_line("home", e.home_margin_wh),
    ];
    if let Some(m) = &e.mission {
        lines.push(Line::raw(format!(
            "item {}/{} {}%",
            m.current_seq,
            m.items,
            num(m.progress_pct, 0)
        )));
    }
    lines
}

pub fn power_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let e = &r.energy;
    let on = match &e.forecast_model {
        Some(m) => format!("{m}{}", if e.forecast_adapted { "~" } else { "" }),
        None => "measured".into(),
    };
    vec![
        Line::styled(
            format!(
                "{} measured",
                opt(r.estimate.sample.measured_w.map(f64::from), 0, "W")
            ),
            Style::default().fg(Color::Yellow).bold(),
        ),
        Line::raw(format!("forecast {}", opt(e.forecast_w, 0, "W"))),
        Line::styled(format!("on {on}"), Style::default().fg(Color::DarkGray)),
    ]
}

pub fn pack_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let pk = &r.energy.pack;
    let b = &r.energy.battery;
    vec![
        Line::raw(format!("model {}", opt(pk.battery_v_model, 2, "V"))),
        Line::raw(format!(
            "OCV {}  R {}",
            opt(pk.soc_pct, 0, "%"),
            opt(pk.internal_r_ohm.map(|r| r * 1000.0), 0, "mΩ")
        )),
        Line::styled(
            match b.capacity() {
                Some(c) => format!("{}S {} Wh", b.cell_count.value, num(c, 1)),
                None => format!("{}S, capacity not known", b.cell_count.value),
            },
            Style::default().fg(Color::DarkGray),
        ),
    ]
}

pub fn link_lines(rate: f64, link: &LinkView, r: Option<&Report>) -> Vec<Line<'static>> {
    let n = &link.stats;
    let state = if link.silent {
        Line::styled("SILENT", red())
    } else {
        Line::styled(
            format!("{} msg/s", num(rate, 0)),
            Style::default().fg(Color::Green),
        )
    };
    let mut lines = vec![
        state,
        Line::raw(format!(
            "bad {} gaps {} unk {}",
            n.frames_bad, n.gaps, n.unknown
        )),
    ];
    let stale = r.map_or(Vec::new(), |r| {
        crate::features::stale_names(r.estimate.sample.stale_mask)
    });
    if link.missed > 0 {
        lines.push(Line::styled(
            format!("{} reports missed", link.missed),
            Style::default().fg(Color::Yellow),
        ));
    } else if !stale.is_empty() {
        lines.push(Line::styled(
            format!("stale: {}", stale.join(",")),
            Style::default().fg(Color::Yellow),
        ));
    } else {
        lines.push(Line::styled(
            format!("ok {}", n.frames_ok),
            Style::default().fg(Color::DarkGray),
        ));
    }
    lines
}

/// Every model's estimate, raw~adapted (`--detail`), the forecast's model first and marked.
pub fn model_lines(r: Option<&Report>) -> Vec<Line<'static>> {
    let Some(r) = r else {
        return vec![Line::raw("—")];
    };
    let forecast = r.energy.forecast_model.as_deref();
    if r.estimate.models.is_empty() {
        return vec![Line::styled(
            "no power model ran",
            Style::default().fg(Color::DarkGray),
        )];
    }
    // The forecast's model first: a short tile (80×24) shows it whatever else it cuts.
    let mut models: Vec<_> = r.estimate.models.iter().collect();
    models.sort_by_key(|m| Some(m.name.as_str()) != forecast);
    models
        .into_iter()
        .map(|m| {
            let mut txt = format!("{} {}", m.name, num(f64::from(m.power_w), 0));
            if let Some(a) = m.adapted_w {
                txt.push_str(&format!("~{}", num(f64::from(a), 0)));
            }
            txt.push_str(" W");
            if forecast == Some(m.name.as_str()) {
                Line::styled(format!("{txt} ◀"), Style::default().fg(Color::Cyan))
            } else {
                Line::raw(txt)
            }
        })
        .collect()
}

#[cfg(test)]
#[path = "tiles_tests.rs"]
mod tests;
