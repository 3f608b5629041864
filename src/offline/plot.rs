//! PNG plots of models against measured power over a flight (the comparative study's
//! model-comparison figure), with plotters' bitmap backend.
//!
//! Text needs a font and a fresh machine may have none: DejaVu Sans (Bitstream Vera
//! licence, `config/fonts/LICENSE-DejaVu.txt`) is compiled in and registered once.

use std::path::Path;
use std::sync::Once;

use anyhow::Context;
use plotters::prelude::*;

static FONT: &[u8] = include_bytes!("../../config/fonts/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Register the embedded font as `sans-serif` (idempotent).
pub fn register_font() {
    REGISTER.call_once(|| {
        // The embedded file is a valid TTF; a failure would only lose the text.
        if plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_err() {
            tracing::warn!("embedded font rejected: plots will have no text");
        }
    });
}

/// One line on a plot.
pub struct Series<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Power, W, one per time.
    pub power_w: &'a [f64],
}

/// One panel: a caption and its lines (each panel also shows the measured power).
pub struct Panel<'a> {
    /// Panel caption.
    pub caption: String,
    /// The model lines.
    pub series: Vec<Series<'a>>,
}

/// Write `path` (PNG): one panel per entry of `panels`, stacked, each with `measured` in
/// black and every series in its own colour, time on x, the same power scale throughout.
pub fn power_over_flight(path: &Path, title: &str, t_s: &[f64], measured: &[f64], panels: &[Panel]) -> anyhow::Result<()> {
    register_font();
    let t0 = t_s.first().copied().unwrap_or(0.0);
    let t1 = t_s.last().copied().unwrap_or(1.0).max(t0 + 1.0);
    let all = || measured.iter().chain(panels.iter().flat_map(|p| p.series.iter().flat_map(|s| s.power_w.iter()))).filter(|v| v.is_finite());
    let ymax = all().fold(100.0f64, |a, &b| a.max(b)) * 1.05;
    let ymin = all().fold(0.0f64, |a, &b| a.min(b));
    let height = 120 + 520 * panels.len().max(1) as u32;
    let root = BitMapBackend::new(path, (1400, height)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        let root = root.titled(title, ("sans-serif", 28))?;
        let areas = root.split_evenly((panels.len().max(1), 1));
        let pts = |v: &[f64]| t_s.iter().zip(v).filter(|(t, p)| t.is_finite() && p.is_finite()).map(|(&t, &p)| (t, p)).collect::<Vec<_>>();
        for (area, panel) in areas.iter().zip(panels) {
            let mut chart = ChartBuilder::on(area)
                .caption(&panel.caption, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(45)
                .y_label_area_size(70)
                .build_cartesian_2d(t0..t1, ymin..ymax)?;
            chart
                .configure_mesh()
                .x_desc("time (s)")
                .y_desc("electrical power (W)")
                .label_style(("sans-serif", 16))
                .axis_desc_style(("sans-serif", 18))
                .draw()?;
            chart
                .draw_series(LineSeries::new(pts(measured), BLACK.stroke_width(2)))?
                .label("measured")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(3)));
            for (i, s) in panel.series.iter().enumerate() {
                let c = Palette99::pick(i).to_rgba();
                chart
                    .draw_series(LineSeries::new(pts(s.power_w), c.stroke_width(2)))?
                    .label(s.label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(3)));
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 16))
                .draw()?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("{e}")).with_context(|| format!("{}: cannot write plot", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.png");
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let m: Vec<f64> = t.iter().map(|x| 400.0 + 50.0 * x.sin()).collect();
        let a = vec![420.0; 50];
        let panel = Panel { caption: "one".into(), series: vec![Series { label: "flat", power_w: &a }] };
        power_over_flight(&p, "test", &t, &m, &[panel]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
    }
}
