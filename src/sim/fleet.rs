//! A fleet on one link: many vehicles flown at once and their messages interleaved.

use super::*;

/// Most vehicles one fleet simulation flies (MAVLink system ids 1..=255; 255 is the usual
/// ground station's, so it is left free).
pub const MAX_FLEET: u8 = 254;

/// Fly `n` vehicles of `opts` at once, as one link carries them: vehicle `i` (0-based) is
/// MAVLink system `i + 1`, flies the route turned by `i` × 137.5° about home (the golden
/// angle: no two headings alike) with seed `opts.seed + i`, and starts `i` × 37 ms (mod 1 s)
/// after the first, so the vehicles' 10 Hz ticks do not all fall together. Returns one flight per vehicle, in system-id order; [`merge`] interleaves
/// their messages. Pure computation, deterministic per seed.
pub fn simulate_fleet(opts: &SimOptions, n: u8) -> anyhow::Result<Vec<SimFlight>> {
    if !(1..=MAX_FLEET).contains(&n) {
        anyhow::bail!("--vehicles {n}: must be 1..={MAX_FLEET} (one MAVLink system id each)");
    }
    (0..n)
        .map(|i| {
            let turn = (f64::from(i) * 137.5).to_radians();
            let (s, c) = turn.sin_cos();
            let mut o = opts.clone();
            o.seed = opts.seed.wrapping_add(u64::from(i));
            for w in &mut o.route.waypoints {
                (w.north_m, w.east_m) =
                    (c * w.north_m - s * w.east_m, s * w.north_m + c * w.east_m);
            }
            let mut f = simulate(&o)?;
            let delay_us = (u64::from(i) * 37_000) % 1_000_000;
            for r in &mut f.records {
                r.header.system_id = u32::from(i) + 1;
                r.t_us += delay_us;
            }
            Ok(f)
        })
        .collect()
}

/// Every vehicle's messages as one stream in time order (ties: lower system id first).
pub fn merge(flights: &[SimFlight]) -> Vec<SimRecord> {
    let mut all: Vec<SimRecord> = flights
        .iter()
        .flat_map(|f| f.records.iter().cloned())
        .collect();
    all.sort_by_key(|r| r.t_us);
    all
}
