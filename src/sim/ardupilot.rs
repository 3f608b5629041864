//! ArduPilot's way: ArduCopter flight modes in HEARTBEAT (ArduPlane's for a plane, with
//! its Q modes and EXTENDED_SYS_STATE `vtol_state` for a quadplane), ATTITUDE (Euler) at
//! 10 Hz, RAW_IMU in ArduPilot's scaling (mG, mrad/s, mgauss), WIND at 2 Hz, no
//! quaternion, no landed state; parameters `BATT_*`, `MOT_THST_HOVER`, `FRAME_CLASS`, the
//! integer ones cast to the float (ArduPilot's encoding).

use super::emit::{param, Every, Imu, Instant, Style};
use super::{Frame, SimOptions};
use crate::dialect as d;
use crate::features::units::G;
use crate::features::VtolState;
use crate::sim::guidance::Phase;
use crate::MavMessage;

/// ArduPilot Copter's telemetry style.
#[derive(Debug, Clone, Copy)]
pub struct ArduPilot;

impl Style for ArduPilot {
    /// ArduCopter: STABILIZE 0 on the ground, AUTO 3 flying the mission, LAND 9.
    /// ArduPlane: MANUAL 0 on the ground, TAKEOFF 13, AUTO 10 (legs, loiters, the landing).
    /// An ArduPlane quadplane: QLOITER 19 on the ground, QHOVER 18 in the VTOL climb,
    /// AUTO 10 through the transitions and forward flight, QLAND 20 once back on its rotors.
    fn custom_mode(&self, now: &Instant) -> u32 {
        match (now.frame, now.phase) {
            (Frame::Multirotor, Phase::PreArm | Phase::Done) => 0,
            (Frame::Multirotor, Phase::Descent | Phase::Landed) => 9,
            (Frame::Multirotor, _) => 3,
            (Frame::Plane, Phase::PreArm | Phase::Done) => 0,
            (Frame::Plane, Phase::Spinup | Phase::Climb) => 13,
            (Frame::Plane, _) => 10,
            (Frame::Quadplane, Phase::PreArm | Phase::Done) => 19,
            (Frame::Quadplane, Phase::Spinup | Phase::Climb) => 18,
            (Frame::Quadplane, Phase::Descent | Phase::Landed) if now.st.vtol == VtolState::Mc => {
                20
            }
            (Frame::Quadplane, _) => 10,
        }
    }

    /// ArduCopter QUADROTOR; ArduPlane FIXED_WING, for a quadplane too (`Q_MAV_TYPE` 0 on
    /// many builds: the type the quadplane log said).
    fn mav_type(&self, frame: Frame) -> d::MavType {
        match frame {
            Frame::Multirotor => d::MavType::MAV_TYPE_QUADROTOR,
            Frame::Plane | Frame::Quadplane => d::MavType::MAV_TYPE_FIXED_WING,
        }
    }

