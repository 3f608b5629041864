//! Every PNG the offline commands write, with plotters' bitmap backend:
//!
//! - [`power_over_flight`]: models against measured power over a flight (the comparative
//!   study's model-comparison figure; `eval --plot`, `train`'s `flight276.png`);
//! - [`lines`]: named x–y series (`train`'s loss curves);
//! - [`diverging_bars`]: changes around zero (`sensitivity`, the paper's Table 3 chart).
//!
//! Text needs a font and a fresh machine may have none: DejaVu Sans (Bitstream Vera
//! licence, `config/fonts/DejaVuSans.LICENSE`) is compiled in ([`crate::assets::FONT`]) and
//! registered once.

use std::path::Path;
use std::sync::Once;

use anyhow::Context;
use plotters::coord::Shift;
use plotters::prelude::*;

static FONT: &[u8] = crate::assets::FONT;
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

/// What a drawing step returns: plotters' errors, boxed.
type Drawn = Result<(), Box<dyn std::error::Error>>;

/// Write a PNG of `size` pixels to `path`: the font registered, a white background,
/// `draw` on it, saved. A failure (no such folder, a full disk) is an error naming the file.
fn png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend, Shift>) -> Drawn,
) -> anyhow::Result<()> {
    register_font();
    let root = BitMapBackend::new(path, size).into_drawing_area();
    let drawn = (|| -> Drawn {
        root.fill(&WHITE)?;
        draw(&root)?;
        root.present()?;
        Ok(())
    })();
    drawn
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("{}: cannot write plot", path.display()))
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
pub fn power_over_flight(
    path: &Path,
    title: &str,
    t_s: &[f64],
    measured: &[f64],
    panels: &[Panel],
) -> anyhow::Result<()> {
    let t0 = t_s.first().copied().unwrap_or(0.0);
    let t1 = t_s.last().copied().unwrap_or(1.0).max(t0 + 1.0);
    let all = || {
        measured
            .iter()
            .chain(
                panels
                    .iter()
                    .flat_map(|p| p.series.iter().flat_map(|s| s.power_w.iter())),
            )
            .filter(|v| v.is_finite())
    };
    let ymax = all().fold(100.0f64, |a, &b| a.max(b)) * 1.05;
    let ymin = all().fold(0.0f64, |a, &b| a.min(b));
    let height = 120 + 520 * panels.len().max(1) as u32;
    png(path, (1400, height), |root| {
        let root = root.titled(title, ("sans-serif", 28))?;
        let areas = root.split_evenly((panels.len().max(1), 1));
        let pts = |v: &[f64]| {
            t_s.iter()
                .zip(v)
                .filter(|(t, p)| t.is_finite() && p.is_finite())
                .map(|(&t, &p)| (t, p))
                .collect::<Vec<_>>()
        };
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
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(3))
                });
            for (i, s) in panel.series.iter().enumerate() {
                let c = Palette99::pick(i).to_rgba();
                chart
                    .draw_series(LineSeries::new(pts(s.power_w), c.stroke_width(2)))?
                    .label(s.label)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(3))
                    });
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 16))
                .draw()?;
        }
        Ok(())
    })
}

/// Write `path` (PNG, 900 × 500): a line chart of named series of (x, y) points, the
/// first two drawn thicker.
pub fn lines(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(&str, Vec<(f64, f64)>)],
) -> anyhow::Result<()> {
    let finite = || {
        series
            .iter()
            .flat_map(|s| s.1.iter())
            .filter(|p| p.0.is_finite() && p.1.is_finite())
    };
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in finite() {
        (x0, x1, y0, y1) = (x0.min(*x), x1.max(*x), y0.min(*y), y1.max(*y));
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let pad = ((y1 - y0) * 0.05).max(1e-9);
    png(path, (900, 500), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1.max(x0 + 1e-9), (y0 - pad)..(y1 + pad))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .draw()?;
        for (i, (name, pts)) in series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(
                    pts.iter().cloned(),
                    color.stroke_width(if i < 2 { 2 } else { 1 }),
                ))?
                .label(*name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
        Ok(())
    })
}

/// Write `path` (PNG, 900 × 520): one horizontal bar per (label, value) around zero, red
/// above and blue below, with `x_label` under the axis.
pub fn diverging_bars(
    path: &Path,
    title: &str,
    x_label: &str,
    bars: &[(String, f64)],
) -> anyhow::Result<()> {
    let m = bars.iter().map(|b| b.1.abs()).fold(1.0, f64::max) * 1.1;
    png(path, (900, 520), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(130)
            .build_cartesian_2d(-m..m, (0..bars.len() as i32).into_segmented())?;
        chart
            .configure_mesh()
            .y_labels(bars.len() + 1)
            .y_label_formatter(&|v| match v {
                SegmentValue::CenterOf(i) => bars
                    .get(*i as usize)
                    .map(|b| b.0.clone())
                    .unwrap_or_default(),
                _ => String::new(),
            })
            .x_desc(x_label)
            .draw()?;
        chart.draw_series(bars.iter().enumerate().map(|(i, (_, v))| {
            let color = if *v >= 0.0 {
                RED.mix(0.7)
            } else {
                BLUE.mix(0.7)
            };
            let (a, b) = (
                SegmentValue::Exact(i as i32),
                SegmentValue::Exact(i as i32 + 1),
            );
            Rectangle::new([(0.0, a), (*v, b)], color.filled())
        }))?;
        Ok(())
    })
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
        let panel = Panel {
            caption: "one".into(),
            series: vec![Series {
                label: "flat",
                power_w: &a,
            }],
        };
        power_over_flight(&p, "test", &t, &m, &[panel]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
    }

    #[test]
    fn writes_lines_and_bars() {
        let dir = tempfile::tempdir().unwrap();
        let (l, b) = (dir.path().join("l.png"), dir.path().join("b.png"));
        lines(
            &l,
            "loss",
            "epoch",
            "loss",
            &[("a", vec![(1.0, 0.5), (2.0, 0.3)]), ("empty", vec![])],
        )
        .unwrap();
        diverging_bars(
            &b,
            "change",
            "W",
            &[("up".into(), 3.0), ("down".into(), -1.5)],
        )
        .unwrap();
        for p in [l, b] {
            assert_eq!(&std::fs::read(&p).unwrap()[1..4], b"PNG", "{}", p.display());
        }
        // A folder that does not exist is an error naming the file, not a panic.
        let bad = dir.path().join("missing/x.png");
        let err = lines(&bad, "t", "x", "y", &[]).unwrap_err().to_string();
        assert!(err.contains("missing/x.png"), "{err}");
    }
}
