//! The `plan` command's two renderings of its forecast: the table it prints, and the PNG of
//! cumulative energy along the route with the P90 band and the reserve.

use super::*;

pub(super) fn plan_table(r: &PlanReport) -> String {
    use std::fmt::Write;
    let f = r.forecast;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} items, {:.1} m/s, payload {:.0} g, wind {:.1} m/s from {:.0}°",
        r.plan, r.items, r.speed_m_s, r.payload_g, r.wind.speed_m_s, r.wind.from_deg
    );
    let _ = writeln!(s, "vehicle: {}; forecast: {}", r.vehicle, r.forecast_from);
    let _ = writeln!(
        s,
        "P50: {} (P90 = {:.3} × P50)",
        if f.model.contains(" + ") {
            format!("the mean of {}", f.model)
        } else {
            f.model.clone()
        },
        f.p90_ratio
    );
    let _ = writeln!(
        s,
        "{:>4} {:<18} {:>8} {:>8} {:>9} {:>9}",
        "item", "leg", "time s", "dist m", "P50 Wh", "P90 Wh"
    );
    for l in &f.legs {
        let _ = writeln!(
            s,
            "{:>4} {:<18} {:>8.1} {:>8.0} {:>9.2} {:>9.2}",
            l.item, l.label, l.duration_s, l.distance_m, l.energy_p50_wh, l.energy_p90_wh
        );
    }
    let _ = writeln!(
        s,
        "{:>4} {:<18} {:>8.1} {:>8.0} {:>9.2} {:>9.2}",
        "", "total", f.duration_s, f.distance_m, f.energy_p50_wh, f.energy_p90_wh
    );
    let _ = writeln!(
        s,
        "battery {:.1} Wh{}, reserve {:.0} %: margin over reserve {:.1} Wh at P50, {:.1} Wh at P90{}",
        r.capacity_wh,
        r.pack.as_ref().map(|p| format!(" ({:.1} Wh in it now)", p.start_wh)).unwrap_or_default(),
        r.reserve_pct,
        r.margin_p50_wh,
        r.margin_p90_wh,
        if r.margin_p90_wh < 0.0 { "  — the mission may not finish above reserve" } else { "" }
    );
    if let Some(p) = &r.pack {
        let _ = writeln!(
            s,
            "pack: {:.2} V at rest ({} {}S, {:.0} % charged, {:.1} Wh to empty): lowest loaded voltage {:.2} V at {:.0} s{}, landing {:.2} V",
            p.rest_v,
            p.chemistry,
            p.cells,
            p.soc_pct,
            p.start_wh,
            p.v_min_v,
            p.v_min_at_s,
            p.v_min_leg.as_deref().map(|l| format!(" ({l})")).unwrap_or_default(),
            p.landing_v
        );
        let _ = writeln!(
            s,
            "low threshold {:.2} V ({}): {}",
            p.low_v,
            p.low_source,
            match p.low_crossed_at_s {
                Some(t) =>
                    format!("crossed at {t:.0} s — the voltage failsafe would fire on this plan"),
                None => format!(
                    "not crossed ({:.2} V above it at the lowest)",
                    p.v_min_v - p.low_v
                ),
            }
        );
    }
    for n in &r.not_modelled {
        let _ = writeln!(s, "not modelled: {n}");
    }
    if !r.terrain_frame_items.is_empty() {
        let _ = writeln!(
            s,
            "terrain-relative altitudes flown as above home (flat terrain): items {:?}",
            r.terrain_frame_items
        );
    }
    let _ = writeln!(
        s,
        "models (uncorrected, whole plan): {}",
        f.models_raw_wh
            .iter()
            .map(|(n, e)| format!("{n} {e:.1}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    s
}

/// Cumulative energy along the route: P50 line, P50–P90 band, the usable-energy line
/// (capacity − reserve), leg boundaries.
pub(super) fn plot_plan(
    path: &Path,
    title: &str,
    tr: &Trajectory,
    f: &MissionForecast,
    usable: f64,
    usable_label: &str,
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    crate::offline::plot::register_font();
    let t: Vec<f64> = (0..f.cum_p50_wh.len())
        .map(|i| (i + 1) as f64 * f.dt_s)
        .collect();
    let ymax = (f.energy_p90_wh.max(usable) * 1.08).max(1.0);
    let xmax = t.last().copied().unwrap_or(1.0).max(1.0);
    let root = BitMapBackend::new(path, (1200, 700)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{title}: cumulative energy along the plan"),
                ("sans-serif", 24),
            )
            .margin(14)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..xmax, 0.0..ymax)?;
        chart
            .configure_mesh()
            .x_desc("time from the motors' start (s)")
            .y_desc("energy (Wh)")
            .label_style(("sans-serif", 16))
            .axis_desc_style(("sans-serif", 18))
            .draw()?;
        let band: Vec<(f64, f64)> = t
            .iter()
            .zip(&f.cum_p50_wh)
            .map(|(&x, &e)| (x, e * f.p90_ratio))
            .chain(t.iter().zip(&f.cum_p50_wh).rev().map(|(&x, &e)| (x, e)))
            .collect();
        chart
            .draw_series(std::iter::once(Polygon::new(band, BLUE.mix(0.2))))?
            .label("P50–P90")
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], BLUE.mix(0.2).filled()));
        chart
            .draw_series(LineSeries::new(
                t.iter().zip(&f.cum_p50_wh).map(|(&x, &e)| (x, e)),
                BLUE.stroke_width(2),
            ))?
            .label("P50")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(3)));
        chart
            .draw_series(LineSeries::new(
                [(0.0, usable), (xmax, usable)],
                RED.stroke_width(2),
            ))?
            .label(usable_label)
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(3)));
        for l in &tr.legs {
            chart.draw_series(LineSeries::new(
                [(l.t_end_s, 0.0), (l.t_end_s, ymax * 0.03)],
                BLACK,
            ))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw()
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("{}: cannot write plot", path.display()))
}

/// The plan's plot (`--plot PNG`): the forecast against the usable energy, labelled with
/// the pack it starts from and the reserve.
pub(super) fn plot_report(png: &Path, report: &PlanReport, tr: &Trajectory) -> anyhow::Result<()> {
    let what = match &report.pack {
        Some(p) => format!("pack at {:.0} %", p.soc_pct),
        None => "full pack".into(),
    };
    let label = format!(
        "{what} − {:.0} % reserve: {:.1} Wh",
        report.reserve_pct, report.usable_wh
    );
    plot_plan(
        png,
        report.plan,
        tr,
        report.forecast,
        report.usable_wh,
        &label,
    )
}
