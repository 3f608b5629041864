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

/// Write `path` (PNG): `measured` in black, each series in its own colour, time on x.
pub fn power_over_flight(path: &Path, title: &str, t_s: &[f64], measured: &[f64], series: &[Series]) -> anyhow::Result<()> {
    register_font();
    let t0 = t_s.first().copied().unwrap_or(0.0);
    let t1 = t_s.last().copied().unwrap_or(1.0).max(t0 + 1.0);
    let finite = |v: &&f64| v.is_finite();
    let ymax = measured
        .iter()
        .chain(series.iter().flat_map(|s| s.power_w.iter()))
        .filter(finite)
        .fold(100.0f64, |a, &b| a.max(b))
        * 1.05;
    let ymin = measured.iter().chain(series.iter().flat_map(|s| s.power_w.iter())).filter(finite).fold(0.0f64, |a, &b| a.min(b));
    let root = BitMapBackend::new(path, (1400, 800)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 26))
            .margin(15)
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
        let pts = |v: &[f64]| t_s.iter().zip(v).filter(|(t, p)| t.is_finite() && p.is_finite()).map(|(&t, &p)| (t, p)).collect::<Vec<_>>();
        chart
            .draw_series(LineSeries::new(pts(measured), BLACK.stroke_width(2)))?
            .label("measured")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(3)));
        for (i, s) in series.iter().enumerate() {
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
        power_over_flight(&p, "test", &t, &m, &[Series { label: "flat", power_w: &a }]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
    }
}
