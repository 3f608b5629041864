//! The plan a planner would have had for a data-set flight (what `plan-eval` forecasts).
//!
//! ## How each flight's plan is built
//!
//! The M100 flights fly fixed delivery routes: take off at home, fly to the route's
//! waypoints, return, land. For each route flight:
//! - **home** is the flight's own first GPS fix (where it stood before take-off);
//! - **waypoints** (geometry only) come from the nearest-numbered *training* flight of the
//!   same route (test flights excluded, and never the flight itself); routes with no
//!   other training flight (R2, R3, R4, and the test-only R6 and R7) use the flight's own
//!   track: the part above 50 % of the first/last commanded altitude (GPS altitude drifts: flight 275 cruises at 18 m by it, commanded 25), reduced to its
//!   corners by Ramer–Douglas–Peucker on the horizontal track (tolerance `RDP_TOL_M`),
//!   corners within `HOME_RADIUS_M` of home dropped (take-off and landing are there).
//!   Nothing of the track's timing, speed profile or power is used;
//! - **altitudes** are the flight's commanded ones (`parameters.csv`): one altitude, or
//!   for multi-stage routes (R7, `25-50-100-25`) each corner gets the stage nearest to the
//!   track's height there, and a last waypoint over home at the last stage before landing;
//! - **speed** and **payload** are the commanded ones; **wind** is the anemometer's mean
//!   over the rows before take-off (the ground wind a planner would look up), unless
//!   `--no-ground-wind`.

use anyhow::Context;

use dronewatt::mission::plan::{GeoPoint, Plan};
use dronewatt::mission::trajectory::{enu_of, Wind};
use dronewatt::source::logs::dataset::{self, Flight};

/// Electrical power above which the vehicle counts as flying (motors spun up), W.
pub const AIRBORNE_W: f64 = 150.0;

/// Corner tolerance of the track reduction, m.
pub const RDP_TOL_M: f64 = 10.0;
/// Corners this close to home (horizontally) are take-off/landing, not waypoints, m.
pub const HOME_RADIUS_M: f64 = 15.0;

/// Ramer–Douglas–Peucker: indices of the corners of a polyline kept within `tol` (m).
pub fn rdp(points: &[(f64, f64)], tol: f64) -> Vec<usize> {
    fn rec(p: &[(f64, f64)], a: usize, b: usize, tol: f64, keep: &mut Vec<usize>) {
        let (ax, ay) = p[a];
        let (bx, by) = p[b];
        let (dx, dy) = (bx - ax, by - ay);
        let len = dx.hypot(dy);
        let mut worst = (0.0, a);
        for (i, &(x, y)) in p.iter().enumerate().take(b).skip(a + 1) {
            let d = if len > 1e-9 {
                ((x - ax) * dy - (y - ay) * dx).abs() / len
            } else {
                (x - ax).hypot(y - ay)
            };
            if d > worst.0 {
                worst = (d, i);
            }
        }
        if worst.0 > tol {
            rec(p, a, worst.1, tol, keep);
            keep.push(worst.1);
            rec(p, worst.1, b, tol, keep);
        }
    }
    if points.len() < 2 {
        return (0..points.len()).collect();
    }
    let mut keep = vec![0];
    rec(points, 0, points.len() - 1, tol, &mut keep);
    keep.push(points.len() - 1);
    keep
}

fn stages(f: &Flight) -> Vec<f64> {
    let s: Vec<f64> = f
        .altitude_text
        .split('-')
        .filter_map(|x| x.trim().parse::<f64>().ok())
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if s.is_empty() {
        vec![f.altitude_m]
    } else {
        s
    }
}

fn home_of(f: &Flight) -> Option<GeoPoint> {
    let r = f
        .rows
        .iter()
        .find(|r| r.lat_deg != 0.0 || r.lon_deg != 0.0)?;
    Some(GeoPoint {
        lat_deg: r.lat_deg,
        lon_deg: r.lon_deg,
        alt_m: r.alt_m,
    })
}

