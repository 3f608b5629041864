//! Tests of the parent module.

use super::*;

#[test]
fn crc_matches_rust_mavlink() {
    let data = [1u8, 2, 3, 250, 251, 0, 7];
    assert_eq!(crc16(&data, 50), mavlink::calculate_crc(&data, 50));
}

#[test]
fn crc_is_mcrf4xx_and_crc_extra_is_the_published_table() {
    // CRC-16/MCRF4XX check value: "123456789" → 0x6F91 (the last byte rides as `extra`).
    assert_eq!(crc16(b"12345678", b'9'), 0x6F91);
    // CRC_EXTRA of the messages dronewatt reads, as common.xml / ardupilotmega.xml
    // generate them (pymavlink's mavlink_map and the C headers agree).
    for (id, extra) in [
        (0, 50),    // HEARTBEAT
        (1, 124),   // SYS_STATUS
        (24, 24),   // GPS_RAW_INT
        (27, 144),  // RAW_IMU
        (30, 39),   // ATTITUDE
        (32, 185),  // LOCAL_POSITION_NED
        (33, 104),  // GLOBAL_POSITION_INT
        (36, 222),  // SERVO_OUTPUT_RAW
        (74, 20),   // VFR_HUD
        (147, 154), // BATTERY_STATUS
        (168, 1),   // WIND (ardupilotmega)
        (242, 104), // HOME_POSITION
        (251, 170), // NAMED_VALUE_FLOAT
        (253, 83),  // STATUSTEXT
    ] {
        assert_eq!(crc_extra(id), Some(extra), "message id {id}");
    }
}

#[test]
fn unknown_ids_are_unknown_and_known_ones_known() {
    assert!(crc_extra(0).is_some()); // HEARTBEAT
    assert!(crc_extra(147).is_some()); // BATTERY_STATUS
    assert!(crc_extra(60_000).is_none());
    assert!(crc_extra(0xFF_FFFF).is_none());
}
