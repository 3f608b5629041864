//! What a MAVLink message says about the pack's electrical power: one reading rule for
//! every stage that counts it (the telemetry stage's measured power, the live mission
//! forecast's energy so far), so the two cannot disagree on which messages count.
//!
//! - BATTERY_STATUS of battery 0: the cell voltages summed (`voltages`, `UINT16_MAX` absent;
//!   `voltages_ext`, 0 absent) × `current_battery`; rank 0, preferred.
//! - SYS_STATUS: `voltage_battery` × `current_battery`; rank 1. 0 V and `UINT16_MAX` are "no
//!   voltage" (an autopilot without a voltage monitor sends 0), so a current without a
//!   voltage is no power reading rather than 0 W.
//! - A current of −1 is "not measured" in both: no reading.

use crate::MavMessage;

/// One power reading from a message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerReading {
    /// Which message it came from: 0 BATTERY_STATUS (battery 0), 1 SYS_STATUS. A stage that
    /// hears both follows the lower rank.
    pub rank: usize,
    /// Pack voltage, V.
    pub voltage_v: f64,
    /// Pack current, A (positive discharging).
    pub current_a: f64,
}

impl PowerReading {
    /// V × I, W.
    pub fn power_w(&self) -> f64 {
        self.voltage_v * self.current_a
    }
}

/// The power reading `m` carries, if any (see the module docs for the rule).
pub fn power_reading(m: &MavMessage) -> Option<PowerReading> {
    let (rank, mv, centiamps) = match m {
        MavMessage::BATTERY_STATUS(b) if b.id == 0 => {
            let cells = b.voltages.iter().filter(|&&c| c != u16::MAX);
            let ext = b.voltages_ext.iter().filter(|&&c| c != 0);
            let mv: f64 = cells.chain(ext).map(|&c| f64::from(c)).sum();
            (0, mv, b.current_battery)
        }
        MavMessage::SYS_STATUS(s) if !matches!(s.voltage_battery, 0 | u16::MAX) => {
            (1, f64::from(s.voltage_battery), s.current_battery)
        }
        _ => return None,
    };
    (centiamps != -1 && mv > 0.0).then(|| PowerReading {
        rank,
        voltage_v: mv * 1e-3,
        current_a: f64::from(centiamps) * 0.01,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect as d;

    fn sys(mv: u16, ca: i16) -> MavMessage {
        MavMessage::SYS_STATUS(d::SYS_STATUS_DATA {
            voltage_battery: mv,
            current_battery: ca,
            ..Default::default()
        })
    }

    fn batt(id: u8, cells: &[u16], ca: i16) -> MavMessage {
        let mut voltages = [u16::MAX; 10];
        voltages[..cells.len()].copy_from_slice(cells);
        MavMessage::BATTERY_STATUS(d::BATTERY_STATUS_DATA {
            id,
            voltages,
            current_battery: ca,
            ..Default::default()
        })
    }

    #[test]
    fn sys_status_without_voltage_or_current_is_no_reading() {
        let r = power_reading(&sys(22_800, 1_500)).unwrap();
        assert_eq!((r.rank, r.voltage_v, r.current_a), (1, 22.8, 15.0));
        assert!((r.power_w() - 342.0).abs() < 1e-9);
        assert_eq!(
            power_reading(&sys(0, 1_500)),
            None,
            "0 V: no voltage monitor"
        );
        assert_eq!(power_reading(&sys(u16::MAX, 1_500)), None);
        assert_eq!(
            power_reading(&sys(22_800, -1)),
            None,
            "current not measured"
        );
        assert_eq!(
            power_reading(&sys(22_800, 0)).unwrap().power_w(),
            0.0,
            "0 A is 0 W"
        );
    }

    #[test]
    fn battery_status_sums_the_cells_it_has() {
        // A full 3S pack at exactly 4.2 V a cell, 10 A.
        let r = power_reading(&batt(0, &[4_200, 4_200, 4_200], 1_000)).unwrap();
        assert_eq!(r.rank, 0);
        assert!((r.voltage_v - 12.6).abs() < 1e-9 && (r.current_a - 10.0).abs() < 1e-12);
        assert_eq!(
            power_reading(&batt(1, &[4_200; 3], 1_000)),
            None,
            "battery 1"
        );
        assert_eq!(power_reading(&batt(0, &[4_200; 3], -1)), None);
        assert_eq!(power_reading(&batt(0, &[], 1_000)), None, "no cells");
    }
}
