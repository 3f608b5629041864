//! `dronewatt vehicles --nats URL`: the fleet as NATS shows it, read as a viewer (no lease,
//! no stream: a plain subscription to `dronewatt.estimates.>`, which the shipped server
//! config lets the `viewer` user read and nothing more). It listens for a few seconds and
//! lists each vehicle's latest estimate, whichever worker published it: a table, or the
//! estimates themselves as a JSON array (as the workers' `--json` writes them).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::time::Duration;

use anyhow::{Context as _, Result};
use futures_util::StreamExt;
use serde_json::Value;

use super::publish::ESTIMATES;
use super::NatsArgs;

/// Listen on `a.nats` for `listen` and list the vehicles heard (`json`: as a JSON array).
pub fn run(a: &NatsArgs, listen: Duration, json: bool) -> Result<String> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let latest = rt.block_on(latest(a, listen))?;
    Ok(if json {
        let all: Vec<&Value> = latest.values().collect();
        format!("{}\n", serde_json::to_string(&all)?)
    } else {
        table(&latest, listen)
    })
}

/// Each vehicle's (network, system id) latest estimate heard within `listen`.
async fn latest(a: &NatsArgs, listen: Duration) -> Result<BTreeMap<(u64, u64), Value>> {
    let client = super::connect(a, "dronewatt viewer").await?;
    let subject = format!("{ESTIMATES}.>");
    let mut sub = client
        .subscribe(subject.clone())
        .await
        .with_context(|| format!("NATS: subscribe {subject}"))?;
    let mut latest: BTreeMap<(u64, u64), Value> = BTreeMap::new();
    let end = tokio::time::Instant::now() + listen;
    while let Ok(Some(m)) = tokio::time::timeout_at(end, sub.next()).await {
        let Ok(v) = serde_json::from_slice::<Value>(&m.payload) else {
            tracing::debug!("NATS: {}: not a JSON estimate; skipped", m.subject);
            continue;
        };
        let (Some(sys), net) = (v["system_id"].as_u64(), v["network"].as_u64().unwrap_or(0)) else {
            continue;
        };
        let t = v["t"].as_f64().unwrap_or(f64::NEG_INFINITY);
        let newer = latest
            .get(&(net, sys))
            .is_none_or(|old| old["t"].as_f64().unwrap_or(f64::NEG_INFINITY) <= t);
        if newer {
            latest.insert((net, sys), v);
        }
    }
    Ok(latest)
}

/// One line per vehicle: its latest time, power, energy used, what is left.
fn table(latest: &BTreeMap<(u64, u64), Value>, listen: Duration) -> String {
    let mut out = String::new();
    if latest.is_empty() {
        let _ = writeln!(
            out,
            "no estimate heard on {ESTIMATES}.> in {:.0} s (no worker running, or no vehicle)",
            listen.as_secs_f64()
        );
        return out;
    }
    let num = |v: &Value, k: &str, prec: usize| {
        v[k].as_f64()
            .map_or("-".to_string(), |x| format!("{x:.prec$}"))
    };
    let _ = writeln!(
        out,
        "{:<9} {:>9} {:>9} {:>10} {:>10} {:>7} {:>10} {:>10}",
        "VEHICLE", "T S", "POWER W", "USED WH", "LEFT WH", "LEFT %", "EMPTY IN S", "HOME WH"
    );
    for ((net, sys), v) in latest {
        let _ = writeln!(
            out,
            "{:<9} {:>9} {:>9} {:>10} {:>10} {:>7} {:>10} {:>10}",
            format!("{net}:{sys}"),
            num(v, "t", 1),
            num(v, "measured_w", 0),
            num(v, "energy_used_wh", 2),
            num(v, "remaining_wh", 1),
            num(v, "remaining_pct", 0),
            num(v, "time_to_empty_s", 0),
            num(v, "home_margin_wh", 1),
        );
    }
    let _ = writeln!(
        out,
        "{} vehicles heard on {ESTIMATES}.> in {:.0} s",
        latest.len(),
        listen.as_secs_f64()
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_has_a_line_per_vehicle_and_dashes_for_what_is_not_known() {
        let mut m = BTreeMap::new();
        m.insert(
            (0, 7),
            serde_json::json!({"system_id": 7, "t": 12.26, "measured_w": 410.4,
                "energy_used_wh": 1.234, "remaining_wh": null}),
        );
        let t = table(&m, Duration::from_secs(3));
        let line = t.lines().nth(1).unwrap();
        assert!(line.starts_with("0:7") && line.contains("12.3") && line.contains("1.23"));
        assert!(line.contains(" - "), "{line}");
        assert!(t.contains("1 vehicles heard"));
        assert!(table(&BTreeMap::new(), Duration::from_secs(3)).contains("no estimate heard"));
    }
}
