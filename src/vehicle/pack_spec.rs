//! A pack named for a run: the `--pack` flag's spec, and a vehicle profile's `[battery]`.

use super::BatteryConfig;
use crate::battery::Chemistry;

/// A pack as `--pack` writes it: `<cells>S[<parallel>P]:<capacity>[:<chemistry>]`, e.g.
/// `4S2P:5000mAh:li-ion`, `6S:129.96Wh:lihv`, `3S:2.2Ah`. The capacity is the whole pack's
/// (what its label and `BATT_CAPACITY` say) in mAh, Ah or Wh; the chemistry `lipo`
/// (default), `lihv`, `li-ion`, `lifepo4`. Errors say what part is wrong and why.
pub fn parse_pack(spec: &str) -> Result<BatteryConfig, String> {
    let bad = |why: String| format!("--pack {spec}: {why} (expected e.g. 4S2P:5000mAh:li-ion)");
    let mut parts = spec.split(':');
    let layout = parts.next().unwrap_or("").trim().to_ascii_uppercase();
    let capacity = parts
        .next()
        .ok_or_else(|| bad("no capacity".into()))?
        .trim();
    let chemistry = match parts.next() {
        Some(c) => Some(Chemistry::parse_loose(c.trim()).ok_or_else(|| {
            bad(format!(
                "chemistry '{c}' is none of lipo, lihv, li-ion, lifepo4"
            ))
        })?),
        None => None,
    };
    if parts.next().is_some() {
        return Err(bad("more than three parts".into()));
    }
    let (series, parallel) = match layout.split_once('S') {
        Some((n, rest)) => (n, rest.strip_suffix('P').unwrap_or(rest)),
        None => return Err(bad(format!("'{layout}' is not <cells>S[<n>P]"))),
    };
    let cells: u32 = series
        .parse()
        .ok()
        .filter(|n| (1..=24).contains(n))
        .ok_or_else(|| bad(format!("'{series}' cells in series: 1-24")))?;
    if !parallel.is_empty() {
        parallel
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=64).contains(n))
            .ok_or_else(|| bad(format!("'{parallel}' in parallel: 1-64")))?;
    }
    let lower = capacity.to_ascii_lowercase();
    let (number, unit) = lower
        .find(|c: char| c.is_ascii_alphabetic())
        .map_or((lower.as_str(), ""), |k| lower.split_at(k));
    let x: f64 = number
        .trim()
        .parse()
        .ok()
        .filter(|x: &f64| x.is_finite() && *x > 0.0)
        .ok_or_else(|| bad(format!("capacity '{capacity}' is not a positive number")))?;
    let nominal = chemistry.unwrap_or(Chemistry::LiPo).nominal_v();
    let wh = match unit {
        "mah" => x / 1000.0 * f64::from(cells) * nominal,
        "ah" => x * f64::from(cells) * nominal,
        "wh" => x,
        _ => return Err(bad(format!("capacity '{capacity}': give mAh, Ah or Wh"))),
    };
    if !(1.0..=50_000.0).contains(&wh) {
        return Err(bad(format!("{wh:.1} Wh is no drone's pack (1-50000 Wh)")));
    }
    Ok(BatteryConfig {
        capacity_wh: Some(wh),
        cell_count: Some(cells),
        nominal_cell_v: None,
        chemistry: Some(chemistry.unwrap_or(Chemistry::LiPo)),
        named: Some(format!("--pack {spec}")),
    })
}

/// The pack a vehicle profile's `[battery]` describes (cells, mAh, its OCV's full voltage
/// for LiHV or LiPo), named after the profile.
pub fn profile_pack(p: &crate::model::profile::VehicleProfile) -> Option<BatteryConfig> {
    let b = p.battery.as_ref()?;
    let full = b.ocv_cell_v.last().map_or(4.2, |x| x[1]);
    let chem = if full > 4.3 {
        Chemistry::LiHv
    } else {
        Chemistry::LiPo
    };
    (b.cells > 0 && b.capacity_mah > 0.0).then(|| BatteryConfig {
        capacity_wh: Some(b.capacity_mah / 1000.0 * f64::from(b.cells) * chem.nominal_v()),
        cell_count: Some(b.cells),
        nominal_cell_v: None,
        chemistry: Some(chem),
        named: Some(format!("vehicle profile {} [battery]", p.name)),
    })
}
