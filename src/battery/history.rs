//! What one flight leaves of its pack for the next: the resistance it showed, its warmth,
//! the resting voltage it landed at, and how long ago. Kept by the vehicle store, carried in
//! when the same pack flies again soon (the data set's packs flown again within
//! [`SAME_PACK_GAP_S`] were the same pack).

/// What the last flight of a vehicle left of its pack: carried into the next flight when it
/// starts soon after on what looks like the same pack.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackHistory {
    /// Seconds since that flight ended.
    pub gap_s: f64,
    /// Its resistance scale.
    pub r_scale: Option<f64>,
    /// Its heat proxy at the end, A²·s.
    pub heat: f64,
    /// Its resting voltage after landing, V.
    pub end_rest_v: Option<f64>,
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
            && (0.0..=SAME_PACK_GAP_S).contains(&self.gap_s)
            && self
                .end_rest_v
                .is_none_or(|end| rest_v >= end - 0.02 * n && rest_v <= end + 0.15 * n)
    }
}
