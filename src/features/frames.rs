//! Frame and unit conversions between MAVLink (NED world, FRD body, SI units) and the M100
//! data set's columns, which do not share one frame (`../shared/data/m100/SOURCE.md`).
//!
//! ## What the data show (flights 100, 150, 276; `tests/it/telemetry_frames.rs` re-checks it)
//!
//! Write `q_v` for the vehicle's attitude as MAVLink has it (FRD body → NED) and derive it
//! from the data-set quaternion by `q_v = Q ⊗ q_ds ⊗ Q`, `Q = (w 0, x √½, y √½, z 0)`, the
//! rotation that swaps x/y and negates z (ENU ↔ NED, and body right-forward-up ↔ FRD).
//! That is: **the data-set quaternion rotates a body frame x-right, y-forward, z-up into
//! ENU.** With that reading, against body rates differentiated from the quaternion and the
//! specific force `q_v* (a_gps − g) q_v` from GPS accelerations:
//!
//! | column | correlation with the FRD component (flights 100 / 150 / 276) |
//! |---|---|
//! | `angular_x/y/z` | 0.62 / 0.73 / 0.69, 0.89 / 0.86 / 0.86, 0.82 / 0.80 / 0.88 |
//! | `linear_acceleration_x/y/z` | 0.90 / 0.93 / 0.88, 0.69 / 0.66 / 0.78, 0.65 / 0.66 / 0.58 (mean z −9.81) |
//!
//! so rates and accelerations are plain FRD (as MAVLink sends them), while reading the
//! quaternion as FLU→ENU (SOURCE.md's "x forward, y left") puts the IMU's x and y 90° off
//! (x/y correlations near 0, and −0.6…−0.9 across). In cruise the vehicle moves along
//! `velocity_y` (mean |vy| 9.9 m/s, |vx| 0.3 m/s, flight 100), nose first: `velocity_*`
//! is the ground velocity in the heading frame **x right, y forward, z up** (correlation
//! with the rotated GPS velocity 0.84–0.97 for x, 1.00 for y, 0.55–0.80 for z; magnitude
//! about 0.95 × GPS ground speed). SOURCE.md's "x forward, y left" is the same frame named
//! after the quaternion's own axes.
//!
//! `wind_speed`/`wind_angle` are the apparent wind at the anemometer: in cruise (ground
//! speed > 4 m/s) `cos(wind_angle − course)` averages 0.80 / 0.80 / 0.88 with `wind_speed`
//! ≈ ground speed, so the angle is the direction the air comes FROM, degrees clockwise from
//! north (WIND's convention).
//!
//! | data-set column | convention | MAVLink source |
//! |---|---|---|
//! | `orientation_*` | body RFU → ENU, `w ≥ 0` | ATTITUDE_QUATERNION or ATTITUDE (FRD→NED) |
//! | `velocity_*` | heading frame: right, forward, up | NED velocity rotated by the heading |
//! | `angular_*` | FRD body rates | ATTITUDE / HIGHRES_IMU / SCALED_IMU / RAW_IMU, as they are |
//! | `linear_acceleration_*` | FRD specific force (z ≈ −9.81 at rest) | HIGHRES_IMU / SCALED_IMU / RAW_IMU, as they are |
//! | `wind_speed/_angle` | apparent wind, from-direction, deg from north | (WIND or WIND_COV) − ground velocity; VFR_HUD airspeed + heading |

/// A quaternion as `[w, x, y, z]`.
pub type Quat = [f64; 4];

const H: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// Swaps x and y and negates z: ENU ↔ NED on the world side, right-forward-up ↔ FRD on the
/// body side (its own inverse up to sign).
const Q_SWAP: Quat = [0.0, H, H, 0.0];