    /// From the profile's `[battery]`: `BATT_CAPACITY` (mAh, INT32), `BATT_LOW_VOLT` and
    /// `BATT_CRT_VOLT` (3.6 and 3.5 V a cell, Mission Planner's initial-setup values for
    /// LiPo; 3.5 and 3.4 V for a LiHV pack), `BATT_LOW_MAH` and `BATT_CRT_MAH` (20 % and 10 % of the capacity left);
    /// `MOT_THST_HOVER` 0.5 (the simulator's VFR_HUD throttle in the hover is 50 %);
    /// `MOT_BAT_VOLT_MAX` / `MOT_BAT_VOLT_MIN` (cells × 4.35 for a LiHV pack, else × 4.2;
    /// cells × 3.3);
    /// `FRAME_CLASS` 1 (quad, INT8). A plane: the `BATT_*` ones, `ARSPD_FBW_MIN`,
    /// `TRIM_ARSPD_CM` and `ROLL_LIMIT_DEG` from `[plane]` (a quadplane also `Q_ENABLE` 1)
    /// instead of the copter's motor and frame ones.
    fn parameters(&self, opts: &SimOptions) -> Vec<d::PARAM_VALUE_DATA> {
        use d::MavParamType::{
            MAV_PARAM_TYPE_INT32 as INT32, MAV_PARAM_TYPE_INT8 as INT8,
            MAV_PARAM_TYPE_REAL32 as REAL32,
        };
        let Some(b) = &opts.vehicle.battery else {
            return Vec::new();
        };
        let (mah, cells) = (b.capacity_mah, f64::from(b.cells));
        let lihv = super::physics::Battery::facts(b).chemistry.value == "lihv";
        // LiHV: 4.35 V full; its failsafe a cell lower (3.5 / 3.4 V: the data set's M100
        // flights fly down to 3.5 V a cell under load).
        let (full_cell, low_cell) = if lihv { (4.35, 3.5) } else { (4.2, 3.6) };
        let mut out = vec![
            param("BATT_CAPACITY", mah.round() as i32 as f32, INT32),
            param("BATT_LOW_VOLT", (low_cell * cells) as f32, REAL32),
            param("BATT_CRT_VOLT", ((low_cell - 0.1) * cells) as f32, REAL32),
            param("BATT_LOW_MAH", (0.2 * mah) as f32, REAL32),
            param("BATT_CRT_MAH", (0.1 * mah) as f32, REAL32),
        ];
        if let Some(pl) = &opts.vehicle.plane {
            let stall = super::plane::Wing::new(pl, opts.vehicle.mass_kg(0.0)).stall_mps(1.225);
            out.extend([
                param("ARSPD_FBW_MIN", (1.25 * stall).round() as f32, INT32),
                param(
                    "TRIM_ARSPD_CM",
                    (pl.cruise_mps * 100.0).round() as f32,
                    INT32,
                ),
                param("ROLL_LIMIT_DEG", pl.bank_limit_deg as f32, INT32),
            ]);
            if Frame::of(&opts.vehicle) == Frame::Quadplane {
                out.push(param("Q_ENABLE", 1.0, INT8));
            }
            return out;
        }
        out.extend([
            param("MOT_THST_HOVER", 0.5, REAL32),
            // The pack's full and empty voltages, as ArduCopter's voltage scaling holds them
            // (cells × 4.2 or 4.35, cells × 3.3): who the pack is.
            param("MOT_BAT_VOLT_MAX", (full_cell * cells) as f32, REAL32),
            param("MOT_BAT_VOLT_MIN", (3.3 * cells) as f32, REAL32),
            param("FRAME_CLASS", 1.0, INT8),
        ]);
        out
    }

    /// A quadplane's EXTENDED_SYS_STATE (its `vtol_state`, ArduPlane's landed state) at
    /// 2 Hz; none for a copter or a plane.
    fn landed_state(&self, now: &Instant) -> Option<MavMessage> {
        (now.frame == Frame::Quadplane && Every::new(500, 10).due(now.t_ms))
            .then(|| super::emit::extended_sys_state(now))
    }

    /// RAW_IMU carries acceleration in mG, rates in mrad/s and the field in mgauss
    /// (ArduPilot's send_raw_imu scales by 1000/GRAVITY_MSS).
    fn imu(&self, now: &Instant, Imu { f, w, mag }: &Imu) -> MavMessage {
        let mg = |x: f64| (x * 1000.0 / G).round().clamp(-32768.0, 32767.0) as i16;
        let milli = |x: f64| (x * 1000.0).round().clamp(-32768.0, 32767.0) as i16;
        MavMessage::RAW_IMU(d::RAW_IMU_DATA {
            time_usec: now.t_ms * 1000,
            xacc: mg(f.x),
            yacc: mg(f.y),
            zacc: mg(f.z),
            xgyro: milli(w.x),
            ygyro: milli(w.y),
            zgyro: milli(w.z),
            xmag: milli(mag.x),
            ymag: milli(mag.y),
            zmag: milli(mag.z),
            id: 0,
            temperature: 2500,
        })
    }

    /// WIND at 2 Hz: ArduPilot's direction is degrees(atan2(−wind.y, −wind.x)), where the
    /// wind comes from.
    fn air_data(&self, now: &Instant) -> Option<MavMessage> {
        if !Every::new(500, 70).due(now.t_ms) {
            return None;
        }
        let w = now.wind_est;
        Some(MavMessage::WIND(d::WIND_DATA {
            direction: (-w.y).atan2(-w.x).to_degrees() as f32,
            speed: (w.x.powi(2) + w.y.powi(2)).sqrt() as f32,
            speed_z: w.z as f32,
        }))
    }
}
