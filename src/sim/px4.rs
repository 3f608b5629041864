//! PX4's way: PX4 main/sub modes in HEARTBEAT, ATTITUDE_QUATERNION at 10 Hz (and ATTITUDE
//! at 5 Hz), HIGHRES_IMU in SI units, EXTENDED_SYS_STATE (landed state) at 1 Hz, ALTITUDE
//! at 5 Hz, no WIND; parameters `BAT1_*`, the integer ones packed bytewise into the float
//! (PX4's encoding).

use nalgebra::{UnitQuaternion, Vector3};

use super::emit::{param, pressure_pa, Every, Imu, Instant, Style};
use super::{Frame, SimOptions, HOME};
use crate::dialect as d;
use crate::sim::guidance::Phase;
use crate::MavMessage;

/// PX4's telemetry style.
#[derive(Debug, Clone, Copy)]
pub struct Px4;

impl Style for Px4 {
    /// PX4: main mode in bits 16..24, sub mode in 24..32. AUTO = 4; sub: TAKEOFF 2,
    /// MISSION 4, LAND 6. Disarmed: POSCTL (3). The same for planes and VTOLs (PX4 says a
    /// VTOL's state in EXTENDED_SYS_STATE, not in its modes).
    fn custom_mode(&self, now: &Instant) -> u32 {
        let (main, sub) = match now.phase {
            Phase::Spinup | Phase::Climb => (4u32, 2u32),
            Phase::Descent | Phase::Landed => (4, 6),
            Phase::Leg(_) | Phase::Hold(_) => (4, 4),
            Phase::PreArm | Phase::Done => (3, 0),
        };
        (main << 16) | (sub << 24)
    }

    /// PX4: QUADROTOR, FIXED_WING, and VTOL_FIXEDROTOR (22, the standard VTOL) for a quadplane.
    fn mav_type(&self, frame: Frame) -> d::MavType {
        match frame {
            Frame::Multirotor => d::MavType::MAV_TYPE_QUADROTOR,
            Frame::Plane => d::MavType::MAV_TYPE_FIXED_WING,
            Frame::Quadplane => d::MavType::MAV_TYPE_VTOL_FIXEDROTOR,
        }
    }

    /// From the profile's `[battery]`: `BAT1_CAPACITY` (mAh, REAL32), `BAT1_N_CELLS`
    /// (INT32, its bytes in the float), `BAT1_V_CHARGED` 4.05 V and `BAT1_V_EMPTY` 3.6 V a
    /// cell (PX4 1.14's defaults).
    fn parameters(&self, opts: &SimOptions) -> Vec<d::PARAM_VALUE_DATA> {
        use d::MavParamType::{MAV_PARAM_TYPE_INT32 as INT32, MAV_PARAM_TYPE_REAL32 as REAL32};
        let Some(b) = &opts.vehicle.battery else {
            return Vec::new();
        };
        vec![
            param("BAT1_CAPACITY", b.capacity_mah as f32, REAL32),
            param("BAT1_N_CELLS", f32::from_bits(b.cells), INT32),
            param("BAT1_V_CHARGED", 4.05, REAL32),
            param("BAT1_V_EMPTY", 3.6, REAL32),
        ]
    }

    /// EXTENDED_SYS_STATE at 1 Hz (2 Hz for a VTOL: its transitions last seconds).
    fn landed_state(&self, now: &Instant) -> Option<MavMessage> {
        let every = if now.frame == Frame::Quadplane {
            Every::new(500, 0)
        } else {
            Every::new(1000, 500)
        };
        every
            .due(now.t_ms)
            .then(|| super::emit::extended_sys_state(now))
    }

    fn attitude(
        &self,
        now: &Instant,
        (roll, pitch, yaw): (f64, f64, f64),
        rates: &Vector3<f64>,
        out: &mut Vec<MavMessage>,
    ) {
        let q = UnitQuaternion::from_euler_angles(roll, pitch, yaw).cast::<f32>();
        let [rollspeed, pitchspeed, yawspeed] = rates.cast::<f32>().into();
        out.push(MavMessage::ATTITUDE_QUATERNION(
            d::ATTITUDE_QUATERNION_DATA {
                time_boot_ms: now.boot_ms(),
                q1: q.w,
                q2: q.i,
                q3: q.j,
                q4: q.k,
                rollspeed,
                pitchspeed,
                yawspeed,
                repr_offset_q: [0.0; 4],
            },
        ));
        if Every::new(200, 30).due(now.t_ms) {
            out.push(super::emit::attitude(now, (roll, pitch, yaw), rates));
        }
    }

    fn imu(&self, now: &Instant, Imu { f, w, mag }: &Imu) -> MavMessage {
        let alt = now.alt_amsl_m();
        let (f, w, mag) = (f.cast::<f32>(), w.cast::<f32>(), mag.cast::<f32>());
        MavMessage::HIGHRES_IMU(d::HIGHRES_IMU_DATA {
            time_usec: now.t_ms * 1000,
            xacc: f.x,
            yacc: f.y,
            zacc: f.z,
            xgyro: w.x,
            ygyro: w.y,
            zgyro: w.z,
            xmag: mag.x,
            ymag: mag.y,
            zmag: mag.z,
            abs_pressure: (pressure_pa(alt) / 100.0) as f32,
            diff_pressure: 0.0,
            pressure_alt: alt as f32,
            temperature: 25.0,
            fields_updated: d::HighresImuUpdatedFlags::all(),
            id: 0,
        })
    }

    /// ALTITUDE at 5 Hz: the barometric altitude carries 30 % of the GNSS vertical error.
    fn air_data(&self, now: &Instant) -> Option<MavMessage> {
        if !Every::new(200, 80).due(now.t_ms) {
            return None;
        }
        let amsl = (now.alt_amsl_m() + now.gps_err.z * 0.3) as f32;
        let home = HOME.alt_amsl_m as f32;
        Some(MavMessage::ALTITUDE(d::ALTITUDE_DATA {
            time_usec: now.t_ms * 1000,
            altitude_monotonic: amsl,
            altitude_amsl: amsl,
            altitude_local: amsl - home,
            altitude_relative: amsl - home,
            altitude_terrain: f32::NAN,
            bottom_clearance: f32::NAN,
        }))
    }
}
