//! Tests of `src/source/links/mod.rs` (a file of their own: the module stays under 600 lines).

use super::*;

/// Heard first (handed on), the sender's sequence unbroken or broken before it.
const FIRST: Heard = Heard::First { gap: false };
const FIRST_AFTER_GAP: Heard = Heard::First { gap: true };

fn h(sys: u32, comp: u8, seq: u8) -> mavlink::MavHeader {
    mavlink::MavHeader {
        system_id: sys,
        component_id: comp,
        sequence: seq,
    }
}

#[test]
fn a_copy_within_the_window_is_a_duplicate_and_nothing_else_is() {
    let mut d = Dedup::default();
    assert_eq!(d.hear(0.0, 0, 0, &h(1, 1, 7), 0, 0), FIRST);
    // The same frame from the other radio, 40 ms later.
    assert_eq!(d.hear(0.04, 1, 0, &h(1, 1, 7), 0, 0), Heard::Duplicate);
    // Another message with the same numbers (another sender's stream): not a copy.
    assert_eq!(d.hear(0.05, 0, 0, &h(1, 1, 7), 33, 0), FIRST_AFTER_GAP);
    assert_eq!(d.hear(0.05, 0, 0, &h(1, 2, 7), 0, 0), FIRST);
    // The next frame; then one after a lost one.
    assert_eq!(d.hear(0.1, 0, 0, &h(1, 1, 8), 30, 0), FIRST);
    assert_eq!(d.hear(0.2, 0, 0, &h(1, 1, 10), 30, 0), FIRST_AFTER_GAP);
    // The sequence wrapped and the number came round again: new, not a copy.
    assert_eq!(
        d.hear(0.04 + DEDUP_WINDOW_S, 0, 0, &h(1, 1, 7), 0, 0),
        FIRST_AFTER_GAP
    );
    // The same numbers on another network: another vehicle, never a copy.
    assert_eq!(d.hear(1.1, 0, 0, &h(1, 1, 9), 0, 0), FIRST_AFTER_GAP);
    assert_eq!(d.hear(1.1, 0, 2, &h(1, 1, 9), 0, 0), FIRST);
}

/// A PX4 on USB: 2,200 frames/s from one component, so each sequence number comes round
/// every 116 ms, with a stuck sensor's message repeating the same bytes; two links carry
/// it, each losing 30 % independently, the second 3 ms late, or 200 frames late (most of a
/// sequence wrap: a reader starved under load). What is handed on is exactly the union of
/// what arrived: every copy dropped, no new frame taken for one.
#[test]
fn at_a_fast_link_s_rate_the_merge_hands_on_exactly_the_union() {
    for (frames_per_s, lag_frames) in [
        (110.0, 0.33),
        (2_200.0, 6.6),
        (11_000.0, 33.0),
        (2_200.0, 200.0),
        (11_000.0, 200.0),
    ] {
        let lag_s = |rate: f64| lag_frames / rate;
        let mut d = Dedup::default();
        let mut lcg = 0x2545_f491_u64;
        let mut lost = || {
            lcg = lcg.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (lcg >> 33) % 100 < 30
        };
        let (mut union, mut first, mut dup) = (0u32, 0u32, 0u32);
        let mut arrivals: Vec<(f64, usize, u8, u32, u64)> = Vec::new();
        for n in 0..20_000u32 {
            let t = f64::from(n) / frames_per_s;
            let seq = (n % 256) as u8;
            // Every 4th frame is the stuck sensor (same id, same bytes); the rest differ.
            let (id, fp) = if n % 4 == 0 {
                (29, 7)
            } else {
                (30, u64::from(n))
            };
            let (a, b) = (!lost(), !lost());
            union += u32::from(a || b);
            if a {
                arrivals.push((t, 0, seq, id, fp));
            }
            if b {
                arrivals.push((t + lag_s(frames_per_s), 1, seq, id, fp));
            }
        }
        arrivals.sort_by(|x, y| x.0.total_cmp(&y.0));
        for (t, link, seq, id, fp) in arrivals {
            match d.hear(t, link, 0, &h(1, 1, seq), id, fp) {
                Heard::First { .. } => first += 1,
                Heard::Duplicate => dup += 1,
            }
        }
        assert_eq!(
            first, union,
            "{frames_per_s} frames/s, the second link {lag_frames} frames late: {dup} dropped as copies"
        );
    }
}

#[test]
fn a_frame_with_the_same_numbers_and_other_bytes_is_not_a_copy() {
    let mut d = Dedup::default();
    assert_eq!(d.hear(0.0, 0, 0, &h(1, 1, 7), 30, 1), FIRST);
    assert_eq!(d.hear(0.01, 0, 0, &h(1, 1, 7), 30, 2), FIRST_AFTER_GAP);
    assert_eq!(d.hear(0.02, 1, 0, &h(1, 1, 7), 30, 2), Heard::Duplicate);
    use crate::dialect::{MavMessage, HEARTBEAT_DATA, SYS_STATUS_DATA};
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
    let st = |mv| {
        MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            voltage_battery: mv,
            ..Default::default()
        })
    };
    assert_eq!(fingerprint(&hb), fingerprint(&hb.clone()));
    assert_ne!(fingerprint(&st(12_600)), fingerprint(&st(12_601)));
}

#[test]
fn links_sharing_a_name_are_one_network_and_others_are_numbered_in_order() {
    let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let one = Networks::number(&names(&["", ""])).unwrap();
    assert_eq!(one.of_link, [0, 0]);
    assert_eq!(one.name(0), None);
    let same = Networks::number(&names(&["radio", "radio"])).unwrap();
    assert_eq!(
        same.of_link,
        [0, 0],
        "one name is one network, read as today"
    );
    let two = Networks::number(&names(&["", "", "lte"])).unwrap();
    assert_eq!(two.of_link, [1, 1, 2]);
    assert_eq!((two.name(1), two.name(2)), (Some("default"), Some("lte")));
    let named = Networks::number(&names(&["lte", "default", "lte"])).unwrap();
    assert_eq!(named.of_link, [1, 2, 1]);
}

/// A link cut for several sequence wraps comes back: its copies are still copies (it is
/// placed again by content, not by the number it last brought), and nothing new is lost.
#[test]
fn a_link_back_after_a_cut_of_many_wraps_still_merges_to_the_union() {
    let mut d = Dedup::default();
    let (mut union, mut first) = (0u32, 0u32);
    for n in 0..10_000u32 {
        let t = f64::from(n) / 2_200.0;
        let seq = (n % 256) as u8;
        let (id, fp) = if n % 4 == 0 {
            (29, 7)
        } else {
            (30, u64::from(n))
        };
        let a = n % 7 != 0;
        let b = !(3_000..6_000).contains(&n) && n % 5 != 0;
        union += u32::from(a || b);
        for (on, link, late) in [(a, 0, 0.0), (b, 1, 0.002)] {
            if on
                && matches!(
                    d.hear(t + late, link, 0, &h(1, 1, seq), id, fp),
                    Heard::First { .. }
                )
            {
                first += 1;
            }
        }
    }
    assert_eq!(first, union);
}
