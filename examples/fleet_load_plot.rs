//! Plots what `scripts/fleet-load.sh` measured: `cargo run --example fleet_load_plot --
//! fleet-load.csv fleet-load.png` writes three charts: `fleet-load.png` (CPU µs per
//! vehicle-second against fleet size), `fleet-load-rss.png` (peak resident memory per
//! vehicle, KiB) and `fleet-load-latency.png` (p99 message → estimate, ms); one line per
//! LSTM rate (and live/MQTT variant), both axes logarithmic (1 → 10 → 100 → 1,000
//! vehicles). Where a size was measured more than once, the last row counts.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use plotters::prelude::*;

type Lines = BTreeMap<String, BTreeMap<u64, f64>>;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [csv, png] = args.as_slice() else {
        bail!("usage: fleet_load_plot FLEET-LOAD.CSV OUT.PNG")
    };
    let text = std::fs::read_to_string(csv).with_context(|| format!("{csv}: cannot read"))?;
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().context("empty CSV")?.split(',').collect();
    let col = |name: &str| {
        head.iter()
            .position(|h| *h == name)
            .with_context(|| format!("{csv}: no column {name}"))
    };
    let (lstm, n, cpu, rss) = (
        col("lstm")?,
        col("vehicles")?,
        col("cpu_us_per_vs")?,
        col("rss_kib_per_vehicle")?,
    );
    let p99 = col("p99_ms")?;
    let (mut cpu_lines, mut rss_lines, mut p99_lines) = (Lines::new(), Lines::new(), Lines::new());
    for (i, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let num = |c: usize| {
            f.get(c)
                .and_then(|v| v.parse::<f64>().ok())
                .with_context(|| format!("{csv}: line {}: column {}", i + 2, head[c]))
        };
        let label = label(f.get(lstm).copied().unwrap_or("?"));
        let vehicles = num(n)? as u64;
        cpu_lines
            .entry(label.clone())
            .or_default()
            .insert(vehicles, num(cpu)?);
        rss_lines
            .entry(label.clone())
            .or_default()
            .insert(vehicles, num(rss)?);
        p99_lines
            .entry(label)
            .or_default()
            .insert(vehicles, num(p99)?);
    }
    let png = PathBuf::from(png);
    log_log(
        &png,
        "dronewatt fleet load: CPU per vehicle",
        "CPU µs per vehicle-second",
        &cpu_lines,
    )?;
    let beside = |what: &str| {
        png.with_file_name(format!(
            "{}-{what}.png",
            png.file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("fleet-load")
        ))
    };
    log_log(
        &beside("rss"),
        "dronewatt fleet load: memory per vehicle",
        "peak RSS per vehicle, KiB",
        &rss_lines,
    )?;
    log_log(
        &beside("latency"),
        "dronewatt fleet load: message → estimate, p99",
        "p99 latency, ms",
        &p99_lines,
    )?;
    Ok(())
}

/// A row's `lstm` column in words: `2hz` → `LSTM 2 Hz`, `live-2hz+mqtt` → `live UDP, LSTM 2 Hz, MQTT`.
fn label(lstm: &str) -> String {
    let (live, rest) = lstm
        .strip_prefix("live-")
        .map_or((false, lstm), |r| (true, r));
    let (rate, mqtt) = rest
        .strip_suffix("+mqtt")
        .map_or((rest, false), |r| (r, true));
    let mut s = format!(
        "{}LSTM {} Hz",
        if live { "live UDP, " } else { "" },
        rate.trim_end_matches("hz")
    );
    if mqtt {
        s.push_str(", MQTT");
    }
    s
}

/// The values `m × 10^k` (m from `steps`) between `lo` and `hi`: where the labels go.
fn decades(lo: f64, hi: f64, steps: &[f64]) -> Vec<f64> {
    let mut v = Vec::new();
    let mut d = 10f64.powf(lo.log10().floor());
    while d <= hi {
        v.extend(
            steps
                .iter()
                .map(|m| m * d)
                .filter(|x| (lo..=hi).contains(x)),
        );
        d *= 10.0;
    }
    v
}

/// One line per entry, vehicles on a log x axis, `y_label` on a log y axis, points marked.
fn log_log(path: &Path, title: &str, y_label: &str, lines: &Lines) -> Result<()> {
    dronewatt::offline::plot::register_font();
    let pts = || {
        lines
            .values()
            .flat_map(|l| l.iter().map(|(&x, &y)| (x as f64, y)))
            .filter(|p| p.0 > 0.0 && p.1 > 0.0)
    };
    let (x1, y0, y1) = pts().fold((10.0f64, f64::MAX, f64::MIN), |(x1, y0, y1), (x, y)| {
        (x1.max(x), y0.min(y), y1.max(y))
    });
    if y0 > y1 {
        bail!("{}: nothing to plot", path.display());
    }
    let root = BitMapBackend::new(path, (900, 520)).into_drawing_area();
    let drawn = (|| -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (0.8..x1 * 1.25)
                    .log_scale()
                    .with_key_points(decades(1.0, x1 * 1.25, &[1.0])),
                (y0 / 1.3..y1 * 1.3).log_scale().with_key_points(decades(
                    y0 / 1.3,
                    y1 * 1.3,
                    &[1.0, 2.0, 5.0],
                )),
            )?;
        chart
            .configure_mesh()
            .x_desc("vehicles")
            .y_desc(y_label)
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:.0}"))
            .draw()?;
        for (i, (name, l)) in lines.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let series: Vec<(f64, f64)> = l.iter().map(|(&x, &y)| (x as f64, y)).collect();
            chart
                .draw_series(LineSeries::new(series.clone(), color.stroke_width(2)))?
                .label(name.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
            chart.draw_series(series.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    })();
    drawn
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("{}: cannot write plot", path.display()))
}