/// The route's waypoints (lat, lon, and the height above home there, m) from a flight's
/// track: the part above 50 % of the first/last stage, reduced to its corners.
fn route_corners(f: &Flight) -> Option<Vec<(f64, f64, f64)>> {
    let home = home_of(f)?;
    let st = stages(f);
    let (first, last) = (st[0], st[st.len() - 1]);
    let h = |r: &dataset::Row| r.alt_m - home.alt_m;
    let a = f.rows.iter().position(|r| h(r) > 0.5 * first)?;
    let b = f.rows.iter().rposition(|r| h(r) > 0.5 * last)?;
    if b <= a {
        return None;
    }
    let pts: Vec<(f64, f64)> = f.rows[a..=b]
        .iter()
        .map(|r| enu_of(&home, r.lat_deg, r.lon_deg))
        .collect();
    let keep = rdp(&pts, RDP_TOL_M);
    Some(
        keep.into_iter()
            .filter(|&i| pts[i].0.hypot(pts[i].1) > HOME_RADIUS_M)
            .map(|i| {
                let r = &f.rows[a + i];
                (r.lat_deg, r.lon_deg, h(r))
            })
            .collect(),
    )
}

/// The plan a planner would have had for flight `f`, with waypoints from `geometry`'s
/// track (another training flight of the route, or `f` itself).
pub fn flight_plan(f: &Flight, geometry: &Flight) -> anyhow::Result<Plan> {
    let home = home_of(f).with_context(|| format!("flight {}: no GPS fix", f.flight))?;
    let corners = route_corners(geometry).with_context(|| {
        format!(
            "flight {}: no cruise part to take waypoints from",
            geometry.flight
        )
    })?;
    let st = stages(f);
    let nearest = |h: f64| {
        st.iter().copied().fold(
            st[0],
            |b, s| if (s - h).abs() < (b - h).abs() { s } else { b },
        )
    };
    let single = st.len() == 1;
    let mut wps: Vec<GeoPoint> = corners
        .iter()
        .map(|&(lat, lon, h)| GeoPoint {
            lat_deg: lat,
            lon_deg: lon,
            alt_m: if single { st[0] } else { nearest(h) },
        })
        .collect();
    let last = st[st.len() - 1];
    if wps.last().is_some_and(|w| (w.alt_m - last).abs() > 0.5) {
        wps.push(GeoPoint {
            alt_m: last,
            ..home
        });
    }
    let mut plan = Plan::from_waypoints(
        &format!(
            "flight {} ({}, waypoints from flight {})",
            f.flight, f.route, geometry.flight
        ),
        home,
        &wps,
        f.speed_m_s,
    );
    // take-off to the first stage (the first waypoint may be at a later stage)
    for it in plan.items.iter_mut() {
        if let dronewatt::mission::plan::ItemKind::Takeoff { alt_m } = &mut it.kind {
            *alt_m = st[0];
        }
    }
    Ok(plan)
}

/// The flight whose track gives `f`'s waypoints: the nearest-numbered training flight of
/// the same route other than `f`, else `f` itself.
pub(crate) fn geometry_for<'a>(f: &'a Flight, all_train: &[&'a Flight]) -> &'a Flight {
    all_train
        .iter()
        .filter(|g| g.route == f.route && g.flight != f.flight)
        .min_by_key(|g| g.flight.abs_diff(f.flight))
        .copied()
        .unwrap_or(f)
}

/// Mean anemometer reading before take-off, as the wind (the ground wind a planner looks up).
pub(crate) fn ground_wind(f: &Flight) -> Wind {
    let pre: Vec<&dataset::Row> = f
        .rows
        .iter()
        .take_while(|r| r.voltage_v * r.current_a < AIRBORNE_W)
        .collect();
    if pre.is_empty() {
        return Wind::default();
    }
    // average as a vector (bearing the wind comes from)
    let (mut e, mut n) = (0.0, 0.0);
    for r in &pre {
        let b = r.wind_angle.to_radians();
        e += r.wind_speed * b.sin();
        n += r.wind_speed * b.cos();
    }
    let k = pre.len() as f64;
    let (e, n) = (e / k, n / k);
    Wind {
        speed_m_s: e.hypot(n).min(40.0),
        from_deg: e.atan2(n).to_degrees().rem_euclid(360.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rdp_keeps_the_corners_of_a_noisy_square() {
        let mut pts = Vec::new();
        for i in 0..=100 {
            pts.push((i as f64, 0.3 * ((i * 7) % 3) as f64));
        }
        for i in 1..=100 {
            pts.push((100.0 + 0.3 * ((i * 5) % 3) as f64, i as f64));
        }
        let keep = rdp(&pts, 2.0);
        assert_eq!(keep, vec![0, 100, 200]);
    }
}
