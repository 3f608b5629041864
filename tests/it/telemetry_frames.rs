//! The frame conventions of the data set's columns, checked on real flights (100, 150,
//! 276) against what the GPS and the quaternion imply. This is the evidence behind
//! `telemetry::frames`: if these correlations fail, the live path would feed the models
//! features in the wrong frame.
//!
//! Needs the data set (`DRONEWATT_DATA`).

use dronewatt::features::frames::{
    ds_to_ned, ne_offset_m, ned_to_body_vel, qmul, rotate, yaw_ned, Quat,
};
use dronewatt::source::logs::dataset::{read_flights, Row};

fn corr(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

fn conj(q: Quat) -> Quat {
    [q[0], -q[1], -q[2], -q[3]]
}

const K: usize = 5;

/// GPS velocity (north, east, down) at row j by central difference over ±K rows.
fn gps_vel(rs: &[Row], j: usize) -> [f64; 3] {
    let (a, c) = (&rs[j - K], &rs[j + K]);
    let dt = c.time_s - a.time_s;
    let (n, e) = ne_offset_m(a.lat_deg, a.lon_deg, c.lat_deg, c.lon_deg);
    [n / dt, e / dt, -(c.alt_m - a.alt_m) / dt]
}

/// Per flight: correlations of (angular x/y/z, acceleration x/y/z, velocity x/y/z) with
/// what the quaternion and GPS predict under `attitude` (data-set quaternion → FRD→NED),
/// and the mean cosine between `wind_angle` and the course in cruise.
fn check(rs: &[Row], attitude: impl Fn(&Row) -> Quat) -> ([f64; 9], f64) {
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); 18];
    let mut cos = Vec::new();
    for i in 2 * K..rs.len() - 2 * K {
        if rs[i + 2 * K].time_s - rs[i - 2 * K].time_s > 4.0 {
            continue; // skip gaps
        }
        let q = attitude(&rs[i]);
        let (mut qa, qc) = (attitude(&rs[i - 1]), attitude(&rs[i + 1]));
        if qa.iter().zip(&qc).map(|(x, y)| x * y).sum::<f64>() < 0.0 {
            qa = qa.map(|x| -x);
        }
        let dt = rs[i + 1].time_s - rs[i - 1].time_s;
        let dq = [0, 1, 2, 3].map(|k| (qc[k] - qa[k]) / dt);
        let w = qmul(conj(q), dq);
        let v = gps_vel(rs, i);
        let (v1, v2) = (gps_vel(rs, i - K), gps_vel(rs, i + K));
        let da = rs[i + K].time_s - rs[i - K].time_s;
        let a = [0, 1, 2].map(|k| (v2[k] - v1[k]) / da);
        let f = rotate(conj(q), [a[0], a[1], a[2] - 9.81]);
        let vb = ned_to_body_vel(v, yaw_ned(q));
        let r = &rs[i];
        let got = [
            r.ang[0], r.ang[1], r.ang[2], r.acc[0], r.acc[1], r.acc[2], r.vel[0], r.vel[1],
            r.vel[2],
        ];
        let want = [
            2.0 * w[1],
            2.0 * w[2],
            2.0 * w[3],
            f[0],
            f[1],
            f[2],
            vb[0],
            vb[1],
            vb[2],
        ];
        for k in 0..9 {
            cols[k].push(got[k]);
            cols[9 + k].push(want[k]);
        }
        if v[0].hypot(v[1]) > 4.0 {
            let course = v[1].atan2(v[0]);
            cos.push((r.wind_angle.to_radians() - course).cos());
        }
    }
    let c = std::array::from_fn(|k| corr(&cols[k], &cols[9 + k]));
    (c, cos.iter().sum::<f64>() / cos.len() as f64)
}

#[test]
fn columns_follow_the_documented_frames_on_flights_100_150_276() {
    let ds = read_flights(&dronewatt::default_data_path(), Some(&[100, 150, 276]))
        .expect("data set readable");
    assert_eq!(ds.flights.len(), 3);
    for f in &ds.flights {
        let (c, wind_cos) = check(&f.rows, |r| ds_to_ned(r.q_wxyz()));
        let names = [
            "angular_x",
            "angular_y",
            "angular_z",
            "acc_x",
            "acc_y",
            "acc_z",
            "velocity_x",
            "velocity_y",
            "velocity_z",
        ];
        // Documented mapping: every column correlates positively and clearly.
        for (k, n) in names.iter().enumerate() {
            assert!(
                c[k] > 0.5,
                "flight {}: {n} vs its predicted FRD/heading-frame value: r = {:.2}",
                f.flight,
                c[k]
            );
        }
        assert!(
            c[6] > 0.8 && c[7] > 0.9,
            "flight {}: velocities r = {:.2}, {:.2}",
            f.flight,
            c[6],
            c[7]
        );
        // The apparent wind comes from the direction of travel: a from-direction from north.
        assert!(
            wind_cos > 0.7,
            "flight {}: mean cos(wind_angle − course) = {wind_cos:.2}",
            f.flight
        );
        // In cruise the vehicle moves along velocity_y (forward), not velocity_x.
        let cruise: Vec<&Row> = f
            .rows
            .iter()
            .filter(|r| r.vel[0].hypot(r.vel[1]) > 5.0)
            .collect();
        let mean =
            |k: usize| cruise.iter().map(|r| r.vel[k].abs()).sum::<f64>() / cruise.len() as f64;
        assert!(
            mean(1) > 5.0 * mean(0),
            "flight {}: |vy| {:.2} vs |vx| {:.2}",
            f.flight,
            mean(1),
            mean(0)
        );

        // The reading SOURCE.md started from (quaternion as body FLU → ENU, i.e. ours turned
        // by 90° about the body z axis) leaves the IMU's x and y uncorrelated.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let (alt, _) = check(&f.rows, |r| qmul(ds_to_ned(r.q_wxyz()), [h, 0.0, 0.0, h]));
        for k in [0, 1, 3, 4] {
            assert!(
                alt[k].abs() < 0.35,
                "flight {}: FLU reading of {}: r = {:.2}",
                f.flight,
                names[k],
                alt[k]
            );
        }
    }
}