/// Hamilton product `a ⊗ b`.
pub fn qmul(a: Quat, b: Quat) -> Quat {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

fn qconj(q: Quat) -> Quat {
    [q[0], -q[1], -q[2], -q[3]]
}

/// Data-set quaternion (body RFU→ENU, `[w, x, y, z]`) → MAVLink attitude (FRD→NED,
/// `[w, x, y, z]`).
pub fn ds_to_ned(q_ds: Quat) -> Quat {
    qmul(qmul(Q_SWAP, q_ds), Q_SWAP)
}

/// MAVLink attitude (FRD→NED) → data-set quaternion (body RFU→ENU), both `[w, x, y, z]`.
/// Exact inverse of [`ds_to_ned`].
pub fn ned_to_ds(q_ned: Quat) -> Quat {
    qmul(qmul(qconj(Q_SWAP), q_ned), qconj(Q_SWAP))
}

/// Heading (yaw) of an FRD→NED quaternion, radians clockwise from north, in (−π, π].
pub fn yaw_ned(q: Quat) -> f64 {
    let [w, x, y, z] = q;
    (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
}

/// ZYX Euler angles (roll, pitch, yaw; radians, MAVLink ATTITUDE) of an FRD→NED quaternion.
pub fn euler_ned(q: Quat) -> [f64; 3] {
    let [w, x, y, z] = q;
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    [roll, pitch, yaw_ned(q)]
}

/// FRD→NED quaternion from MAVLink ATTITUDE's ZYX Euler angles (radians).
pub fn quat_from_euler(roll: f64, pitch: f64, yaw: f64) -> Quat {
    let (sr, cr) = (roll / 2.0).sin_cos();
    let (sp, cp) = (pitch / 2.0).sin_cos();
    let (sy, cy) = (yaw / 2.0).sin_cos();
    [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]
}

/// Rotate a vector by a quaternion (`q v q*`).
pub fn rotate(q: Quat, v: [f64; 3]) -> [f64; 3] {
    let r = qmul(qmul(q, [0.0, v[0], v[1], v[2]]), qconj(q));
    [r[1], r[2], r[3]]
}

/// NED ground velocity → the data set's (right, forward, up) velocity for heading `yaw`
/// (radians clockwise from north).
pub fn ned_to_body_vel(v_ned: [f64; 3], yaw: f64) -> [f64; 3] {
    let (s, c) = yaw.sin_cos();
    [
        -v_ned[0] * s + v_ned[1] * c,
        v_ned[0] * c + v_ned[1] * s,
        -v_ned[2],
    ]
}

/// The data set's (right, forward, up) velocity → NED for heading `yaw`. Inverse of
/// [`ned_to_body_vel`].
pub fn body_to_ned_vel(v: [f64; 3], yaw: f64) -> [f64; 3] {
    let (s, c) = yaw.sin_cos();
    [-v[0] * s + v[1] * c, v[0] * c + v[1] * s, -v[2]]
}

/// A horizontal wind given as (speed m/s, direction it blows FROM, degrees clockwise from
/// north) → the air's velocity (north, east), m/s.
pub fn wind_from_to_vec(speed: f64, from_deg: f64) -> [f64; 2] {
    let (s, c) = from_deg.to_radians().sin_cos();
    [-speed * c, -speed * s]
}

/// The air's velocity (north, east) → (speed m/s, direction it blows FROM in [0, 360) deg).
pub fn wind_vec_to_from(v: [f64; 2]) -> [f64; 2] {
    let speed = v[0].hypot(v[1]);
    let from = (-v[1]).atan2(-v[0]).to_degrees().rem_euclid(360.0);
    // rem_euclid can round up to exactly 360.0.
    [speed, if from >= 360.0 { 0.0 } else { from }]
}

/// What an anemometer on the vehicle reads (the data set's `wind_speed`, `wind_angle`):
/// the air's velocity relative to the vehicle, from the true wind (north, east) and the
/// ground velocity (north, east).
pub fn apparent_wind(true_wind_ne: [f64; 2], ground_ne: [f64; 2]) -> [f64; 2] {
    wind_vec_to_from([
        true_wind_ne[0] - ground_ne[0],
        true_wind_ne[1] - ground_ne[1],
    ])
}

/// The one Earth radius of every flat-earth conversion (the mean radius, to the km), m. The
/// readers, the simulator and the mission forecast all convert through the functions
/// below, so a position written by one reads back where it was.
pub const EARTH_RADIUS_M: f64 = 6_371_000.0;

/// Whether a latitude/longitude (degrees) is a position fix: finite, on the globe, and not
/// (0, 0), which autopilots send before they have a fix (and which no drone flies at).
pub fn is_fix(lat_deg: f64, lon_deg: f64) -> bool {
    lat_deg.abs() <= 90.0 && lon_deg.abs() <= 180.0 && (lat_deg != 0.0 || lon_deg != 0.0)
}

/// Horizontal distance between two WGS84 points (degrees), metres: equirectangular, good to
/// well under 0.1 % over the few kilometres a delivery drone flies.
pub fn ground_distance_m(lat1: f64, lon1: f64, lat2: f64, lon2: f64) -> f64 {
    let (dn, de) = ne_offset_m(lat1, lon1, lat2, lon2);
    dn.hypot(de)
}

/// North and east offset (m) of point 2 from point 1 (equirectangular, at the mean
/// latitude). [`offset_ne`] is its exact inverse.
pub fn ne_offset_m(lat1: f64, lon1: f64, lat2: f64, lon2: f64) -> (f64, f64) {
    let lat_m = ((lat1 + lat2) / 2.0).to_radians();
    (
        (lat2 - lat1).to_radians() * EARTH_RADIUS_M,
        (lon2 - lon1).to_radians() * EARTH_RADIUS_M * lat_m.cos(),
    )
}

/// The point `north_m`, `east_m` from (`lat_deg`, `lon_deg`): latitude, longitude (deg).
/// The inverse of [`ne_offset_m`].
pub fn offset_ne(lat_deg: f64, lon_deg: f64, north_m: f64, east_m: f64) -> (f64, f64) {
    let lat = lat_deg + (north_m / EARTH_RADIUS_M).to_degrees();
    let lat_m = ((lat_deg + lat) / 2.0).to_radians();
    let lon = lon_deg + (east_m / (EARTH_RADIUS_M * lat_m.cos())).to_degrees();
    (lat, lon)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < tol)
    }

    #[test]
    fn quaternion_conversion_round_trips_and_maps_axes() {
        let q = [0.2636, 0.0040, 0.0151, -0.9645];
        assert!(close(&ned_to_ds(ds_to_ned(q)), &q, 1e-12));
        // The data set's identity: body right = east, forward = north, up = up, which is
        // MAVLink's identity (level, nose north), up to the sign of the quaternion.
        let qn = ds_to_ned([1.0, 0.0, 0.0, 0.0]);
        assert!(close(&rotate(qn, [1.0, 0.0, 0.0]), &[1.0, 0.0, 0.0], 1e-12));
        assert!(close(&rotate(qn, [0.0, 1.0, 0.0]), &[0.0, 1.0, 0.0], 1e-12));
        // A data-set yaw of +90° (ENU, counter-clockwise) is a heading of 270° (west).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let qw = ds_to_ned([h, 0.0, 0.0, h]);
        assert!((yaw_ned(qw) + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn euler_round_trip() {
        let q = quat_from_euler(0.1, -0.2, 2.5);
        assert!(close(&euler_ned(q), &[0.1, -0.2, 2.5], 1e-12));
    }

    #[test]
    fn body_velocity_and_wind() {
        // Heading north, flying north at 5 m/s and climbing 1 m/s: forward is y.
        assert!(close(
            &ned_to_body_vel([5.0, 0.0, -1.0], 0.0),
            &[0.0, 5.0, 1.0],
            1e-12
        ));
        // Heading east, moving north = moving to the left (negative right).
        let v = ned_to_body_vel([1.0, 0.0, 0.0], std::f64::consts::FRAC_PI_2);
        assert!(close(&v, &[-1.0, 0.0, 0.0], 1e-12));
        assert!(close(
            &body_to_ned_vel(v, std::f64::consts::FRAC_PI_2),
            &[1.0, 0.0, 0.0],
            1e-12
        ));
        // Still air, flying north at 10 m/s: the apparent wind comes from the north.
        assert!(close(
            &apparent_wind([0.0, 0.0], [10.0, 0.0]),
            &[10.0, 0.0],
            1e-9
        ));
        // A 3 m/s wind from the west, hovering.
        let w = wind_from_to_vec(3.0, 270.0);
        assert!(close(&apparent_wind(w, [0.0, 0.0]), &[3.0, 270.0], 1e-9));
    }
}
