//! What one flight leaves of its pack for the next: the resistance it showed, its warmth,
//! the resting voltage it landed at, and how long ago. Kept by the vehicle store, carried in
//! when the same pack flies again soon (the data set's packs flown again within
//! [`SAME_PACK_GAP_S`] were the same pack). Where the vehicle identifies its pack
//! (BATTERY_INFO's serial), the history is that pack's own last flight and the gap rule is
//! not needed: any gap is the same pack (its warmth has decayed over the gap).

/// What the last flight of a vehicle left of its pack: carried into the next flight when it
/// starts soon after on what looks like the same pack.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PackHistory {
    /// That flight was of the pack flying now by its identity (BATTERY_INFO's serial), not
    /// just the vehicle's last flight: the gap rule does not apply.
    pub identified: bool,
    /// Seconds since that flight ended.
    pub gap_s: f64,
    /// Its resistance scale.
    pub r_scale: Option<f64>,
    /// Its heat proxy at the end, A²·s.
    pub heat: f64,
    /// Its resting voltage after landing, V.
    pub end_rest_v: Option<f64>,
    /// The slope of its sag's growth as it empties, as that flight left it
    /// ([`super::deep`]): a property of the pack, carried whenever the pack is known to be the
    /// same (its identity, or [`PackHistory::same_pack`]), recharged or not.
    pub deep_slope: Option<f64>,
}

/// The longest gap after which a pack still counts as the same warm pack, s (the data set's
/// packs flown again within this were the same pack; beyond, packs were swapped or cold).
pub const SAME_PACK_GAP_S: f64 = 25.0 * 60.0;

impl PackHistory {
    /// Whether a pack resting at `rest_v` now is that flight's pack: soon enough, and its
    /// voltage no lower than it ended at and not much higher (relaxed, not recharged).
    pub fn same_pack(&self, rest_v: f64, cells: u32) -> bool {
        let n = f64::from(cells);
        self.gap_s.is_finite()
            && self.gap_s >= 0.0
            && (self.identified || self.gap_s <= SAME_PACK_GAP_S)
            && self
                .end_rest_v
                .is_none_or(|end| rest_v >= end - 0.02 * n && rest_v <= end + 0.15 * n)
    }
}

/// What the vehicle store holds of a vehicle's packs, for the energy stage to pick from once
/// it knows which pack flies ([`PackHistories::pick`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PackHistories {
    /// The vehicle's last flight, whatever its pack.
    pub last: Option<PackHistory>,
    /// Each identified pack's last flight on this vehicle, by pack id.
    pub by_pack: Vec<(String, PackHistory)>,
}

impl PackHistories {
    /// The history for the pack flying now: with an identity, that pack's own last flight
    /// (none when it never flew here: the vehicle's last flight was another pack, or one it
    /// did not identify); without one, the vehicle's last flight under the gap rule.
    pub fn pick(&self, pack_id: Option<&str>) -> Option<PackHistory> {
        match pack_id {
            Some(id) => self
                .by_pack
                .iter()
                .find(|(p, _)| p == id)
                .map(|(_, h)| PackHistory {
                    identified: true,
                    ..*h
                }),
            None => self.last.map(|h| PackHistory {
                identified: false,
                ..h
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hist(gap_s: f64) -> PackHistory {
        PackHistory {
            identified: false,
            gap_s,
            r_scale: Some(1.3),
            heat: 0.0,
            end_rest_v: Some(23.3),
            deep_slope: None,
        }
    }

    #[test]
    fn a_known_pack_carries_over_any_gap_an_unknown_one_only_a_short_one() {
        let day = hist(86_400.0);
        assert!(
            !day.same_pack(23.35, 6),
            "a day later, no identity: another pack"
        );
        let h = PackHistories {
            last: Some(hist(60.0)),
            by_pack: vec![("A".into(), day)],
        };
        let a = h.pick(Some("A")).expect("pack A flew here");
        assert!(a.identified && a.same_pack(23.35, 6), "{a:?}");
        assert!(!a.same_pack(25.9, 6), "recharged: its state is not carried");
        assert!(
            !PackHistory { gap_s: -60.0, ..a }.same_pack(23.35, 6),
            "an earlier flight"
        );
        assert_eq!(h.pick(Some("B")), None, "pack B never flew here");
        let v = h.pick(None).expect("the vehicle's last flight");
        assert!(!v.identified && v.same_pack(23.35, 6));
    }
}
