//! Plots what `scripts/fleet-load.sh` measured: `cargo run --example fleet_load_plot --
//! fleet-load.csv fleet-load.png` writes two charts, `fleet-load.png` (CPU µs per
//! vehicle-second against fleet size) and `fleet-load-rss.png` (peak resident memory), one
//! line per LSTM rate.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [csv, png] = args.as_slice() else { bail!("usage: fleet_load_plot FLEET-LOAD.CSV OUT.PNG") };
    let text = std::fs::read_to_string(csv).with_context(|| format!("{csv}: cannot read"))?;
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().context("empty CSV")?.split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).with_context(|| format!("{csv}: no column {name}"));
    let (lstm, n, cpu, rss) = (col("lstm")?, col("vehicles")?, col("cpu_us_per_vs")?, col("rss_mib")?);
    let mut cpu_series: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    let mut rss_series: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    for (i, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let num = |c: usize| f.get(c).and_then(|v| v.parse::<f64>().ok()).with_context(|| format!("{csv}: line {}: column {c}", i + 2));
        let label = format!("LSTM at {}", f.get(lstm).copied().unwrap_or("?"));
        cpu_series.entry(label.clone()).or_default().push((num(n)?, num(cpu)?));
        rss_series.entry(label).or_default().push((num(n)?, num(rss)?));
    }
    fn series(m: &BTreeMap<String, Vec<(f64, f64)>>) -> Vec<(&str, Vec<(f64, f64)>)> {
        m.iter().map(|(k, v)| (k.as_str(), v.clone())).collect()
    }
    let png = PathBuf::from(png);
    dronewatt::offline::plot::lines(&png, "dronewatt fleet load: CPU per vehicle", "vehicles", "CPU µs per vehicle-second", &series(&cpu_series))?;
    let rss_png = png.with_file_name(format!("{}-rss.png", png.file_stem().and_then(|s| s.to_str()).unwrap_or("fleet-load")));
    dronewatt::offline::plot::lines(&rss_png, "dronewatt fleet load: memory", "vehicles", "peak RSS, MiB", &series(&rss_series))?;
    Ok(())
}
